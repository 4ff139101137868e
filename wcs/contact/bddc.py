"""BDDC preconditioner of the Newton steps' operators (`solver.iterative.preconditioner: bddc`).

Balancing domain decomposition by constraints (PETSc's PCBDDC) needs each subdomain's own
(Neumann) stiffness matrix, not only the assembled one: K = Σ_s R_sᵀ K_s R_s, K_s assembled
over the cells of subdomain s, R_s the restriction to its dofs. A Newton step's operator is
Zᵀ K Z plus the diagonal of K on the eliminated pivots P (`wcs.contact.iterative._eliminated`),
K itself Tᵀ K_dofs T after the supports' and glued interfaces' elimination T. Both are sums
over the subdomains: Tᵀ K T = Σ_s T_sᵀ K_s T_s with T_s the rows of T on s's dofs, on the
unknowns those rows touch (`transformed`; Z is node-local, a node's pivots eliminated by its own
unknowns, so a subdomain's part of a step mostly keeps its own unknowns), and diag(K)_P =
Σ_s diag(K_s)_P. The interface dofs are held by
several subdomains: that is MATIS's local-to-global map with repeated entries, so all
subdomains of this process are one local matrix (block diagonal, `setISAllowRepeated`).

Constraints: vertices, edge and face averages of each displacement component (PCBDDC's fields,
`components`) and the rigid modes (the near-nullspace), the edges' imposed by a change of basis
(`use_change_of_basis`), the interface weighted by deluxe scaling (`use_deluxe_scaling`: on the
glued step of the 3D patch at 1.1e4 unknowns, 8 parts, 43 CG iterations with the default
multiplicity scaling, 14 with deluxe, 10 with the rigid modes too). A floating subdomain without
enough primal vertices (four columns of a cube: no vertex inside) leaves its Neumann matrix
singular and PCBDDC's set-up fails (PC failed); the solve is then set up again with the faces'
constraints by a change of basis too (`FACES`), which holds there but costs on the patch 27 s
of set-up against 6 s (so it is not the first choice). The set-up taken depends on the
matrices alone; `faces` counts the solves that took the second.
"""
from __future__ import annotations

import itertools
import time

import numpy as np
import scipy.sparse as sp

OPTIONS = {"pc_bddc_use_faces": "true", "pc_bddc_use_change_of_basis": "true",
           "pc_bddc_use_deluxe_scaling": "true"}
FACES = {"pc_bddc_use_change_on_faces": "true"}     # the faces' constraints by a change of basis too
MAX_IT = 2000
_PREFIX = itertools.count()


def bisection(points: np.ndarray, parts: int) -> np.ndarray:
    """The part (0..parts−1) of each point (dim, n) by recursive coordinate bisection: the
    longest extent is cut at the quantile that gives both halves their share of the parts."""
    out = np.zeros(points.shape[1], dtype=int)

    def split(idx, first, count):
        if count == 1 or len(idx) == 0:
            out[idx] = first
            return
        x = points[:, idx]
        axis = int(np.argmax(x.max(axis=1) - x.min(axis=1)))
        order = idx[np.argsort(x[axis], kind="stable")]
        left = count // 2
        cut = int(round(len(idx) * left / count))
        split(order[:cut], first, left)
        split(order[cut:], first + left, count - left)

    split(np.arange(points.shape[1]), 0, parts)
    return out


def subdomain_stiffness(t: np.ndarray, local, group: np.ndarray, coefficients, cells: np.ndarray):
    """(dofs, K_s): a subdomain's own stiffness Σ_cells c[group(cell)] · K_cell over its cells
    only (`wcs.fem.affine.CellAffineOperator`'s sum restricted to them; local: its cell matrices,
    made chunk by chunk), on the dofs of those cells."""
    from wcs.fem.affine import CHUNK
    c = np.asarray(coefficients, dtype=float).reshape(-1, local.npieces)[group]
    b, n = local.block, t.shape[0]
    rows, cols, vals = [], [], []
    for s in range(0, len(cells), CHUNK):
        e = cells[s:s + CHUNK]
        cell = np.einsum("ek,keabij->eaibj", c[e], local.of(e))              # (e, n, b, n, b)
        dof = (b * t[:, e].T[:, :, None] + np.arange(b)).reshape(len(e), n * b)   # (e, n·b)
        rows.append(np.repeat(dof, n * b, axis=1).ravel())
        cols.append(np.tile(dof, (1, n * b)).ravel())
        vals.append(cell.ravel())
    dofs, inverse = np.unique(np.concatenate(rows), return_inverse=True)
    cols = np.searchsorted(dofs, np.concatenate(cols))
    K_s = sp.csr_matrix((np.concatenate(vals), (inverse, cols)), shape=(len(dofs), len(dofs)))
    K_s.sum_duplicates()
    return dofs, K_s


