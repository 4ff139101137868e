"""The seed's scenes in 3D (studies/*-3d.yaml) and when the 2D plane-strain study suffices.

With u_y = 0 on its end planes and a fault that contains the tunnel axis, the 3D tunnel is the
2D plane-strain section extruded: the continuous solutions agree exactly, so the mid-section
criteria of the two P1 discretizations differ by their mesh errors only. Each mesh error is
estimated from the change to a mesh 1.5× coarser near the tunnel (h → 1.5 h): for a
quantity converging at rate p ≥ 1, Richardson's estimate of the error at h is
|Φ_h − Φ_1.5h| / (1.5^p − 1) ≤ 2 |Φ_h − Φ_1.5h|. So the tolerance is
2 (|ΔΦ_3D| + |ΔΦ_2D|), every number measured in the test itself.

The comparison runs on the studies as written (Tresca friction on the fault, slip limit 1e6
Pa at the nominal data) and on their frictionless variants (the slip limit dropped in both);
the oblique fault (strike 30° off the axis) departs from 2D by more than that tolerance."""
from pathlib import Path

import numpy as np
import pytest
import yaml

from wcs.model.evaluation import Evaluator
from wcs import load_study

STUDIES = Path(__file__).resolve().parents[2] / "studies"


def frictionless(doc: dict) -> dict:
    for contact in doc["scene"]["contacts"].values():
        contact.pop("friction", None)
    doc["uncertain"] = {k: v for k, v in doc["uncertain"].items() if "slip_limit" not in k}
    doc.pop("sweep", None)
    return doc


def as_written(doc: dict) -> dict:
    doc.pop("sweep", None)
    return doc


def nominal_criteria(doc: dict, monkeypatch) -> dict:
    monkeypatch.chdir(STUDIES)                   # the material library is named relative to it
    ev = Evaluator(load_study(doc))
    res = ev.evaluate(ev.study.nominal())
    assert res.status == 0, res.message
    return res.phi


def tunnel_3d(name: str, size: float, fine: float, variant=frictionless) -> dict:
    doc = variant(yaml.safe_load((STUDIES / name).read_text()))
    mesh = doc["scene"]["mesh"]
    mesh["size"] = size
    mesh["refine"][0]["size"], mesh["refine"][1]["size"] = fine, 2 * fine
    return doc


def tunnel_2d(size: float, fine: float, variant=frictionless) -> dict:
    doc = variant(yaml.safe_load((STUDIES / "tunnel-fault.yaml").read_text()))
    doc["scene"]["mesh"]["size"] = size
    for r in doc["scene"]["mesh"]["refine"]:
        r["size"] = fine if "disc" in r else 4 * fine
    return doc


def two_d_criteria(variant) -> list[dict]:
    """The 2D plane-strain study's criteria on a mesh 1.5× finer than its own (2 m, 1/6 m at
    the tunnel) and on its own (3 m, 0.25 m)."""
    mp = pytest.MonkeyPatch()
    try:
        return [nominal_criteria(tunnel_2d(2.0 * k, 0.25 / 1.5 * k, variant), mp) for k in (1.0, 1.5)]
    finally:
        mp.undo()


@pytest.fixture(scope="module")
def two_d(request):
    return two_d_criteria(frictionless)


def three_d(name: str, variant=frictionless, fine: float = 1.0) -> list[dict]:
    """The 3D study's criteria at 8 m far away, `fine` near the tunnel and 2 `fine` along the
    fault, and on that mesh 1.5× coarser near the tunnel."""
    mp = pytest.MonkeyPatch()
    try:
        return [nominal_criteria(tunnel_3d(name, 8.0, fine * k, variant), mp) for k in (1.0, 1.5)]
    finally:
        mp.undo()


def tolerance(a: list[dict], b: list[dict], name: str) -> float:
    return 2.0 * (abs(a[0][name] - a[1][name]) + abs(b[0][name] - b[1][name]))


@pytest.mark.slow
def test_plane_strain_slice_matches_the_2d_study_within_the_mesh_errors(two_d):
    d3 = three_d("tunnel-fault-3d.yaml")
    for name in ("convergence", "shear"):
        tol = tolerance(d3, two_d, name)
        print(f"{name}: 3D {d3[0][name]:.6g} (1.5h {d3[1][name]:.6g}), 2D {two_d[0][name]:.6g} "
              f"(1.5h {two_d[1][name]:.6g}), |3D - 2D| {abs(d3[0][name] - two_d[0][name]):.3g} <= {tol:.3g}")
        assert abs(d3[0][name] - two_d[0][name]) <= tol
        assert tol <= 0.05 * abs(two_d[0][name])           # a tolerance that still says something


@pytest.mark.slow
def test_with_tresca_friction_the_slice_matches_the_2d_study_within_the_mesh_errors():
    """The studies as written, Tresca on the fault, on 3D meshes of 2/3 m and 1 m near the
    tunnel: at 1.5 m and 1 m the 3D wall convergence is not yet in its asymptotic range
    (0.09609, 0.09600, then 0.09625 at 0.8 m and 0.09638 at 2/3 m, towards the 2D 0.09679),
    and the change between them would understate the 3D mesh error."""
    d2, d3 = two_d_criteria(as_written), three_d("tunnel-fault-3d.yaml", as_written, fine=2.0 / 3.0)
    for name in ("convergence", "shear"):
        tol = tolerance(d3, d2, name)
        print(f"{name}: 3D {d3[0][name]:.6g} (1.5h {d3[1][name]:.6g}), 2D {d2[0][name]:.6g} "
              f"(1.5h {d2[1][name]:.6g}), |3D - 2D| {abs(d3[0][name] - d2[0][name]):.3g} <= {tol:.3g}")
        assert abs(d3[0][name] - d2[0][name]) <= tol
        assert tol <= 0.05 * abs(d2[0][name])


@pytest.mark.slow
def test_a_fault_striking_obliquely_departs_from_the_2d_section(two_d):
    """The 30° fault's mid-section wall convergence is off the 2D value by more than the mesh
    errors: this scene needs 3D (README). The shear intensity is printed beside it."""
    d3 = three_d("tunnel-fault-oblique-3d.yaml")
    for name in ("convergence", "shear"):
        off = (d3[0][name] - two_d[0][name]) / two_d[0][name]
        print(f"{name}: oblique 3D {d3[0][name]:.6g}, 2D {two_d[0][name]:.6g}: {100 * off:+.1f} % "
              f"(mesh-error tolerance {tolerance(d3, two_d, name):.3g})")
    assert abs(d3[0]["convergence"] - two_d[0]["convergence"]) > tolerance(d3, two_d, "convergence")


def test_the_knee_tilt_box_lies_in_the_five_degree_cone():
    """The tilt is a box of traction components [t_x, t_z]: every corner (hence every point)
    must have |t_x| ≤ tan 5° |t_z|, and the box must reach the cone's edge at its smallest load."""
    study = load_study(STUDIES / "knee-replacement-3d.yaml")
    box = {e.path: (e.lower, e.upper) for e in study.uncertain}
    tx, tz = box["loads.femur_top.traction.0"], box["loads.femur_top.traction.2"]
    corners = np.array([[x, z] for x in tx for z in tz])
    assert np.all(np.abs(corners[:, 0]) <= np.tan(np.radians(5.0)) * np.abs(corners[:, 1]))
    assert max(np.abs(tx)) == pytest.approx(np.tan(np.radians(5.0)) * min(np.abs(tz)), rel=0.01)
