"""Whole pipeline (study file -> gmsh mesh -> FEM) against closed forms that
P1 reproduces exactly (linear displacement fields): agreement to 1e-8
relative is round-off of a ~1e3-unknown direct solve, not discretisation."""
from pathlib import Path

import numpy as np
import pytest

import wcs
from wcs.model.evaluation import Evaluator
from wcs.model.materials import lame, thermal_beta

STUDIES = Path(__file__).resolve().parents[2] / "studies"
RTOL = 1e-8


@pytest.fixture(scope="module")
def plate():
    study = wcs.load_study(STUDIES / "heated-plate.yaml")
    ev = Evaluator(study)
    return study, ev, ev.evaluate(study.nominal())


def test_uniform_heating_of_constrained_plate(plate):
    study, ev, res = plate
    mat = study.scene.materials["steel"].model_dump(by_alias=True, exclude_none=True)
    lam, mu = lame(mat)
    dT = 343.0 - 293.0
    beta = thermal_beta(mat, "strain")
    eyy = beta * dT / (lam + 2 * mu)
    p = ev.smesh.mesh.p
    u = res.state.u.reshape(-1, 2)
    assert np.allclose(res.state.T, 343.0, rtol=0, atol=RTOL * 343.0)
    assert np.max(np.abs(u[:, 0])) <= RTOL * eyy
    assert np.allclose(u[:, 1], eyy * p[1], rtol=0, atol=RTOL * eyy * 0.5)
    s = res.state.stress
    sxx = lam * eyy - beta * dT
    assert np.allclose(s[0], sxx, rtol=RTOL) and np.allclose(s[2], sxx, rtol=RTOL)
    assert np.max(np.abs(s[1])) <= RTOL * abs(sxx) and np.max(np.abs(s[3])) <= RTOL * abs(sxx)
    assert res.phi["heave"] == pytest.approx(0.5 * eyy, rel=RTOL)
    assert res.phi["temperature"] == pytest.approx(343.0, rel=RTOL)
    I2 = (2 / 3) * (2 * sxx**2 - sxx**2)       # τxx = τzz = s, τyy = 0: (2/3)(s²+s²−s²)
    assert res.phi["shear"] == pytest.approx(I2, rel=1e-7)


def test_confined_compression_of_glued_layers():
    study = wcs.load_study(STUDIES / "glued-layers.yaml")
    ev = Evaluator(study)
    res = ev.evaluate(study.nominal())
    mats = study.scene.materials
    pres = 1.0e6
    lm = {m: lame(mats[m].model_dump(by_alias=True, exclude_none=True)) for m in ("concrete", "steel")}
    eyy = {m: -pres / (l + 2 * mu) for m, (l, mu) in lm.items()}
    p = ev.smesh.mesh.p
    uy = res.state.u[1::2]
    exact = np.where(p[1] <= 0.3, eyy["concrete"] * p[1], eyy["concrete"] * 0.3 + eyy["steel"] * (p[1] - 0.3))
    assert np.allclose(uy, exact, rtol=0, atol=RTOL * abs(exact).max())
    assert np.max(np.abs(res.state.u[0::2])) <= RTOL * abs(exact).max()
    soft = ev.smesh.cell_region == ev.smesh.region_index("soft")
    s = res.state.stress
    assert np.allclose(s[1], -pres, rtol=RTOL)
    assert np.max(np.abs(s[3])) <= RTOL * pres
    for m, cells in (("concrete", soft), ("steel", ~soft)):
        assert np.allclose(s[0][cells], lm[m][0] * eyy[m], rtol=RTOL)
        assert np.allclose(s[2][cells], lm[m][0] * eyy[m], rtol=RTOL)
    assert res.phi["settlement"] == pytest.approx(-(eyy["concrete"] * 0.3 + eyy["steel"] * 0.2), rel=RTOL)
