"""The mesh check of `wcs run`: the extremes re-solved on the mesh split once and twice,
Richardson's order, extrapolation and error estimate, and the PASS / FAIL / MARGINAL verdict."""
import math
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from tests.model.test_contact_pressure import hertz_mean
from wcs.cli import main
from wcs.model.evaluation import Evaluator
from wcs.results.meshcheck import Richardson, refined_nodes, richardson, verdict
from wcs.report import render_report
from wcs.scene.mesher2d import build_mesh
from wcs import load_study

ROOT = Path(__file__).resolve().parents[2]
SLAB = ROOT / "tests" / "data" / "heated-slab.yaml"
VALIDATION = ROOT / "studies" / "validation"


def slab_exact(q: float, k: float) -> float:
    """Mean of T0 + q/(2k) y(1 - y) over 0.3 <= y <= 0.7 (the header of heated-slab.yaml)."""
    return 300.0 + q / (2 * k) * (0.7**2 / 2 - 0.7**3 / 3 - 0.3**2 / 2 + 0.3**3 / 3) / 0.4


def _run(tmp_path, study: Path, *flags, edit=None) -> xr.Dataset:
    doc = yaml.safe_load(study.read_text())
    if edit:
        edit(doc)
    (tmp_path / study.name).write_text(yaml.safe_dump(doc, sort_keys=False))
    out = tmp_path / (study.stem + ".nc")
    assert main(["run", str(tmp_path / study.name), "-o", str(out), "--quiet", *flags]) in (0, 3)
    return xr.load_dataset(out, engine="h5netcdf")


@pytest.fixture(scope="module")
def slab(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("slab"), SLAB)


# ---------------------------------------------------------------- Richardson and the verdict

@pytest.mark.parametrize("p, c", [(1.0, 0.3), (2.0, -5.0), (1.5, 2e-3)])
def test_richardson_is_exact_on_f_plus_c_h_to_the_p(p, c):
    f = [7.0 + c * h**p for h in (1.0, 0.5, 0.25)]
    est = richardson(*f, 1e-12)
    assert est.order == pytest.approx(p, rel=1e-12)
    assert est.extrapolated == pytest.approx(7.0, rel=1e-12)
    assert est.error == pytest.approx(-c, rel=1e-9)            # exact = f(h) + error


def test_richardson_gives_no_order_when_the_differences_do_not_shrink_or_vanish():
    oscillating = richardson(1.0, 1.1, 1.05, 1e-8)             # r = -2
    growing = richardson(1.0, 1.1, 1.3, 1e-8)                  # r = 0.5
    for est in (oscillating, growing):
        assert math.isnan(est.order) and math.isnan(est.extrapolated) and math.isnan(est.error)
        assert "do not shrink" in est.note
    assert oscillating.spread == pytest.approx(0.1) and growing.spread == pytest.approx(0.3)
    flat = richardson(2.0, 2.0 + 1e-10, 2.0 - 1e-10, 1e-8)
    assert math.isnan(flat.order) and "within the solver tolerance" in flat.note
    assert "not to be trusted" in richardson(1.0, 1.5, 1.5 + 0.5 / 64, 1e-8).note   # order 6
    assert "missing" in richardson(1.0, math.nan, 1.2, 1e-8).note


def test_verdict_is_marginal_when_the_limit_lies_within_the_error():
    est = Richardson(2.0, 10.5, 0.5, 0.45, "")                 # exact about 10.5 for the value 10
    assert verdict(10.0, est, 10.4, "worst") == "MARGINAL"
    assert verdict(10.0, est, 9.6, "worst") == "MARGINAL"
    assert verdict(10.0, est, 10.6, "worst") == "PASS"
    assert verdict(10.0, est, 9.4, "worst") == "FAIL"
    assert verdict(10.0, est, 9.4, "best") == "PASS"           # a lower limit
    assert verdict(10.0, est, math.nan, "worst") == ""
    no_order = Richardson(math.nan, math.nan, math.nan, 0.45, "")
    assert verdict(10.0, no_order, 10.4, "worst") == "MARGINAL"   # the spread instead
    assert verdict(10.0, no_order, 10.5, "worst") == "PASS"


# ---------------------------------------------------------------- the refined meshes

DISC = {"study": "disc", "scene": {
    "mesh": {"size": 0.3},
    "materials": {"steel": {"E": 2.0e11, "nu": 0.3}},
    "bodies": {"disc": {"regions": [{"material": "steel", "shape": {"disc": {"center": [0.0, 1.0], "radius": 1.0}}}]},
               "block": {"regions": [{"material": "steel", "shape": {"rectangle": [-1.0, -1.0, 1.0, 0.0]}}]}},
    "boundaries": {"arc": {"body": "disc", "circle": {"center": [0.0, 1.0], "radius": 1.0}},
                   "top": {"body": "block", "segment": [[-1.0, 0.0], [1.0, 0.0]]}},
    "supports": {"top": {"u": [0.0, 0.0]}}}}


def test_splitting_keeps_the_geometry_and_halves_every_edge():
    scene = load_study(DISC).scene
    base = build_mesh(scene)
    for s in (1, 2):
        sm = build_mesh(scene, splits=s)
        assert sm.mesh.t.shape[1] == 4**s * base.mesh.t.shape[1]
        assert sm.mesh.p.shape[1] == refined_nodes(base.mesh, s)
        arc = sm.boundary_nodes("arc")
        r = np.hypot(*(sm.mesh.p[:, arc] - np.array([[0.0], [1.0]])))
        assert np.abs(r - 1.0).max() < 1e-12                 # the new nodes lie on the circle
        assert arc.size == 2**s * base.boundary_nodes("arc").size          # a closed curve
        assert sm.boundary_nodes("top").size == 2**s * (base.boundary_nodes("top").size - 1) + 1


