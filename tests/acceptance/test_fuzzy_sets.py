"""Fuzzy admissible sets: `{support: [a, b], core: [c, d]}` numbers and
`fuzzy: {levels}`; the α-cut [a + α(c − a), b − α(b − d)] of each level searched from the core
outwards, reusing every evaluation made so far.

References: on the heated plate every criterion is monotone in every datum, so each level's
extremes are vertex values of that level's α-cut (enumerated; the search evaluates the same
data sets, so they agree to round-off: 1e-10 relative); on the cooled
layer the maximum over ν is interior, ν* = 1 − sqrt(1 − α_T |ΔT| E / p) at the cut's lowest E
and highest p (its study header)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import wcs
from tests.support.search_problems import vertex_ranges
from tests.app.test_mpi import serial_and_two_ranks
from wcs.app import runner
from wcs.cli import main
from wcs.report import render_report
from wcs.report.html import limit_membership
from wcs.search import Worst
from wcs.results.store import store_path
from wcs.study.fuzzy import alpha_cut
from wcs.study.source import _read_yaml

ROOT = Path(__file__).resolve().parents[2]
PLATE = ROOT / "studies" / "heated-plate.yaml"
COOLED = ROOT / "studies" / "validation" / "cooled-layer.yaml"
DEMO = ROOT / "studies" / "two-blocks-demo.yaml"

FUZZY_PLATE = {"materials.steel.E": {"support": [1.9e11, 2.3e11], "core": [2.05e11, 2.15e11]},
               "materials.steel.expansion": {"support": [1.0e-5, 1.4e-5], "core": [1.2e-5, 1.2e-5]},
               "thermal.temperature.bottom": {"support": [323.0, 363.0], "core": [338.0, 348.0]}}


def plate_doc(fuzzy: bool = True, sense: str = "both") -> dict:
    """The heated plate with three fuzzy numbers (two crisp boxes left); fuzzy=False: the same
    study on the support boxes."""
    doc = _read_yaml(PLATE)[0]
    for c in doc["criteria"]:
        c["sense"] = sense
    doc.pop("limits")
    doc.setdefault("search", {})["budget"] = 200       # over the included preset's search
    for path, spec in FUZZY_PLATE.items():
        doc["uncertain"][path] = spec if fuzzy else spec["support"]
    return doc


def load(doc, path):
    return wcs.load_study(doc, base_dir=path.parent)


def test_alpha_cuts_are_the_formula_nested_and_exact_at_the_ends():
    study = load(plate_doc(), PLATE)
    assert study.levels == (0.0, 0.25, 0.5, 0.75, 1.0)            # the default levels
    names = study.parameters.names
    lo0, hi0 = alpha_cut(study, 0.0)
    lo1, hi1 = alpha_cut(study, 1.0)
    assert np.array_equal(lo0, study.parameters.lower) and np.array_equal(hi0, study.parameters.upper)
    for path, spec in FUZZY_PLATE.items():
        i = names.index(path)
        (a, b), (c, d) = spec["support"], spec["core"]
        assert (lo1[i], hi1[i]) == (c, d)                             # bit for bit
        lo, hi = alpha_cut(study, 0.3)
        assert lo[i] == pytest.approx(a + 0.3 * (c - a), rel=1e-15) and hi[i] == pytest.approx(b - 0.3 * (b - d), rel=1e-15)
    for path in ("materials.steel.nu", "thermal.temperature.top"):    # a crisp box: the same at every level
        i = names.index(path)
        assert all((alpha_cut(study, a)[0][i], alpha_cut(study, a)[1][i]) == (lo0[i], hi0[i]) for a in study.levels)
    cuts = [alpha_cut(study, a) for a in np.linspace(0, 1, 101)]
    assert all(np.all(p[0] <= q[0]) and np.all(q[1] <= p[1]) for p, q in zip(cuts, cuts[1:]))


def test_monotone_study_levels_equal_vertex_values_nested_at_a_fraction_of_the_cost():
    study = load(plate_doc(), PLATE)
    ds = wcs.run(study, output=False)
    crisp = wcs.run(load(plate_doc(fuzzy=False), PLATE), output=False)
    assert list(ds["level"].values) == [0.0, 0.25, 0.5, 0.75, 1.0]
    reference = load(plate_doc(), PLATE)
    for i, alpha in enumerate(study.levels):
        for c, (lo, hi) in vertex_ranges(reference, *alpha_cut(reference, alpha)).items():
            pick = {"level": i, "criterion": c}
            assert float(ds["best_value"].isel(level=i).sel(criterion=c)) == pytest.approx(lo, rel=1e-10), pick
            assert float(ds["worst_value"].isel(level=i).sel(criterion=c)) == pytest.approx(hi, rel=1e-10), pick
            assert str(ds["certificate"].isel(level=i).sel(criterion=c).values) == "corner-kkt", pick
            assert str(ds["best_certificate"].isel(level=i).sel(criterion=c).values) == "corner-kkt", pick
        assert np.array_equal(ds["level_lower"].values[i], alpha_cut(study, alpha)[0])
    # nested: the smaller the level, the wider the range
    assert np.all(np.diff(ds["worst_value"].values, axis=0) <= 0) and np.all(np.diff(ds["best_value"].values, axis=0) >= 0)
    # the widest level is the crisp study on the support boxes: the same values, to the last
    # bits where a criterion does not depend on a parameter (the heave does not move with E:
    # the vertices on either side of E tie up to one ulp and each search may keep either)
    np.testing.assert_allclose(ds["worst_value"].values[0], crisp["worst_value"].values, rtol=1e-14)
    np.testing.assert_allclose(ds["best_value"].values[0], crisp["best_value"].values, rtol=1e-14)
    # five levels cost at most 2.5 times one search on the support boxes (solves counted): every
    # level after the core starts from the inner levels' evaluations and pays for its new vertices only
    assert ds.sizes["eval"] <= 2.5 * crisp.sizes["eval"], (ds.sizes["eval"], crisp.sizes["eval"])
    assert "started from the best of" in str(ds["certificate_note"].values[0, 0])


def test_triangular_numbers_core_is_one_data_set_and_certified():
    """Every number a triangle at its nominal value: the core (α = 1) is one data set, its own
    maximum and minimum; the levels outside still equal their cuts' vertex values."""
    doc = plate_doc()
    nominal = load(plate_doc(fuzzy=False), PLATE).nominal()
    for (path, spec), x0 in zip(list(doc["uncertain"].items()), nominal):
        doc["uncertain"][path] = {"support": spec["support"] if isinstance(spec, dict) else spec,
                                  "core": [float(x0), float(x0)]}
    study = load(doc, PLATE)
    ds = wcs.run(study, output=False)
    core = {"level": len(study.levels) - 1}
    assert np.all(ds["certificate"].isel(core).values == "corner-kkt")
    assert np.all(ds["best_certificate"].isel(core).values == "corner-kkt")
    assert "one data set" in str(ds["certificate_note"].isel(core).values[0])
    assert np.array_equal(ds["worst_value"].isel(core).values, ds["best_value"].isel(core).values)
    plate = load(doc, PLATE)
    for c, (lo, hi) in vertex_ranges(plate, *alpha_cut(plate, 0.5)).items():
        half = {"level": 2, "criterion": c}
        assert float(ds["worst_value"].sel(criterion=c).isel(level=2)) == pytest.approx(hi, rel=1e-10), half
        assert float(ds["best_value"].sel(criterion=c).isel(level=2)) == pytest.approx(lo, rel=1e-10), half


