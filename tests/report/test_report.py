"""`wcs report`: the HTML report of a results file, its sections and its figures.

The results file of `wcs run` has the layout of wcs.results.dataset.run_dataset; `synthetic_run` builds one
in that layout from real forward solves, so the report is tested independently of the
search. Run `python -m tests.report.test_report STUDY.yaml OUT.nc [N]` to write such a file.
"""
from __future__ import annotations

import base64
import os
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import wcs
from wcs.cli import main
from wcs.status import flag_attrs
from wcs.report import SECTION_IDS, render_report, write_report
from wcs.results.dataset import provenance, write_netcdf

ROOT = Path(__file__).resolve().parents[2]
MESH_VARS = ("coords", "cells", "cell_body", "cell_region")
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


# ---------------------------------------------------------------- a synthetic run file

def synthetic_run(study_path, n=6, seed=0, failures=(), limits=None, stage=None,
                  certificates=None, with_fields=True) -> xr.Dataset:
    """A results Dataset in the layout of wcs.results.dataset.run_dataset from n real evaluations at
    points of the box (a random design plus the upper corner). `failures`: evaluation
    indices recorded as failed (status 1, phi NaN); `limits`: {criterion: limit}
    overriding the study's."""
    study = wcs.load_study(study_path)
    p = study.parameters
    rng = np.random.default_rng(seed)
    xs = p.lower + rng.random((n, len(p))) * (p.upper - p.lower)
    xs[-1] = p.upper
    names = [c.name for c in study.criteria]
    phi = np.full((n, len(names)), np.nan)
    status = np.zeros(n, np.int32)
    iterations = np.zeros(n, np.int32)
    wall = np.zeros(n)
    evs = {}
    for i, x in enumerate(xs):
        if i in failures:
            status[i] = 1
            continue
        ev = study.evaluate(x)
        status[i], iterations[i], wall[i] = ev.status, ev.iterations, ev.wall_time
        phi[i] = [ev.phi[c] for c in names]
        evs[i] = ev
    ok = np.isfinite(phi)
    best = [int(np.nanargmax(np.where(ok[:, j], phi[:, j], -np.inf))) for j in range(len(names))]
    lim = {**study.limits, **(limits or {})}
    ds = xr.Dataset(coords={"param": p.names, "criterion": names})
    ds["param_lower"] = ("param", p.lower)
    ds["param_upper"] = ("param", p.upper)
    ds["x"] = (("eval", "param"), xs)
    ds["phi"] = (("eval", "criterion"), phi)
    ds["status"] = xr.Variable("eval", status, flag_attrs())
    ds["stage"] = ("eval", np.array(stage or (["sample"] * (n - 2) + ["local"] * 2), dtype=object))
    ds["wall_time"] = xr.Variable("eval", wall, {"units": "s"})
    ds["iterations"] = xr.Variable("eval", iterations, {"long_name": "semismooth Newton iterations"})
    ds["worst_value"] = ("criterion", np.array([phi[b, j] for j, b in enumerate(best)]))
    ds["worst_x"] = (("criterion", "param"), xs[best])
    ds["limit"] = ("criterion", np.array([float(lim.get(c, np.nan)) for c in names]))
    if certificates is not False:
        ds["certificate"] = ("criterion", np.array(certificates or ["heuristic"] * len(names), dtype=object))
    if with_fields:
        fields = [evs[b].fields for b in best]
        for v in MESH_VARS:
            ds[v] = fields[0][v]
        for v in fields[0].data_vars:
            if v not in MESH_VARS:
                ds[f"worst_{v}"] = xr.concat([f[v] for f in fields], dim="criterion").assign_coords(criterion=names)
        ds = ds.assign_coords(body=fields[0]["body"].values, region=fields[0]["region"].values)
    ds.attrs.update(provenance(study, study._evaluator))
    return ds


# ---------------------------------------------------------------- parsing the page

