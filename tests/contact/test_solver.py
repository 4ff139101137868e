"""Contact solver: condensed semismooth Newton against the cvxpy reference on small two-block problems.

Tolerances: the Newton solver satisfies its KKT system to round-off (~1e-14 relative);
Clarabel stops at a duality gap ~1e-10 of the objective, which moves u by ~1e-8 relative
on these meshes (condition numbers ~1e3). Agreement to 1e-6 therefore has two orders of
margin over the reference's own error while still catching any wrong active node.
"""
import numpy as np
import scipy.sparse as sp
import skfem
from skfem.models.elasticity import lame_parameters, linear_elasticity

from wcs.contact import solver as cs
from wcs.contact.qp import solve_contact_qp
from wcs.status import Status


def _block(x, y, E, nu):
    mesh = skfem.MeshTri.init_tensor(x, y)
    basis = skfem.Basis(mesh, skfem.ElementVectorH1(skfem.ElementTriP1()))
    return mesh, basis, skfem.asm(linear_elasticity(*lame_parameters(E, nu)), basis)


def two_blocks(N=10, *, floating=False, shear=0.004, press=0.01, load=(0.0, -0.01), E=(1.0, 1.0), nu=0.3):
    """A pad [0.5,1.5]x[0,0.5] (N x N/2 cells) on a base [0,2]x[-1,0] (2N x N cells), matching nodes.

    Base bottom fixed. Held pad: its top displaced by (shear, -press), eliminated into f.
    Floating pad: no Dirichlet, a uniform traction `load` on its top, R = its 3 rigid modes.
    Contact normal = the pad's outward normal (0,-1): Bn u = u_base_y - u_pad_y <= 0;
    tangent (1,0): Bt u = u_pad_x - u_base_x. Returns dict(K, f, Bn, Bt, d, w, R) on free DOFs.
    """
    h = 1.0 / N
    mb, bb, Kb = _block(np.linspace(0.0, 2.0, 2 * N + 1), np.linspace(-1.0, 0.0, N + 1), E[0], nu)
    xp = np.linspace(0.5, 1.5, N + 1)
    mp, bp, Kp = _block(xp, np.linspace(0.0, 0.5, N // 2 + 1), E[1], nu)
    nb = Kb.shape[0]
    K = sp.block_diag([Kb, Kp], format="csr")
    n = K.shape[0]
    top_b = np.flatnonzero(np.isclose(mb.p[1], 0.0) & (mb.p[0] > 0.5 - h / 4) & (mb.p[0] < 1.5 + h / 4))
    top_b = top_b[np.argsort(mb.p[0, top_b])]
    bot_p = np.flatnonzero(np.isclose(mp.p[1], 0.0))
    bot_p = bot_p[np.argsort(mp.p[0, bot_p])]
    m = len(bot_p)
    w = np.full(m, h)
    w[[0, -1]] = h / 2
    rows = np.r_[np.arange(m), np.arange(m)]
    pm = np.r_[np.ones(m), -np.ones(m)]
    Bn = sp.csr_matrix((pm, (rows, np.r_[bb.nodal_dofs[1, top_b], nb + bp.nodal_dofs[1, bot_p]])), shape=(m, n))
    Bt = sp.csr_matrix((pm, (rows, np.r_[nb + bp.nodal_dofs[0, bot_p], bb.nodal_dofs[0, top_b]])), shape=(m, n))
    fixed = list(bb.nodal_dofs[:, np.isclose(mb.p[1], -1.0)].ravel())
    top_p = np.flatnonzero(np.isclose(mp.p[1], 0.5))
    dx, dy = nb + bp.nodal_dofs[0, top_p], nb + bp.nodal_dofs[1, top_p]
    ud, f = np.zeros(n), np.zeros(n)
    R = None
    if floating:
        wt = np.where(np.isclose(mp.p[0, top_p], 0.5) | np.isclose(mp.p[0, top_p], 1.5), h / 2, h)
        f[dx], f[dy] = load[0] * wt, load[1] * wt
        x, y = mp.p
        R = np.zeros((n, 3))
        R[nb + bp.nodal_dofs[0], 0] = 1.0
        R[nb + bp.nodal_dofs[1], 1] = 1.0
        R[nb + bp.nodal_dofs[0], 2] = -(y - 0.25)
        R[nb + bp.nodal_dofs[1], 2] = x - 1.0
    else:
        ud[dx], ud[dy] = shear, -press
        fixed += list(dx) + list(dy)
    free = np.setdiff1d(np.arange(n), fixed)
    f = f - K @ ud
    return dict(K=K[free][:, free].tocsr(), f=f[free], Bn=Bn[:, free].tocsr(), Bt=Bt[:, free].tocsr(),
                d=np.zeros(m), w=w, R=None if R is None else R[free])


def args(P):
    return [P[k] for k in ("K", "f", "Bn", "Bt", "d", "w")]


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def assert_kkt(P, r, gw, tol=1e-10, bound_tol=0.0):
    """Equilibrium, non-penetration, λn ≥ 0, complementarity, |λt| ≤ gw, and the friction sign:
    λt = +gw sign(Bt u) where |Bt u| > 0 (λt is the subgradient of Σ gw|Bt u|), Bt u = 0 where |λt| < gw.
    Scales: forces by max|λn|, displacements by max|u|; 1e-10 is ~1e4 × round-off of the dense algebra.
    bound_tol: relative slack of the friction bound itself (Coulomb: the bound F·p lags one
    fixed-point iterate, whose relative pressure change is ≤ tol_fp)."""
    K, f, Bn, Bt, d, w = args(P)
    fs, us = np.abs(r.lam_n).max(), np.abs(r.u).max()
    assert np.abs(K @ r.u + Bn.T @ r.lam_n + Bt.T @ r.lam_t - f).max() <= tol * fs
    gap, slip = d - Bn @ r.u, Bt @ r.u
    assert gap.min() >= -tol * us and r.lam_n.min() >= -tol * fs
    assert np.abs(r.lam_n * gap).max() <= tol * fs * us
    assert np.all(np.abs(r.lam_t) <= gw + tol * fs + bound_tol * fs)
    slipping = np.abs(slip) > 1e-8 * us
    np.testing.assert_allclose(r.lam_t[slipping], (gw * np.sign(slip))[slipping], atol=tol * fs + bound_tol * fs)
    assert np.all(np.abs(slip[np.abs(r.lam_t) < gw - 1e-8 * fs]) <= tol * us)


def test_frictionless_matches_qp_and_complementarity():
    P = two_blocks(10)
    r, q = cs.solve_contact(*args(P)), solve_contact_qp(*args(P))
    assert r.status == Status.SOLVED and q.status == Status.SOLVED
    assert rel(r.u, q.u) < 1e-6
    assert_kkt(P, r, np.zeros(len(P["w"])))
    assert np.all(r.lam_t == 0)


def test_tresca_partial_slip():
    P = two_blocks(10)
    m = len(P["w"])
    g = np.full(m, 0.006)
    r, q = cs.solve_contact(*args(P), g=g), solve_contact_qp(*args(P), g=g)
    assert r.status == Status.SOLVED
    assert {cs.STICK, cs.SLIP} <= set(r.active)  # a genuine partial-slip case
    assert_kkt(P, r, g * P["w"])
    tau = r.lam_t / P["w"]
    assert np.all(np.abs(tau) <= g * (1 + 1e-12))
    np.testing.assert_allclose(np.abs(tau[r.active == cs.SLIP]), g[r.active == cs.SLIP], rtol=1e-12)
    # pad sheared to +x: it slips to +x over the base, Bt u > 0, and λt = +gw there
    assert np.all(P["Bt"] @ r.u >= -1e-12) and np.all(r.lam_t[r.active == cs.SLIP] > 0)
    assert rel(r.u, q.u) < 1e-6


def test_tresca_limits():
    P = two_blocks(10)
    m = len(P["w"])
    free = cs.solve_contact(*args(P))
    zero = cs.solve_contact(*args(P), g=np.zeros(m))
    assert rel(zero.u, free.u) < 1e-12  # the same linear algebra: round-off only
    huge = cs.solve_contact(*args(P), g=np.full(m, 1e6))
    assert np.all(huge.active == cs.STICK)
    K, f, Bn, Bt, d, _ = args(P)
    C = sp.vstack([Bn, Bt])
    tie = sp.bmat([[K, C.T], [C, None]], format="csc")
    glued = sp.linalg.spsolve(tie, np.r_[f, d, np.zeros(m)])[: K.shape[0]]
    assert rel(huge.u, glued) < 1e-8  # both exact linear solves of the same system (cond ~1e4)


def test_floating_body_matches_qp():
    P = two_blocks(10, floating=True, load=(0.002, -0.01))
    m = len(P["w"])
    g = np.full(m, 0.005)
    r = cs.solve_contact(*args(P), g=g, R=P["R"])
    q = solve_contact_qp(*args(P), g=g)
    assert r.status == Status.SOLVED
    assert_kkt(P, r, g * P["w"])
    # singular K: Clarabel's KKT error is amplified by the soft rigid modes (its gap residual
    # is ~1e-10 absolute at u ~ 1e-3), hence 1e-5 rather than 1e-6
    assert rel(r.u, q.u) < 1e-5


def test_generalized_inverse_is_exact():
    P = two_blocks(6, floating=True)
    K, R = P["K"], P["R"]
    Kp = np.linalg.inv(cs.regularize(K, cs.pinned_dofs(R)).toarray())
    Kd = K.toarray()
    assert np.abs(Kd @ Kp @ Kd - Kd).max() <= 1e-10 * np.abs(Kd).max()  # cond(K_reg) ~1e4 × eps


def test_unbalanced_floating_body():
    P = two_blocks(10, floating=True, load=(0.003, -0.01))
    r = cs.solve_contact(*args(P), R=P["R"])
    assert r.status == Status.UNSOLVABLE and r.u is None
    np.testing.assert_allclose(r.alpha, [1.0, 0.0, 0.0], atol=1e-9)  # slide along +x, the pull
    assert "unbalanced" in r.message
    # enough friction holds it
    ok = cs.solve_contact(*args(P), g=np.full(len(P["w"]), 0.01), R=P["R"])
    assert ok.status == Status.SOLVED


def test_coulomb_fixed_point():
    P = two_blocks(10)
    F = np.full(len(P["w"]), 0.5)
    r, q = cs.solve_contact(*args(P), F=F), solve_contact_qp(*args(P), F=F)
    assert r.status == Status.SOLVED and r.fixed_point_iterations > 1
    assert_kkt(P, r, F * r.lam_n, bound_tol=10 * 1e-8)     # 10 × the default tol_fp
    # fixed point stopped at ‖Δp‖ ≤ 1e-8‖p‖ in both; the remaining QP error is ~1e-8
    assert rel(r.u, q.u) < 1e-6
    stop = cs.solve_contact(*args(P), F=F, max_fp_iter=2)
    assert stop.status == Status.FIXED_POINT_NOT_CONVERGED and stop.fixed_point_iterations == 2


def test_iteration_limit_falls_back_then_ends_with_a_status():
    P = two_blocks(10)
    g = np.full(len(P["w"]), 0.006)
    full = cs.solve_contact(*args(P), g=g)
    # one Newton step, then the dual QP and a capped polish: still the right answer
    capped = cs.solve_contact(*args(P), g=g, max_iter=1)
    assert capped.status == Status.SOLVED and rel(capped.u, full.u) < 1e-8
    # an unreachable tolerance: the solve ends, with the status saying so
    r = cs.solve_contact(*args(P), g=g, tol=0.0, max_iter=3)
    assert r.status == Status.CONTACT_NOT_CONVERGED and r.iterations <= 2 * 3 + 1



def test_warm_resolve_new_stiffness():
    P0 = two_blocks(10)
    P1 = two_blocks(10, E=(1.3, 0.8), shear=0.005)
    m = len(P0["w"])
    g = np.full(m, 0.006)
    r0 = cs.solve_contact(*args(P0), g=g)
    cold = cs.solve_contact(*args(P1), g=g)
    warm = cs.solve_contact(*args(P1), g=g, warm=r0)
    assert warm.status == Status.SOLVED and warm.factor.factor is r0.factor.factor  # analysis reused
    assert rel(warm.u, cold.u) < 1e-10  # both converge to the exact KKT point: round-off only
    assert warm.iterations < cold.iterations


def test_reported_state_is_that_of_the_answer_when_the_start_already_solves_it():
    """Contact open everywhere: λ = 0 solves the problem at once; the reported state must say
    'open', not echo the all-closed starting set (the adjoint and the non-smoothness flag read it)."""
    P = two_blocks(6)
    K, f, Bn, Bt, d, w = args(P)
    r = cs.solve_contact(K, f, Bn, Bt, d + 1.0, w)          # a gap far larger than any displacement
    assert r.status == Status.SOLVED and np.all(r.lam_n == 0)
    assert not r.free[: len(w)].any() and np.all(r.active == cs.OPEN)