def test_a_budget_spent_at_the_core_leaves_the_outer_levels_uncertified_and_says_so():
    doc = plate_doc()
    doc["search"]["budget"] = 10
    ds = wcs.run(load(doc, PLATE), output=False)
    assert ds.sizes["eval"] == 10
    outer = ds["certificate"].values[:-1]
    assert np.all(outer == "heuristic") and np.all(ds["best_certificate"].values[:-1] == "heuristic")
    assert all("no budget left for this level" in str(n) for n in ds["certificate_note"].values[:-1].ravel())
    assert np.all(np.diff(ds["worst_value"].values, axis=0) <= 0)       # still nested: lower bounds of the ranges


COOLED_FUZZY = {"materials.polymer.nu": {"support": [0.05, 0.45], "core": [0.3, 0.4]},
                "materials.polymer.E": {"support": [1.9e9, 2.1e9], "core": [2.0e9, 2.0e9]},
                "loads.top.pressure": {"support": [0.95e7, 1.05e7], "core": [1.0e7, 1.0e7]}}


def test_cooled_layer_each_level_finds_its_interior_maximum_at_a_fraction_of_the_cost():
    """The maximum sits inside in ν and at the cut's lowest E and highest p at every level: each
    level after the core carries the inner level's maximum out to its own bounds and ascends in ν
    from there, without the restarts (the active bounds are kept)."""
    doc = _read_yaml(COOLED)[0]
    doc.setdefault("search", {})["budget"] = 200       # over the included preset's search
    crisp = wcs.run(load(doc, COOLED), output=False)
    doc["uncertain"] = {path: dict(spec) for path, spec in COOLED_FUZZY.items()}
    study = load(doc, COOLED)
    ds = wcs.run(study, output=False)
    # five levels cost at most 2.5 times one search on the support box (solves counted; before: 145 against 39)
    assert ds.sizes["eval"] <= 2.5 * crisp.sizes["eval"], (ds.sizes["eval"], crisp.sizes["eval"])
    assert float(crisp["worst_value"].values[0]) == pytest.approx(float(ds["worst_value"].values[0, 0]), rel=1e-9)
    for i, alpha in enumerate(study.levels):
        lower, upper = alpha_cut(study, alpha)
        E, p = lower[1], upper[2]
        nu = 1 - np.sqrt(1 - 5.0e-5 * 60.0 * E / p)
        assert lower[0] < nu < upper[0]                                    # inside the cut: an interior maximum
        exact = (1 + nu) / (1 - nu) * (5.0e-5 * 60.0 + p / E * (1 - 2 * nu))
        x = ds["worst_x"].values[i, 0]
        assert x[0] == pytest.approx(nu, rel=1e-4) and (x[1], x[2]) == (E, p), alpha
        assert float(ds["worst_value"].values[i, 0]) == pytest.approx(exact, rel=1e-6), alpha
        assert str(ds["certificate"].values[i, 0]) == "local-kkt", alpha
        if alpha < 1:
            note = str(ds["certificate_note"].values[i, 0])
            assert "carried out" in note and "restarts skipped" in note, alpha


