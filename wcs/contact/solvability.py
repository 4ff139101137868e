r"""Solvability of contact with floating bodies: does the load balance on the rigid motions?

A body held by contact only (rigid modes R, KR = 0) has a solution only if no admissible
rigid motion v = Rα gains work against friction, L(v) ≤ j(v) for rigid v ∈ K
([21, Remark 2.1]). Both sides are positively homogeneous in α, so the maximum of
fᵀRα − j(Rα) over the admissible α in a bounded set is 0 exactly when the load is balanced,
and positive otherwise, at an unbalanced motion.

Both problems are solved by Clarabel directly (no modelling layer: importing cvxpy alone took
1.9 s of a 7 s `wcs solve`; Clarabel itself is imported by the first check that runs, so a solve
with no floating body loads none of it), on data scaled to O(1) by s = max(Σ|Rᵀf|, max gw): the linear
program in 2D, the second-order-cone program in 3D.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

CLARABEL_TIGHT = {k: 1e-12 for k in ("tol_gap_abs", "tol_gap_rel", "tol_feas", "tol_ktratio")}


def rigid_load(R, f) -> np.ndarray:
    """e = Rᵀf, the load's work on the rigid modes, with its round-off taken out: a component
    |e_i| ≤ 1e-12 (|R|ᵀ|f|)_i is 0. Rᵀf sums n products; for a load balanced on mode i its
    computed value is round-off of order ε (|R|ᵀ|f|)_i (measured 1e-16 of it on the 3D Tresca
    patch without loads, where the block is held by contact alone). Kept, that round-off is a
    load pulling a body off its contact, and the equilibrium G λ = e of the rigid modes has no
    λ ≥ 0: the Newton cycles instead of finding the free motion (status NOT_UNIQUE)."""
    e = R.T @ f
    return np.where(np.abs(e) <= 1e-12 * (np.abs(R).T @ np.abs(f)), 0.0, e)


def unbalanced(f, Bn, Bt, gw, R):
    """(value, α) of `unbalanced_rigid_motion` when the load is unbalanced beyond round-off
    (value > 1e-9 of the load's work on the rigid modes, `rigid_load`), else None. A load that
    does no work on the rigid modes is balanced: the maximum is max −j(Rα) = 0 exactly, and
    what a solver returns beyond it is its round-off."""
    work = np.abs(rigid_load(R, f)).sum()
    if work == 0.0:
        return None
    value, alpha = unbalanced_rigid_motion(f, Bn, Bt, gw, R)
    return (value, alpha) if value > 1e-9 * work else None


def unbalanced_rigid_motion(f, Bn, Bt, gw, R):
    """max fᵀRα − Σ gw_i |(Bt Rα)_i| over admissible rigid motions (Bn Rα ≤ 0), α ∈ [−1, 1]^r
    (3D: |α| ≤ 1).

    The problem is solvable only if this maximum is 0 (L(w) ≤ j(w) for rigid w ∈ K, [21, Remark 2.1]).
    2D: a linear program in (α, s) with s ≥ |Bt Rα|. 3D: |(Bt Rα)_i| is the 2-norm of node i's
    two tangential slips, and the exact problem is a second-order-cone program (a polyhedral
    norm would not be exact: the 1-norm overstates the friction's hold and can pass an
    unbalanced load, the ∞-norm understates it); α in the unit ball there, so that the
    unbalanced motion follows the load (a box would bend it to a corner). Returns (value, α).
    """
    m = Bn.shape[0]
    BnR, BtR, e = Bn @ R, Bt @ R, rigid_load(R, f)
    if Bt.shape[0] > m:
        return _unbalanced_socp(BnR, BtR, e, gw)
    return _unbalanced_lp(BnR, BtR, e, gw)


def _scale(e, gw) -> float:
    return max(np.abs(e).sum(), np.abs(gw).max(initial=0.0), 1e-300)


def _unbalanced_lp(BnR, BtR, e, gw):
    """`unbalanced_rigid_motion` in 2D: min −eᵀα/s + gwᵀσ/s over x = (α, σ) subject to
    Bn Rα ≤ 0, ±Bt Rα − σ ≤ 0, −1 ≤ α ≤ 1 (σ ≥ 0 follows), as Clarabel's A x + z = 0 + b,
    z ≥ 0."""
    m, r = BnR.shape
    A = np.zeros((3 * m + 2 * r, r + m))      # [[BnR, 0], [BtR, −I], [−BtR, −I], [I, 0], [−I, 0]]
    A[:m, :r], A[m:2 * m, :r], A[2 * m:3 * m, :r] = BnR, BtR, -BtR
    A[m:2 * m, r:] = A[2 * m:3 * m, r:] = -np.eye(m)
    A[3 * m:3 * m + r, :r], A[3 * m + r:, :r] = np.eye(r), -np.eye(r)
    b = np.zeros(3 * m + 2 * r)
    b[3 * m:] = 1.0
    s = _scale(e, gw)
    import clarabel
    return _clarabel(np.r_[-e / s, gw / s], sp.csc_matrix(A), b, [clarabel.NonnegativeConeT(A.shape[0])], s, r, "LP")


def _clarabel(q, A, b, cones, s: float, r: int, kind: str):
    """(value, α) of min qᵀx subject to A x + z = b, z in the cones (Clarabel at CLARABEL_TIGHT),
    the value −s times the minimum, α the first r entries of x."""
    import clarabel
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    for k, v in CLARABEL_TIGHT.items():
        setattr(settings, k, v)
    sol = clarabel.DefaultSolver(sp.csc_matrix((A.shape[1],) * 2), q, A, b, cones, settings).solve()
    if sol.status not in (clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved):
        raise RuntimeError(f"the solvability {kind} ended with status {sol.status}")
    return -s * sol.obj_val, np.asarray(sol.x[:r], float)


def _unbalanced_socp(BnR, BtR, e, gw):
    """`unbalanced_rigid_motion` with disc friction: min −eᵀα/s + gwᵀσ/s over x = (α, σ) subject
    to Bn Rα ≤ 0, (σ_i, node i's tangential slips (Bt Rα)_{i + c m}) in the second-order cone
    (σ_i ≥ |slip_i|), (1, α) in it (|α| ≤ 1), as Clarabel's A x + z = b."""
    m, r = BnR.shape
    k = BtR.shape[0] // m                     # tangential components a node
    sigma = sp.hstack([sp.csr_matrix((m, r)), -sp.identity(m)])
    slips = sp.hstack([-sp.csr_matrix(BtR), sp.csr_matrix((k * m, m))])
    # node i's cone: its σ row, then its slips (rows i + c m of Bt), node after node
    cone = np.column_stack([np.arange(m)] + [m + c * m + np.arange(m) for c in range(k)]).ravel()
    ball = sp.vstack([sp.csr_matrix((1, r + m)), sp.hstack([-sp.identity(r), sp.csr_matrix((r, m))])])
    A = sp.vstack([sp.hstack([sp.csr_matrix(BnR), sp.csr_matrix((m, m))]),
                   sp.vstack([sigma, slips]).tocsr()[cone], ball]).tocsc()
    b = np.zeros(A.shape[0])
    b[m + (k + 1) * m] = 1.0
    s = _scale(e, gw)
    import clarabel
    cones = [clarabel.NonnegativeConeT(m)] + [clarabel.SecondOrderConeT(k + 1)] * m + [clarabel.SecondOrderConeT(r + 1)]
    return _clarabel(np.r_[-e / s, gw / s], A, b, cones, s, r, "SOCP")