def test_a_mesh_file_has_no_geometry_to_refine(tmp_path):
    study = load_study(ROOT / "studies" / "user-mesh-demo.yaml")
    with pytest.raises(Exception, match="no geometry to refine"):
        Evaluator(study, splits=1)


# ---------------------------------------------------------------- a run with the mesh check

def test_mesh_check_estimates_the_known_error_of_the_heated_slab(slab):
    """T is quadratic, P1 linear: O(h^2). The estimate is within 10% of the true error, of its
    sign, and the extrapolated value beats the finest mesh's by a factor > 10."""
    q, k, _ = slab["worst_x"].values[0]
    exact = slab_exact(q, k)
    f = slab["mesh_check_value"].sel(extreme="worst", criterion="warmth").values
    assert f[0] == slab["worst_value"].values[0]
    true = exact - f[0]
    est = float(slab["mesh_check_error"].sel(extreme="worst", criterion="warmth"))
    assert true > 10 and 0.9 < est / true < 1.1                  # measured: 22.03 against 22.00
    assert float(slab["mesh_check_order"].values[0, 0]) == pytest.approx(2.0, abs=0.1)
    extrap = float(slab["mesh_check_extrapolated"].values[0, 0])
    assert abs(extrap - exact) < abs(f[2] - exact) / 10
    assert str(slab["mesh_check_verdict"].values[0, 0]) == "PASS"        # limit 1200, worst 1067 + 22
    nodes = slab["mesh_check_nodes"].values
    assert nodes[0] == slab.attrs["mesh_nodes"] and nodes[1] > 3 * nodes[0] and nodes[2] > 3 * nodes[1]
    assert slab.attrs["mesh_check"].startswith("done")


def test_marginal_reaches_the_report(tmp_path):
    def near(doc):
        doc["limits"] = {"warmth": 1075.0}                          # worst 1066.9, estimated error 22
    ds = _run(tmp_path, SLAB, edit=near)
    assert str(ds["mesh_check_verdict"].values[0, 0]) == "MARGINAL"
    page = render_report(ds, strict=True)
    assert '<div class="verdict none" id="verdict">MARGINAL</div>' in page
    assert 'id="mesh-check-table"' in page


def test_check_prints_the_cost(capsys):
    assert main(["check", str(SLAB)]) == 0
    out = capsys.readouterr().out
    line = [s for s in out.splitlines() if "mesh check" in s]
    ev = Evaluator(load_study(SLAB))
    n1, n2 = (3 * refined_nodes(ev.smesh.mesh, s) for s in (1, 2))     # T, u_x, u_y per node
    assert len(line) == 1 and f"{n1} unknowns and {n2} unknowns" in line[0] and " s (" in line[0]


# ---------------------------------------------------------------- acceptance on the closed forms

@pytest.mark.slow
def test_cooled_layer_mesh_share_is_nil(tmp_path):
    """P1 is exact on the cooled layer (linear fields): the three values equal the closed form
    and the check says the mesh's share is below the solver tolerance."""
    ds = _run(tmp_path, VALIDATION / "cooled-layer.yaml")
    nu, E, p = ds["worst_x"].values[0]
    exact = 1.0 * (1 + nu) / (1 - nu) * (5e-5 * 60.0 + p / E * (1 - 2 * nu))
    f = ds["mesh_check_value"].values[0, 0]
    assert np.abs(f - exact).max() < 1e-9 * exact
    assert "within the solver tolerance" in str(ds["mesh_check_note"].values[0, 0])


@pytest.mark.slow
def test_hertz_mesh_check_estimates_the_known_error(tmp_path):
    """hertz-meshcheck.yaml (a/R = 0.026, h ≈ a/3, the mean pressure over x ∈ [0, 0.0125]):
    the model error (−1.3e-4, tests/model/test_contact_pressure.py::
    test_hertz_model_error_scales_as_a_over_r_squared) is 1/65 of the mesh's share, so the closed form stands for the exact value. The
    values 1.380336e9, 1.388327e9, 1.390924e9 on h, h/2, h/4 (order 1.62) give an estimated
    error +1.184e7 against the true +1.211e7, and an extrapolated value 2.7e5 from the closed
    form against 1.5e6 for the finest (measured). Before, on hertz.yaml (a/R = 0.053, h ≈ a/13):
    2.784166e9, 2.783546e9, 2.783414e9, order 2.23, estimated error −7.9e5 against the true
    +7.2e5 (the model error, −1.5e6, dominated), the extrapolated value farther than the finest."""
    ds = _run(tmp_path, VALIDATION / "hertz-meshcheck.yaml")
    p_top = float(ds["worst_x"].values[0, 0])
    assert p_top == 3.0e7                                          # the load's upper bound
    exact = hertz_mean(p_top, 0.0125)
    f = ds["mesh_check_value"].values[0, 0]
    assert f[0] == ds["worst_value"].values[0]
    true = exact - f[0]
    est = float(ds["mesh_check_error"].values[0, 0])
    assert true > 0 and 0.8 < est / true < 1.25                    # a factor 3 is asked
    assert 1.2 < float(ds["mesh_check_order"].values[0, 0]) < 2.0
    extrap = float(ds["mesh_check_extrapolated"].values[0, 0])
    assert abs(extrap - exact) < abs(f[2] - exact) / 3
