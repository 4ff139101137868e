"""3D Tresca semismooth Newton on faults held by rollers, its stopping scale, and its step length on discs.

The tunnel slice of tests/contact/test_solver_3d_inclined_fault.py with its fault turned 30° about the vertical
through the slice's centre (the oblique variant of studies/tunnel-fault-oblique-3d.yaml). Where
the fault meets the x-roller on the left side, both of its sides have u_x = 0: the fault's normal
row and its tangent along the dip act on one relative motion (a redundant pair), and the split
of their force between the two is free. Split at the minimum norm, the tangent carried
κλn/(1 + κ²) (0.12 λn on the oblique study at 8 m / 1 m), beyond the slip bound g w, so the
node was predicted to slip, then to stick again: Newton cycled between the two (99 iterations
with the dual-QP restart on this scene; on the oblique study at 8 m / 1 m, 400 iterations and
status 1). With the tied tangent at λt = 0 it converges in 7.
"""
import functools
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import yaml

import wcs.contact.solver as cs
from wcs.contact.qp import solve_contact_qp
from wcs.contact.solver import OPEN, SLIP, STICK, solve_contact
from wcs.model.evaluation import Evaluator
from wcs.status import Status
from wcs import load_study

from tests.contact.test_solver_3d_inclined_fault import solve_and_compare, tunnel_fault_3d


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


def test_a_period_three_disc_cycle_is_broken_by_the_step_length():
    """Three contact nodes pressed closed (normals uncoupled), each with a first tangent that acts
    on nothing (a zero row of Bt, as the tangents along the axis of the 3D tunnel's nodes on the
    rollers front and back) and second tangents coupled by the flexibility A (SPD, eigenvalues
    0.011 … 0.23). With the disc's c = 2/A_ii (one c per disc, the null row in its mean) the full
    Newton steps cycled with period 3 — node 0 slipping at λt = −g, then +g, then sticking at
    −1.02 g; node 2 between slip and stick at 4.3 g — and never a pattern without a node slipping
    on a disc, so no cycle was counted: 100 iterations, status 1. Armijo on ‖Φ‖² ends it in 4.
    Reference: the primal SOCP (Clarabel at 1e-12): u and λ to 1e-8 of their largest."""
    A = np.array([[0.147, 0.004, 0.097], [0.004, 0.024, -0.017], [0.097, -0.017, 0.112]])
    qt, g = np.array([0.81, 0.3, 1.8]), np.array([15.96, 14.83, 7.49])
    I3, Z3 = np.eye(3), np.zeros((3, 3))
    K = sp.csr_matrix(np.block([[I3, Z3], [Z3, np.linalg.inv(A)]]))   # W = C K⁻¹ Cᵀ = diag(I, 0, A)
    f = np.r_[np.ones(3), np.linalg.solve(A, qt)]                       # q = (1, 1, 1, 0, 0, 0, qt)
    Bn, Bt = sp.csr_matrix(np.c_[I3, Z3]), sp.csr_matrix(np.r_[np.zeros((3, 6)), np.c_[Z3, I3]])
    res = solve_contact(K, f, Bn, Bt, np.zeros(3), np.ones(3), g=g, qp=False, max_iter=100, tol=1e-12)
    assert res.status == Status.SOLVED, res.message
    assert res.iterations <= 8
    with warnings.catch_warnings():       # Clarabel at 1e-12 may end OPTIMAL_INACCURATE: checked below
        warnings.simplefilter("ignore")
        ref = solve_contact_qp(K, f, Bn, Bt, np.zeros(3), np.ones(3), g=g, tol=1e-12)
    assert ref.status == Status.SOLVED, ref.message
    assert np.abs(res.u - ref.u).max() <= 1e-8 * np.abs(ref.u).max()
    lam, lam_ref = np.r_[res.lam_n, res.lam_t], np.r_[ref.lam_n, ref.lam_t]
    assert np.abs(lam - lam_ref).max() <= 1e-8 * np.abs(lam_ref).max()
    assert list(res.active) == [STICK, SLIP, SLIP]


STUDIES = Path(__file__).resolve().parents[2] / "studies"