class Page(HTMLParser):
    def __init__(self, text):
        super().__init__()
        self.ids, self.images, self.rows, self._row, self._cell = set(), [], [], None, None
        self.h2 = []
        self._in_h2 = False
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.ids.add(a["id"])
        if tag == "img":
            self.images.append(a.get("src", ""))
        if tag == "tr":
            self._row = {"attrs": a, "cells": []}
        if tag in ("td", "th") and self._row is not None:
            self._cell = {"class": a.get("class", ""), "text": ""}
        if tag == "h2":
            self._in_h2 = True

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row["cells"].append(self._cell)
            self._cell = None
        if tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None
        if tag == "h2":
            self._in_h2 = False

    def handle_data(self, data):
        if self._cell is not None:
            self._cell["text"] += data
        if self._in_h2:
            self.h2.append(data)

    def limit_row(self, criterion):
        row = next(r for r in self.rows if r["attrs"].get("data-criterion") == criterion)
        return {k: c for k, c in zip(["name", "kind", "units", "worst", "limit", "margin", "pct", "verdict", "cert"],
                                     row["cells"])}


def check_page(text) -> Page:
    page = Page(text)
    missing = [s for s in SECTION_IDS if s not in page.ids]
    assert not missing, f"sections missing: {missing}"
    assert "report-error" not in text, "a section failed to draw"
    lower = text.lower()
    # self-contained: no linked stylesheet or script; a script only inline, and only for the 3D view
    assert "<link" not in lower and "<script src" not in lower
    assert ("<script" in lower) == ('id="view3d"' in text), "a script on a page without the 3D view"
    assert page.images
    for src in page.images:
        assert src.startswith("data:image/png;base64,"), src[:60]
        raw = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert raw.startswith(PNG_MAGIC) and raw[12:16] == b"IHDR" and raw.endswith(b"IEND\xaeB`\x82")
    return page


# ---------------------------------------------------------------- tests

@pytest.fixture(scope="module")
def contact_run(tmp_path_factory):
    """granite-crack (two bodies, a Tresca contact): one limit broken, one satisfied, one failure."""
    ds = synthetic_run(ROOT / "studies/granite-crack.yaml", n=5, failures=(2,),
                       limits={"crack_pressure": 1.0e6, "settlement": 1.0},
                       certificates=["corner-kkt", "local-kkt", "heuristic"])
    path = write_netcdf(ds, tmp_path_factory.mktemp("run") / "granite.nc")
    return ds, path


