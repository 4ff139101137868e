"""Both ends of the range: `criteria[i].sense: max | min | both` and
`limits: {lower, upper}`.

The minimum is searched as the maximum of −Φ by the same strategy, so its certificates are
the same kinds. References: the cooled layer's closed form (an interior maximum over ν, a
vertex minimum: its header), the heated plate's and the stacked layers' exhaustive vertex
values (every criterion is monotone in every datum there, so both ends are vertices). The
values found are evaluations at the very data sets the references evaluate, so they agree to
round-off; 1e-6 relative is asked of them."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import wcs
from tests.support.search_problems import vertex_ranges
from wcs.cli import main
from wcs.results.summary import limits_broken, summary_table
from wcs.report import render_report
from wcs.report.html import number
from wcs.results.extremes import extremes
from wcs.study.source import _read_yaml

ROOT = Path(__file__).resolve().parents[2]
COOLED = ROOT / "studies" / "validation" / "cooled-layer.yaml"
PLATE = ROOT / "studies" / "heated-plate.yaml"
STACKED = ROOT / "studies" / "validation" / "stacked-layers.yaml"


def study_doc(path: Path, sense: str | dict = "both", **top) -> dict:
    """The study's mapping with every criterion's sense set (a dict: per criterion name)."""
    doc = _read_yaml(path)[0]
    for c in doc["criteria"]:
        c["sense"] = sense if isinstance(sense, str) else sense.get(c["name"], "max")
    doc.pop("limits", None)
    doc.update(top)
    return doc


def load(doc: dict, path: Path):
    return wcs.load_study(doc, base_dir=path.parent)


def settlement(nu, E, p, alpha=5.0e-5, dT=60.0, h=1.0):
    """The cooled layer's closed form (its study header)."""
    return h * (1 + nu) / (1 - nu) * (alpha * dT + p / E * (1 - 2 * nu))


def test_cooled_layer_both_ends_equal_the_closed_form():
    study = load(study_doc(COOLED), COOLED)
    ds = wcs.run(study, output=False)
    names = study.parameters.names
    lo, hi = study.parameters.lower, study.parameters.upper
    i_nu, i_E, i_p = (names.index(n) for n in ("materials.polymer.nu", "materials.polymer.E", "loads.top.pressure"))
    nu_star = 1 - np.sqrt(1 - 5.0e-5 * 60.0 * lo[i_E] / hi[i_p])          # the interior maximum
    exact_max = settlement(nu_star, lo[i_E], hi[i_p])
    exact_min = min(settlement(nu, hi[i_E], lo[i_p]) for nu in (lo[i_nu], hi[i_nu]))   # s is concave in ν
    c = {"criterion": "settlement"}
    assert float(ds["worst_value"].sel(c)) == pytest.approx(exact_max, rel=1e-6)
    assert float(ds["best_value"].sel(c)) == pytest.approx(exact_min, rel=1e-6)
    assert ds["worst_x"].sel(c).values[i_nu] == pytest.approx(nu_star, rel=1e-4)
    assert np.array_equal(ds["best_x"].sel(c).values, [lo[i_nu], hi[i_E], lo[i_p]])
    assert str(ds["certificate"].sel(c).values) == "local-kkt"
    assert str(ds["best_certificate"].sel(c).values) == "corner-kkt"
    assert ds.sizes["eval"] <= study.search.budget


@pytest.mark.parametrize("path", [PLATE, STACKED], ids=["heated-plate", "stacked-layers"])
def test_monotone_studies_both_ends_equal_the_vertex_values(path):
    study = load(study_doc(path), path)
    ds = wcs.run(study, output=False)
    fresh = load(study_doc(path), path)              # a fresh evaluator for the reference
    reference = vertex_ranges(fresh, fresh.parameters.lower, fresh.parameters.upper)
    for c, (lo, hi) in reference.items():
        assert float(ds["best_value"].sel(criterion=c)) == pytest.approx(lo, rel=1e-6), c
        assert float(ds["worst_value"].sel(criterion=c)) == pytest.approx(hi, rel=1e-6), c
        assert str(ds["best_certificate"].sel(criterion=c).values) == "corner-kkt", c
        assert str(ds["certificate"].sel(criterion=c).values) == "corner-kkt", c
    ends = extremes(ds)
    assert [(e.criterion, e.sense) for e in ends] == [(c, s) for c in reference for s in ("max", "min")]
    for e in ends:                       # the record the checks after a search iterate over
        assert np.array_equal(ds["x"].values[e.eval], e.x) and ds["phi"].values[e.eval, list(reference).index(e.criterion)] == e.value


def test_sense_max_is_the_default_and_writes_no_best():
    study = load(study_doc(COOLED, sense="max", search={"method": "auto", "budget": 12}), COOLED)
    ds = wcs.run(study, output=False)
    assert "best_value" not in ds and "limit_lower" not in ds
    assert [e.sense for e in extremes(ds)] == ["max"]


