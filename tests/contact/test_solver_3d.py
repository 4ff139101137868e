"""3D frictional contact: the semismooth Newton on discs |λt,i| ≤ gw_i against the cvxpy SOCP.

Systems: a pad [0.25,0.75]²×[0,0.25] on a base [0,1]²×[−0.5,0] (linear tetrahedra from
scikit-fem, matching nodes on z = 0), or the pad on a rigid base. Contact normal = the
pad's outward normal (0,0,−1): Bn u = u_base,z − u_pad,z ≤ 0; tangents e_x, e_y, stacked by
component (row j·m + i): Bt u = u_pad − u_base tangentially.

Tolerances. Newton satisfies its KKT system to ~1e-14 relative (checked to 1e-10 by
`assert_kkt`). The reference is Clarabel on the primal program at tolerance 1e-12: without
cones (frictionless) it agrees with Newton to ~1e-12; with the disc cones its own error
floors at 1e-8 – 7e-8 relative in u on these problems (measured: 6e-7, 5e-8, 1e-8 at
tolerances 1e-10, 1e-12, 1e-13 on the twisted Tresca pad, the objective of Newton's answer
below the reference's every time). Agreement is therefore asserted to 2e-7 with friction
(3× the reference's worst measured error; a node in a wrong state moves u by ~1e-3) and
1e-10 without, and Newton's objective must not exceed the reference's.
"""
import numpy as np
import scipy.sparse as sp
import skfem
from skfem.models.elasticity import lame_parameters, linear_elasticity

from wcs.contact import solver as cs
from wcs.contact.qp import solve_contact_qp
from wcs.status import Status


def _block(x, y, z, E, nu):
    mesh = skfem.MeshTet1.init_tensor(x, y, z)
    basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementTetP1()))
    return mesh, basis, skfem.asm(linear_elasticity(*lame_parameters(E, nu)), basis)


def _sorted_face(mesh, nodes):
    return nodes[np.lexsort((mesh.p[0, nodes], mesh.p[1, nodes]))]