# A data set of the 3D tunnel's sample (E, ν, weight, two top pressures, the right side's push,
# then the slip limit's 8 × 2 grid values) on which Newton's full steps cycled to max_iter, and
# the polish after the dual-QP restart ended at |λt| − g w = 37.7: status 1.
CYCLED = [4.8866125148e+09, 1.6324667118e-01, 2.4261815764e+04, 4.7049122825e+06, 8.1818312073e+06,
          -2.2413222907e-02, 9.2024912088e+05, 1.3770214047e+06, 1.3128199841e+06, 8.0244010990e+05,
          5.2661826216e+05, 1.3563640672e+06, 7.9401282797e+05, 1.4116459132e+06, 9.1456919408e+05,
          6.5648508515e+05, 8.0617704726e+05, 8.8882147141e+05, 1.0599324630e+06, 8.6921673891e+05,
          1.4449984485e+06, 1.4549266063e+06]


def finer_tunnel(monkeypatch) -> dict:
    """studies/tunnel-fault-3d.yaml meshed at 0.55 m near the tunnel and 1.6 m along the fault
    (3.9e4 unknowns), run from the studies folder (its material library is named relative to it)."""
    doc = yaml.safe_load((STUDIES / "tunnel-fault-3d.yaml").read_text())
    refine = doc["scene"]["mesh"]["refine"]
    refine[0]["size"], refine[1]["size"] = 0.55, 1.6
    monkeypatch.chdir(STUDIES)
    return doc


@pytest.mark.slow
def test_the_finer_3d_tunnel_with_a_varying_slip_limit_converges_in_newton(monkeypatch):
    """studies/tunnel-fault-3d.yaml at 0.55 m near the tunnel and 1.6 m along the fault (3.9e4
    unknowns, 1060 fault nodes): from a fresh evaluator (the nominal solve first, then this data
    set warm from it) Newton converges with no dual-QP restart (`qp` off: a cycle or the budget
    would be status 1) in 10 iterations, against 200 and a refused answer before."""
    doc = finer_tunnel(monkeypatch)
    ev = Evaluator(load_study(doc))
    monkeypatch.setattr(cs, "_newton", functools.partial(cs._newton, fallback=False))
    res = ev.evaluate(np.array(CYCLED))
    assert res.status == Status.SOLVED, res.message
    assert res.iterations <= 20


def test_a_tangent_held_by_supports_is_left_out_of_its_discs_scale():
    """The iterative method's c on a disc is 1 / the mean W_ii estimate of the tangents that act: a
    tangent held by supports (a row of round-off, as on the rollers of the 3D tunnel's end planes)
    averaged in doubled c, and those nodes predicted their slip reversed, stuck, slipped again."""
    from wcs.contact.iterative import _scales
    K = sp.diags([2.0, 4.0, 5.0, 8.0, 10.0, 1.0])
    Bn = sp.csr_matrix(np.eye(6)[:2])                                   # normals of nodes 0, 1
    Bt = sp.csr_matrix(np.r_[[1e-17 * np.eye(6)[2]], np.eye(6)[3:6]])   # t1: node 0 held, node 1; t2: nodes 0, 1
    c = _scales(K, sp.vstack([Bn, Bt]).tocsr(), 2, 2)
    np.testing.assert_allclose(c, [2.0, 4.0, 10.0, 2.0 / (1 / 8 + 1 / 1), 10.0, 2.0 / (1 / 8 + 1 / 1)], rtol=1e-12)


def test_a_normal_held_by_supports_gets_c_one_as_the_monolithic_null_rows():
    """A row that does not act (node 0's normal and first tangent of round-off, a fault node held
    by supports on both sides) gets c = 1, as `solve_contact`'s exactly null rows, not
    1/w_i = 2e34: its gap's round-off times that c made ‖Φ‖ ~ 1e18 on the finer 3D tunnel."""
    from wcs.contact.iterative import _scales
    K = sp.diags([2.0, 4.0, 5.0, 8.0, 10.0, 1.0])
    Bn = sp.csr_matrix(np.r_[[1e-17 * np.eye(6)[0]], [np.eye(6)[1]]])  # normals: node 0 held, node 1
    Bt = sp.csr_matrix(np.r_[[1e-17 * np.eye(6)[2]], np.eye(6)[3:6]])   # t1: node 0 held, node 1; t2: nodes 0, 1
    c = _scales(K, sp.vstack([Bn, Bt]).tocsr(), 2, 2)
    np.testing.assert_allclose(c, [1.0, 4.0, 10.0, 2.0 / (1 / 8 + 1 / 1), 10.0, 2.0 / (1 / 8 + 1 / 1)], rtol=1e-12)


