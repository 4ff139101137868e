"""The admissible set U_ad in scaled coordinates, and its polytope geometry.

Scaling. With w = upper − lower, a data set x is the image of z ∈ [0, 1]^n,

    x = lower·(1 − z) + upper·z          (exact at the bounds: z = 1 gives upper bit for bit)
    z = (x − lower) / w                  (z = 0 where w = 0: a fixed parameter)
    dΦ/dz = dΦ/dx ⊙ w                    (chain rule, component-wise)

so every optimiser sees O(1) numbers whatever the physical units.

Linear constraints. A x ≤ b (the Lipschitz slip-limit profiles) becomes
(A W) z ≤ b − A·lower with W = diag(w); rows are normalised to unit length in
z so that one tolerance fits all. P = {z ∈ [0,1]^n : Ã z ≤ b̃} is the
admissible polytope in scaled coordinates.

Geometry used by the strategies:
- `lp_vertex(g)`: a vertex of P maximising g·z (box: the gradient-sign corner;
  otherwise the LP by HiGHS dual simplex, which returns a vertex);
- `gap(z, g) = max_{z'∈P} g·(z' − z) ≥ 0`: the Frank–Wolfe gap, i.e. the best
  gain the linearisation promises anywhere in U_ad. It is 0 exactly when the
  KKT conditions of max Φ over P hold at z (for a vertex of the box: ∂Φ/∂x_i ≥ 0
  where x_i = upper, ≤ 0 where x_i = lower);
- `project(z)`: the Euclidean projection onto P (SLSQP on ½‖y − z‖², followed
  by a step towards the Chebyshev centre that removes round-off violations);
- `is_vertex(z)`: n linearly independent active constraints.
"""
from __future__ import annotations

import numpy as np

TOL = 1e-9          # feasibility / activity tolerance in scaled coordinates
FD_STEP = 1e-6      # finite-difference step in z (of each interval): a quotient errs by O(h) from the
                    # curvature and by the solve's round-off (~1e-14 of Φ) / h ~ 1e-8 of Φ per interval


