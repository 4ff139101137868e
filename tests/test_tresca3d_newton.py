"""3D Tresca semismooth Newton on faults held by rollers, and its stopping scale.

The tunnel slice of tests/test_contact3d_robust.py with its fault turned 30° about the vertical
through the slice's centre (the oblique variant of studies/tunnel-fault-oblique-3d.yaml). Where
the fault meets the x-roller on the left side, both of its sides have u_x = 0: the fault's normal
row and its tangent along the dip act on one relative motion (a redundant pair), and the split
of their force between the two is free. Split at the minimum norm, the tangent carried
κλn/(1 + κ²) (0.12 λn on the oblique study at 8 m / 1 m), beyond the slip bound g w, so the
node was predicted to slip, then to stick again: Newton cycled between the two (99 iterations
with the dual-QP restart on this scene; on the oblique study at 8 m / 1 m, 400 iterations and
status 1). With the tied tangent at λt = 0 it converges in 7.
"""
import numpy as np
import scipy.sparse as sp

from wcs.contact.solver import OPEN, SLIP, solve_contact
from wcs.status import Status

from test_contact3d_robust import solve_and_compare, tunnel_fault_3d


def oblique(d: dict, strike_deg: float = 30.0) -> dict:
    """The fault plane of `tunnel_fault_3d` turned by `strike_deg` about the vertical through
    (0, length/2, 0): normal (−2 cos s, −2 sin s, 3)."""
    s = np.radians(strike_deg)
    normal = [float(-2 * np.cos(s)), float(-2 * np.sin(s)), 3.0]
    length = d["scene"]["boundaries"]["back"]["plane"]["point"][1]
    point = [0.0, length / 2, 0.0]
    for body, sign in (("hanging", -1.0), ("footwall", 1.0)):
        for r in d["scene"]["bodies"][body]["regions"]:
            r["shape"]["intersect"] = [{"halfspace": {"point": point, "normal": [sign * x for x in normal]}}]
    for b in ("fault_h", "fault_f"):
        d["scene"]["boundaries"][b]["plane"] = {"point": point, "normal": normal}
    return d


def test_an_oblique_fault_on_a_roller_converges_without_cycling():
    a = solve_and_compare(oblique(tunnel_fault_3d(size=20.0, fine=3.0)))
    assert (a.active == 1).any() and (a.active == 2).any()           # stick and slip on the fault
    assert a.iterations <= 12


def test_the_stopping_scale_leaves_out_frictionless_tangents():
    """Two contact nodes coupled along z (stiffness s [[2, −1], [−1, 2]]), pressed by P on node 0
    and pulled by X on node 1, free along x and y under a tangential load T ≫ P, frictionless.
    The glued first step gives λn = (P, −X); node 1 then opens: λn = (P − X/2, 0), u_z1 = −X/(2s).
    A frictionless tangent's c q = T is no force of the answer: counted in the stopping scale
    (tolerance × T = 10), Newton stopped before its first step, at λ = 0 (|Φ| = c q_n = 6.3),
    and the penetration u_z0 = 6.3e-9 passed the certificate (1e-6 of max|u| = T/s): a wrong
    answer reported as solved."""
    s, P, X, T = 1.0e9, 10.0, 1.0, 1.0e9
    K = sp.block_diag([s * np.eye(2), s * np.eye(2), s * np.array([[2.0, -1.0], [-1.0, 2.0]])], format="csr")
    f = np.r_[T, T, 0.0, 0.0, P, -X]
    Bn = sp.csr_matrix(np.eye(6)[4:])                       # u_z: closing the gap d = 0
    Bt = sp.csr_matrix(np.eye(6)[:4])                       # u_x of nodes 0, 1, then u_y
    res = solve_contact(K, f, Bn, Bt, np.zeros(2), np.ones(2), tol=1e-8)
    assert res.status == Status.SOLVED, res.message
    assert np.allclose(res.lam_n, [P - X / 2, 0.0], rtol=0, atol=1e-12 * P)
    assert np.all(res.lam_t == 0.0)
    assert np.allclose(res.u, [T / s, T / s, 0, 0, 0, -X / (2 * s)], rtol=1e-12, atol=1e-12 * X / s)
    assert list(res.active) == [SLIP, OPEN]                 # closed and slipping freely; open
