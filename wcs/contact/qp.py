r"""Reference contact solver: the same problem as a convex program in cvxpy (Clarabel).

    minimise ½ uᵀKu − fᵀu + Σ w_i g_i s_i
    subject to  Bn u ≤ d          (dual λn)
                Bt u ≤ s          (dual μ⁺)
               −Bt u ≤ s          (dual μ⁻)

The epigraph variables s ≥ |Bt u| make the friction multiplier recoverable:
stationarity in u gives K u + Bnᵀλn + Btᵀ(μ⁺ − μ⁻) = f, so λt = μ⁺ − μ⁻,
and stationarity in s gives μ⁺ + μ⁻ = gw, hence |λt| ≤ gw — the sign
conventions of `wcs.contact.solver`. In 3D (two tangent rows per node, stacked by
component as in `wcs.contact.solver`) s_i ≥ |(Bt u)_i| is a second-order cone and
the program an SOCP: with the cone's dual (ν_i, μ_i), stationarity in u gives
λt,i = −μ_i and in s gives ν_i = gw_i ≥ |μ_i|, the disc condition. K may be singular (floating bodies):
`psd_wrap` skips cvxpy's eigenvalue check; an unbalanced load makes the
program unbounded, reported as UNSOLVABLE. Coulomb (slip limit g + F p) by the
same fixed point as the Newton solver, started from a stuck state (a slip limit
far above any load, the convex stand-in for the Newton solver's glued start).
Meant as a small-mesh reference and the "generic tool" baseline.
"""
from __future__ import annotations

import time

import cvxpy as cp
import numpy as np
import scipy.sparse as sp

from ..status import Status
from .methods import Primal
from .problem import ContactProblem
from .solver import ContactResult


def _tresca_qp(K, f, Bn, Bt, d, gw, tol):
    """One Tresca problem; returns (u, λn, λt, cvxpy status).

    Solved for v = D u / a, D = diag(K)^½ and a = max|D⁻¹f|, i.e. for the objective divided
    by a² with the unit-diagonal stiffness D⁻¹KD⁻¹: every DOF's stiffness is 1 and the
    objective O(1), so Clarabel's absolute gap tolerance means a relative one (unscaled,
    u ~ 1e-3 lost three digits) whatever the moduli (with one scale a = max|f| / mean diag K,
    a pad of 1e7 Pa on a 1e14 Pa foundation was declared unbounded: the pad's stiffness was
    1e-7 of the mean). Multipliers scale back as λ = a μ.
    """
    n, m = K.shape[0], Bn.shape[0]
    Dinv = sp.diags(1.0 / np.sqrt(K.diagonal()))
    K, Bn, Bt, f = Dinv @ K @ Dinv, Bn @ Dinv, Bt @ Dinv, Dinv @ f
    a = max(np.abs(f).max(), 1e-300)
    k = Bt.shape[0] // m if m else 1
    v, s = cp.Variable(n), cp.Variable(m)
    if k == 1:
        cons = [Bn @ v <= d / a, Bt @ v <= s, -Bt @ v <= s]
    else:
        cons = [Bn @ v <= d / a, cp.SOC(s, cp.reshape(Bt @ v, (k, m), order="C"), axis=0)]
    obj = 0.5 * cp.quad_form(v, cp.psd_wrap(K)) - (f / a) @ v + (gw / a) @ s
    prob = cp.Problem(cp.Minimize(obj), cons)
    prob.solve(solver=cp.CLARABEL, tol_gap_abs=tol, tol_gap_rel=tol, tol_feas=tol, tol_ktratio=tol)
    if prob.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
        return None, None, None, prob.status
    lt = (cons[1].dual_value - cons[2].dual_value if k == 1
          else -np.asarray(cons[1].dual_value[1], float).reshape(k * m))
    return a * (Dinv @ v.value), a * cons[0].dual_value, a * lt, prob.status


def solve_contact_qp(K, f, Bn, Bt, d, w, g=None, F=None, R=None, *, tol=1e-10,
                     tol_fp=1e-8, max_fp_iter=50) -> ContactResult:
    """Tresca (g) or Coulomb (F) contact through cvxpy + Clarabel. R is accepted for API symmetry
    (the convex program needs no rigid modes; unbalanced loads show up as unboundedness)."""
    return solve_qp(ContactProblem(K, f, Bn, Bt, d, w, g, F, R), tol=tol, tol_fp=tol_fp, max_fp_iter=max_fp_iter)


class _TrescaQP:
    """The Tresca problems of one contact problem as convex programs (`_tresca_qp`), for the
    bounds a law gives (`wcs.contact.laws.TrescaSolve`); `last` holds the last one's answer."""

    def __init__(self, problem: ContactProblem, tol: float):
        self.problem, self.tol, self.last = problem, tol, None

    def __call__(self, gw):
        p = self.problem
        self.last = _tresca_qp(p.K, p.f, p.Bn, p.Bt, p.d, gw, self.tol)
        return self.last[1], self.last[0] is not None, 0


def solve_qp(problem: ContactProblem, *, tol=1e-10, tol_fp=1e-8, max_fp_iter=50) -> ContactResult:
    """`solve_contact_qp` of a `ContactProblem`, its law driving the convex programs. Coulomb
    starts stuck: slip bounds above g·w by Σ|f|, finite (a convex program's bound), beyond
    what any load can shear; its bounds g·w + F λn take the program's λn, a dual of the
    nonnegative cone (never negative)."""
    t0 = time.perf_counter()
    law, tresca = problem.law, _TrescaQP(problem, tol)
    driven = law.drive(tresca, law.start(None, np.abs(problem.f).sum()), tol_fp, max_fp_iter)
    u, ln, lt, st = tresca.last
    timings = {"total": time.perf_counter() - t0}
    if u is None:
        code = Status.UNSOLVABLE if st in (cp.UNBOUNDED, cp.UNBOUNDED_INACCURATE) else Status.SINGULAR
        return ContactResult(None, None, None, code, f"cvxpy status {st}", timings=timings)
    status, msg = ((Status.SOLVED, st) if driven.settled
                   else (Status.FIXED_POINT_NOT_CONVERGED, "Coulomb fixed point not converged"))
    return ContactResult(u, ln, lt, status, msg, fixed_point_iterations=driven.fixed_point_iterations,
                         timings=timings)


QP = Primal("qp", lambda model, problem: solve_qp(problem), polish=True)   # at its own tolerances