def transformed(dofs: np.ndarray, K_s: sp.spmatrix, T: sp.spmatrix, diagonal=None):
    """(dofs', T_sᵀ K_s T_s + diag(K_s) on `diagonal`): a subdomain's part of Tᵀ K T (+ diag(K)
    on the unknowns `diagonal`, the step's pivots, `wcs.contact.iterative._eliminated`), T_s
    the rows of T on its dofs, on the columns they touch (dofs'; a row of T that refers to
    another subdomain's unknowns, a glued slave's master or a contact pivot's, adds that unknown
    to this subdomain's: Σ_s of the parts is Tᵀ K T exactly). T square where diagonal is given."""
    Ts = sp.csr_matrix(T)[dofs]
    Ts.eliminate_zeros()
    held = np.zeros(0, dtype=int) if diagonal is None else np.flatnonzero(np.isin(dofs, diagonal))
    local = np.union1d(np.unique(Ts.indices), dofs[held])
    out = Ts[:, local].T @ K_s @ Ts[:, local]
    at = np.searchsorted(local, dofs[held])
    out = out + sp.csr_matrix((sp.csr_matrix(K_s).diagonal()[held], (at, at)), shape=out.shape)
    return local, out.tocsr()


def components(T: sp.spmatrix, dim: int) -> np.ndarray:
    """The displacement component of each unknown w of u = T w (dof = dim·node + component):
    the component of the first dof its column of T moves."""
    T = sp.csc_matrix(T)
    return T.indices[T.indptr[:-1]] % dim


def _aij(A, PETSc):
    A = sp.csr_matrix(A)
    return PETSc.Mat().createAIJ(A.shape, csr=(A.indptr.astype(PETSc.IntType), A.indices.astype(PETSc.IntType),
                                                A.data), comm=PETSc.COMM_SELF)


class Bddc:
    """CG on the assembled operator A preconditioned by BDDC of its subdomain matrices (this
    process holds all subdomains). dofs: each subdomain's dofs; local: each subdomain's part of
    A (`transformed`, Σ_s R_sᵀ local_s R_s = A); near_nullspace: (n, r) rigid modes; components:
    each unknown's displacement component (PCBDDC's constraints are per component: its fields)."""

    def __init__(self, dofs, local, components, near_nullspace=None):
        self.dofs, self.local, self.N, self.components = dofs, local, near_nullspace, np.asarray(components)
        self.timings = {"bddc_setup": 0.0, "cg": 0.0}
        self.faces = 0

    def solve(self, A: sp.csr_matrix, b: np.ndarray, rtol: float):
        """x with ‖b − A x‖ ≤ rtol ‖b‖ (unpreconditioned norm): (x, iterations, converged)."""
        import dolfinx_solver  # noqa: F401  (loads the PETSc libraries petsc4py binds to)
        from petsc4py import PETSc
        x, its, reason = self._solve(A, b, rtol, OPTIONS, PETSc)
        if reason == PETSc.KSP.ConvergedReason.DIVERGED_PCSETUP_FAILED:     # singular Neumann matrix (docstring)
            self.faces += 1
            x, more, reason = self._solve(A, b, rtol, {**OPTIONS, **FACES}, PETSc)
            its += more
        return x, its, reason > 0

    def _solve(self, A, b, rtol, options, PETSc):
        """One set-up with these PCBDDC options and its CG: (x, iterations, converged reason)."""
        t = time.perf_counter()
        n = A.shape[0]
        prefix = f"wcs_bddc{next(_PREFIX)}_"
        opts = PETSc.Options()
        for key, value in options.items():
            opts[prefix + key] = value
        lg = PETSc.LGMap().create(np.concatenate(self.dofs).astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        M = PETSc.Mat().create(comm=PETSc.COMM_SELF)
        M.setSizes((n, n))
        M.setType("is")
        M.setISAllowRepeated(True)
        M.setLGMap(lg, lg)
        local = _aij(sp.block_diag(self.local, format="csr"), PETSc)
        M.setISLocalMat(local)
        M.assemble()
        vecs = []
        if self.N is not None and self.N.shape[1]:
            Q = np.linalg.qr(np.asarray(self.N, dtype=float))[0]
            vecs = [PETSc.Vec().createWithArray(Q[:, j].copy(), comm=PETSc.COMM_SELF) for j in range(Q.shape[1])]
            M.setNearNullSpace(PETSc.NullSpace().create(vectors=vecs, comm=PETSc.COMM_SELF))
        Aa = _aij(A, PETSc)
        ksp = PETSc.KSP().create(PETSc.COMM_SELF)
        ksp.setOptionsPrefix(prefix)
        ksp.setType("cg")
        ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        ksp.getPC().setType("bddc")
        held = self.components[np.concatenate(self.dofs)]
        fields = [PETSc.IS().createGeneral(np.flatnonzero(held == k).astype(PETSc.IntType), comm=PETSc.COMM_SELF)
                  for k in np.unique(held)]
        ksp.getPC().setBDDCDofsSplittingLocal(fields)
        ksp.setOperators(Aa, M)
        ksp.setTolerances(rtol=rtol, atol=0.0, max_it=MAX_IT)
        ksp.setFromOptions()
        try:
            ksp.setUp()
            self.timings["bddc_setup"] += time.perf_counter() - t
            t = time.perf_counter()
            x, rhs = Aa.createVecs()
            rhs.setArray(np.asarray(b, dtype=float))
            ksp.solve(rhs, x)
            reason = ksp.getConvergedReason()
            its = ksp.getIterationNumber()
            out = x.getArray().copy()
            x.destroy()
            rhs.destroy()
            self.timings["cg"] += time.perf_counter() - t
            return out, its, reason
        finally:
            for o in (ksp, Aa, M, local, lg, *vecs, *fields):
                o.destroy()
            for key in options:
                del opts[prefix + key]
