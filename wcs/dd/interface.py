r"""Local objects of the decomposition: linear subdomains and contact pairs.

Each *unit* (a linear subdomain `s ∈ T`, or a pair `p` of subdomains across
one or more contacts) owns its local matrix `A_u = T_uᵀ K_u T_u` (its cells
only, in the reduced space of the constraint elimination u = T w + U0 c), its
DOFs split into interior `I` and interface `B` (DOFs shared with another
unit; Dirichlet DOFs are already eliminated), and:

* the Dirichlet solve ([21, (4.24)–(4.25)])
  `S_u v = A_BB v − A_BI A_II⁻¹ A_IB v`, `g_u = f_B − A_BI A_II⁻¹ f_I`,
  by a factorization of `A_II` — `S_u` is never formed;
* the Neumann solve ([21, (5.1)–(5.4)]) `S_u† r = x_B`, `A_u x = [0; r]`,
  by a factorization of `A_u` regularised on DOFs where its kernel `Z_u`
  is nonsingular (a generalized inverse on balanced data, `Z_uᵀ r = 0`);
* the kernel `Z_u` (rigid motions the supports leave free) for the coarse
  space ([21, (5.11)]).

A pair is linear in the auxiliary problem of [21, (4.35)]: bilateral contact
without friction, `C v = 0` with `C = Bn` (the normal jumps) — or `C = [Bn; Bt]`
(glued) where a half held by nothing else would slide — and its Dirichlet
and Neumann solves are saddle-point solves ([21, (4.49)], (5.3)). Its
nonlinear Schur complement ([21, (4.27)–(4.28)])
`S_p(V) = A_BI u_I(V) + A_BB V − f_B` takes `u_I(V)` from the local contact
problem with `V` as Dirichlet data, solved by `wcs.contact.solver.solve_contact`
(friction enters only here).

Every unit works on its own arrays only (`gamma` maps its interface DOFs to
positions in the global interface vector), so the units can later be
distributed over MPI ranks unchanged.
"""
from __future__ import annotations

import copy

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from wcs import linalg
from wcs.contact.solver import pinned_dofs, solve_contact
from wcs.status import Status


class SetupError(RuntimeError):
    """The decomposition cannot be used for this scene (singular local or coarse problem)."""


# ---- kernels -----------------------------------------------------------------------------
def rigid_basis(p: np.ndarray, nodes: np.ndarray, ncomp: int) -> np.ndarray:
    """(ncomp·k, r): rigid motions of the nodes, node-interleaved, O(1) scaled columns —
    r = 1 for a scalar field, else the d translations and d(d − 1)/2 rotations of the
    dimension d = ncomp (3 in 2D, 6 in 3D)."""
    k = nodes.size
    if ncomp == 1:
        return np.ones((k, 1))
    xy = p[:, nodes].T
    x = (xy - xy.mean(axis=0)) / max(np.ptp(xy, axis=0).max(), 1e-300)
    rotations = [(a, b) for a in range(ncomp) for b in range(a + 1, ncomp)]
    R = np.zeros((ncomp * k, ncomp + len(rotations)))
    for a in range(ncomp):
        R[a::ncomp, a] = 1.0
    for j, (a, b) in enumerate(rotations):        # rotation in the (a, b) plane
        R[a::ncomp, ncomp + j] = -x[:, b]
        R[b::ncomp, ncomp + j] = x[:, a]
    return R


def admissible(M: np.ndarray, Tloc: sp.csr_matrix, rtol: float = 1e-10) -> np.ndarray:
    """Reduced coordinates of the motions in span(M) the elimination admits: M α ∈ range(T).

    T has orthonormal columns (one node each), so the defect is (I − T Tᵀ) M α.
    Returns an orthonormal basis (columns) of Tᵀ M N, N = null space of the defect.
    """
    if M.shape[1] == 0:
        return np.zeros((Tloc.shape[1], 0))
    E = M - Tloc @ (Tloc.T @ M)
    s_ref = max(np.linalg.norm(M, 2), 1e-300)
    _, s, vt = np.linalg.svd(E, full_matrices=False)     # M has ≤ 6 columns and many rows
    rank = int(np.sum(s > rtol * s_ref))
    Z = Tloc.T @ (M @ vt[rank:].T)
    return _orth(Z)