def test_a_lipschitz_profile_keeps_its_slope_bound_at_every_level(monkeypatch):
    doc = _read_yaml(DEMO)[0]
    doc["uncertain"]["contacts.interface.friction.slip_limit"] = {
        "support": [0.5e5, 1.5e5], "core": [0.9e5, 1.1e5], "lipschitz": 2.0e5, "points": 6}
    doc["fuzzy"] = {"levels": [0.0, 0.5, 1.0]}
    study = load(doc, DEMO)
    seen = []

    def spy(problem, config, rng):
        seen.append(problem)
        yield from ()
        return Worst(x={}, value={}, certificate={})

    monkeypatch.setattr(runner, "get_strategy", lambda name: spy)
    ds = runner.Runner(study, False).run()
    assert [float(a) for a in ds["level"].values] == [0.0, 0.5, 1.0]
    assert len(seen) == 3
    slip = [i for i, n in enumerate(study.parameters.names) if "slip_limit[" in n]
    assert len(slip) == 6
    for problem, alpha in zip(seen, (1.0, 0.5, 0.0)):                       # from the core outwards
        assert np.array_equal(problem.A_ub, seen[0].A_ub) and np.array_equal(problem.b_ub, seen[0].b_ub)
        lower, upper = alpha_cut(study, alpha)
        assert np.array_equal(problem.lower, lower) and np.array_equal(problem.upper, upper)
        assert np.all(problem.lower[slip] == 0.5e5 + alpha * 0.4e5)
    assert seen[0].A_ub is not None and np.count_nonzero(seen[0].A_ub[:, slip]) > 0


