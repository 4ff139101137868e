r"""A contact pair of the decomposition (`PairUnit`): subdomains glued across one or more
contacts, linear in the auxiliary problem and nonlinear by its local contact solve.

A pair is linear in the auxiliary problem of [21, (4.35)]: bilateral contact
without friction, `C v = 0` with `C = Bn` (the normal jumps) — or `C = [Bn; Bt]`
(glued) where a half held by nothing else would slide — its Dirichlet and
Neumann operators eliminate the contact DOFs on the null space of `C`
([21, (4.49)], (5.3)). Its nonlinear Schur complement ([21, (4.27)–(4.28)])
`S_p(V) = A_BI u_I(V) + A_BB V − f_B` takes `u_I(V)` from the local contact
problem with `V` as Dirichlet data, condensed on the contact DOFs and solved by
`wcs.contact.solver.solve_contact` (friction enters only here).
"""
from __future__ import annotations

import copy
import dataclasses

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.linalg import blas

from wcs import linalg
from wcs.contact.solver import OPEN, ContactFactor, pinned_dofs, regularize, solve_contact
from wcs.status import Status

from .kernels import _null_basis, _orth, independent_rows, null_space
from .unit import SetupError, Unit, _packed, _pinned_inverse


HELD_KEPT = 4      # linearised Schur complements a pair keeps per data set (Hertz: 3 active sets a solve)


class _DenseFactor:
    """Cholesky of a small dense SPD matrix with the `solve` of a `wcs.linalg` factor: the
    contact solver's factor of a pair's condensed contact problem, made once per data set and
    handed to its solves as `factored` (never refactored)."""

    def __init__(self, K):
        K = K.toarray() if sp.issparse(K) else np.asarray(K, float)
        try:
            self._c = sla.cho_factor(K)
        except np.linalg.LinAlgError as exc:
            raise linalg.FactorizationError(f"condensed contact matrix not positive definite: {exc}") from exc

    def solve(self, b):
        """K⁻¹ b (the factor was checked finite when it was made: not scanned again per solve)."""
        return sla.cho_solve(self._c, np.asarray(b, float), check_finite=False)

    def congruence(self, C: np.ndarray) -> np.ndarray:
        """C K⁻¹ Cᵀ (C dense, on all of K's DOFs) as XᵀX, X = U⁻ᵀCᵀ (K = UᵀU): one triangular
        solve and a symmetric rank-k product, a third of the flops of C_S (K⁻¹)_SS C_Sᵀ from
        the inverse block (the Delassus operator of the pair's contact problem)."""
        U, lower = self._c
        return _gram(sla.solve_triangular(U, C.T, lower=lower, trans="N" if lower else "T"))


def _cho(M: np.ndarray, what: str):
    try:
        return sla.cho_factor(0.5 * (M + M.T))
    except np.linalg.LinAlgError as exc:
        raise SetupError(f"{what} is not positive definite: {exc}") from exc


def _gram(X: np.ndarray) -> np.ndarray:
    """XᵀX by BLAS dsyrk (one triangle: half the flops of a general product), symmetric."""
    if X.size == 0:                           # an empty factor (LAPACK refuses a zero leading dimension)
        return np.zeros((X.shape[1], X.shape[1]))
    return _fill_lower(blas.dsyrk(1.0, X, trans=1))


def _fill_lower(U: np.ndarray, k: int = 64) -> np.ndarray:
    """U with its lower triangle set from its upper one (in place, U square), by blocks of k
    rows: a third faster than np.triu(U) + np.triu(U, 1).T at 850 rows, the same numbers."""
    n = U.shape[0]
    for i in range(0, n, k):
        U[i:i + k, :i] = U[:i, i:i + k].T
        for j in range(i + 1, min(i + k, n)):
            U[j, i:j] = U[i:j, j]
    return U


def tangent_rows(rows: np.ndarray, m: int, k: int) -> np.ndarray:
    """The rows of Bt (k tangents per node, stacked by component: tangent j of node i at
    j·m + i, m nodes) of the nodes `rows`, in the same stacking."""
    return (np.arange(k)[:, None] * m + rows).ravel()