def test_contact_run_report(contact_run, tmp_path, capsys):
    ds, path = contact_run
    out = tmp_path / "report.html"
    assert main(["report", str(path), "-o", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    text = out.read_text()
    page = check_page(text)
    assert len(page.images) >= 6          # scene, worst case, contact, 3 scatter grids, best so far, failures
    broken, fine = page.limit_row("crack_pressure"), page.limit_row("settlement")
    assert broken["verdict"]["text"] == "FAIL" and "fail" in broken["verdict"]["class"]
    assert fine["verdict"]["text"] == "PASS" and "pass" in fine["verdict"]["class"]
    assert broken["margin"]["text"].startswith("−")          # negative margin
    assert broken["worst"]["text"].endswith(" Pa") and broken["limit"]["text"] == "1.000 × 10⁶ Pa"
    assert fine["worst"]["text"].endswith(" m") and fine["limit"]["text"] == "1.000 m"
    assert page.limit_row("shear")["units"]["text"] == "Pa²"
    assert page.limit_row("settlement")["cert"]["text"] == "corner-kkt"
    assert 'id="verdict">FAIL<' in text
    assert "contact solver did not converge" in text      # the failure, with its meaning
    assert "magnified ×" in text and "crack" in text          # deformed shape, contact pair
    assert "at upper bound" in text                           # the upper corner is a worst case
    assert ds.attrs["study_sha256"] in text and "<details>" in text
    assert out.stat().st_size < 3e6


def test_solve_file_report(tmp_path, capsys):
    nc = tmp_path / "solve.nc"
    assert main(["solve", str(ROOT / "studies/granite-crack.yaml"), "-o", str(nc), "--quiet"]) == 0
    out = tmp_path / "solve.html"
    assert main(["report", str(nc), "-o", str(out), "--quiet"]) == 0
    text = out.read_text()
    page = check_page(text)
    # settlement 0.003 m and shear 6e14 Pa^2 hold at the nominal data; crack_pressure has no limit
    assert page.limit_row("settlement")["verdict"]["text"] == "PASS"
    assert page.limit_row("crack_pressure")["verdict"]["text"] == "no limit"
    assert "Only 1 evaluation" in text and "single forward solve" in text
    assert 'id="verdict">PASS<' in text


def test_thermal_run_report(tmp_path):
    ds = synthetic_run(ROOT / "studies/heated-plate.yaml", n=5)   # heave limit 1e-4 m is broken
    text = render_report(ds, strict=True)
    page = check_page(text)
    assert page.limit_row("heave")["verdict"]["text"] == "FAIL"
    assert page.limit_row("temperature")["verdict"]["text"] == "no limit"
    assert page.limit_row("temperature")["worst"]["text"].endswith("°C)")
    assert "No contact in this study" in text
    assert "0 of 5 evaluations failed" in text


def test_sweep_without_fields_or_certificates(tmp_path):
    ds = synthetic_run(ROOT / "studies/heated-plate.yaml", n=4, stage=["sweep"] * 4,
                       certificates=False, with_fields=False)
    ds = ds.drop_vars(["worst_value", "worst_x", "limit"])     # the reader derives them
    path = write_netcdf(ds, tmp_path / "sweep.nc")
    out = write_report(path, tmp_path / "sweep.html", strict=True)
    text = out.read_text()
    page = Page(text)
    assert set(SECTION_IDS) <= page.ids and "report-error" not in text
    assert "grid sweep" in text and "holds no mesh" in text
    assert page.limit_row("heave")["verdict"]["text"] == "FAIL"    # limit from the study text


def test_report_of_a_real_run_file(tmp_path, capsys):
    """The file `wcs run` writes (when the runner is there) reads as the synthetic one."""
    pytest.importorskip("wcs.app.runner")
    nc = tmp_path / "run.nc"
    assert main(["run", str(ROOT / "studies/heated-plate.yaml"), "-o", str(nc), "--quiet"]) == 0
    out = tmp_path / "run.html"
    assert main(["report", str(nc), "-o", str(out), "--quiet", "--verbose"]) == 0
    page = check_page(out.read_text())
    assert page.limit_row("heave")["verdict"]["text"] == "FAIL"
    assert page.limit_row("heave")["cert"]["text"].startswith(("corner-kkt", "local-kkt", "heuristic"))


def test_bare_dataset_without_provenance():
    ds = xr.Dataset({"phi": (("eval", "criterion"), [[1.0], [np.nan]]),
                     "x": (("eval", "param"), [[0.5], [0.9]]),
                     "status": ("eval", [0, 4])},
                    coords={"param": ["a"], "criterion": ["c"]})
    text = render_report(ds, strict=True)
    page = Page(text)
    assert set(SECTION_IDS) <= page.ids
    assert "NO LIMITS" in text and "singular system" in text


def test_missing_file_exits_2_without_traceback(tmp_path):
    exe = Path(sys.executable).with_name("wcs")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "wcs.cli"]
    proc = subprocess.run([*cmd, "report", "missing.nc"], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "missing.nc" in proc.stderr
    assert not (tmp_path / "missing.html").exists()


@pytest.mark.parametrize("make", ["garbage", "not-wcs", "directory", "bad-output"])
def test_bad_results_file_exits_2(make, tmp_path, capsys):
    path, out = tmp_path / "x.nc", tmp_path / "r.html"
    if make == "garbage":
        path.write_text("not netcdf")
    elif make == "not-wcs":
        xr.Dataset({"a": ("t", [1.0])}).to_netcdf(path, engine="h5netcdf")
    elif make == "directory":
        path.mkdir()
    else:
        xr.Dataset({"a": ("t", [1.0])}).to_netcdf(path, engine="h5netcdf")
        out = tmp_path / "r.pdf"
    assert main(["report", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err and len(err.splitlines()) == 1
    assert not out.exists()


# ---------------------------------------------------------------- the person's check (slow)

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--hide-scrollbars"]


def chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        exe = shutil.which(name)
        if exe:
            return exe
    return None


def ensure_chromium() -> str:
    exe = chromium()
    if exe:
        return exe
    if os.geteuid() != 0 or not shutil.which("apt-get"):
        pytest.skip("chromium is not installed and cannot be installed here (needs root and apt-get)")
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    subprocess.run(["apt-get", "update"], check=False, capture_output=True, env=env, timeout=600)
    proc = subprocess.run(["apt-get", "install", "-y", "chromium"], capture_output=True, text=True, env=env, timeout=1200)
    exe = chromium()
    if not exe:
        pytest.skip(f"apt-get install chromium failed: {proc.stderr[-300:]}")
    return exe


def screenshot(html_path: Path, png_path: Path, exe: str, height=4000, workdir=None) -> Path:
    workdir = Path(workdir or png_path.parent)
    profile = workdir / "chromium-profile"
    png_path.unlink(missing_ok=True)
    subprocess.run([exe, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", f"--screenshot={png_path}",
                    f"--window-size=1280,{height}", html_path.resolve().as_uri()],
                   capture_output=True, text=True, timeout=180)
    shutil.rmtree(profile, ignore_errors=True)
    return png_path


@pytest.mark.slow
def test_report_renders_in_chromium(contact_run, tmp_path):
    from PIL import Image
    exe = ensure_chromium()
    _, path = contact_run
    html_path = write_report(path, tmp_path / "report.html", strict=True)
    png_path = screenshot(html_path, tmp_path / "shot.png", exe)
    assert png_path.exists() and png_path.stat().st_size > 10_000
    im = Image.open(png_path).convert("RGB")
    assert im.size[0] == 1280
    small = im.resize((320, im.size[1] // 4))
    colours = len(np.unique(np.asarray(small).reshape(-1, 3), axis=0))
    assert colours > 200, f"the screenshot looks blank ({colours} colours)"
    # the FAIL badge (#d1242f) is on the page
    arr = np.asarray(im)
    red = np.all(np.abs(arr.astype(int) - [0xd1, 0x24, 0x2f]) < 12, axis=-1)
    assert red.sum() > 200


if __name__ == "__main__":          # write a synthetic run file of a study
    study, out = sys.argv[1], sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 6
    print(write_netcdf(synthetic_run(study, n=n, failures=(1,)), out))


@pytest.mark.slow
def test_after_search_sections_render_in_chromium(tmp_path):
    """A real `wcs run` (the heated plate, the heave's both ends) then `wcs report`: the range
    against its limits, the mesh check's table and the drivers' bars are on the page Chromium
    draws (the bars' colours: red grows with x_i, blue falls)."""
    import yaml
    from PIL import Image
    doc = yaml.safe_load((ROOT / "studies/heated-plate.yaml").read_text())
    doc["criteria"][0]["sense"] = "both"
    doc["search"] = {**(doc.get("search") or {}), "budget": 40}
    study = tmp_path / "plate.yaml"
    study.write_text(yaml.safe_dump(doc))
    nc, html_path = tmp_path / "plate.nc", tmp_path / "plate.html"
    assert main(["run", str(study), "-o", str(nc), "--quiet"]) == 0
    assert main(["report", str(nc), "-o", str(html_path)]) == 0
    text = html_path.read_text()
    for sid in ("mesh-check-table", "range-text", 'id="drivers"'):
        assert sid in text, sid
    drivers = text[text.index('<section id="drivers">'):]
    drivers = drivers[:drivers.index("</section>")]
    assert drivers.count("<img") >= len(doc["criteria"])        # one bar chart per extreme at least
    arr = np.asarray(Image.open(screenshot(html_path, tmp_path / "shot.png", ensure_chromium(),
                                           height=9000)).convert("RGB")).astype(int)
    for colour in ([0xd6, 0x27, 0x28], [0x1f, 0x77, 0xb4]):
        assert np.all(np.abs(arr - colour) < 12, axis=-1).sum() > 500, colour


def test_a_temperature_difference_is_not_shown_in_celsius():
    """A temperature is also given in °C; a margin or an error (a difference of temperatures)
    is not: 0.00193 K of error is not −273.1 °C."""
    from wcs.report.html import number
    assert number(300.0, "K").endswith("(26.9 °C)")
    assert "°C" not in number(0.00193, "K", difference=True)


def test_an_incomplete_run_says_so_once_and_passes_nothing(contact_run, tmp_path):
    """An incomplete run: one banner, which says "incomplete" once (before: "This run is incomplete.
    the run is incomplete: …"), and no green PASS cell (a limit that holds among the evaluations so
    far is not passed); a crisp study has no membership section (before: in every report)."""
    ds, _ = contact_run
    ds = ds.copy()
    ds.attrs["complete"] = "no"
    from wcs.report.data import load
    from wcs.report.html import Report
    path = write_netcdf(ds, tmp_path / "stopped.nc")     # read with the store's account of the run
    report = Report(load(path), str(path), strict=True)
    text = report.summary() + report.limits()            # the sections concerned, not the figures: fast
    assert "--resume" in text
    page = Page(text)
    banner = text[text.index('id="incomplete">') + len('id="incomplete">'):]
    banner = banner[:banner.index("</p>")]
    assert text.count('id="incomplete"') == 1 and len(re.findall(r"\bincomplete\b", banner.lower())) == 1
    assert page.limit_row("settlement")["verdict"]["text"] == "holds so far (incomplete run)"
    assert not [c for r in page.rows for c in r["cells"] if "pass" in c["class"].split()]
    assert page.limit_row("crack_pressure")["verdict"]["text"] == "FAIL"
    assert not report.shown("membership")


@pytest.mark.slow
def test_the_mesh_check_table_keeps_within_the_page_in_chromium(tmp_path):
    """The mesh check's table with three meshes and a long note (the 3D tunnel's) fits the page
    Chromium draws at 1280 px: the page is no wider than the window and the table scrolls inside
    the page's column (before, it ran off the page)."""
    from tests.support.cdp import Browser
    from tests.results.test_verdict import _knee_like
    note = ("split once only (the mesh split 2 times would have 1.59e+06 cells, beyond mesh.max_cells = 1e+06): "
            "f(h/2) − f(h) = 1.231e+12; no order observed: the error assumes the linear elements' theoretical "
            "order 1 (stresses and contact tractions converge as h; displacements faster, so it overstates theirs)")
    ds = _knee_like("PASS", "done: the extreme data sets re-solved on the mesh split once and twice")
    ds["mesh_check_value"][:] = [[[6.563921e13, 6.687069e13, 6.751234e13]]]
    ds["mesh_check_nodes"][:] = [6268, 41502, 301234]
    ds["mesh_check_time"][:] = [0.0, 59.4, 412.0]
    for name, v in (("order", 1.23), ("extrapolated", 6.810217e13), ("error", 2.463e12)):
        ds[f"mesh_check_{name}"][:] = [[v]]
    ds["mesh_check_note"][:] = np.array([[note]], dtype=object)
    ds["criterion_units"] = ("criterion", np.array(["Pa^2"], dtype=object))
    html_path = tmp_path / "mesh-check.html"
    html_path.write_text(render_report(ds, strict=True), encoding="utf-8")
    with Browser(ensure_chromium(), tmp_path, width=1280, height=1000) as b:
        b.open(html_path)
        page, window = b.evaluate("[document.documentElement.scrollWidth, window.innerWidth]")
        table, box = b.evaluate("(() => { const t = document.getElementById('mesh-check-table').parentElement;"
                                "return [t.getBoundingClientRect().right, document.querySelector('main')"
                                ".getBoundingClientRect().right]; })()")
        assert b.errors == []
    assert page <= window and table <= box, (page, window, table, box)


def page_units(ds) -> dict:
    """{criterion: units} of a results file's `phi`."""
    return dict(piece.split(": ", 1) for piece in ds["phi"].attrs["units"].split(", "))


def _solve_kinds():
    """(name, study document) of each kind of file `wcs solve` writes besides a static one with
    contact (`test_solve_file_report`): static thermal (the heated plate, coarse, without uncertain
    numbers), dynamic (the two bars, coarse, with an uncertain modulus and a limit; the levels to
    past the impact) and dynamic over a thermal scene (the plate from its static state)."""
    import yaml
    load = lambda name: yaml.safe_load((ROOT / name).read_text())        # noqa: E731
    bars = load("studies/validation/two-bars-impact.yaml")
    bars["dynamics"].update(end_time=3.0e-4, time_step=1.0e-5, output_every=5)
    bars["scene"]["mesh"]["size"] = 0.05
    bars["uncertain"] = {"materials.steel.E": [1.9e11, 2.3e11]}
    bars["limits"] = {"peak_pressure": 1.0e8}
    static = load("studies/heated-plate.yaml")
    static.pop("include")
    static.pop("uncertain")
    static["scene"]["mesh"]["size"] = 0.1
    plate = load("studies/heated-plate.yaml")
    plate.pop("include")
    plate["scene"]["mesh"]["size"] = 0.1
    plate["scene"]["materials"]["steel"]["density"] = 7850.0
    plate["dynamics"] = {"end_time": 4.0e-5, "time_step": 1.0e-5, "scheme": "seed", "output_every": 2,
                         "initial": "static"}
    return [("thermal", static), ("dynamic", bars), ("dynamic-thermal", plate)]


@pytest.mark.parametrize("kind, doc", _solve_kinds(), ids=[k for k, _ in _solve_kinds()])
def test_every_solve_file_makes_a_report(kind, doc, tmp_path):
    """The file of `wcs solve` of every kind of study makes a report (a dynamic one had neither the
    box nor the data set: "no param"): its values, its one data set (the nominal, in the box or
    named as such without uncertain numbers), a dynamic study's histories drawn one per criterion."""
    import yaml
    from wcs.report.html import number
    doc.pop("include", None)
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump(doc, sort_keys=False))
    nc, out = tmp_path / "solve.nc", tmp_path / "solve.html"
    assert main(["solve", str(study), "-o", str(nc), "--quiet"]) == 0
    assert main(["report", str(nc), "-o", str(out), "--quiet"]) == 0
    text = out.read_text()
    page = check_page(text)
    assert "single forward solve" in text and "every evaluation failed" not in text
    with xr.open_dataset(nc, engine="h5netcdf") as ds:
        names, phi, units = [str(c) for c in ds["criterion"].values], ds["phi"].values, page_units(ds)
        x, params = ds["x"].values, [str(p) for p in ds["param"].values]
        assert np.array_equal(x, wcs.load_study(study).nominal())
    for name, value in zip(names, phi):
        assert page.limit_row(name)["worst"]["text"] == number(value, units[name]), name
        assert f"{name}: worst value {number(value, units[name])}" in text, name
    worst = text[text.index('id="worst-data"'):text.index('id="drivers"')]
    assert worst.count("<tr>") == len(names) * (len(params) + 1) if params else \
        worst.count("no uncertain numbers") == len(names)
    if kind.startswith("dynamic"):
        section = text[text.index('id="histories"'):text.index('id="scene"')]
        assert section.count("<img") == len(names)


def test_a_uniform_temperature_is_drawn_in_one_colour_with_its_value(tmp_path):
    """The heated plate with one temperature prescribed (bottom) and no heat source: T equals it
    everywhere, up to the heat solve's round-off (a few 1e-13 K). The report states that value
    and draws one colour, not a colour scale spanning the round-off; a field varying by 1 mK
    keeps its scale. On the report's data: the drawn values, their colour limits, the colour
    bars and the words."""
    import matplotlib.pyplot as plt
    import yaml
    from matplotlib.tri import Triangulation

    from wcs.report.data import from_dataset, uniform_value
    from wcs.report.html import number
    from wcs.report.plots import temperature_panel
    doc = yaml.safe_load((ROOT / "studies/heated-plate.yaml").read_text())
    doc["scene"]["thermal"]["temperature"] = {"bottom": 343.0}
    del doc["uncertain"]["thermal.temperature.top"]
    (tmp_path / "plate.yaml").write_text(yaml.safe_dump(doc))
    ds = synthetic_run(tmp_path / "plate.yaml", n=2)
    res = from_dataset(ds)
    bottom = list(res.params).index("thermal.temperature.bottom")
    for j, f in enumerate(res.worst_fields):
        prescribed = float(ds["worst_x"].values[j, bottom])
        assert uniform_value(f.temperature) == pytest.approx(prescribed, rel=1e-12)
    text = render_report(ds, strict=True)
    assert f"temperature uniform, {number(prescribed, 'K')}." in text
    assert re.search(r"temperature [0-9.]+ K[^<]*…", text) is None          # no range of round-off
    tri = Triangulation(res.mesh.coords[:, 0], res.mesh.coords[:, 1], res.mesh.cells)
    T = res.worst_fields[0].temperature
    noise = T + 1e-12 * np.random.default_rng(1).standard_normal(len(T))  # round-off of 343 K: 3e-15 relative
    fig, ax = plt.subplots()
    temperature_panel(fig, ax, tri, noise)
    drawn = ax.collections[0]
    lo, hi = drawn.get_clim()
    assert np.ptp(drawn.get_array()) == 0 and lo < float(drawn.get_array()[0]) < hi and hi - lo >= 1.0
    assert len(fig.axes) == 1 and ax.get_title() == f"temperature: uniform, {uniform_value(noise):.6g} K"
    plt.close(fig)
    varying = T + 1e-3 * res.mesh.coords[:, 0]                              # 1 mK across the 1 m plate
    assert uniform_value(varying) is None
    fig, ax = plt.subplots()
    temperature_panel(fig, ax, tri, varying)
    assert np.array_equal(ax.collections[0].get_array(), varying) and len(fig.axes) == 2
    assert ax.get_title() == "temperature"
    plt.close(fig)