def _orth(Z: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    if Z.shape[1] == 0:
        return Z
    q, r, _ = sla.qr(Z, mode="economic", pivoting=True)
    d = np.abs(np.diag(r))
    return q[:, d > rtol * max(d.max(initial=0.0), 1e-300)]


def null_space(C: np.ndarray, Z: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of {Z α : C Z α = 0}."""
    if Z.shape[1] == 0 or C.shape[0] == 0:
        return Z
    CZ = C @ Z
    ref = max(np.linalg.norm(Z, 2) * max(np.abs(C).max(initial=0.0), 1e-300), 1e-300)
    _, s, vt = np.linalg.svd(CZ, full_matrices=True)
    rank = int(np.sum(s > rtol * ref))
    return _orth(Z @ vt[rank:].T)


def independent_rows(C: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """Rows of C forming a basis of its row space (pivoted QR of Cᵀ), ascending.

    Glue rows can be dependent (e.g. a contact node on a roller support), which
    would make the saddle-point matrices singular."""
    if C.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    C = C[:, np.flatnonzero(np.abs(C).sum(axis=0))]      # the few columns the rows touch
    _, r, piv = sla.qr(C.T, mode="economic", pivoting=True)
    d = np.abs(np.diag(r))
    return np.sort(piv[: int(np.sum(d > rtol * max(d.max(initial=0.0), 1e-300)))])


def _spd_factor(A: sp.spmatrix):
    return linalg.factorize(sp.csr_matrix(A), spd=True)


class _KKT:
    """LU of the saddle point [[A, Cᵀ], [C, 0]] (partial pivoting: the zero block needs it)."""

    def __init__(self, A: sp.spmatrix, C: sp.spmatrix):
        self.n = A.shape[0]
        m = C.shape[0]
        C = C * float(np.abs(A.diagonal()).mean())      # same scale as A: keeps the LU accurate
        K = sp.bmat([[A, C.T], [C, sp.csr_matrix((m, m))]], format="csc")
        try:
            self.lu = spla.splu(K)
        except RuntimeError as exc:
            raise SetupError(f"singular saddle-point problem of a pair: {exc}") from exc
        self.m = m

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, float)
        rhs = np.zeros((self.n + self.m,) + b.shape[1:])
        rhs[: self.n] = b
        return self.lu.solve(rhs)[: self.n]


# ---- units -------------------------------------------------------------------------------
class Unit:
    """A linear subdomain (or, in its linear uses, a pair): local Dirichlet and Neumann solves.

    dofs:  global reduced DOFs of the unit (sorted); `B`, `I`: local positions of the
           interface and interior DOFs; `gamma`: positions of `B` in the interface vector.
    op:    local CellAffineOperator on the unit's nodes; `Tloc` the local block of T.
    Z:     kernel of A_u (orthonormal columns, local DOF order).
    """

    kind = "linear"

    def __init__(self, index, subdomains, dofs, op, Tloc, Z, rho):
        self.index = index
        self.subdomains = tuple(subdomains)
        self.dofs = dofs
        self.op = op
        self.Tloc = Tloc
        self.Z = Z
        self.rho = rho
        self.B = self.I = self.gamma = None
        self.f = None

    # structure
    def set_interface(self, is_interface: np.ndarray, position: np.ndarray) -> None:
        mask = is_interface[self.dofs]
        self.B, self.I = np.flatnonzero(mask), np.flatnonzero(~mask)
        self.gamma = position[self.dofs[self.B]]

    # numbers
    def assemble(self, coefficients: np.ndarray) -> None:
        """Local matrix A_u = T_uᵀ K_u(c) T_u and its factorizations (analysis reused)."""
        A = (self.Tloc.T @ self.op(coefficients) @ self.Tloc).tocsr()
        A.sort_indices()
        self.A = A
        I, B = self.I, self.B
        self.A_II = A[I][:, I].tocsr()
        self.A_IB = A[I][:, B].tocsr()
        self.A_BI = self.A_IB.T.tocsr()
        self.A_BB = A[B][:, B].tocsr()
        self._factor_dirichlet()
        self._factor_neumann()

    def _factor_dirichlet(self):
        old = getattr(self, "_fI", None)
        if self.I.size:
            self._fI = old.refactor(self.A_II) if old is not None else _spd_factor(self.A_II)

    def _factor_neumann(self):
        pinned = pinned_dofs(self.Z) if self.Z.shape[1] else np.zeros(0, dtype=np.int64)
        A = self.A.copy()
        if pinned.size:
            d = A.diagonal()[pinned]
            A = (A + sp.csr_matrix((np.where(d > 0, d, 1.0), (pinned, pinned)), shape=A.shape)).tocsr()
        old = getattr(self, "_fN", None)
        self._fN = old.refactor(A) if old is not None else _spd_factor(A)

    def set_load(self, f_local: np.ndarray) -> None:
        self.f = f_local

    def interior_solve(self, b_I: np.ndarray) -> np.ndarray:
        return self._fI.solve(b_I) if self.I.size else np.zeros((0,) + np.shape(b_I)[1:])

    def apply_S(self, v: np.ndarray) -> np.ndarray:
        """S_u v = A_BB v − A_BI A_II⁻¹ A_IB v (one Dirichlet solve; v may have columns)."""
        out = self.A_BB @ v
        if self.I.size:
            out = out - self.A_BI @ self.interior_solve(self.A_IB @ v)
        return out

    def condensed_load(self) -> np.ndarray:
        """g_u = f_B − A_BI A_II⁻¹ f_I ([21, (4.24)])."""
        g = self.f[self.B].copy()
        if self.I.size:
            g -= self.A_BI @ self.interior_solve(self.f[self.I])
        return g

    def neumann(self, r: np.ndarray) -> np.ndarray:
        """S_u† r: the interface trace of A_u x = [0; r] (regularised on ker A_u)."""
        b = np.zeros((self.dofs.size,) + r.shape[1:])
        b[self.B] = r
        return self._fN.solve(b)[self.B]

    def interior(self, V: np.ndarray) -> np.ndarray:
        """Local solution with interface values V: u_I = A_II⁻¹ (f_I − A_IB V)."""
        u = np.zeros(self.dofs.size)
        u[self.B] = V
        if self.I.size:
            u[self.I] = self.interior_solve(self.f[self.I] - self.A_IB @ V)
        return u


class PairUnit(Unit):
    """Subdomains glued across contacts: linear with `C v = 0` (auxiliary problem), and the
    nonlinear Schur complement by the local contact solve.

    rows:  zone rows (contact nodes) of the pair; Bn, Bt: their local jump operators
           (columns in local DOF order; zero on B since contact nodes are interior);
    C:     glue rows of the auxiliary problem (Bn, or [Bn; Bt] where Bn alone leaves a
           half free to slide);  R_int: interior kernel (halves touching neither a support
           nor the interface), passed to the contact solver as its floating modes.
    """

    kind = "pair"

    def __init__(self, index, subdomains, dofs, op, Tloc, comp_modes, rho, rows, Bn, Bt):
        Z_halves = np.hstack(comp_modes) if comp_modes else np.zeros((dofs.size, 0))
        super().__init__(index, subdomains, dofs, op, Tloc, Z_halves, rho)
        self.rows, self.Bn, self.Bt = rows, Bn.tocsr(), Bt.tocsr()
        self.comp_modes = comp_modes     # per facet-connected component: its admissible rigid modes
        self.Z_halves = Z_halves
        self.warm = None
        self.result = None

    def set_interface(self, is_interface, position):
        super().set_interface(is_interface, position)
        if self.B.size and (abs(self.Bn[:, self.B]).sum() or abs(self.Bt[:, self.B]).sum()):
            raise SetupError("a contact node lies on a subdomain interface (partition bug)")
        onB = np.zeros(self.dofs.size, bool)
        onB[self.B] = True
        free = [Zc for Zc in self.comp_modes if Zc.shape[1] and not np.any(np.abs(Zc[onB]) > 0)]
        self.R_int = np.hstack(free)[self.I] if free else None
        # glue: normal only ([21, (4.35)]) unless that leaves an interior mode free
        Cn = self.Bn.toarray()
        full = self.R_int is not None and null_space(Cn[:, self.I], self.R_int).shape[1] > 0
        self.glue = "normal+tangential" if full else "normal"
        C = sp.vstack([self.Bn, self.Bt]).tocsr() if full else self.Bn
        self.C = C[independent_rows(C.toarray())]
        self.Z = null_space(self.C.toarray(), self.Z_halves)

    def _factor_dirichlet(self):
        I = self.I
        if I.size:
            self._kI = _KKT(self.A_II, self.C[:, I])

    def _factor_neumann(self):
        A = self.A.copy()
        if self.Z.shape[1]:
            pinned = pinned_dofs(self.Z)
            d = A.diagonal()[pinned]
            A = (A + sp.csr_matrix((np.where(d > 0, d, 1.0), (pinned, pinned)), shape=A.shape)).tocsr()
        self._kN = _KKT(A, self.C)

    def interior_solve(self, b_I):
        return self._kI.solve(b_I) if self.I.size else np.zeros((0,) + np.shape(b_I)[1:])

    def neumann(self, r):
        b = np.zeros((self.dofs.size,) + r.shape[1:])
        b[self.B] = r
        return self._kN.solve(b)[self.B]

    def glued_interior(self, V):
        """Local solution of the auxiliary (glued) problem with interface values V."""
        return Unit.interior(self, V)

    def contact(self, V: np.ndarray, d, w, g, F, tol: float, max_iter: int):
        """Nonlinear Schur complement S_p(V) ([21, (4.27)–(4.28)]) by the local contact solve.

        Returns (residual on B, local solution, ContactResult)."""
        I, B = self.I, self.B
        b = self.f[I] - self.A_IB @ V
        Bn, Bt = self.Bn[:, I], self.Bt[:, I]
        res = solve_contact(self.A_II, b, Bn, Bt, d, w, g=g, F=F, R=self.R_int, tol=tol,
                            max_iter=max_iter, warm=self.warm)
        self.result = res
        if res.u is None:
            return None, None, res
        self.warm = res
        u = np.zeros(self.dofs.size)
        u[B], u[I] = V, res.u
        r = self.A_BI @ res.u + self.A_BB @ V - self.f[B]
        return r, u, res

    def tresca(self, V: np.ndarray, d, bound, tol: float, max_iter: int):
        """S_p(V) ([21, (4.27)–(4.28)]) of the Tresca problem with nodal slip bounds `bound`
        (g·w, or a Coulomb fixed point's g·w + F λn); `bound` None: every node sticks (the
        fixed point's start, solve_contact's all-stick Coulomb step). Returns (residual on
        B, local solution, ContactResult); the result's `free` is the active set."""
        I, B = self.I, self.B
        m = self.rows.size
        b = self.f[I] - self.A_IB @ V
        Bn, Bt = self.Bn[:, I], self.Bt[:, I]
        if bound is None:
            res = solve_contact(self.A_II, b, Bn, Bt, d, np.ones(m), F=np.ones(m), R=self.R_int, tol=tol,
                                max_iter=max_iter, factor=self.warm.factor if self.warm else None, max_fp_iter=0)
            if res.status is Status.FIXED_POINT_NOT_CONVERGED:     # no fixed-point step was asked for
                res.status, res.message = Status.SOLVED, "converged (all stick)"
        else:
            res = solve_contact(self.A_II, b, Bn, Bt, d, np.ones(m), g=bound, R=self.R_int, tol=tol,
                                max_iter=max_iter, warm=self.warm)
        self.result = res
        if res.u is None:
            return None, None, res
        self.warm = res
        u = np.zeros(self.dofs.size)
        u[B], u[I] = V, res.u
        return self.A_BI @ res.u + self.A_BB @ V - self.f[B], u, res

    def linearised(self, free: np.ndarray, factor: bool = True) -> "PairUnit":
        """The pair made linear by an active set: the closed normal and stuck tangential rows
        of `free` (`ContactResult.free`, (2m,)) as its equations C v = 0 instead of the glue;
        open and slipping rows carry forces that do not vary with V. S_p is affine where the
        active set holds ([21, (4.27)–(4.28)] piece by piece), and this pair's Schur complement
        is its derivative there. Factored only with `factor` (the rank that owns the pair);
        the kernel Z (the halves' rigid motions C leaves free) always."""
        lin = copy.copy(self)
        C = sp.vstack([self.Bn, self.Bt]).tocsr()[np.flatnonzero(free)]
        lin.C = C[independent_rows(C.toarray())]
        lin.Z = null_space(lin.C.toarray(), self.Z_halves)
        lin.glue = "active set"
        if factor:
            lin._factor_dirichlet()
            lin._factor_neumann()
        return lin
