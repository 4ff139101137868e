r"""Adjoint gradients of the criteria with respect to the data.

On a fixed active set the discrete problem is linear in the data, so each
criterion needs one adjoint solve with the factorization of the forward solve.

Forward (reduced unknowns w, full u = T w + U0 c_U; heat unknowns θ = T_h w_T + U0_h c_T):

    heat:     T_hᵀ [K_h(κ) θ − q(W)] = 0
    elastic:  Tᵀ [K(λ, μ) u − f(c, Pθ)] + Cᵀ λ = 0,       C = [B_n; B_t] (reduced)
    contact:  per component, an equality C_i u = d_i (closed normal / stuck tangent)
              or a fixed multiplier λ_t,i − s_i F_i λ_n,i = s_i g_i w_i (slip; λ_n,i = 0 open).

In 3D a node has two tangent rows and a slipping node's λ_t = gw ν, ν = s/|s| (the projection
onto the disc |λ_t| ≤ gw, gw = g w + F λ_n). Its linearization, from the projection's Jacobian
D = gw/|z| (I − ννᵀ), is two rows in the frame (ν, ν⊥) of the slip: νᵀ δλ_t = δgw, a fixed
multiplier as in 2D, and |s| ν⊥ᵀ δλ_t = gw ν⊥ᵀ δs, which divided by gw is the equality row of
ν⊥ᵀ C with the compliance |s|/gw on its own multiplier. The adjoint below works in that frame
(the rows of C turned by Q, W by Q W Qᵀ; Q = I for the stuck and open nodes and in 2D).

With K⁺ the generalized inverse the contact solver factored and R the rigid modes of
floating bodies, u = K⁺(f − Cᵀλ) + Rα and the multipliers solve a small system
N [λ; α] = [d_A − C_A K⁺ f; h; Rᵀ f] (equalities A, fixed rows B, equilibrium of the
rigid modes). For Φ with partials φ_w = ∂Φ/∂w, φ_λ = ∂Φ/∂λ:

    Nᵀ μ = [φ_λ − C K⁺ φ_w; Rᵀ φ_w],      z = K⁺(φ_w − C_Aᵀ μ_A) + R μ_R,

and dΦ = z · δf_eff + μ_A · δd_A + μ_B · (δh − δN y) + explicit partials, where
δf_eff = Tᵀ(δf − δK u − K U0 δc_U) is the change of the effective load. Without
contact z = K⁻¹ φ_w. The heat step adds one more adjoint solve with the load
∂Φ/∂θ + Pᵀ Σ_j β_j B_jᵀ (T z). All of it yields ∂Φ/∂c for the flat coefficient
vector c (moduli per region, loads, support values, temperatures, slip limits per
contact node, …); the chain rule to the parameters x uses the exact ∂c/∂x of the
parameter map (`wcs.model.coefficients.ParameterMap.jacobian`).

Every factorization is the solution's own (`Solution.factor`, `heat_factor`,
`contact_factor`): the adjoint of a solution is the same whatever was solved after it. A
method with its own adjoint (`adjoint(model, state)`: the iterative one's `IterativeAdjoint`,
the same system by CG on the final active set, no W) gives (z, μ, σ) in its place.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .coefficients import flatten
from ..contact.slipframe import _slip_frame
from ..contact.solver import redundant_pairs
from .criteria import KINDS, REL_TOL, Partials, node_norm


def criterion_partials(criterion, model, state) -> tuple[Partials, bool]:
    """Partials of Φ = max_r Φ_r at the maximising region; flags a near-tie between regions
    and a kink of Φ_r itself (the kind says)."""
    values = criterion.region_values(model, state)
    r = int(np.argmax(values))
    others = np.delete(values, r)
    tie = others.size > 0 and np.max(others) >= values[r] - REL_TOL * max(abs(values[r]), 1e-300)
    P, kink = KINDS[criterion.kind].partials(criterion, model, state, r)
    return P, bool(tie or kink)


class ContactAdjoint:
    """The adjoint system of a contact solution on its final active set, built and factored once
    for all criteria: N of the module docstring in the slip frame (`_slip_frame`), its LU (or,
    where N is singular because constraints are redundant, least squares), and the solution's
    own factor K⁺. `solve` gives (z, μ, σ) for one criterion's partials, μ in the slip frame;
    None when N is singular and the system inconsistent."""

    def __init__(self, model, state):
        res = state.raw
        self.cf, m = state.contact_factor(model), res.lam_n.size
        C = model.contact_rows
        n = C.shape[0]
        k = n // m - 1
        Q, self.sigma, compliance, free = _slip_frame(model, state, m, k)
        W = self.cf.W
        if Q is not None:
            C, W = (Q @ C).tocsr(), np.asarray(Q @ self.cf.W @ Q.T)
        R = model.R_r
        r = 0 if R is None else R.shape[1]
        N = np.zeros((n + r, n + r))
        CR = C @ R if r else np.zeros((n, 0))
        A = np.flatnonzero(free)
        B = np.flatnonzero(~free)
        N[np.ix_(A, np.arange(n))] = -W[A]
        N[A, A] -= compliance[A]
        if r:
            N[np.ix_(A, n + np.arange(r))] = CR[A]
            N[n:, :n] = CR.T
        N[B, B] = 1.0
        tang = B[B >= m]
        node = (tang - m) % m
        N[tang, node] = -self.sigma[tang - m] * np.asarray(state.coefficients.coulomb, float)[node]
        # a closed and stuck node whose rows are parallel (rollers on both sides): its tangential
        # equation is κ times its normal one, so its adjoint multiplier is set to 0 and the row
        # dropped (exact; in floating point the full system is cond ~1e17, and an LU solve puts an
        # arbitrary ~1e20 along the redundant combination, whose cancellation ruins the gradient)
        # A closed or stuck row that vanishes (a node held by supports on both sides: W's row is 0)
        # cannot move the solution either: its adjoint multiplier is 0 and the row dropped too
        held = np.diag(W) <= 1e-14 * max(np.diag(W).max(initial=0.0), 1e-300)
        parallel = redundant_pairs(W, k) & np.tile(free[:m], k) & free[m:] & (compliance[m:] == 0)
        drop = np.r_[np.flatnonzero(held & free & (compliance == 0)), m + np.flatnonzero(parallel)]
        self.keep = np.setdiff1d(np.arange(N.shape[0]), drop)
        self.system = _FixedRowsSystem(N, self.keep, np.isin(self.keep, B))
        self.C, self.Q, self.R, self.A, self.m, self.n, self.size = C, Q, R, A, m, n, N.shape[0]

    def solve(self, phi_w: np.ndarray, phi_lam_n: np.ndarray | None, phi_lam_t: np.ndarray | None = None):
        m, n, C, R = self.m, self.n, self.C, self.R
        Kp_phi = self.cf.factor.solve(phi_w)
        g_lam = -(C @ Kp_phi)
        if phi_lam_n is not None:
            g_lam[:m] += phi_lam_n
        if phi_lam_t is not None:        # in the adjoint's frame (Q: the slip frame of disc nodes)
            t = np.r_[np.zeros(m), phi_lam_t]
            g_lam += t if self.Q is None else self.Q @ t
        g = np.r_[g_lam, R.T @ phi_w] if R is not None else g_lam
        mu = np.zeros(self.size)
        mu_keep = self.system.solve(g[self.keep])
        if mu_keep is None:
            return None
        mu[self.keep] = mu_keep
        z = self.cf.factor.solve(phi_w - C[self.A].T @ mu[self.A])
        if R is not None:
            z = z + R @ mu[n:]
        return z, mu, self.sigma


class _FixedRowsSystem:
    """Solves Mᵀ μ = g for M = N[keep, keep] by eliminating the fixed rows first: a fixed row of
    N (an open normal, a slipping tangent: λ_B = h_B) is the identity row plus, with Coulomb
    friction, the coupling −σF to its node's normal, so M_PP (P: the fixed rows) is sparse and
    only the Schur complement S = M_QQ − M_QP M_PP⁻¹ M_PQ on the other rows Q (closed normals,
    stuck tangents, slip-frame rows, rigid modes) needs a dense LU:

        Sᵀ μ_Q = g_Q − (M_PP⁻¹ M_PQ)ᵀ g_P,     M_PPᵀ μ_P = g_P − M_QPᵀ μ_Q.

    Without Coulomb friction M_PQ = 0 and S = M_QQ. On the 3D tunnel at 1.1e5 unknowns the LU of
    the full M took about 1 s an evaluation; a third of its rows are fixed."""

    def __init__(self, N: np.ndarray, keep: np.ndarray, fixed: np.ndarray):
        P, Q = keep[fixed], keep[~fixed]
        self.Mqp = N[np.ix_(Q, P)]
        Mpq = sp.csr_matrix(N[np.ix_(P, Q)])
        self.lu_pp = spla.splu(sp.csc_matrix(N[np.ix_(P, P)])) if P.size else None
        S = N[np.ix_(Q, Q)]
        self.X = None
        if Mpq.nnz:
            self.X = self.lu_pp.solve(Mpq.toarray())            # M_PP⁻¹ M_PQ
            S = S - self.Mqp @ self.X
        self.schur = _ConsistentSystem(S.T)
        self.fixed, self.size = fixed, keep.size

    def solve(self, g: np.ndarray) -> np.ndarray | None:
        gq, gp = g[~self.fixed], g[self.fixed]
        mu_q = self.schur.solve(gq if self.X is None else gq - self.X.T @ gp)
        if mu_q is None:
            return None
        mu = np.empty(self.size)
        mu[~self.fixed] = mu_q
        if self.lu_pp is not None:
            mu[self.fixed] = self.lu_pp.solve(gp - self.Mqp.T @ mu_q, trans="T")
        return mu


class _ConsistentSystem:
    """A⁻¹ b for many b from one LU of A, or — when A is singular because constraints are
    redundant (a contact node held by supports on both sides, normal and tangential rows made
    parallel by rollers) — the least-squares solution where the system is consistent there:
    the multipliers are then not unique but the displacements, and so the criteria's
    gradients, are."""

    def __init__(self, A: np.ndarray):
        self.A = A
        self.lu = None
        if A.size:
            lu, piv, info = sla.lapack.dgetrf(A)
            if info == 0 and np.all(np.isfinite(lu)):
                self.lu = (lu, piv)

    def solve(self, b: np.ndarray) -> np.ndarray | None:
        A = self.A
        if not A.size:
            return np.zeros(0)
        if self.lu is not None:
            x, info = sla.lapack.dgetrs(*self.lu, b)
            if info == 0 and np.all(np.isfinite(x)):
                return x
        x = np.linalg.lstsq(A, b, rcond=None)[0]
        scale = max(np.abs(b).max(initial=0.0), 1e-300)
        # redundant rows make A ill-conditioned (seen: cond 1e16, residual 1e-7 of |b|): round-off, not an
        # inconsistency, which would leave a residual of the order of |b|
        return x if np.abs(A @ x - b).max() <= 1e-6 * scale else None


def contact_nonsmooth(model, state) -> bool:
    """An active-set change within reach: weakly active normals or tangents at the switch
    (3D: |λ_t| at the disc's radius gw on a stuck node, |s| ≈ 0 on a slipping one)."""
    res, c = state.raw, state.contact
    m = res.lam_n.size
    if m == 0:
        return False
    k = c.slip.size // m
    fs = max(np.abs(res.lam_n).max(), 1e-300)
    us = max(np.abs(c.gap).max(), np.abs(c.slip).max(), np.abs(state.u).max(), 1e-300)
    closed, stick = res.free[:m], res.free[m:2 * m]
    weak_closed = closed & (res.lam_n <= REL_TOL * fs)
    weak_open = ~closed & (np.abs(c.gap) <= REL_TOL * us)
    gw = np.where(np.isfinite(res.gw), res.gw, 0.0)
    weak_stick = stick & (gw > 0) & (node_norm(res.lam_t, m) >= (1 - REL_TOL) * gw)
    weak_slip = ~stick & (gw > 0) & (node_norm(c.slip, m) <= REL_TOL * us)
    # constraints that cannot move the solution: a row held by supports on both sides (it
    # vanishes, or is round-off: `Model.held`), and a tangent parallel to the normal (rollers on
    # both sides) while closed; a held normal leaves a free tangent's stick/slip switch counting
    moves = ~model.held[:m]
    t_moves = (~model.held[m:]).reshape(k, m)
    tangent_free = (t_moves & ~model.tied[0].reshape(k, m)).any(axis=0)     # `tied_rows`
    weak_t = (weak_stick | weak_slip) & (tangent_free | ~closed) & t_moves.any(axis=0)
    return bool(np.any((weak_closed | weak_open) & moves | weak_t))


def coefficient_gradients(model, state, partials: list[Partials]) -> list[np.ndarray | None]:
    """dΦ/dc (flat, `flatten` order) of each criterion's partials by the adjoint; None where the
    active-set system is singular. What the criteria share — the stiffness, K U0, the contact
    adjoint system and its LU — is built once."""
    c = state.coefficients
    U0 = model.elim.U0.tocsc()
    KU0 = model.support_stiffness(c)
    own = getattr(model.method, "adjoint", None)      # a method with its own adjoint (the iterative one)
    contact = None if state.raw is None else own(model, state) if own is not None else ContactAdjoint(model, state)
    Kh = model.H(c.kappa) if model.thermal else None
    return [_coefficient_gradient(model, state, P, contact, U0, KU0, Kh) for P in partials]


def _coefficient_gradient(model, state, P: Partials, contact, U0, KU0, Kh) -> np.ndarray | None:
    c = state.coefficients
    flat, sl = flatten(c)
    grad = np.zeros_like(flat)
    for name, v in (P.coef or {}).items():
        grad[sl[name]] += v
    T, Tt = model.elim.T, model.Tt
    phi_u = np.zeros(T.shape[0]) if P.u is None else P.u
    phi_w = Tt @ phi_u
    mu = sigma = None
    if contact is None:
        z = state.factor().solve(phi_w)
    else:
        out = contact.solve(phi_w, P.lam_n, P.lam_t)
        if out is None:
            return None
        z, mu, sigma = out
    Z = T @ z
    u = state.u
    sK = model.K.sensitivities(Z, u)
    grad[sl["lam"]] -= sK[:, 0]
    grad[sl["mu"]] -= sK[:, 1]
    grad[sl["body_force"]] += (model.body_force_vectors @ Z).ravel()
    grad[sl["pressure"]] += [model.pressure_vectors[b] @ Z for b in sorted(model.pressure_vectors)]
    grad[sl["traction"]] += np.concatenate([model.traction_vectors[b] @ Z for b in sorted(model.traction_vectors)]
                                           ) if model.traction_vectors else np.zeros(0)
    g_sup = -(KU0.T @ Z) + U0.T @ phi_u
    if mu is not None:
        m = state.raw.lam_n.size
        A = np.flatnonzero(state.raw.free[:m])                      # closed normals carry d
        g_sup += -(model.zone.Bn[A] @ U0).T @ mu[A]
        tang = np.flatnonzero(~state.raw.free[m:] & (sigma != 0))  # fixed tangent rows λ_t = σ gw
        node = tang % m
        w = model.zone.weight
        np.add.at(grad, sl["slip"].start + node, mu[m + tang] * sigma[tang] * w[node])
        np.add.at(grad, sl["coulomb"].start + node, mu[m + tang] * sigma[tang] * state.raw.lam_n[node])
    grad[sl["support_values"]] += g_sup
    if model.thermal:
        dT = state.T - c.reference
        coupled = np.zeros(model.nnodes)
        for j, Bj in enumerate(model.coupling):
            BtZ = Bj.T @ Z
            grad[sl["beta"].start + j] += BtZ @ dT
            grad[sl["reference"]] -= c.beta[j] * BtZ.sum()
            coupled += c.beta[j] * BtZ
        load = model.P.T @ coupled + (0.0 if P.theta is None else P.theta)
        zeta = state.heat_factor().solve(model.heat_Tt @ load)
        Zh = model.heat_elim.T @ zeta
        grad[sl["kappa"]] -= model.H.sensitivities(Zh, state.theta)[:, 0]
        grad[sl["source"]] += model.source_vectors @ Zh
        U0h = model.heat_elim.U0.tocsc()
        grad[sl["temperature_values"]] += -((Kh @ U0h).T @ Zh) + U0h.T @ load
    return grad


def gradients(evaluator, state, x: np.ndarray, others=None) -> tuple[dict[str, np.ndarray | None], bool]:
    """dΦ/dx for every criterion at the solution `state` of data set x (and `others`, the
    other addressed numbers), and whether the point is non-smooth (an active-set change or
    a switch of the maximising region nearby)."""
    model = evaluator.model
    J = evaluator.map.jacobian(x, others)
    nonsmooth = state.raw is not None and contact_nonsmooth(model, state)
    partials = []
    for crit in evaluator.criteria:
        P, tie = criterion_partials(crit, model, state)
        nonsmooth |= tie
        partials.append(P)
    out = {}
    for crit, gc in zip(evaluator.criteria, coefficient_gradients(model, state, partials)):
        out[crit.name] = None if gc is None else J.T @ gc
        nonsmooth |= gc is None
    return out, bool(nonsmooth)
