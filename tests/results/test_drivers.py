"""What drives an extreme: |dPhi/dx_i| (u_i - l_i) at the extreme data set, in the results file
(`drivers`) and the report, with the parameters that do not move the criterion said in words."""
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr

from wcs.cli import main
from wcs.results.drivers import drivers, idle
from wcs.results.extremes import extremes
from wcs.report import render_report
from wcs import load_study

SLAB = Path(__file__).resolve().parents[1] / "data" / "heated-slab.yaml"


@pytest.fixture(scope="module")
def slab(tmp_path_factory):
    out = tmp_path_factory.mktemp("drivers") / "slab.nc"
    assert main(["run", str(SLAB), "-o", str(out), "--quiet", "--no-mesh-check"]) == 0
    return xr.load_dataset(out, engine="h5netcdf")


def test_drivers_of_the_heated_slab_are_its_exact_derivatives(slab):
    """The discrete temperature is T0 + (q/k) w with w independent of q and k (K(k) = k K1):
    dPhi/dq = (Phi - T0)/q and dPhi/dk = -(Phi - T0)/k exactly; E does not enter."""
    d = slab["drivers"].sel(extreme="worst", criterion="warmth")
    sign = slab["drivers_sign"].sel(extreme="worst", criterion="warmth")
    q, k, _ = slab["worst_x"].values[0]
    rise = float(slab["worst_value"].values[0]) - 300.0
    width = slab["param_upper"].values - slab["param_lower"].values
    assert float(d.sel(param="thermal.sources.slab")) == pytest.approx(rise / q * width[0], rel=1e-10)
    assert float(d.sel(param="materials.clay.conductivity")) == pytest.approx(rise / k * width[1], rel=1e-10)
    assert list(sign.values[:2]) == [1, -1]
    assert idle(d.values).tolist() == [False, False, True]
    assert "run's adjoint gradient" in str(slab["drivers_note"].values[0, 0])
    page = render_report(slab, strict=True)
    assert ("Parameters that do not move warmth (to first order at its worst data set): "
            "materials.clay.E.") in page
    assert page.count("drivers of warmth") == 1                    # the chart


def test_no_mesh_check_skips_it_and_keeps_the_drivers(slab):
    assert slab.attrs["mesh_check"] == "skipped (--no-mesh-check)"
    assert not any(str(v).startswith("mesh_check_") for v in slab.data_vars)
    assert 'id="no-mesh-check"' in render_report(slab, strict=True)


def test_an_extreme_without_a_kept_gradient_is_solved_again(slab):
    ds = slab.copy(deep=True)
    row = int(ds["worst_eval"].values[0])
    ds["grad"].values[row] = np.nan
    study = load_study(SLAB)
    calls = []

    def evaluate(x):
        calls.append(x)
        return study.evaluate(x, gradients=True)
    out = drivers(ds, extremes(ds), evaluate)
    assert len(calls) == 1
    np.testing.assert_allclose(out["drivers"].values, slab["drivers"].values, rtol=1e-12, atol=0)
    assert "solved again" in str(out["drivers_note"].values[0, 0])


@pytest.mark.parametrize("outcome, said", [
    (SimpleNamespace(status=1, message="the contact Newton did not converge", grad=None, nonsmooth=False),
     "did not solve again"),
    (SimpleNamespace(status=0, message="solved", grad={"warmth": None}, nonsmooth=False), "singular"),
])
def test_no_gradient_gives_no_number(slab, outcome, said):
    ds = slab.copy(deep=True)
    ds["grad"].values[int(ds["worst_eval"].values[0])] = np.nan
    out = drivers(ds, extremes(ds), lambda x: outcome)
    assert np.isnan(out["drivers"].values).all() and said in str(out["drivers_note"].values[0, 0])
    page = render_report(ds.drop_vars(["drivers", "drivers_sign", "drivers_note"]).assign(out.data_vars), strict=True)
    assert 'class="warn no-gradient">No drivers' in page and "drivers of warmth" not in page