def test_the_monolithic_discs_scale_leaves_out_a_tangent_held_by_supports_too():
    """`solve_contact`'s c from the exact diag(W) by the same rule (`disc_scales`): node 0's first
    tangent a row of round-off (W_ii 1e-40 against 16), its c that of its second tangent alone,
    not 2 / (W_ii + 8) = 1/4."""
    W = np.diag([1.0, 2.0, 1e-40, 4.0, 8.0, 16.0])       # n0, n1, t1 (node 0 held), t1, t2, t2
    np.testing.assert_allclose(cs.scales(W, 2), [1.0, 0.5, 1 / 8, 2 / 20, 1 / 8, 2 / 20], rtol=1e-12)


# A data set of the 3D tunnel's box (a Latin hypercube point, slip limits between 0.53 and 1.48 MPa over the
# 8 x 2 grid): evaluated after `CYCLED`, the iterative method took 24 Newton steps, the nodes on the rollers front
# and back switching between a reversed slip and stick at 2-7 g w.
REVERSED = [4.7968475667e+09, 1.6049536304e-01, 2.3927920194e+04, 4.6837835176e+06, 8.4587790320e+06,
            -2.7372210748e-02, 5.2871623436e+05, 1.0984668106e+06, 1.4084010521e+06, 6.6207348113e+05,
            1.3744144819e+06, 5.7697611446e+05, 7.7837804725e+05, 8.6859521610e+05, 1.4494675285e+06,
            1.4244170184e+06, 1.4776597171e+06, 1.0994811689e+06, 1.1327574599e+06, 6.2294777659e+05,
            1.3749392212e+06, 1.4532652070e+06]


@pytest.mark.slow
def test_the_finer_3d_tunnel_on_rollers_converges_in_fewer_iterative_newton_steps(monkeypatch):
    """studies/tunnel-fault-3d.yaml at 0.55 m / 1.6 m (3.9e4 unknowns, 1052 fault nodes) by the
    iterative method, fresh evaluator, the nominal, `CYCLED` and `REVERSED` in turn: `REVERSED`
    in 14 Newton steps (24 with the held tangents in the discs' scale), its criteria those of
    the monolithic method."""
    doc = finer_tunnel(monkeypatch)
    ev = Evaluator(load_study({**doc, "solver": {"method": "iterative"}}))
    for x in (ev.study.nominal(), CYCLED):
        assert ev.evaluate(np.array(x), gradients=False).status == Status.SOLVED
    res = ev.evaluate(np.array(REVERSED), gradients=False)
    assert res.status == Status.SOLVED, res.message
    assert res.state.raw.iterations <= 16
    ref = Evaluator(load_study(doc)).evaluate(np.array(REVERSED), gradients=False)
    for name, value in ref.phi.items():
        assert res.phi[name] == pytest.approx(value, rel=1e-7)


@pytest.mark.slow
def test_a_normal_held_by_supports_leaves_the_merit_at_the_finer_tunnels_corner(monkeypatch):
    """studies/tunnel-fault-3d.yaml at 0.55 m / 1.6 m (3.9e4 unknowns) by the iterative method at a
    corner of its box (E, ν, the east pressure and the push high, the rest low, the slip limit
    0.5 MPa everywhere), warm from the nominal answer. A fault node held by supports on both sides
    has a normal row of round-off (not acting, λn = 0); with c = 1/w_i ~ 4e39 there its gap's
    round-off (1e-21) made ‖Φ‖ ~ 1e18, Armijo found no decrease and the full step reproduced
    itself: 200 Newton steps, status 1. With c = 1 on that row: 11 steps (measured,
    deterministic), the criteria those of the monolithic method."""
    doc = finer_tunnel(monkeypatch)
    study = load_study({**doc, "solver": {"method": "iterative"}})
    lo, hi = study.parameters.lower, study.parameters.upper
    corner = lo + np.r_[1, 1, 0, 0, 1, 1, np.zeros(len(lo) - 6)] * (hi - lo)
    ev = Evaluator(study)
    assert ev.evaluate(study.nominal(), gradients=False).status == Status.SOLVED
    res = ev.evaluate(corner, gradients=False)
    assert res.status == Status.SOLVED, res.message
    assert res.state.raw.iterations <= 12
    ref = Evaluator(load_study(doc)).evaluate(corner, gradients=False)
    for name, value in ref.phi.items():
        assert res.phi[name] == pytest.approx(value, rel=1e-7)
