r"""A linear subdomain of the decomposition (`Unit`): its local Dirichlet and Neumann solves.

Each *unit* (a linear subdomain `s ∈ T`, or a pair `p` of subdomains across
one or more contacts: `wcs.dd.pair.PairUnit`) owns its local matrix
`A_u = T_uᵀ K_u T_u` (its cells only, in the reduced space of the constraint
elimination u = T w + U0 c), its DOFs split into interior `I` and interface `B` (DOFs shared with another
unit; Dirichlet DOFs are already eliminated), and:

* the Dirichlet operator ([21, (4.24)–(4.25)])
  `S_u = A_BB − A_BI A_II⁻¹ A_IB`, `g_u = f_B − A_BI A_II⁻¹ f_I`;
* the Neumann solve ([21, (5.1)–(5.4)]) `S_u† r`, a generalized inverse
  regularised on DOFs where the kernel `Z_u` is nonsingular (exact on
  balanced data, `Z_uᵀ r = 0`);
* the kernel `Z_u` (rigid motions the supports leave free) for the coarse
  space ([21, (5.11)]).

All from ONE sparse factorization per unit: PARDISO's Cholesky of `A_u`
(regularised on its kernel) returning the dense Schur complement on a small
block `X` of DOFs — `B`, and for a pair also its contact DOFs — during the
numeric phase; the symbolic analysis of the first data set is kept, a new data
set costs a numeric refactor. `S_u` and `S_u†` are then dense matrices of the
interface size: a PCG iteration costs no sparse solve.

Every unit works on its own arrays only (`gamma` maps its interface DOFs to
positions in the global interface vector), so the units can be distributed
over MPI ranks unchanged.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.linalg import blas, lapack

from wcs import linalg
from wcs.contact.solver import pinned_dofs, regularize
from wcs.fem.constraints import Reduction

from .kernels import _orth


AFFINE_PIECES = 8  # coefficients acting on a unit up to which its matrix is a sum of reduced pieces


class SetupError(RuntimeError):
    """The decomposition cannot be used for this scene (singular local or coarse problem)."""


def _pinned_inverse(S: np.ndarray, Z: np.ndarray, what: str) -> np.ndarray:
    """(S + Σ_{j∈P} S_jj e_j e_jᵀ)⁻¹, dense, P: DOFs on which the kernel basis Z of S is
    nonsingular; a generalized inverse of S: for Zᵀr = 0, x = (S + D)⁻¹ r gives Z_Pᵀ D x = 0,
    so x_P = 0 and S x = r (the Neumann solve of [21, (5.1)–(5.4)]). Formed once per data set:
    a product with it is 5–10× faster than two triangular solves (measured at 150–800 DOFs).
    S must be exactly symmetric (one triangle is read). Returns the inverse's upper triangle
    packed (`_packed`): one copy of S in Fortran order factored and inverted in place."""
    if S.shape[0] == 0:                       # a unit without interface DOFs (LAPACK refuses n = 0)
        return np.zeros(0)
    A = np.array(S.T, order="F")              # S's memory as it lies (S = Sᵀ): Fortran order, one copy
    if Z.shape[1]:
        P = pinned_dofs(Z)
        A[P, P] += np.where(A[P, P] > 0, A[P, P], 1.0)
    L, info = lapack.dpotrf(A, lower=False, overwrite_a=True)
    if info == 0:
        L, info = lapack.dpotri(L, lower=False, overwrite_c=True)  # the upper triangle of the inverse
    if info != 0:
        raise SetupError(f"{what} is not positive definite (LAPACK info {info})")
    return _packed(L.T)


def _packed(M: np.ndarray) -> np.ndarray:
    """The upper triangle of a symmetric matrix in BLAS packed storage (column by column),
    from the lower triangle of M taken row by row (M C-contiguous: contiguous slices)."""
    if M.shape[0] == 0:
        return np.zeros(0)
    return np.concatenate([M[j, :j + 1] for j in range(M.shape[0])])


def _packed_product(ap: np.ndarray, v: np.ndarray) -> np.ndarray:
    """M v for M symmetric in packed storage (`_packed`) by BLAS dspmv (v may have columns)."""
    n = v.shape[0]
    if n == 0:
        return np.zeros(v.shape)
    if v.ndim == 1:
        return blas.dspmv(n, 1.0, ap, v)
    return np.column_stack([blas.dspmv(n, 1.0, ap, np.ascontiguousarray(c)) for c in v.T]).reshape(v.shape)


class Unit:
    """A linear subdomain (or, in its linear uses, a pair): local Dirichlet and Neumann solves.

    dofs:  global reduced DOFs of the unit (sorted); `B`, `I`: local positions of the
           interface and interior DOFs; `gamma`: positions of `B` in the interface vector.
    op:    local CellAffineOperator on the unit's nodes; `Tloc` the local block of T.
    Z:     kernel of A_u (orthonormal columns, local DOF order).

    One factorization: PARDISO's Cholesky of A_u (regularised on DOFs of the block X where its
    kernel is nonsingular) with the dense Schur complement Σ on X (X = B here; a pair adds its
    contact DOFs), numeric refactor per data set on the analysis of the first. The Dirichlet
    operator S_u = Σ⁰ (Σ without the regularisation, [21, (4.24)]) and the Neumann solve
    (Σ⁰ + D_P)⁻¹ on B are dense: applying them in PCG costs no sparse solve. Interior values
    take one solve with the factor: A_reg z = [b_Y; Σ u_X + h_X] has z_X = u_X and
    z_Y = A_YY⁻¹(b_Y − A_YX u_X), h_X = A_XY A_YY⁻¹ b_Y (from z = A_reg⁻¹[b_Y; 0]: h_X = −Σ z_X).
    """

    kind = "linear"

    def __init__(self, index, subdomains, dofs, op, Tloc, Z):
        self.index = index
        self.subdomains = tuple(subdomains)
        self.dofs = dofs
        self.op = op
        self.Tloc = Tloc
        self.Z = Z
        self.B = self.I = self.gamma = None
        self.f = None
        self._F = None
        self._coefficients = None
        self._reduce = None             # Tᵀ K T on the structural pattern (`wcs.fem.constraints.Reduction`)
        self._S_packed = None           # (S, its packed upper triangle) for PCG's products
        self._pieces = None             # [(region, coefficient, A_u's piece on the pattern)] (`_matrix`)

    # structure
    def set_interface(self, is_interface: np.ndarray, position: np.ndarray) -> None:
        self._split(is_interface, position)
        self._blocks(self.B, self.Z)

    def _split(self, is_interface: np.ndarray, position: np.ndarray) -> None:
        """The local positions of the interface DOFs `B` and the interior ones `I`, and `gamma`:
        B's positions in the interface vector."""
        mask = is_interface[self.dofs]
        self.B, self.I = np.flatnonzero(mask), np.flatnonzero(~mask)
        self.gamma = position[self.dofs[self.B]]

    def _blocks(self, X: np.ndarray, kernel: np.ndarray) -> None:
        """The Schur block X (sorted local DOFs), the rest Y, and the regularised DOFs (in X)."""
        self.X = X
        self.Y = np.setdiff1d(np.arange(self.dofs.size), X)
        self.xB = np.searchsorted(X, self.B)
        self.pinned = X[pinned_dofs(kernel[X])] if kernel.shape[1] else np.zeros(0, dtype=np.int64)
        self._F = None

    # numbers
    def assemble(self, coefficients: np.ndarray) -> None:
        """Local matrix A_u = T_uᵀ K_u(c) T_u, its factorization (analysis reused) and the
        dense Schur blocks; nothing to do when the coefficients are those of the last call."""
        coefficients = np.array(coefficients, dtype=float)
        if self._F is not None and np.array_equal(coefficients, self._coefficients):
            return
        self._coefficients = None                          # a failure below leaves no stale record
        self.f = None                                      # the load's condensation goes with the factor
        A = self.A = self._matrix(coefficients)
        Areg = regularize(A, self.pinned)
        try:
            self._F = self._F.refactor(Areg) if self._F is not None else \
                linalg.factorize(Areg, spd=True, block=self.X)
        except linalg.FactorizationError as exc:
            raise SetupError(f"local factorization of unit {self.index} failed: {exc}") from exc
        self._sigma = self._F.schur(copy=False)               # the factor's buffer: renewed with it
        if getattr(self._F, "symmetric_schur", False):        # Σ⁰: the regularisation taken off, and
            S0 = self._sigma.copy()                           # symmetrised unless the factor's Σ is
        else:
            S0 = self._sigma + self._sigma.T
            S0 *= 0.5                                         # (on the diagonal: exact)
        p = np.searchsorted(self.X, self.pinned)
        S0[p, p] -= (Areg.diagonal() - A.diagonal())[self.pinned]
        self._schur0 = S0
        self._dense()
        self._coefficients = coefficients

    def _matrix(self, coefficients: np.ndarray) -> sp.csr_matrix:
        """A_u = T_uᵀ K_u(c) T_u on the structural pattern of the reduction (a sparse product
        drops entries that vanish for some data: a new pattern, a new analysis — Hertz's pair).
        A_u is affine in c: with at most `AFFINE_PIECES` coefficients acting on the unit, its
        pieces A_u^{gk} (region g, coefficient k) are reduced once and A_u(c) = Σ c_gk A_u^{gk}
        costs a few sums over the pattern (measured on Hertz's 11 units, warm: 21 → 2.5 ms a data
        set against the weighted scatter of the cell matrices and the reduction's product, up to
        0.1 s inside a solve where the cell matrices have left the cache)."""
        if self._reduce is None:
            self._reduce = Reduction(self.op.pattern(), self.Tloc)
            npieces = self.op.npieces
            used = [(g, k) for g in np.unique(self.op.group) for k in range(npieces)]
            if len(used) <= AFFINE_PIECES:
                shape = (int(self.op.group.max()) + 1, npieces)
                self._pieces = []
                for g, k in used:
                    e = np.zeros(shape)
                    e[g, k] = 1.0
                    self._pieces.append((g, k, self._reduce(self.op(e)).data))
        if self._pieces is None:
            return self._reduce(self.op(coefficients))
        c = np.asarray(coefficients, dtype=float).reshape(-1, self.op.npieces)
        g, k, D = self._pieces[0]
        data = c[g, k] * D
        for g, k, D in self._pieces[1:]:
            data += c[g, k] * D
        R = self._reduce
        return sp.csr_matrix((data, R.indices, R.indptr), shape=R.shape)

    def _dense(self):
        self.S = self._schur0
        self._N = _pinned_inverse(self.S, _orth(self.Z[self.B]) if self.Z.shape[1] else self.Z[self.B],
                                  f"the Neumann matrix of unit {self.index}")

    def set_load(self, f_local: np.ndarray) -> bool:
        """The local load and its condensation on X (one solve), kept while the load and the
        factor stay (a study that samples friction or gaps only). Returns whether it changed."""
        if self.f is not None and np.array_equal(f_local, self.f):
            return False
        self.f = f_local
        self._h = self._condense(f_local[self.Y])
        self._g = f_local[self.X] - self._h                  # load condensed on X
        return True

    def _condense(self, bY: np.ndarray) -> np.ndarray:
        """h_X = A_XY A_YY⁻¹ b_Y (one solve; b_Y may have columns)."""
        rhs = np.zeros((self.dofs.size,) + bY.shape[1:])
        rhs[self.Y] = bY
        return -(self._sigma @ self._F.solve(rhs)[self.X])       # not (−Σ) @ …: a copy of Σ

    def _extend(self, bY: np.ndarray, uX: np.ndarray, hX: np.ndarray) -> np.ndarray:
        """z_Y = A_YY⁻¹(b_Y − A_YX u_X), given h_X = A_XY A_YY⁻¹ b_Y (one solve)."""
        rhs = np.zeros((self.dofs.size,) + np.shape(uX)[1:])
        rhs[self.Y] = bY
        rhs[self.X] = self._sigma @ uX + hX
        return self._F.solve(rhs)[self.Y]

    def apply_S(self, v: np.ndarray) -> np.ndarray:
        """S_u v = A_BB v − A_BI A_II⁻¹ A_IB v (dense). A vector by BLAS dspmv on S's upper
        triangle packed at the first product with this S (PCG's products are memory bound: on
        Hertz's 11 units, S and S† packed, measured 3.3–4.1 → 1.8–2.1 ms an iteration against
        dsymv on the full arrays, which the cache prefetches whole); columns by `S @ v`."""
        if v.ndim != 1:
            return self.S @ v
        packed = self._S_packed
        if packed is None or packed[0] is not self.S:       # a new S (data set, linearisation)
            self._S_packed = packed = (self.S, _packed(self.S))
        return _packed_product(packed[1], v)

    def condensed_load(self) -> np.ndarray:
        """g_u = f_B − A_BI A_II⁻¹ f_I ([21, (4.24)])."""
        return self._g[self.xB].copy()

    def neumann(self, r: np.ndarray) -> np.ndarray:
        """S_u† r (a generalized inverse, regularised on ker S_u = Z on B)."""
        return _packed_product(self._N, r)

    def interior(self, V: np.ndarray) -> np.ndarray:
        """Local solution with interface values V: u_I = A_II⁻¹ (f_I − A_IB V)."""
        u = np.zeros(self.dofs.size)
        u[self.B] = V
        u[self.Y] = self._extend(self.f[self.Y], V, self._h)
        return u