def test_a_nonsmooth_extreme_has_one_sided_drivers(slab):
    """Where the criterion is not differentiable (flagged here on the slab's worst case), the
    drivers are one-sided differences, labelled so: for Phi = T0 + c q / k (exact, as above) the
    forward and backward quotients of step h = 1e-6 of the interval are dPhi/dq = (Phi - T0)/q
    exactly (Phi is linear in q) and -(Phi - T0)/k · k/(k ± h) in k (to 1e-5 with the interval
    2.5 k at most: |h/k| <= 3e-6); E does not move it. Before: NaN and "no gradient"."""
    ds = slab.copy(deep=True)
    ds["nonsmooth"].values[int(ds["worst_eval"].values[0])] = 1
    study = load_study(SLAB)
    out = drivers(ds, extremes(ds), lambda x, gradients=True: study.evaluate(x, gradients))
    q, k, _ = ds["worst_x"].values[0]
    lower, upper = ds["param_lower"].values, ds["param_upper"].values
    width = upper - lower
    rise = float(ds["worst_value"].values[0]) - 300.0
    exact = np.array([rise / q, -rise / k]) * width[:2]
    fwd, back = out["drivers_forward"].values[0, 0], out["drivers_backward"].values[0, 0]
    for side, values in (("forward", fwd), ("backward", back)):
        inside = (ds["worst_x"].values[0] + (1 if side == "forward" else -1) * 1e-6 * width)[:2]
        taken = (inside >= lower[:2]) & (inside <= upper[:2])
        assert np.array_equal(np.isfinite(values[:2]), taken), side
        np.testing.assert_allclose(values[:2][taken], exact[taken], rtol=1e-5)
    np.testing.assert_allclose(out["drivers"].values[0, 0, :2], np.abs(exact), rtol=1e-5)
    assert out["drivers"].values[0, 0, 2] <= 1e-9 * np.abs(exact).max()      # E: the round-off of a solve
    assert list(out["drivers_sign"].values[0, 0, :2]) == [1, -1]
    note = str(out["drivers_note"].values[0, 0])
    assert note.startswith("one-sided differences") and "not differentiable at the extreme" in note
    page = render_report(ds.drop_vars(["drivers", "drivers_sign", "drivers_note"]).assign(out.data_vars), strict=True)
    assert "drivers of warmth" in page and "<b>one-sided differences</b>" in page and "No drivers" not in page


def test_one_sided_differences_pointing_out_of_the_box_make_a_corner_maximum(slab):
    """At the corner the slab's worst case sits at in q and k (E moved to a bound too), every
    one-sided difference into the box is a fall of the criterion: the note says it is a maximum
    along every edge of the box leaving that corner; at the opposite corner it is not."""
    ds = slab.copy(deep=True)
    row = int(ds["worst_eval"].values[0])
    ds["nonsmooth"].values[row] = 1
    study = load_study(SLAB)
    lower, upper = ds["param_lower"].values, ds["param_upper"].values
    for corner, said in ((np.where([1, 0, 0], upper, lower), True), (np.where([0, 1, 0], upper, lower), False)):
        ds["worst_x"].values[0] = corner
        ds["worst_value"].values[0] = study.evaluate(corner).phi["warmth"]
        out = drivers(ds, extremes(ds), lambda x, gradients=True: study.evaluate(x, gradients))
        note = str(out["drivers_note"].values[0, 0])
        assert ("a maximum along every edge of the box leaving it" in note) is said, note


def test_drivers_below_the_round_off_of_the_criterion_are_no_effect(slab):
    """Drivers of about 6e-10 of |Phi| everywhere (6e-10 Pa against a 1e7 Pa mean
    pressure, here against the slab's ~300 K): each is the largest, so relative to the largest
    every parameter used to "move" the criterion; relative to |Phi| they are the solves'
    round-off (IDLE = 1e-9), shown as "no effect", with no bars and no claim that every
    parameter moves it. One real driver beside them keeps its bar and names the idle ones."""
    phi = float(slab["worst_value"].values[0])
    tiny = np.array([6e-10, 3e-10, 5e-10]) * abs(phi) * 1e-1
    assert idle(tiny).tolist() == [False, False, False]          # against the largest alone
    assert idle(tiny, phi).all() and not idle(tiny, 1e-3 * phi).any()
    from wcs.report import data, html

    def section(ds):                                               # the report's drivers, without the rest
        return html.Report(data.from_dataset(ds, "slab")).drivers()
    ds = slab.copy(deep=True)
    ds["drivers"].values[0, 0] = tiny
    page = section(ds)
    assert "No effect: no parameter moves warmth beyond round-off at its worst data set" in page
    assert "drivers of warmth" not in page and "Every parameter moves warmth" not in page
    ds["drivers"].values[0, 0] = [1.0, 3e-10 * abs(phi), 5e-10 * abs(phi)]
    page = section(ds)
    assert page.count("drivers of warmth") == 1
    assert ("Parameters that do not move warmth (to first order at its worst data set): "
            "materials.clay.conductivity, materials.clay.E.") in page