class PairUnit(Unit):
    """Subdomains glued across contacts: linear with `C v = 0` (auxiliary problem), and the
    nonlinear Schur complement by the local contact solve.

    rows:  zone rows (contact nodes) of the pair; Bn, Bt: their local jump operators
           (columns in local DOF order; zero on B since contact nodes are interior);
    C:     glue rows of the auxiliary problem (Bn, or [Bn; Bt] where Bn alone leaves a
           half free to slide);  R_int: interior kernel (halves touching neither a support
           nor the interface), passed to the contact solver as its floating modes.

    The Schur block X is B and the contact DOFs c (the columns of Bn, Bt): everything the
    pair solves is dense on X. The glued Schur complement on B ([21, (4.49)]) eliminates c on
    the null space N of the glue, S⁰_p = Σ⁰_BB − Σ⁰_Bc N (Nᵀ Σ⁰_cc N)⁻¹ Nᵀ Σ⁰_cB; the local
    contact problem with interface values V ([21, (4.27)–(4.28)]) is the condensed one,
    stiffness Σ⁰_cc and load g_c − Σ⁰_cB V, solved by `solve_contact` on a dense Cholesky
    factor (once per data set), its residual S_p(V) = Σ⁰_BB V + Σ⁰_Bc u_c − g_B. The load's
    balance on the floating modes does not depend on V (they vanish on B and A_BI R = 0), so
    it is checked at the first contact solve of a data set and slip bounds only; the dual QP
    runs only where the semismooth Newton cycled (counted, and said in the DD's message).
    """

    kind = "pair"

    def __init__(self, index, subdomains, dofs, op, Tloc, comp_modes, rows, Bn, Bt):
        Z_halves = np.hstack(comp_modes) if comp_modes else np.zeros((dofs.size, 0))
        super().__init__(index, subdomains, dofs, op, Tloc, Z_halves)
        self.rows, self.Bn, self.Bt = rows, Bn.tocsr(), Bt.tocsr()
        self.k = self.Bt.shape[0] // max(rows.size, 1)     # tangent rows per node: d − 1
        self.comp_modes = comp_modes     # per facet-connected component: its admissible rigid modes
        self.Z_halves = Z_halves
        self.warm = None
        self.result = None
        self.qp_restarts = 0

    def set_interface(self, is_interface, position):
        self._split(is_interface, position)
        if self.B.size and (abs(self.Bn[:, self.B]).sum() or abs(self.Bt[:, self.B]).sum()):
            raise SetupError("a contact node lies on a subdomain interface (partition bug)")
        onB = np.zeros(self.dofs.size, bool)
        onB[self.B] = True
        free = [Zc for Zc in self.comp_modes if Zc.shape[1] and not np.any(np.abs(Zc[onB]) > 0)]
        R_local = np.hstack(free) if free else None
        self.R_int = R_local[self.I] if free else None
        # glue: normal only ([21, (4.35)]) unless that leaves an interior mode free
        Cn = self.Bn.toarray()
        full = self.R_int is not None and null_space(Cn[:, self.I], self.R_int).shape[1] > 0
        self.glue = "normal+tangential" if full else "normal"
        Cfull = sp.vstack([self.Bn, self.Bt]).tocsr()
        candidates = np.arange(Cfull.shape[0] if full else self.Bn.shape[0])
        self.glue_rows = candidates[independent_rows(Cfull[candidates].toarray())]   # rows of [Bn; Bt]
        self.C = Cfull[self.glue_rows]
        self.Z = null_space(self.C.toarray(), self.Z_halves)
        # the Schur block: B and the contact DOFs
        self.c = np.unique(sp.vstack([self.Bn, self.Bt]).tocsr().indices)
        self._blocks(np.union1d(self.B, self.c), self.Z_halves)
        self.xc = np.searchsorted(self.X, self.c)
        self.Bn_c, self.Bt_c = self.Bn[:, self.c].tocsr(), self.Bt[:, self.c].tocsr()
        self.R_c = R_local[self.c] if free else None
        self._C_c = Cfull[:, self.c].toarray()
        C = self._C_c[self.glue_rows]             # the glue's null basis and C⁺: geometry, kept
        self._glue_null = _null_basis(C)
        CCt = _cho(C @ C.T, f"the glue rows of pair {self.index}")
        self._Cp = sla.cho_solve(CCt, C).T
        self._glue = sp.csr_matrix(C)                               # C sparse and (C Cᵀ)⁻¹: products with
        self._CCt_inv = sla.cho_solve(CCt, np.eye(C.shape[0]))      # C⁺ from the few entries of C
        m = self.rows.size
        moves = np.abs(self._C_c).reshape(-1, m, self.c.size).sum(axis=(0, 2)) > 0
        self.live = None if moves.all() else np.flatnonzero(moves)   # nodes the local contact problem keeps
        # the local contact problem's rows (Bn, Bt) on c, of the `live` nodes, and its floating modes'
        # pinned DOFs: geometry, kept for its factors (`_contact_factor`)
        self._jumps = (self.Bn_c, self.Bt_c) if self.live is None else \
            (self.Bn_c[self.live], self.Bt_c[tangent_rows(self.live, m, self.k)])
        self._pinned_c = pinned_dofs(self.R_c) if free else np.zeros(0, dtype=np.int64)

    def _held(self, rows: np.ndarray, basis=None):
        """(G, T): G = N (Nᵀ Σ⁰_cc N)⁻¹ Nᵀ, N = Π [−W; I] spanning the contact displacements with
        the rows `rows` of [Bn; Bt] held at zero (`_null_basis`; `basis`: its (d, f, W) when
        known, the glue rows' kept from the set-up: it depends on the geometry only), and
        T = G Σ⁰_cB, T V the contact displacements of the extension of V. Σ⁰_cc N and Nᵀ Σ⁰_cc N
        by products with W; G = XᵀX with X = L⁻¹Nᵀ (Nᵀ Σ⁰_cc N = LLᵀ): one triangular solve and
        one symmetric rank-k product. SetupError where the rows leave a rigid motion of a
        floating half free (Nᵀ Σ⁰_cc N is then singular; in floating point its Cholesky may
        still pass)."""
        (d, f, W), (L, lower) = self._held_cholesky(rows, basis)
        Nt = np.zeros((f.size, self.c.size))
        Nt[:, d], Nt[:, f] = -W.T, np.eye(f.size)
        X = sla.solve_triangular(L, Nt, lower=lower, trans="N" if lower else "T")
        G = _gram(X)
        return G, G @ self._Sbc.T

    def _check_held(self, rows: np.ndarray) -> None:
        """SetupError where the contact rows `rows` held leave a rigid motion of a floating half
        free (the contact block with them held is then singular)."""
        if self.R_c is not None and null_space(self._C_c[rows], self.R_c).shape[1]:
            raise SetupError(f"pair {self.index}: the {len(rows)} contact rows held leave a floating half free")

    def _held_cholesky(self, rows: np.ndarray, basis=None):
        """((d, f, W), Cholesky factor of Nᵀ Σ⁰_cc N) for the rows `rows` held (`_held`), or
        SetupError where they leave a rigid motion of a floating half free."""
        self._check_held(rows)
        d, f, W = _null_basis(self._C_c[rows]) if basis is None else basis
        SN = self._Scc[:, f] - self._Scc[:, d] @ W
        return (d, f, W), _cho(SN[f] - W.T @ SN[d], f"the contact block of pair {self.index} with {len(rows)} rows held")

    def _half(self, M: np.ndarray) -> np.ndarray:
        """L⁻¹ Nᵀ M for the glue's null basis N = Π [−W; I] and Nᵀ Σ⁰_cc N = L Lᵀ (M: rows on c,
        columns): G = N (Nᵀ Σ⁰_cc N)⁻¹ Nᵀ = (L⁻¹Nᵀ)ᵀ (L⁻¹Nᵀ), so a product with G, or G between
        two blocks of rows, is one with each half (`_unhalf`)."""
        d, f, W = self._glue_null
        L, lower = self._KN
        return sla.solve_triangular(L, M[f] - W.T @ M[d], lower=lower, trans="N" if lower else "T")

    def _unhalf(self, R: np.ndarray) -> np.ndarray:
        """N L⁻ᵀ R (rows on c): G M = `_unhalf(_half(M))`."""
        d, f, W = self._glue_null
        L, lower = self._KN
        y = sla.solve_triangular(L, R, lower=lower, trans="T" if lower else "N")
        out = np.empty((self.c.size,) + y.shape[1:])
        out[f], out[d] = y, -(W @ y)
        return out

    def held_schur(self, rows: np.ndarray, springs=None) -> np.ndarray:
        """Dense Schur complement on B of the pair with the rows `rows` of [Bn; Bt] held (closed
        normals, stuck tangents: the linearisation at an active set; the glue rows give S⁰_p).
        From the inverse of the glued contact block (`_glue_inverse`), no new null basis: the
        glue rows R not held released, a downdate of rank |R|, S' = S⁰_p − P_R (−H_RR)⁻¹ P_Rᵀ
        (G' = G − E_R H_RR⁻¹ E_Rᵀ, H_RR negative definite), then the held rows C_T outside the glue added, an update
        S' + Wᵀ Q⁺ W with W = C_T G' Σ⁰_cB, Q = C_T G' C_Tᵀ (Q⁺: its pseudo-inverse, exact
        where a row of C_T depends on the others). Where the glue without R is singular (it
        leaves a floating half to the rows of C_T: −H_RR not positive definite), from the null
        basis of the rows (`_held`). SetupError where the rows leave a floating half free.
        `springs` (`across_slip`, 3D): rows A with compliances D that act as springs A u = D λ
        (the slipping nodes' discs), last: S'' + W_Aᵀ (A G'' Aᵀ + D)⁻¹ W_A, W_A = A G'' Σ⁰_cB
        (Woodbury; G'' the inverse of the contact block with the held rows)."""
        rows = np.asarray(rows, dtype=np.int64)
        self._check_held(rows)
        released = ~np.isin(self.glue_rows, rows)
        try:
            M = sla.cho_factor(-self._H[np.ix_(released, released)])
        except np.linalg.LinAlgError:
            G, T = self._held(rows)
            S = self._Sbb - self._Sbc @ T
            if springs is not None:
                A = self._across_rows(springs)
                S = S + self._springs(A @ T, A @ G @ A.T, springs[2])
            return 0.5 * (S + S.T)
        P = self._P[:, released]
        S = self.S - P @ sla.cho_solve(M, P.T)
        added = rows[~np.isin(rows, self.glue_rows)]
        V, Cp = self._V[:, released], self._Cp[:, released]
        if springs is not None:                  # products with G' (released glue), of the spring rows
            A = self._across_rows(springs)
            XA = self._half(A.T)                 # A G Aᵀ = XAᵀXA, A T = XAᵀY, A E = A C⁺ − XAᵀV
            AE = A @ Cp - XA.T @ V
            WA, QA = XA.T @ self._Y + AE @ sla.cho_solve(M, P.T), XA.T @ XA + AE @ sla.cho_solve(M, AE.T)
        if added.size:
            Ct = self._C_c[added]
            Xt = self._half(Ct.T)
            CE = Ct @ Cp - Xt.T @ V
            W = Xt.T @ self._Y + CE @ sla.cho_solve(M, P.T)
            Q = Xt.T @ Xt + CE @ sla.cho_solve(M, CE.T)
            lam, vec = np.linalg.eigh(0.5 * (Q + Q.T))
            keep = lam > 1e-10 * max(lam.max(initial=0.0), 1e-300)
            VW = vec[:, keep].T @ W
            S = S + VW.T @ (VW / lam[keep][:, None])
            if springs is not None:              # G'' = G' − G' C_Tᵀ Q⁺ C_T G'
                VA = vec[:, keep].T @ (Xt.T @ XA + CE @ sla.cho_solve(M, AE.T))
                WA, QA = WA - VA.T @ (VW / lam[keep][:, None]), QA - VA.T @ (VA / lam[keep][:, None])
        if springs is not None:
            S = S + self._springs(WA, QA, springs[2])
        return 0.5 * (S + S.T)

    def _across_rows(self, springs) -> np.ndarray:
        """Rows of the contact DOFs across each slipping node's slip, t⊥ = (−ŝ₂, ŝ₁) in its
        tangent coordinates (`across_slip`)."""
        nodes, shat, _ = springs
        m = self.rows.size
        t1, t2 = self.Bt_c[nodes], self.Bt_c[m + nodes]
        return (t2.multiply(shat[0][:, None]) - t1.multiply(shat[1][:, None])).toarray()

    def _springs(self, WA, QA, compliance) -> np.ndarray:
        """W_Aᵀ (Q_A + D)⁻¹ W_A: the change of the Schur complement on B from springs of
        compliances D on rows A, W_A = A G Σ⁰_cB and Q_A = A G Aᵀ (G the inverse of the contact
        block with the held rows)."""
        QA = 0.5 * (QA + QA.T) + np.diag(compliance)
        return WA.T @ sla.cho_solve(_cho(QA, f"the slip springs of pair {self.index}"), WA)

    def across_slip(self):
        """The disc's stiffness across the slip of the last local contact solve (3D Tresca): at
        a node slipping by s with the bound gw, λt = gw s/|s|, so turning the slip by δ⊥ (across
        it, in the tangent plane) turns λt by gw δ⊥/|s| — a spring of compliance |s|/gw along
        t⊥ (the generalized Jacobian of the disc projection, Hüeber–Stadler–Wohlmuth, at the
        solution; in 2D the interval has no such direction). Returns (nodes, ŝ (2, n),
        compliances (n,)) of the nodes slipping by |s| > 0 under a finite positive bound, None
        in 2D or without a solution."""
        res, m, k = self.result, self.rows.size, self.k
        if k == 1 or res is None or res.u is None:
            return None
        s = (self.Bt_c @ res.u).reshape(k, m)
        size = np.linalg.norm(s, axis=0)
        nodes = np.flatnonzero(~res.free[m:2 * m] & (res.gw > 0) & np.isfinite(res.gw) & (size > 0))
        return nodes, s[:, nodes] / size[nodes], size[nodes] / res.gw[nodes]

    def _glue_inverse(self):
        """(P = Σ⁰_Bc E, H, V) of the inverse [[G, E], [Eᵀ, H]] of the glued contact block
        K = [[Σ⁰_cc, Cᵀ], [C, 0]] (C: the glue rows): G = N (Nᵀ Σ⁰_cc N)⁻¹ Nᵀ,
        E = (I − G Σ⁰_cc) C⁺, H = −(Σ⁰_cc C⁺)ᵀ E, C⁺ = Cᵀ (C Cᵀ)⁻¹ (kept from the set-up).
        Releasing glue rows R is the inverse of K without R: G_R = G − E_R H_RR⁻¹ E_Rᵀ (the
        inverse of a principal block from the full inverse), so the Schur complement on B
        becomes S⁰_p + P_R H_RR⁻¹ P_Rᵀ. With V = L⁻¹Nᵀ Σ⁰_cc C⁺ (`_half`) and Y = L⁻¹Nᵀ Σ⁰_cB:
        P = Σ⁰_Bc C⁺ − YᵀV, H = −(Σ⁰_cc C⁺)ᵀC⁺ + VᵀV, and a block of rows M of E is
        M C⁺ − (L⁻¹NᵀMᵀ)ᵀV (`held_schur`): neither G nor E is formed."""
        C, CCt_inv = self._glue, self._CCt_inv
        CS = C @ self._Scc                                       # C Σ⁰_cc; Σ⁰_cc C⁺ = (C Σ⁰_cc)ᵀ (C Cᵀ)⁻¹
        SCp = CS.T @ CCt_inv
        V = self._half(SCp)
        H = _gram(V) - CCt_inv @ (C @ CS.T) @ CCt_inv          # (Σ⁰_cc C⁺)ᵀ C⁺ = (CCᵀ)⁻¹ C Σ⁰_cc Cᵀ (CCᵀ)⁻¹
        return (C @ self._Sbc.T).T @ CCt_inv - self._Y.T @ V, 0.5 * (H + H.T), V

    def _dense(self):
        """The glued pair's dense operators of a data set: S⁰_p = Σ⁰_BB − YᵀY with
        Y = L⁻¹Nᵀ Σ⁰_cB (N the glue's null basis, Nᵀ Σ⁰_cc N = L Lᵀ: one triangular solve and a
        symmetric rank-k product; G = N (Nᵀ Σ⁰_cc N)⁻¹ Nᵀ and T = G Σ⁰_cB never formed), the
        glue inverse's pieces (`_glue_inverse`) and the Neumann inverse (measured on Hertz's
        pair, 848 contact DOFs and 669 on B: all of it 120–137 → 73–79 ms), and the local
        contact solves' factor (`_contact_factor`): here, in the assembly that the ranks share
        by their measured loads, not at the data set's first contact solve, where the ranks
        without a pair wait (Hertz: ≈ 30 ms)."""
        S0, xB, xc = self._schur0, self.xB, self.xc
        rows_B, rows_c = np.take(S0, xB, axis=0), np.take(S0, xc, axis=0)      # rows, then columns: the
        self._Sbb, self._Sbc = np.take(rows_B, xB, axis=1), np.take(rows_B, xc, axis=1)   # gathers of
        self._Scc = np.take(rows_c, xc, axis=1)                                 # np.ix_ in half the time
        _, self._KN = self._held_cholesky(self.glue_rows, self._glue_null)
        self._Y = self._half(self._Sbc.T)
        self.S = self._Sbb - _gram(self._Y)
        self._P, self._H, self._V = self._glue_inverse()
        self._N = _pinned_inverse(self.S, _orth(self.Z[self.B]) if self.Z.shape[1] else self.Z[self.B],
                                  f"the Neumann matrix of pair {self.index}")
        self._cf = self._contact_factor()
        self._held_kept = {}                # linearisations of this data set by active set

    def set_load(self, f_local):
        if not super().set_load(f_local):
            return False
        self._glued_c = self._unhalf(self._half(self._g[self.xc]))
        self._balanced = None               # slip bounds the floating modes' balance was found for
        return True

    def condensed_load(self):
        """g⁰_p: the load condensed on B with c eliminated on the glue's null space."""
        return self._g[self.xB] - self._Sbc @ self._glued_c

    def _local(self, V, u_c):
        """The local solution with interface values V and contact DOFs u_c (one solve)."""
        uX = np.zeros(self.X.size)
        uX[self.xB], uX[self.xc] = V, u_c
        u = np.zeros(self.dofs.size)
        u[self.X] = uX
        u[self.Y] = self._extend(self.f[self.Y], uX, self._h)
        return u

    def _contact_factor(self) -> ContactFactor:
        """The contact solver's factor of the condensed stiffness Σ⁰_cc, regularized on the
        floating modes' pinned DOFs, with W of the jump rows: made once per data set and handed
        to every local contact solve of it as `factored` (no per-call regularization of the
        |c|² entries, no comparison with what it holds)."""
        Kreg = regularize(sp.csr_matrix(self._Scc), self._pinned_c)
        C = sp.vstack(self._jumps).tocsr()
        S = np.unique(C.indices)
        try:
            f = _DenseFactor(Kreg)
        except linalg.FactorizationError as exc:
            raise SetupError(f"pair {self.index}: {exc}") from exc
        return ContactFactor(f, self._pinned_c, S, C[:, S].toarray(), f.congruence(C.toarray()), Kreg.data)

    def contact(self, V: np.ndarray, d, w, g, F, tol: float, max_iter: int, reference: float = 0.0):
        """Nonlinear Schur complement S_p(V) ([21, (4.27)–(4.28)]) by the local contact solve.

        Returns (residual on B, ContactResult); the result's `u` holds the contact DOFs,
        `solution(V)` the local solution. reference: the size of the displacement the solve's is
        an increment of (a time level's, `ContactProblem.reference`)."""
        return self._solve(V, d, w, g, F, tol, max_iter, warm=self.warm, reference=reference)

    def tresca(self, V: np.ndarray, d, bound, tol: float, max_iter: int, reference: float = 0.0):
        """S_p(V) ([21, (4.27)–(4.28)]) of the Tresca problem with nodal slip bounds `bound`
        (g·w, or a Coulomb fixed point's g·w + F λn); `bound` None: every node sticks (the
        fixed point's start, solve_contact's all-stick Coulomb step). Returns (residual on
        B, ContactResult) as `contact`; the result's `free` is the active set."""
        m = self.rows.size
        if bound is None:
            r, res = self._solve(V, d, np.ones(m), None, np.ones(m), tol, max_iter, max_fp_iter=0,
                                 reference=reference)
            if res.status is Status.FIXED_POINT_NOT_CONVERGED:     # no fixed-point step was asked for
                res.status, res.message = Status.SOLVED, "converged (all stick)"
            return r, res
        return self._solve(V, d, np.ones(m), bound, None, tol, max_iter, warm=self.warm, reference=reference)

    def _full(self, res):
        """A result on the `live` nodes extended to all the pair's nodes: a node whose every
        jump row vanishes (both sides held by supports) is open and carries no force."""
        if self.live is None or res.lam_n is None:
            return res
        m = self.rows.size

        def nodes(x, fill=0):
            out = np.full((x.size // self.live.size, m), fill, dtype=x.dtype)
            out[:, self.live] = x.reshape(-1, self.live.size)
            return out.ravel()
        return dataclasses.replace(res, lam_n=nodes(res.lam_n), lam_t=nodes(res.lam_t),
                                   active=None if res.active is None else nodes(res.active, OPEN),
                                   free=None if res.free is None else nodes(res.free, False),
                                   gw=None if res.gw is None else nodes(res.gw))

    def _solve(self, V, d, w, g, F, tol, max_iter, **kw):
        """The condensed local contact problem with interface values V: stiffness Σ⁰_cc, load
        g_c − Σ⁰_cB V, on the nodes whose jumps move (`live`: a node held on both sides by
        supports has zero rows, which made every active-set system singular and solved by
        least squares, 7× the cost of a solve). The floating modes' balance LP runs once per
        data set and slip bounds (Tresca, frictionless: it depends on the bounds g·w, and on V
        not at all). Where the semismooth Newton cycles from the last active set it restarts
        from all closed and stuck, and where it cycles from there too from the dual QP,
        counted in `qp_restarts`."""
        f_c = self._g[self.xc] - self._Sbc.T @ V
        bounds = None if F is not None and np.any(F > 0) else (np.zeros(len(d)) if g is None else g * w)
        checked = bounds is not None and self._balanced is not None and np.array_equal(bounds, self._balanced)
        if self.live is not None:
            d, w, g, F = (None if a is None else a[self.live] for a in (d, w, g, F))
        args = (self._Scc, f_c, *self._jumps, d, w)
        kw.update(g=g, F=F, R=self.R_c, tol=tol, max_iter=max_iter, factored=self._cf, checked=checked)
        res = solve_contact(*args, **kw, qp=False)
        if res.status is Status.CONTACT_NOT_CONVERGED and kw.get("warm") is not None:
            kw["warm"] = None
            res = solve_contact(*args, **kw, qp=False)
        if res.status is Status.CONTACT_NOT_CONVERGED:
            self.qp_restarts += 1
            res = solve_contact(*args, **kw, qp=True)
        if res.status != Status.UNSOLVABLE and bounds is not None:
            self._balanced = bounds
        if res.u is not None:
            self.warm = res
        self.result = res = self._full(res)
        if res.u is None:
            return None, res
        return self._Sbb @ V + self._Sbc @ res.u - self._g[self.xB], res

    def solution(self, V: np.ndarray) -> np.ndarray:
        """The local solution with interface values V and the contact DOFs of the last local
        contact solve (one sparse solve)."""
        return self._local(V, self.result.u)

    def linearised(self, free: np.ndarray, factor: bool = True, springs=None) -> "PairUnit":
        """The pair made linear by an active set: the closed normal and stuck tangential rows
        of `free` (`ContactResult.free`, (d m,)) held instead of the glue; open and slipping
        rows carry forces that do not vary with V, except across a 3D slip (`springs`: the
        disc's stiffness there, `across_slip`). In 2D S_p is affine where the active set holds
        ([21, (4.27)–(4.28)] piece by piece), and this pair's Schur complement `held_schur`
        is its derivative there; in 3D with the springs it is the derivative at V. Its Neumann
        solve stays the glued pair's generalized inverse (S⁰_p)†: a preconditioner need only
        be positive definite, and no eigendecomposition per active set is needed (a held half
        can be singular beyond its rigid motions to rounding; measured: interface Newton's PCG
        iterations 70 → 49 on Hertz at 1.05e5 unknowns, 36 → 39 on the tunnel). The dense
        operator only with `factor` (the rank that owns the pair, which holds the factor); the
        last `HELD_KEPT` of a data set kept by active set (a 2D Tresca step, or 3D without slip
        springs: those vary continuously) with their packed triangles (`apply_S`), as the
        glued operator is."""
        lin = copy.copy(self)
        lin.glue = "active set"
        if factor:
            rows = np.flatnonzero(free)
            if springs is not None:
                lin.S = self.held_schur(rows, springs)
                return lin
            key = rows.tobytes()
            if key not in self._held_kept:
                if len(self._held_kept) >= HELD_KEPT:
                    del self._held_kept[next(iter(self._held_kept))]      # the oldest
                S = self.held_schur(rows)
                self._held_kept[key] = (S, _packed(S))
            lin._S_packed = self._held_kept[key]             # packed for `apply_S` with it: kept too
            lin.S = lin._S_packed[0]
        return lin
