"""The model on P1 tetrahedra (a 3D scene without contact): closed forms, manufactured solutions
and `wcs solve` of a 3D study.

Tolerances: a linear displacement field is in the P1 space, so uniform heating and a block
under uniform traction are solved exactly up to round-off (1e-8 relative: the conditioning of a
few thousand unknowns times machine epsilon is far below it). The manufactured solutions give
the P1 rates, L2 ~ h² and energy ~ h, measured on three gmsh meshes (h ∝ cells^(-1/3)); the
brief's window is ±0.15."""
import os
import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest
import scipy.sparse.linalg as spla
import xarray as xr
import yaml
from skfem import Basis, ElementTetP1, ElementVector, LinearForm, asm
from skfem.helpers import dot

from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs.geometry import tet
from wcs.model.model import Model, rigid_modes
from wcs.scene.mesher3d import build_mesh3d
from wcs import load_study

E, NU, ALPHA = 2.0e11, 0.3, 1.2e-5
LAM, MU = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))

FACES = {  # the six faces of the unit cube
    "x0": {"plane": {"point": [0, 0, 0], "normal": [1, 0, 0]}},
    "x1": {"plane": {"point": [1, 0, 0], "normal": [1, 0, 0]}},
    "y0": {"plane": {"point": [0, 0, 0], "normal": [0, 1, 0]}},
    "y1": {"plane": {"point": [0, 1, 0], "normal": [0, 1, 0]}},
    "z0": {"plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}},
    "z1": {"plane": {"point": [0, 0, 1], "normal": [0, 0, 1]}},
}


def cube(size=0.25, **scene) -> dict:
    d = {"study": "cube-3d",
         "scene": {"dimension": 3, "mesh": {"size": size},
                   "materials": {"steel": {"E": E, "nu": NU, "expansion": ALPHA, "conductivity": 45.0}},
                   "bodies": {"block": {"regions": [{"material": "steel", "shape": {"box": [0, 0, 0, 1, 1, 1]}}]}},
                   "boundaries": dict(FACES)}}
    d["scene"].update(scene)
    return d


def solve(d):
    ev = Evaluator(load_study(d))
    res = ev.evaluate(ev.study.nominal())
    assert res.status == 0, res.message
    return ev, res


ROLLERS = {"x0": {"u": [0.0, None, None]}, "y0": {"normal": 0.0}, "z0": {"u": [None, None, 0.0]}}


def test_uniform_heating_of_a_constrained_block_is_exact():
    """Rollers on all six faces, T = T0 + ΔT everywhere: u = 0 and τ = −(3λ+2μ)αΔT I."""
    dT = 40.0
    d = cube(supports={f: ({"normal": 0.0} if f[0] == "y" else
                           {"u": [0.0 if f[0] == "x" else None, None, 0.0 if f[0] == "z" else None]})
                       for f in FACES},
             thermal={"reference": 293.0, "temperature": {f: 293.0 + dT for f in FACES}})
    ev, res = solve(d)
    s = res.state.stress
    beta = (3 * LAM + 2 * MU) * ALPHA
    assert s.shape == (6, ev.smesh.mesh.t.shape[1])
    assert np.allclose(res.state.T, 293.0 + dT, rtol=1e-14)
    assert np.abs(res.state.u).max() < 1e-8 * ALPHA * dT
    assert np.abs(s[:3] + beta * dT).max() < 1e-8 * beta * dT
    assert np.abs(s[3:]).max() < 1e-8 * beta * dT


def test_uniform_heating_of_a_block_on_rollers_expands_freely():
    """Rollers on three faces only: u = αΔT x, no stress."""
    dT = -25.0
    ev, res = solve(cube(supports=ROLLERS, thermal={"reference": 300.0, "temperature": {"x1": 300.0 + dT}}))
    p = ev.smesh.mesh.p
    u = res.state.u.reshape(-1, 3).T
    assert np.abs(u - ALPHA * dT * p).max() < 1e-8 * ALPHA * abs(dT)
    assert np.abs(res.state.stress).max() < 1e-8 * (3 * LAM + 2 * MU) * ALPHA * abs(dT)


def test_a_block_under_uniform_traction_and_pressure_is_the_closed_form():
    """Traction t on the top, pressure p on x = 1, rollers on x = 0, y = 0 (a roller by its
    normal), z = 0: τ = diag(−p, 0, t_z) uniform, u = ε x with ε = C⁻¹τ."""
    tz, p = -3.0e6, 1.0e6
    ev, res = solve(cube(supports=ROLLERS, loads={"z1": {"traction": [0.0, 0.0, tz]}, "x1": {"pressure": p}}))
    tau = np.array([-p, 0.0, tz])
    eps = (tau - NU * (tau.sum() - tau)) / E
    pts = ev.smesh.mesh.p
    u = res.state.u.reshape(-1, 3).T
    assert np.abs(u - eps[:, None] * pts).max() < 1e-8 * np.abs(eps).max()
    s = res.state.stress
    assert np.abs(s[:3] - tau[:, None]).max() < 1e-8 * abs(tz)
    assert np.abs(s[3:]).max() < 1e-8 * abs(tz)
    assert tet.von_mises(s) == pytest.approx(np.sqrt(p**2 + tz**2 + p * tz), rel=1e-8)   # √(s1² + s3² − s1 s3)


def test_body_forces_and_specific_weight_act_along_their_components():
    """A body force b and a specific weight γ (along −z): the support reactions balance
    (b − γ e_z) times the volume, to round-off."""
    d = cube(supports={"z0": {"u": [0.0, 0.0, 0.0]}}, body_forces={"block": [1.0e4, -2.0e4, 3.0e4]})
    d["scene"]["materials"]["steel"]["density_weight"] = 7.8e4
    ev, res = solve(d)
    m = ev.model
    c = res.state.coefficients
    K = m.K(m.stiffness_coefficients(c))
    reaction = (K @ res.state.u - m.mechanical_load(c, None)).reshape(-1, 3).sum(axis=0)
    assert reaction == pytest.approx(-np.array([1.0e4, -2.0e4, 3.0e4 - 7.8e4]), rel=1e-9)


def test_six_rigid_modes_span_the_kernel_and_a_free_block_is_refused():
    d = cube()
    study = load_study(d)
    model = Model(study.scene, build_mesh3d(study.scene))
    p = model.smesh.mesh.p
    R = rigid_modes(p, np.arange(p.shape[1]), p.shape[1])
    K = model.K(model.stiffness_coefficients(model.nominal))
    assert R.shape[1] == 6 and np.linalg.matrix_rank(R) == 6
    assert np.abs(K @ R).max() < 1e-9 * abs(K).max()
    with pytest.raises(StudyError, match="all six rigid motions"):
        model.solve(model.nominal)
    # rollers on x = 0 and z = 0 leave the translation along y free
    held = cube(supports={"x0": {"u": [0.0, None, None]}, "z0": {"u": [None, None, 0.0]}})
    study = load_study(held)
    model = Model(study.scene, build_mesh3d(study.scene))
    with pytest.raises(StudyError, match="one rigid motion"):
        model.solve(model.nominal)


def phi(x):
    return np.sin(np.pi * x[0]) * np.sin(np.pi * x[1]) * np.sin(np.pi * x[2])


def hessian(x):
    s, c = np.sin(np.pi * x), np.cos(np.pi * x)
    H = np.empty((3, 3) + x.shape[1:])
    for i in range(3):
        for j in range(3):
            if i == j:
                H[i, j] = -np.pi**2 * s[0] * s[1] * s[2]
            else:
                k = 3 - i - j
                H[i, j] = np.pi**2 * c[i] * c[j] * s[k]
    return H


def gradient(x):
    s, c = np.sin(np.pi * x), np.cos(np.pi * x)
    return np.pi * np.array([c[0] * s[1] * s[2], s[0] * c[1] * s[2], s[0] * s[1] * c[2]])


A = np.array([1.0, 0.5, -0.8])       # u = φ a with φ = sin πx sin πy sin πz (zero on the cube's faces)


def manufactured(size):
    """(h, L2 error, stress error, L2 error of T, H1 error of T) of the P1 solutions of
    −div τ(u) = f with u = φ a: τ = λ (∇φ·a) I + μ (a ⊗ ∇φ + ∇φ ⊗ a), so
    f = −(λ+μ) H(φ) a − μ Δφ a; and of −κ ΔT = 3π²κ φ with T = φ (both zero on the faces),
    through the model's stiffness, stress and conduction pieces."""
    study = load_study(cube(size, thermal={"reference": 293.0, "temperature": {"x0": 293.0}}))
    model = Model(study.scene, build_mesh3d(study.scene))
    mesh = model.smesh.mesh
    c = model.nominal
    K = model.K(model.stiffness_coefficients(c)).tocsr()
    basis = Basis(mesh, ElementVector(ElementTetP1()), intorder=4)

    @LinearForm
    def load(v, w):
        H = hessian(w.x)
        f = -(LAM + MU) * np.einsum("ij...,j->i...", H, A) + 3 * np.pi**2 * MU * phi(w.x) * A[:, None, None]
        return dot(f, v)

    f = asm(load, basis)
    boundary = np.unique(mesh.facets[:, mesh.boundary_facets()])
    fixed = (3 * boundary[:, None] + np.arange(3)).ravel()
    free = np.setdiff1d(np.arange(3 * mesh.p.shape[1]), fixed)
    u = np.zeros(3 * mesh.p.shape[1])
    u[free] = spla.spsolve(K[free][:, free].tocsc(), f[free])
    x, dx = np.asarray(basis.global_coordinates()), basis.dx           # (3, ncells, nqp), (ncells, nqp)
    l2 = np.sum(dx * ((np.asarray(basis.interpolate(u)) - phi(x) * A[:, None, None]) ** 2).sum(axis=0))
    g = gradient(x)
    div = np.einsum("i...,i->...", g, A)
    exact = [LAM * div + 2 * MU * A[0] * g[0], LAM * div + 2 * MU * A[1] * g[1],
             LAM * div + 2 * MU * A[2] * g[2], MU * (A[1] * g[2] + A[2] * g[1]),
             MU * (A[0] * g[2] + A[2] * g[0]), MU * (A[0] * g[1] + A[1] * g[0])]
    s = model.cell_stress(u, None, c)                                # (6, ncells), constant per cell
    energy = sum(np.sum(dx * (s[k][:, None] - exact[k]) ** 2) for k in range(6))

    kappa = c.kappa[0]
    scalar = basis.with_element(ElementTetP1())
    Kh = model.H(c.kappa).tocsr()                                   # on the heat nodes: T = P θ
    q = model.P.T @ asm(LinearForm(lambda v, w: 3 * np.pi**2 * kappa * phi(w.x) * v), scalar)
    hot = np.setdiff1d(np.arange(Kh.shape[0]), model.P[boundary].indices)
    theta = np.zeros(Kh.shape[0])
    theta[hot] = spla.spsolve(Kh[hot][:, hot].tocsc(), q[hot])
    Th = scalar.interpolate(model.P @ theta)
    l2_T = np.sum(dx * (np.asarray(Th) - phi(x)) ** 2)
    h1_T = np.sum(dx * ((np.asarray(Th.grad) - g) ** 2).sum(axis=0))
    return mesh.t.shape[1] ** (-1 / 3), np.sqrt(l2), np.sqrt(energy), np.sqrt(l2_T), np.sqrt(h1_T)


def test_manufactured_elasticity_and_heat_converge_at_the_p1_rates():
    runs = [manufactured(h) for h in (0.25, 0.125, 0.0625)]
    h, l2, energy, l2_T, h1_T = np.array(runs).T
    rate = lambda e: np.polyfit(np.log(h), np.log(e), 1)[0]
    assert rate(l2) == pytest.approx(2.0, abs=0.15), (h, l2)
    assert rate(energy) == pytest.approx(1.0, abs=0.15), (h, energy)
    assert rate(l2_T) == pytest.approx(2.0, abs=0.15), (h, l2_T)
    assert rate(h1_T) == pytest.approx(1.0, abs=0.15), (h, h1_T)


def test_wcs_solve_of_a_3d_study_writes_the_3d_layout(tmp_path):
    d = cube(0.25, supports=ROLLERS, loads={"z1": {"traction": [1.0e5, 0.0, -1.0e6]}},
             thermal={"reference": 293.0, "temperature": {"z1": 333.0, "z0": 293.0}})
    d["uncertain"] = {"loads.z1.traction.2": [-1.5e6, -0.5e6]}
    study = tmp_path / "cube.yaml"
    study.write_text(yaml.safe_dump(d, sort_keys=False))
    out = tmp_path / "cube.nc"
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-m", "wcs.cli", "solve", str(study), "-o", str(out)],
                         capture_output=True, text=True, cwd=tmp_path,
                         env={**os.environ, "PYTHONPATH": str(root)})
    assert run.returncode == 0, run.stderr
    ev, res = solve(d)                                        # the same solve in this process
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        n, nc = ev.smesh.mesh.p.shape[1], ev.smesh.mesh.t.shape[1]
        assert ds["coords"].shape == (n, 3) and ds["cells"].shape == (nc, 4)
        assert list(ds["component"].values) == ["xx", "yy", "zz", "yz", "xz", "xy"]
        assert ds["principal_stress"].shape == (nc, 3)
        assert ds.attrs["dimension"] == 3
        assert np.array_equal(ds["displacement"].values, res.state.u.reshape(-1, 3))
        assert np.array_equal(ds["stress"].values, res.state.stress.T)
        assert np.allclose(ds["principal_stress"].values, tet.principal(res.state.stress), rtol=1e-14)
        assert np.array_equal(ds["temperature"].values, res.state.T)
    vtu = meshio.read(out.with_suffix(".vtu"))
    assert vtu.cells[0].type == "tetra" and vtu.cells[0].data.shape == (nc, 4)
    assert np.array_equal(vtu.point_data["displacement [m]"], res.state.u.reshape(-1, 3))
    tensor = vtu.cell_data["stress [Pa]"][0].reshape(-1, 3, 3)
    assert np.array_equal(tensor[:, 1, 2], res.state.stress[3]) and np.array_equal(tensor[:, 2, 1], res.state.stress[3])