class Space:
    def __init__(self, problem):
        self.lower = np.asarray(problem.lower, dtype=float)
        self.upper = np.asarray(problem.upper, dtype=float)
        self.width = self.upper - self.lower
        self.n = self.lower.size
        self.A = self.b = None
        if problem.A_ub is not None and np.size(problem.A_ub):
            A = np.atleast_2d(np.asarray(problem.A_ub, dtype=float)) * self.width
            b = np.asarray(problem.b_ub, dtype=float).ravel() - np.atleast_2d(problem.A_ub) @ self.lower
            norm = np.linalg.norm(A, axis=1)
            keep = norm > 1e-300                       # a row on fixed parameters only is a constant
            if np.any(b[~keep] < -TOL * np.maximum(1.0, np.abs(b[~keep]))):
                raise ValueError("linear constraints A x ≤ b are infeasible on the box")
            self.A, self.b = A[keep] / norm[keep, None], b[keep] / norm[keep]
            if not len(self.b):
                self.A = self.b = None
        self._interior = None

    @property
    def constrained(self) -> bool:
        return self.A is not None

    # ---------------------------------------------------------------- the map
    def to_x(self, z) -> np.ndarray:
        z = np.clip(np.asarray(z, dtype=float), 0.0, 1.0)
        return np.clip(self.lower * (1.0 - z) + self.upper * z, self.lower, self.upper)

    def to_z(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        w = np.where(self.width > 0, self.width, 1.0)
        return np.where(self.width > 0, np.clip((x - self.lower) / w, 0.0, 1.0), 0.0)

    def grad_z(self, g) -> np.ndarray:
        return np.asarray(g, dtype=float) * self.width

    # -------------------------------------------------------------- polytope
    def feasible(self, z, tol: float = TOL) -> bool:
        z = np.asarray(z, dtype=float)
        if np.any(z < -tol) or np.any(z > 1 + tol):
            return False
        return self.A is None or bool(np.all(self.A @ z <= self.b + tol))

    def interior(self) -> np.ndarray:
        """The Chebyshev centre of P (the centre of the box when unconstrained)."""
        if self._interior is None:
            if self.A is None:
                self._interior = np.full(self.n, 0.5)
            else:                                          # max r: A z + r ≤ b, r ≤ z ≤ 1 − r
                n, k = self.n, len(self.b)
                I = np.eye(n)
                A = np.vstack([np.hstack([self.A, np.ones((k, 1))]),
                               np.hstack([-I, np.ones((n, 1))]),
                               np.hstack([I, np.ones((n, 1))])])
                b = np.concatenate([self.b, np.zeros(n), np.ones(n)])
                c = np.zeros(n + 1)
                c[-1] = -1.0
                from scipy.optimize import linprog   # scipy.optimize (0.4 s) loads where a search needs it
                res = linprog(c, A_ub=A, b_ub=b, bounds=[(0, 1)] * n + [(0, None)], method="highs-ds")
                if res.status != 0:
                    raise ValueError("linear constraints A x ≤ b are infeasible on the box")
                self._interior = np.clip(res.x[:n], 0.0, 1.0)
        return self._interior

    def centre(self) -> np.ndarray:
        """The centre of the box, projected onto P."""
        return self.project(np.full(self.n, 0.5))

    def project(self, z) -> np.ndarray:
        z = np.clip(np.asarray(z, dtype=float), 0.0, 1.0)
        if self.A is None or self.feasible(z, 0.0):
            return z
        from scipy.optimize import minimize
        res = minimize(lambda y: 0.5 * np.dot(y - z, y - z), self.interior().copy(),
                       jac=lambda y: y - z, method="SLSQP", bounds=[(0.0, 1.0)] * self.n,
                       constraints=[{"type": "ineq", "fun": lambda y: self.b - self.A @ y,
                                     "jac": lambda y: -self.A}],
                       options={"ftol": 1e-15, "maxiter": 500})
        return self.repair(res.x)

    def repair(self, z) -> np.ndarray:
        """Move z the least fraction towards the Chebyshev centre that makes it feasible."""
        z = np.clip(np.asarray(z, dtype=float), 0.0, 1.0)
        z = np.where(z < TOL, 0.0, np.where(z > 1 - TOL, 1.0, z))
        if self.A is None or self.feasible(z, 0.0):
            return z
        c = self.interior()
        viol = self.A @ z - self.b
        slack = self.b - self.A @ c
        t = np.max(np.where(viol > 0, viol / np.maximum(viol + slack, 1e-300), 0.0))
        t = min(1.0, t * (1 + 1e-9) + 1e-15)
        return np.clip(z + t * (c - z), 0.0, 1.0)

    def lp_vertex(self, g, z_ref=None) -> np.ndarray:
        """A vertex of P maximising g·z. Box: the sign corner; where g_i = 0 the
        coordinate keeps the nearer bound of z_ref (ties to the lower bound)."""
        g = np.asarray(g, dtype=float)
        if self.A is None:
            ref = np.full(self.n, 0.5) if z_ref is None else np.asarray(z_ref, dtype=float)
            tiny = 1e-14 * np.max(np.abs(g), initial=0.0)
            return np.where(g > tiny, 1.0, np.where(g < -tiny, 0.0, (ref > 0.5).astype(float)))
        scale = np.max(np.abs(g), initial=0.0)           # HiGHS fails on |g| ~ 1e13 (Pa² criteria)
        gs = g / scale if scale > 0 else g
        from scipy.optimize import linprog
        res = linprog(-gs, A_ub=self.A, b_ub=self.b, bounds=[(0.0, 1.0)] * self.n, method="highs-ds")
        if res.status != 0:
            raise RuntimeError(f"LP for the gradient vertex failed: {res.message}")
        return self.repair(res.x)

    def gap(self, z, g) -> float:
        """Frank–Wolfe gap max_{z'∈P} g·(z' − z) ≥ 0 (0 ⇔ KKT at z)."""
        g = np.asarray(g, dtype=float)
        z = np.asarray(z, dtype=float)
        if self.A is None:                                  # closed form on the box
            return float(np.sum(np.maximum(g, 0) * (1 - z) + np.maximum(-g, 0) * z))
        v = self.lp_vertex(g, z)
        return max(0.0, float(g @ (v - z)))

    def is_vertex(self, z, tol: float = TOL) -> bool:
        z = np.asarray(z, dtype=float)
        rows = [np.eye(self.n)[(z <= tol) | (z >= 1 - tol)]]
        if self.A is not None:
            rows.append(self.A[self.A @ z >= self.b - tol])
        M = np.vstack(rows)
        return M.shape[0] >= self.n and np.linalg.matrix_rank(M) == self.n

    def is_box_corner(self, z) -> bool:
        """Whether z is a corner of the box (every parameter at a bound) with no row of A z ≤ b
        active: there the admissible directions are those of the box, spanned by its edges."""
        z = np.asarray(z, dtype=float)
        at = (z == 0.0) | (z == 1.0) | (self.width == 0)
        return bool(np.all(at)) and (self.A is None or bool(np.all(self.A @ z < self.b - TOL)))

    def key(self, z) -> bytes:
        """Identity of a point: the exact bits of its physical data set."""
        return self.to_x(z).tobytes()