def pad_on_base(N=4, *, rigid_base=False, floating=False, top=(0.004, 0.0, -0.01), twist=0.0, tilt=0.0,
                load=(0.0, 0.0, -0.01), nu=0.3):
    """Pad (N×N×N/2 cells) on a base (2N×2N×N cells, bottom fixed) or on a rigid base.

    Held pad: its top displaced by `top` plus a rotation `twist` about the pad's vertical
    axis (slip directions then vary over the face) and a tilt about the y axis (u_z += tilt·x:
    the x > 0.5 side lifts off where tilt·0.25 approaches the press), eliminated into f. Floating pad: a
    uniform traction `load` on its top, R = its 6 rigid modes. Returns dict(K, f, Bn, Bt, d,
    w, R) on the free DOFs."""
    h = 0.5 / N
    xp = np.linspace(0.25, 0.75, N + 1)
    mp, bp, Kp = _block(xp, xp, np.linspace(0.0, 0.25, N // 2 + 1), 1.0, nu)
    bot_p = _sorted_face(mp, np.flatnonzero(np.isclose(mp.p[2], 0.0)))
    if rigid_base:
        nb, K, fixed = 0, Kp, []
    else:
        xb = np.linspace(0.0, 1.0, 2 * N + 1)
        mb, bb, Kb = _block(xb, xb, np.linspace(-0.5, 0.0, N + 1), 1.0, nu)
        nb, K = Kb.shape[0], sp.block_diag([Kb, Kp], format="csr")
        top_b = np.flatnonzero(np.isclose(mb.p[2], 0.0) & (np.abs(mb.p[0] - 0.5) < 0.25 + h / 4)
                               & (np.abs(mb.p[1] - 0.5) < 0.25 + h / 4))
        top_b = _sorted_face(mb, top_b)
        fixed = list(bb.nodal_dofs[:, np.isclose(mb.p[2], -0.5)].ravel())
    n, m = K.shape[0], len(bot_p)
    edge = lambda x: np.where(np.isclose(x, 0.25) | np.isclose(x, 0.75), 0.5, 1.0)
    w = h * h * edge(mp.p[0, bot_p]) * edge(mp.p[1, bot_p])
    rows = np.arange(m)

    def relative(j, sign):    # sign·(u_pad − u_base) in direction j
        cols, vals = [nb + bp.nodal_dofs[j, bot_p]], [np.full(m, sign)]
        if not rigid_base:
            cols.append(bb.nodal_dofs[j, top_b])
            vals.append(np.full(m, -sign))
        return sp.csr_matrix((np.concatenate(vals), (np.tile(rows, len(cols)), np.concatenate(cols))), shape=(m, n))

    Bn, Bt = relative(2, -1.0), sp.vstack([relative(0, 1.0), relative(1, 1.0)])
    top_p = np.flatnonzero(np.isclose(mp.p[2], 0.25))
    ud, f = np.zeros(n), np.zeros(n)
    R = None
    x, y, z = mp.p[0] - 0.5, mp.p[1] - 0.5, mp.p[2] - 0.125
    if floating:
        wt = h * h * edge(mp.p[0, top_p]) * edge(mp.p[1, top_p])
        for j in range(3):
            f[nb + bp.nodal_dofs[j, top_p]] = load[j] * wt
        R = np.zeros((n, 6))
        ux, uy, uz = (nb + bp.nodal_dofs[j] for j in range(3))
        R[ux, 0] = R[uy, 1] = R[uz, 2] = 1.0
        R[uy, 3], R[uz, 3] = -z, y            # rotations about x, y, z
        R[ux, 4], R[uz, 4] = z, -x
        R[ux, 5], R[uy, 5] = -y, x
    else:
        d = [nb + bp.nodal_dofs[j, top_p] for j in range(3)]
        ud[d[0]] = top[0] - twist * y[top_p]
        ud[d[1]] = top[1] + twist * x[top_p]
        ud[d[2]] = top[2] + tilt * x[top_p]
        fixed += [i for dj in d for i in dj]
    free = np.setdiff1d(np.arange(n), fixed)
    f = f - K @ ud
    return dict(K=K[free][:, free].tocsr(), f=f[free], Bn=Bn[:, free].tocsr(), Bt=Bt[:, free].tocsr(),
                d=np.zeros(m), w=w, R=None if R is None else R[free])


REF = dict(tol=1e-12)
AGREE = 2e-7


def energy(P, u, gw):
    """½uᵀKu − fᵀu + Σ gw_i |(Bt u)_i|, the primal objective."""
    return 0.5 * u @ P["K"] @ u - P["f"] @ u + gw @ np.linalg.norm(discs(P["Bt"] @ u, len(P["w"])), axis=1)


def args(P):
    return [P[k] for k in ("K", "f", "Bn", "Bt", "d", "w")]


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def discs(v, m):
    """(m, 2): each node's two tangential components."""
    return v.reshape(2, m).T


def assert_kkt(P, r, gw, tol=1e-10, bound_tol=0.0):
    """Equilibrium, non-penetration, λn ≥ 0, complementarity, |λt,i| ≤ gw_i, and on a disc
    λt,i = gw_i s_i/|s_i| where the node slips (s = Bt u ≠ 0), s_i = 0 where |λt,i| < gw_i.
    Scales: forces by max λn, displacements by max|u|; Newton stops at a residual of `tol`
    in forces, which leaves u (and s) uncertain by ~tol·max|u|, so the direction of a slip
    s_i is known to ~tol·max|u|/|s_i| (a factor 10 of margin on that). bound_tol: relative
    slack of the bound (Coulomb: F·p lags one fixed-point iterate)."""
    K, f, Bn, Bt, d, w = args(P)
    m = len(w)
    fs, us = np.abs(r.lam_n).max(), np.abs(r.u).max()
    assert np.abs(K @ r.u + Bn.T @ r.lam_n + Bt.T @ r.lam_t - f).max() <= tol * fs
    gap = d - Bn @ r.u
    assert gap.min() >= -tol * us and r.lam_n.min() >= -tol * fs
    assert np.abs(r.lam_n * gap).max() <= tol * fs * us
    lt, s = discs(r.lam_t, m), discs(Bt @ r.u, m)
    assert np.all(np.linalg.norm(lt, axis=1) <= gw + (tol + bound_tol) * fs)
    ns = np.linalg.norm(s, axis=1)
    sl = ns > 1e-8 * us
    error = np.linalg.norm(lt[sl] - gw[sl, None] * s[sl] / ns[sl, None], axis=1)
    assert np.all(error <= (tol + bound_tol) * fs + 10 * gw[sl] * tol * us / ns[sl])
    assert np.all(ns[np.linalg.norm(lt, axis=1) < gw - 1e-8 * fs] <= tol * us)


def slip_angles(P, r):
    s = discs(P["Bt"] @ r.u, len(P["w"]))[r.active == cs.SLIP]
    return np.arctan2(s[:, 1], s[:, 0])


def test_frictionless_matches_socp():
    P = pad_on_base(top=(0.003, -0.002, -0.01))
    r, q = cs.solve_contact(*args(P)), solve_contact_qp(*args(P), **REF)
    assert r.status == Status.SOLVED and q.status == Status.SOLVED
    assert_kkt(P, r, np.zeros(len(P["w"])))
    assert np.all(r.lam_t == 0) and rel(r.u, q.u) < 1e-10


def test_tresca_partial_slip_in_varying_directions():
    """A shear with a twist: the slipping nodes slip in directions spread over more than 90°,
    each with λt on its disc's rim along its slip; Newton = the SOCP."""
    P = pad_on_base(top=(0.002, 0.001, -0.01), twist=0.03)
    m = len(P["w"])
    g = np.full(m, 0.01)
    r, q = cs.solve_contact(*args(P), g=g), solve_contact_qp(*args(P), g=g, **REF)
    assert r.status == Status.SOLVED and q.status == Status.SOLVED
    assert {cs.STICK, cs.SLIP} <= set(r.active)
    assert np.ptp(slip_angles(P, r)) > np.pi / 2
    assert_kkt(P, r, g * P["w"])
    np.testing.assert_allclose(np.linalg.norm(discs(r.lam_t, m), axis=1)[r.active == cs.SLIP] / P["w"][r.active == cs.SLIP],
                               0.01, rtol=1e-12)
    assert rel(r.u, q.u) < AGREE and energy(P, r.u, g * P["w"]) <= energy(P, q.u, g * P["w"])
    # the SOCP's λt from its cone duals (λt,i = −μ_i): its error is ~10× that of u (measured 5e-7)
    assert rel(r.lam_t, q.lam_t) < 10 * AGREE


def test_coulomb_matches_socp():
    P = pad_on_base(top=(0.003, 0.002, -0.01), twist=0.02)
    F = np.full(len(P["w"]), 0.3)
    r, q = cs.solve_contact(*args(P), F=F), solve_contact_qp(*args(P), F=F, **REF)
    assert r.status == Status.SOLVED and q.status == Status.SOLVED and r.fixed_point_iterations > 1
    assert cs.SLIP in set(r.active)
    assert_kkt(P, r, F * r.lam_n, bound_tol=10 * 1e-8)     # 10 × the default tol_fp
    assert rel(r.u, q.u) < AGREE


def test_random_problems_match_socp():
    """Random shears, twists, tilts (part of the face lifts off), friction and Poisson ratios,
    frictionless, Tresca and Coulomb: Newton and the SOCP agree (`AGREE`), Newton's answer
    satisfies the disc KKT conditions, and open, stuck and slipping nodes all occur."""
    rng = np.random.default_rng(7)
    states = set()
    for trial in range(3):
        sx, sy = rng.uniform(-0.004, 0.004, 2)
        press = rng.uniform(0.005, 0.015)
        P = pad_on_base(top=(sx, sy, -press), twist=rng.uniform(-0.03, 0.03), tilt=rng.uniform(3, 6) * press,
                        nu=rng.uniform(0.1, 0.4))
        m = len(P["w"])
        for law in ({}, {"g": rng.uniform(0.005, 0.02, m)}, {"F": np.full(m, rng.uniform(0.2, 0.6))}):
            r, q = cs.solve_contact(*args(P), **law), solve_contact_qp(*args(P), **law, **REF)
            assert r.status == Status.SOLVED and q.status == Status.SOLVED
            gw = law["g"] * P["w"] if "g" in law else (law["F"] * r.lam_n if "F" in law else np.zeros(m))
            assert_kkt(P, r, gw, bound_tol=10 * 1e-8 if "F" in law else 0.0)
            assert rel(r.u, q.u) < (AGREE if law else 1e-10), (trial, list(law))
            states |= set(r.active)
    assert states == {cs.OPEN, cs.STICK, cs.SLIP}


def test_floating_pad_matches_socp():
    P = pad_on_base(floating=True, load=(0.001, -0.0015, -0.01))
    m = len(P["w"])
    g = np.full(m, 0.005)
    r, q = cs.solve_contact(*args(P), g=g, R=P["R"]), solve_contact_qp(*args(P), g=g, **REF)
    assert r.status == Status.SOLVED
    assert_kkt(P, r, g * P["w"])
    # singular K: the soft rigid modes amplify Clarabel's KKT error (as in 2D)
    assert rel(r.u, q.u) < 1e-6


def test_block_on_rigid_base_slips_along_the_tangential_load():
    """A floating pad pressed on a rigid base by p with a tangential traction τ(cos θ, sin θ):
    the friction g per unit area holds it while τ < g (all the load carried, Σλt = τ·area: λt
    is the force the pad's load puts on the contact, −λt the friction on the pad);
    past g·area the load is unbalanced and the free rigid motion is the translation along the
    load's tangential direction (the solvability SOCP: no box-corner bias, no rotation)."""
    theta, p, g, area = 0.6, 0.01, 0.004, 0.25
    m = len(pad_on_base(rigid_base=True, floating=True)["w"])
    for tau in (0.003, 0.005):
        load = (tau * np.cos(theta), tau * np.sin(theta), -p)
        P = pad_on_base(rigid_base=True, floating=True, load=load)
        r = cs.solve_contact(*args(P), g=np.full(m, g), R=P["R"])
        if tau < g:
            assert r.status == Status.SOLVED
            np.testing.assert_allclose(discs(r.lam_t, m).sum(axis=0), np.array(load[:2]) * area, rtol=1e-10)
            np.testing.assert_allclose(r.lam_n.sum(), p * area, rtol=1e-10)
        else:
            assert r.status == Status.UNSOLVABLE and "unbalanced" in r.message
            a = r.alpha / np.linalg.norm(r.alpha[:2])
            np.testing.assert_allclose(a, [np.cos(theta), np.sin(theta), 0, 0, 0, 0], atol=1e-6)


def test_tangent_on_the_active_set_matches_finite_differences():
    """d(mean pressure)/d(load) from the linearized Newton system on the final active set
    (closed normals, stuck nodes, and the disc Jacobian D at slipping nodes) against central
    differences: the load scales the top displacement, an affine change of q."""
    g = 0.01

    def solve(s):
        P = pad_on_base(top=(0.002 * s, 0.001 * s, -0.01 * s), twist=0.03 * s)
        return P, cs.solve_contact(*args(P), g=np.full(len(P["w"]), g))

    P, r = solve(1.0)
    m, k = len(P["w"]), 2
    assert {cs.STICK, cs.SLIP} <= set(r.active)
    C = sp.vstack([P["Bn"], P["Bt"]]).tocsr()
    W = r.factor.W
    q = C @ r.factor.factor.solve(P["f"])
    dq = q                                  # q is linear in the load scale (d = 0)
    c = cs.scales(W, k)
    lam = np.r_[r.lam_n, r.lam_t]
    hi = np.r_[np.full(m, np.inf), np.tile(r.gw, k)]
    J, D = cs.disc_slips(lam + c * (q - W @ lam), hi, k)
    assert len(J) == np.sum(r.active == cs.SLIP)
    dlam, _ = cs._newton_point(W, dq, np.zeros((0, 3 * m)), np.zeros(0), r.free, np.zeros(3 * m),
                               cs.redundant_pairs(W, k), (J, D), c)
    mean_p = lambda res: res.lam_n.sum() / P["w"].sum()
    h = 1e-5
    fd = (mean_p(solve(1 + h)[1]) - mean_p(solve(1 - h)[1])) / (2 * h)
    assert abs(dlam[:m].sum() / P["w"].sum() - fd) <= 1e-6 * abs(fd)
    # the tangential part too: the slip direction's change enters through D
    lt = lambda res: res.lam_t
    fdt = (lt(solve(1 + h)[1]) - lt(solve(1 - h)[1])) / (2 * h)
    assert np.abs(dlam[m:] - fdt).max() <= 1e-6 * np.abs(fdt).max()


def test_non_unique_and_non_converging_status():
    """A frictionless floating pad on a rigid base: it may slide along x, y and turn about z
    freely (NOT_UNIQUE, β in that span). Newton capped at one iteration without the dual QP
    restart: CONTACT_NOT_CONVERGED, no silent answer."""
    P = pad_on_base(rigid_base=True, floating=True, load=(0.0, 0.0, -0.01))
    r = cs.solve_contact(*args(P), R=P["R"])
    assert r.status == Status.NOT_UNIQUE and r.u is None
    np.testing.assert_allclose(r.alpha[2:5], 0.0, atol=1e-10)          # no lift, no tilt
    m = len(P["w"])
    Q = pad_on_base(top=(0.002, 0.001, -0.01), twist=0.03)
    s = cs.solve_contact(*args(Q), g=np.full(m, 0.004), max_iter=1, qp=False)
    assert s.status == Status.CONTACT_NOT_CONVERGED and s.u is not None
    full = cs.solve_contact(*args(Q), g=np.full(m, 0.004), max_iter=1)   # the SOCP restart, then a polish
    ref = cs.solve_contact(*args(Q), g=np.full(m, 0.004))
    assert full.status == Status.SOLVED and rel(full.u, ref.u) < 1e-8


def test_coulomb_floating_pad_matches_socp_and_slides_along_the_load_past_F_p():
    """A floating pad under a tangential traction t_t and pressure p = 0.01: held by Coulomb
    friction while |t_t| < F p (Newton = the SOCP fixed point; the soft rigid modes as in the
    Tresca case), unbalanced past it, with the free motion along t_t."""
    P = pad_on_base(floating=True, load=(0.001, -0.0015, -0.01))
    m = len(P["w"])
    F = np.full(m, 0.3)
    r, q = cs.solve_contact(*args(P), F=F, R=P["R"]), solve_contact_qp(*args(P), F=F, **REF)
    assert r.status == Status.SOLVED and q.status == Status.SOLVED and {cs.STICK, cs.SLIP} <= set(r.active)
    assert_kkt(P, r, F * r.lam_n, bound_tol=10 * 1e-8)
    assert rel(r.u, q.u) < 1e-6
    P = pad_on_base(floating=True, load=(0.003, -0.0015, -0.01))         # |t_t| = 0.0034 > F p = 0.003
    r = cs.solve_contact(*args(P), F=np.full(m, 0.3), R=P["R"])
    assert r.status == Status.UNSOLVABLE and "Coulomb" in r.message
    # the last iterate's pressures are not uniform (the oblique load tilts them), so the free
    # motion may turn a little about z (measured 1e-6); lift and tilt stay 0
    np.testing.assert_allclose(r.alpha / np.linalg.norm(r.alpha), [2, -1, 0, 0, 0, 0] / np.sqrt(5), atol=1e-5)


def test_sliding_at_the_limit_is_free_only_along_the_slip():
    """τ = g exactly: every node slips along the load and the pad may slide along it
    (NOT_UNIQUE), but not across it: a motion across the slip would change the slip direction
    and the friction energy gw|s| with it. β is the translation along (cos θ, sin θ)."""
    theta, p, g = 0.6, 0.01, 0.004
    P = pad_on_base(rigid_base=True, floating=True, load=(g * np.cos(theta), g * np.sin(theta), -p))
    r = cs.solve_contact(*args(P), g=np.full(len(P["w"]), g), R=P["R"])
    assert r.status == Status.NOT_UNIQUE and "not unique" in r.message
    # the turn about z is round-off of the null space (1e-11 to 1.2e-10 measured, by the
    # thread count and the factorization that formed W)
    np.testing.assert_allclose(r.alpha / np.linalg.norm(r.alpha), [np.cos(theta), np.sin(theta), 0, 0, 0, 0],
                               atol=1e-9)