def test_sense_min_alone_leaves_the_maximum_unsearched():
    doc = study_doc(PLATE, sense={"temperature": "min"}, search={"method": "auto", "budget": 30})
    study = load(doc, PLATE)
    ds = wcs.run(study, output=False)
    t = {"criterion": "temperature"}
    assert math.isnan(float(ds["worst_value"].sel(t))) and str(ds["certificate"].sel(t).values) == "not-searched"
    assert str(ds["best_certificate"].sel(t).values) == "corner-kkt"
    coldest = study.evaluate({"thermal.temperature.top": 323.0, "thermal.temperature.bottom": 323.0})
    assert float(ds["best_value"].sel(t)) == pytest.approx(coldest.phi["temperature"], rel=1e-12)
    assert math.isnan(float(ds["best_value"].sel(criterion="heave")))
    assert str(ds["best_certificate"].sel(criterion="heave").values) == "not-searched"
    assert "heave" in summary_table(ds) and "min corner-kkt" in summary_table(ds)


def write(tmp_path: Path, doc: dict, path: Path) -> Path:
    import yaml
    doc = dict(doc, scene=str(path.parent / doc["scene"]) if isinstance(doc["scene"], str) else doc["scene"])
    out = tmp_path / "study.yaml"
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


def test_fail_on_limit_counts_a_broken_lower_limit(tmp_path, capsys):
    """The cooled layer settles at least 7.8 mm: a lower limit of 8 mm is broken (exit 3), one of
    7 mm holds (exit 0), with the upper limit 1 cm holding in both."""
    search = {"method": "auto", "budget": 40}
    broken = write(tmp_path, study_doc(COOLED, search=search, limits={"settlement": {"lower": 8e-3, "upper": 1e-2}}),
                   COOLED)
    assert main(["run", str(broken), "-o", str(tmp_path / "a.nc"), "--fail-on-limit", "--quiet"]) == 3
    assert "limit broken: settlement" in capsys.readouterr().err
    ds = xr.open_dataset(tmp_path / "a.nc", engine="h5netcdf")
    assert limits_broken(ds) == ["settlement"] and float(ds["margin_lower"].sel(criterion="settlement")) < 0
    assert float(ds["margin"].sel(criterion="settlement")) > 0
    page = render_report(tmp_path / "a.nc", strict=True)          # the interval against both limits
    assert '<div class="verdict fail" id="verdict">FAIL</div>' in page and "range of each criterion" in page
    best = number(float(ds["best_value"].sel(criterion="settlement")), "m")
    assert f'<td class="num best-value">{best}</td>' in page
    assert f"settlement ∈ [{best}, {number(float(ds['worst_value'].sel(criterion='settlement')), 'm')}]" in page
    held = write(tmp_path, study_doc(COOLED, search=search, limits={"settlement": {"lower": 7e-3, "upper": 1e-2}}),
                 COOLED)
    assert main(["run", str(held), "-o", str(tmp_path / "b.nc"), "--fail-on-limit", "--quiet"]) == 0


@pytest.mark.parametrize("sense, limit, message", [
    ("max", {"lower": 1.0}, "limits.settlement.lower: a lower limit needs the minimum of 'settlement': "
                            "give the criterion sense: min or both (it is max)"),
    ("min", 1.0, "limits.settlement: an upper limit needs the maximum of 'settlement'"),
    ("min", {"upper": 1.0}, "limits.settlement.upper: an upper limit needs the maximum"),
    ("both", {"lower": 2.0, "upper": 1.0}, "limits.settlement: lower limit 2.0 is above upper limit 1.0"),
    ("both", {}, "limits.settlement: give lower, upper or both"),
    ("both", {"lowr": 1.0}, "unknown key 'lowr' (did you mean 'lower'?)"),
    ("bost", 1.0, "criteria.0.sense: must be 'max', 'min' or 'both'"),
])
def test_limits_and_senses_that_do_not_fit_are_refused(tmp_path, capsys, sense, limit, message):
    path = write(tmp_path, study_doc(COOLED, sense=sense, limits={"settlement": limit}), COOLED)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert message in err and str(path) in err and "Traceback" not in err


def test_check_prints_the_sense_and_both_limits(tmp_path, capsys):
    path = write(tmp_path, study_doc(COOLED, limits={"settlement": {"lower": 7e-3, "upper": 1e-2}}), COOLED)
    assert main(["check", str(path)]) == 0
    assert "settlement: mean normal displacement (Φ3/Φ4) over top (mean_normal_displacement) [m], sense both, lower limit 0.007, limit 0.01" \
        in capsys.readouterr().out