def test_resume_of_a_fuzzy_run_is_bitwise(tmp_path):
    """Half the store lost (the newest evaluations): the resumed run solves only those and
    writes the same file."""
    out = tmp_path / "plate.nc"
    doc = plate_doc()
    clean = wcs.run(load(doc, PLATE), out)
    files = sorted(store_path(out).glob("*.npz"), key=lambda f: f.stat().st_mtime_ns)
    lost = files[len(files) // 2:]
    for f in lost:
        f.unlink()
    resumed = wcs.run(load(doc, PLATE), out, resume=True)
    assert resumed.attrs["solves_this_session"] == len(lost)
    assert resumed.attrs["answered_from_store"] == len(files) - len(lost)
    for v in ("x", "phi", "status", "worst_value", "worst_x", "best_value", "best_x", "certificate",
              "best_certificate", "worst_displacement"):
        assert np.array_equal(clean[v].values, resumed[v].values), v


@pytest.mark.slow
def test_two_mpi_ranks_give_the_serial_fuzzy_results_bitwise(tmp_path):
    doc = plate_doc()
    doc["scene"] = str(PLATE.parent / doc["scene"]) if isinstance(doc["scene"], str) else doc["scene"]
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    a, b = serial_and_two_ranks(tmp_path)
    assert "level" in a.dims and a.sizes["eval"] == b.sizes["eval"]
    for v in ("x", "phi", "grad", "status", "worst_value", "worst_x", "best_value", "best_x", "worst_displacement"):
        assert np.array_equal(a[v].values, b[v].values, equal_nan=True), v


def write(tmp_path: Path, doc: dict) -> Path:
    out = tmp_path / "study.yaml"
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


@pytest.mark.parametrize("spec, message", [
    ({"support": [1.9e11, 2.3e11], "core": [2.15e11, 2.2e11]},
     "uncertain.materials.steel.E: the scene's value 210000000000.0 lies outside the core"),
    ({"support": [1.9e11, 2.3e11], "core": [2.2e11, 2.0e11]},
     "uncertain.materials.steel.E.core: the core [220000000000.0, 200000000000.0] must be an interval inside"),
    ({"support": [1.9e11, 2.3e11], "core": [2.0e11, 2.4e11]}, "must be an interval inside the support"),
    ({"support": [1.9e11, 2.3e11], "cores": [2.0e11, 2.2e11]}, "unknown key 'cores' (did you mean 'core'?)"),
    ({"support": [1.9e11, 2.3e11]}, "uncertain.materials.steel.E.core: required key is missing"),
])
def test_bad_fuzzy_numbers_are_refused(tmp_path, capsys, spec, message):
    doc = plate_doc()
    doc["uncertain"]["materials.steel.E"] = spec
    assert main(["check", str(write(tmp_path, doc))]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


@pytest.mark.parametrize("fuzzy, message", [
    ({"levels": [0.0, 0.5, 0.5]}, "fuzzy.levels: the levels must be distinct"),
    ({"levels": [0.0, 1.5]}, "fuzzy.levels.1: must be less than or equal to 1"),
    ({"levels": []}, "fuzzy.levels"),
    ({"level": [0.0]}, "unknown key 'level' (did you mean 'levels'?)"),
])
def test_bad_levels_are_refused(tmp_path, capsys, fuzzy, message):
    doc = plate_doc()
    doc["fuzzy"] = fuzzy
    assert main(["check", str(write(tmp_path, doc))]) == 2
    assert message in capsys.readouterr().err


def test_the_limit_is_read_against_the_membership_function():
    alpha = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    worst = np.array([5.0, 4.0, 3.0, 2.5, 2.0])
    best = np.array([0.0, 0.5, 1.0, 1.2, 1.5])
    nan = float("nan")
    assert limit_membership(alpha, best, worst, nan, 3.5) == \
        "The limit holds for every data set of membership ≥ 0.5; a data set of membership ≥ 0.25 breaks it."
    assert limit_membership(alpha, best, worst, 0.8, 3.5) == \
        "The limits hold for every data set of membership ≥ 0.5; a data set of membership ≥ 0.25 breaks them."
    assert limit_membership(alpha, best, worst, nan, 9.0) == \
        "The limit holds for every admissible data set (membership ≥ 0)."
    assert limit_membership(alpha, best, worst, 1.6, nan) == \
        "The limit is broken even at the highest level searched, membership 1 (the core)."
    assert limit_membership(alpha, best, worst, nan, nan) == "No limit is set."


def test_report_draws_the_membership_function(tmp_path):
    """Heave's maximum against an upper limit; temperature's minimum only (its maximum is not searched)."""
    doc = plate_doc(sense="max")
    doc["criteria"][2]["sense"] = "min"
    doc["limits"] = {"heave": 8.5e-4}
    doc["search"]["budget"] = 60
    ds = wcs.run(load(doc, PLATE), output=False)
    page = render_report(ds, strict=True)
    worst_data = page[page.index('<section id="worst-data">'):page.index('<section id="worst-fields">')]
    assert "temperature</h3><p class=\"note\">Its maximum is not searched (sense: min)" in worst_data
    section = page[page.index('<section id="membership">'):]
    section = section[:section.index("</section>")]
    assert section.count("<img") == 3 and "The limit holds for every data set of membership ≥ 0.5; a data set of membership ≥ 0.25 breaks it." in section


def test_check_prints_the_levels_and_cores(tmp_path, capsys):
    assert main(["check", str(write(tmp_path, plate_doc()))]) == 0
    assert ("fuzzy: levels 0, 0.25, 0.5, 0.75, 1, searched from the core (α = 1) outwards; the boxes above are "
            "the supports; cores: materials.steel.E [2.05e+11, 2.15e+11]") in capsys.readouterr().out


@pytest.mark.slow
def test_fuzzy_report_renders_in_chromium(tmp_path):
    """The membership figures are drawn on the page as Chromium shows it: the minima's line
    (green, #2ca02c) is only in them."""
    from PIL import Image
    from tests.report.test_report import ensure_chromium, screenshot
    from wcs.report import write_report
    doc = plate_doc()
    doc["limits"] = {"heave": {"lower": 3.0e-4, "upper": 8.5e-4}}
    wcs.run(load(doc, PLATE), tmp_path / "plate.nc")
    page = write_report(tmp_path / "plate.nc", tmp_path / "plate.html", strict=True)
    shot = np.asarray(Image.open(screenshot(page, tmp_path / "shot.png", ensure_chromium(), height=5000)).convert("RGB"))
    green = np.all(np.abs(shot.astype(int) - [0x2c, 0xa0, 0x2c]) < 12, axis=-1)
    assert green.sum() > 200
