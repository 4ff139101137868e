"""Absorbing boundaries of a dynamic study (study-format §8, issue 29): Lysmer–Kuhlemeyer dashpots
and the seed's damping layer [101, §2], as matrices; their physics checked by a plane P pulse in a
2D column integrated here with the trapezoidal rule (M ü + C u̇ + K u = 0, no contact)."""
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spl
import skfem
from pydantic import ValidationError
from skfem.helpers import dot
from skfem.models.elasticity import linear_elasticity

from wcs.dynamics.absorbing import (Absorbing, Layer, check_references, dashpot_matrix, dashpots, impedances,
                                    layer_cells, layer_damping, weighted_mass)
from wcs.errors import StudyError
from wcs.scene.meshdata import SceneMesh

LAM = MU = 0.4          # E = 1, ν = 0.25 (plane strain): c_p = √1.2
RHO = 1.0
CP = np.sqrt((LAM + 2 * MU) / RHO)


def _boundary(m, keep):
    bf = np.flatnonzero(m.f2t[1] == -1)
    return bf[np.all(keep(m.p[:, m.facets[:, bf]]), axis=0)]




def _pulse_energy_left(bottom: str, H: float, y0: float, h=0.1, W=0.2, sigma=0.4, layer=None):
    """E(T)/E(0) of a plane P pulse (u_y = g(y − y₀ + c_p t), g Gaussian of width σ) in the column
    [0, W] × [0, H] on lateral rollers, after it has met the bottom (a dashpot, or held) and come
    back up to y₀ − 2 (far from the free top); the trapezoidal rule conserves E without damping."""
    m = skfem.MeshTri.init_tensor(np.linspace(0, W, round(W / h) + 1), np.linspace(0, H, round(H / h) + 1))
    ib = skfem.Basis(m, skfem.ElementVector(skfem.ElementTriP1()))
    K = skfem.asm(linear_elasticity(LAM, MU), ib).tocsr()
    M = skfem.asm(skfem.BilinearForm(lambda u, v, w: RHO * dot(u, v)), ib).tocsr()
    bottom_facets = _boundary(m, lambda x: x[1] < 1e-9)
    C = sp.csr_matrix(K.shape)
    held = [2 * np.flatnonzero((m.p[0] < 1e-9) | (m.p[0] > W - 1e-9))]               # rollers: u_x = 0
    if bottom == "dashpot":
        C = C + dashpot_matrix(m, bottom_facets, *impedances(RHO, LAM, MU))
    else:
        held.append(2 * np.flatnonzero(m.p[1] < 1e-9) + 1)
    if layer is not None:
        D, alpha = layer
        C = C + weighted_mass(m.p, m.t, layer_cells(m, bottom_facets, D), alpha * RHO)
    free = np.setdiff1d(np.arange(K.shape[0]), np.concatenate(held))
    K, M, C = (A[free][:, free] for A in (K, M, C))
    s = m.p[1] - y0
    g = np.exp(-s ** 2 / (2 * sigma ** 2))
    u, v = np.zeros(K.shape[0] + sum(map(len, held))), None
    u[1::2], v = g, np.zeros_like(u)
    v[1::2] = -CP * s / sigma ** 2 * g
    u, v = u[free], v[free]
    energy = lambda u, v: 0.5 * v @ (M @ v) + 0.5 * u @ (K @ u)                  # noqa: E731
    E0 = energy(u, v)
    dt = 0.5 * h / CP
    a = spl.spsolve(M.tocsc(), -C @ v - K @ u)
    lu = spl.splu((M + dt / 2 * C + dt ** 2 / 4 * K).tocsc())
    for _ in range(int(np.ceil((2 * y0 - 2) / CP / dt))):
        a1 = lu.solve(-C @ (v + dt / 2 * a) - K @ (u + dt * v + dt ** 2 / 4 * a))
        u, v, a = u + dt * v + dt ** 2 / 4 * (a + a1), v + dt / 2 * (a + a1), a1
    return energy(u, v) / E0


