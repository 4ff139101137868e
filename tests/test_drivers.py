"""What drives an extreme: |dPhi/dx_i| (u_i - l_i) at the extreme data set, in the results file
(`drivers`) and the report, with the parameters that do not move the criterion said in words."""
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr

from wcs.cli import main
from wcs.drivers import drivers, idle
from wcs.extremes import extremes
from wcs.report import render_report
from wcs.study import load_study

SLAB = Path(__file__).resolve().parent / "data" / "heated-slab.yaml"


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


def test_a_nonsmooth_extreme_has_no_drivers(slab):
    ds = slab.copy(deep=True)
    ds["nonsmooth"].values[int(ds["worst_eval"].values[0])] = 1
    out = drivers(ds, extremes(ds), lambda x: pytest.fail("the run's gradient is there"))
    assert np.isnan(out["drivers"].values).all()
    assert "not differentiable at the extreme" in str(out["drivers_note"].values[0, 0])