def test_dashpot_absorbs_a_p_pulse_at_normal_incidence():
    """Lysmer–Kuhlemeyer at normal incidence matches the impedance ρc_p: no reflection in 1D; the
    mesh (h = σ/4, two cells wide) reflects 0.02 % of the energy (0.002 % at h/2; 0.4 % five cells
    wide). A held bottom reflects it all (the trapezoidal rule keeps the energy to round-off)."""
    assert _pulse_energy_left("held", H=12.0, y0=6.0) == pytest.approx(1.0, abs=1e-9)
    assert _pulse_energy_left("dashpot", H=12.0, y0=6.0) < 0.05


def test_damping_layer_absorbs_a_p_pulse():
    """The seed's layer (D = 3, α = 1/s over a held bottom): the pulse (dominant ω ≈ c_p/σ ≈ 2.7/s)
    loses exp(−2αD/c_p) = 0.4 % of its energy crossing the layer twice, and the layer's edge reflects
    |(1 − √(1 + iα/ω))/(1 + √(1 + iα/ω))|² ≈ 0.8 %: 1.2 % expected, 1.7 % measured."""
    assert _pulse_energy_left("held", H=16.0, y0=9.0, layer=(3.0, 1.0)) < 0.05


@pytest.mark.parametrize("dim", [2, 3])
def test_dashpot_traction_of_a_uniform_velocity(dim):
    """C v summed over the nodes, for a uniform velocity v, is |Γ| (ρc_p n⊗n + ρc_s (I − n⊗n)) v on a
    flat boundary Γ with outward normal n (here a face of a rotated box); C is symmetric, C ⪰ 0."""
    x = np.linspace(0.0, 1.0, 4)
    m = skfem.MeshTri.init_tensor(x, 2 * x) if dim == 2 else skfem.MeshTet.init_tensor(x, x, 2 * x)
    angle = 0.5
    R = np.eye(dim)
    R[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
    m = type(m)(R @ m.p, m.t)
    n = -R[:, dim - 1]                                         # the face first at x_d = 0, outward
    face = _boundary(m, lambda p: np.abs(np.einsum("i,ij...->j...", n, p)) < 1e-9)
    zp, zs = 3.0, 1.2
    C = dashpot_matrix(m, face, zp, zs)
    v = np.array([0.3, -1.1, 0.7])[:dim]
    area = 1.0
    expected = area * (zp * np.outer(n, n) + zs * (np.eye(dim) - np.outer(n, n))) @ v
    assert np.allclose((C @ np.tile(v, m.p.shape[1])).reshape(-1, dim).sum(axis=0), expected, rtol=1e-13, atol=0)
    assert abs(C - C.T).max() == 0.0
    assert np.linalg.eigvalsh(C.toarray()).min() > -1e-14


def test_weighted_mass_is_the_consistent_mass():
    for m in (skfem.MeshTri.init_tensor(*[np.linspace(0, 1, 4)] * 2), skfem.MeshTet.init_tensor(*[np.linspace(0, 1, 3)] * 3)):
        e = skfem.ElementVector(skfem.ElementTriP1() if m.dim() == 2 else skfem.ElementTetP1())
        ref = skfem.asm(skfem.BilinearForm(lambda u, v, w: 2.5 * dot(u, v)), skfem.Basis(m, e))
        assert abs(weighted_mass(m.p, m.t, np.arange(m.t.shape[1]), 2.5) - ref).max() < 1e-15


@pytest.mark.parametrize("dim", [2, 3])
def test_layer_cells_are_those_within_the_thickness(dim):
    """Within D of the whole boundary of the unit square / cube: min(x, 1 − x, ...) <= D at the centroid."""
    x = np.linspace(0.0, 1.0, 9 if dim == 2 else 6)
    m = skfem.MeshTri.init_tensor(x, x) if dim == 2 else skfem.MeshTet.init_tensor(x, x, x)
    centroid = m.p[:, m.t].mean(axis=1)
    depth = np.minimum(centroid, 1 - centroid).min(axis=0)
    for D in (0.1, 0.23, 0.31):
        assert np.array_equal(layer_cells(m, _boundary(m, lambda p: np.ones(p.shape[1:], bool)), D),
                              np.flatnonzero(depth <= D))



@pytest.mark.parametrize("dim", [2, 3])
def test_layer_cells_are_those_of_every_facet_that_near(dim):
    """On a distorted mesh and two sides, the k-d tree's pruning keeps exactly the cells whose
    centroid is within D of some facet (checked against every facet)."""
    from wcs.dynamics.absorbing import _distance_to_simplex
    x = np.linspace(0.0, 1.0, 7 if dim == 2 else 5)
    m = skfem.MeshTri.init_tensor(x, x) if dim == 2 else skfem.MeshTet.init_tensor(x, x, x)
    p = m.p.copy()
    inner = np.all((p > 1e-9) & (p < 1 - 1e-9), axis=0)
    p[:, inner] += 0.04 * np.sin(9.0 * p[:, inner])
    m = type(m)(p, m.t)
    sides = _boundary(m, lambda q: (q[0] < 1e-9) | (q[1] > 1 - 1e-9))
    corners = m.p[:, m.facets[:, sides]].transpose(2, 1, 0)
    centroid = m.p[:, m.t].mean(axis=1).T
    nearest = np.array([_distance_to_simplex(np.repeat(c[None], len(sides), axis=0), corners).min() for c in centroid])
    for D in (0.05, 0.13, 0.27):
        assert np.array_equal(layer_cells(m, sides, D), np.flatnonzero(nearest <= D))


def test_layer_cell_near_a_long_facet_whose_midpoint_is_far():
    """A centroid (0.95, 0.2) is 0.200 from the long facet [0, 1] × {0} (midpoint 0.49 away) and
    0.206 from the short one [1, 1.05] × {0} (midpoint 0.21 away): within D = 0.203 by the long one."""
    p = np.array([[0.0, 1.0, 0.5, 1.05, 1.02, 0.9, 1.0, 0.95], [0.0, 0.0, -0.5, 0.0, -0.3, 0.1, 0.1, 0.4]])
    m = skfem.MeshTri(p, np.array([[0, 1, 2], [1, 3, 4], [5, 6, 7]]).T)
    bottom = _boundary(m, lambda q: np.abs(q[1]) < 1e-12)
    assert layer_cells(m, bottom, 0.203).tolist() == [0, 1, 2] and layer_cells(m, bottom, 0.199).tolist() == [0, 1]

def _scene():
    m = skfem.MeshTri.init_tensor(np.linspace(0, 1, 5), np.linspace(0, 1, 5))
    nc = m.t.shape[1]
    return SceneMesh(m, ["rock"], [("rock", "rock")], np.zeros(nc, int), np.zeros(nc, int),
                     {"bottom": _boundary(m, lambda p: p[1] < 1e-9), "left": _boundary(m, lambda p: p[0] < 1e-9)})


def test_scene_absorbing_reads_its_boundaries_by_name():
    sm = _scene()
    absorbing = Absorbing.model_validate({"layer": {"boundaries": ["bottom"], "thickness": 0.3, "damping": 50},
                                          "dashpots": ["bottom", "left"]})
    C = dashpots(sm, absorbing.dashpots, 2.0, LAM, MU, "scene.absorbing.dashpots")
    zp, zs = impedances(2.0, LAM, MU)
    assert np.allclose((C @ np.tile([0.0, 1.0], 25)).reshape(-1, 2).sum(axis=0), [-0.0, zp + zs], rtol=1e-13)
    L = layer_damping(sm, absorbing.layer, 2.0, "scene.absorbing.layer")
    assert np.tile([1.0, 0.0], 25) @ L @ np.tile([1.0, 0.0], 25) == pytest.approx(50 * 2.0 * 0.25, rel=1e-13)  # α ρ |layer|


def test_unknown_absorbing_boundary_names_its_key():
    sm = _scene()
    absorbing = Absorbing.model_validate({"layer": {"boundaries": ["bottom", "right"], "thickness": 0.3, "damping": 5},
                                          "dashpots": ["left", "botom"]})
    for call, key in ((lambda: check_references(absorbing, sm.boundaries, "scene.absorbing"), "scene.absorbing.dashpots.1"),
                      (lambda: dashpots(sm, absorbing.dashpots, 1, 1, 1, "scene.absorbing.dashpots"),
                       "scene.absorbing.dashpots.1"),
                      (lambda: layer_damping(sm, absorbing.layer, 1, "scene.absorbing.layer"),
                       "scene.absorbing.layer.boundaries.1")):
        with pytest.raises(StudyError) as err:
            call()
        assert err.value.path == key and "unknown boundary" in str(err.value) and "bottom, left" in str(err.value)


@pytest.mark.parametrize("data, loc, words", [
    ({}, (), "give a `layer`, `dashpots` or both"),
    ({"dashpots": ["left", "left"]}, (), "dashpots names boundary 'left' twice"),
    ({"layer": {"boundaries": ["left"], "thickness": 0.0, "damping": 1.0}}, ("layer", "thickness"), "greater than or equal"),
    ({"layer": {"boundaries": ["left"], "thickness": 1.0, "damping": -1.0}}, ("layer", "damping"), "greater than 0"),
    ({"layer": {"boundaries": [], "thickness": 1.0, "damping": 1.0}}, ("layer", "boundaries"), "at least 1"),
])
def test_bad_absorbing_block_names_its_key(data, loc, words):
    with pytest.raises(ValidationError) as err:
        Absorbing.model_validate(data)
    first = err.value.errors()[0]
    assert first["loc"] == loc and words in first["msg"]


def test_tunnel_scene_boundaries_take_dashpots_and_a_layer():
    """studies/tunnel-fault.yaml's cut sides (`left`, `right`, `bottom`, 120 m each, both bodies):
    a uniform vertical velocity meets 120 m (2ρc_s + ρc_p) of dashpots (shear on the sides, normal
    on the bottom); the 10 m layer's cells make the U-shaped band of 120² − 100 · 110 = 3400 m² (to
    the mesh: the cells whose centroid is within 10 m, 3 m cells; 3412 m² measured)."""
    from wcs.materials import lame
    from wcs.scene.mesher import build_mesh
    from wcs.study import load_study
    study = load_study(Path(__file__).resolve().parent.parent / "studies" / "tunnel-fault.yaml")
    sm = build_mesh(study.scene)
    lam, mu = lame(study.scene.materials["rock"].model_dump(by_alias=True, exclude_none=True))
    rho, sides = 2500.0, ["left", "right", "bottom"]
    absorbing = Absorbing.model_validate({"layer": {"boundaries": sides, "thickness": 10.0, "damping": 50.0},
                                          "dashpots": sides})
    check_references(absorbing, study.scene.boundaries, "scene.absorbing")
    zp, zs = impedances(rho, lam, mu)
    uy = np.tile([0.0, 1.0], sm.mesh.p.shape[1])
    force = (dashpots(sm, sides, rho, lam, mu, "scene.absorbing.dashpots") @ uy).reshape(-1, 2).sum(axis=0)
    assert force == pytest.approx([0.0, 120.0 * (2 * zs + zp)], rel=1e-12, abs=1e-6 * zp)
    band = uy @ layer_damping(sm, absorbing.layer, rho, "scene.absorbing.layer") @ uy / (50.0 * rho)
    assert band == pytest.approx(3400.0, rel=0.05)
