"""BDDC preconditioner of the Newton steps' operators (`solver.iterative.preconditioner: bddc`).

Balancing domain decomposition by constraints (PETSc's PCBDDC) needs each subdomain's own
(Neumann) stiffness matrix, not only the assembled one: K = Σ_s R_sᵀ K_s R_s, K_s assembled
over the cells of subdomain s, R_s the restriction to its dofs. A Newton step's operator is
Zᵀ K Z plus the diagonal of K on the eliminated pivots P (`wcs.contact.iterative._eliminated`);
where every row of Z that a subdomain holds refers to that subdomain's dofs only (Z is
node-local: a node's pivots are eliminated by its own unknowns), Zᵀ K Z = Σ_s R_sᵀ Z_sᵀ K_s Z_s R_s
with Z_s = R_s Z R_sᵀ, and diag(K)_P = Σ_s diag(K_s)_P: each subdomain's part of the step is
its own matrix transformed by its own part of Z (`local_step`). The interface dofs are held by
several subdomains: that is MATIS's local-to-global map with repeated entries, so all
subdomains of this process are one local matrix (block diagonal, `setISAllowRepeated`).

Constraints: vertices, edge and face averages of each displacement component, imposed by a
change of basis (PCBDDC's `use_change_of_basis`, `use_change_on_faces`; without it the floating
subdomains' Neumann matrices are singular and the local LU fails), with the rigid-body modes as
the matrices' near-nullspace.
"""
from __future__ import annotations

import itertools
import time

import numpy as np
import scipy.sparse as sp

OPTIONS = {"pc_bddc_use_faces": "true", "pc_bddc_use_change_of_basis": "true",
           "pc_bddc_use_change_on_faces": "true"}
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


def subdomain_dofs(cell_dofs: np.ndarray, part: np.ndarray) -> list[np.ndarray]:
    """The sorted dofs of each part's cells (cell_dofs: (dofs per cell, cells))."""
    return [np.unique(cell_dofs[:, part == s]) for s in range(int(part.max()) + 1)]


def local_step(K_s: sp.spmatrix, dofs: np.ndarray, Z: sp.spmatrix, P: np.ndarray) -> sp.csr_matrix:
    """Z_sᵀ K_s Z_s + diag(K_s) on the pivots P the subdomain holds (module docstring); K_s the
    subdomain's matrix on its dofs. ValueError where a row of Z on these dofs refers to
    another subdomain's dofs (the step's elimination is not local to the subdomain)."""
    Zr = sp.csr_matrix(Z)[dofs]
    Zr.eliminate_zeros()
    Z_s = Zr[:, dofs]
    if Z_s.nnz != Zr.nnz:
        raise ValueError("the contact elimination couples a subdomain's dofs to another subdomain's")
    held = np.flatnonzero(np.isin(dofs, P))
    d = sp.csr_matrix((sp.csr_matrix(K_s).diagonal()[held], (held, held)), shape=K_s.shape)
    return (Z_s.T @ K_s @ Z_s + d).tocsr()


def _aij(A, PETSc):
    A = sp.csr_matrix(A)
    return PETSc.Mat().createAIJ(A.shape, csr=(A.indptr.astype(PETSc.IntType), A.indices.astype(PETSc.IntType),
                                                A.data), comm=PETSc.COMM_SELF)


class Bddc:
    """CG on the assembled operator A preconditioned by BDDC of its subdomain matrices (this
    process holds all subdomains). dofs: each subdomain's dofs; local: each subdomain's part of
    A (`local_step`, Σ_s R_sᵀ local_s R_s = A); near_nullspace: (n, r) rigid modes; block: dofs
    per node (the components PCBDDC constrains separately)."""

    def __init__(self, dofs, local, near_nullspace=None, block: int = 1):
        self.dofs, self.local, self.N, self.block = dofs, local, near_nullspace, block
        self.timings = {"bddc_setup": 0.0, "cg": 0.0}

    def solve(self, A: sp.csr_matrix, b: np.ndarray, rtol: float):
        """x with ‖b − A x‖ ≤ rtol ‖b‖ (unpreconditioned norm): (x, iterations, converged)."""
        import dolfinx_solver  # noqa: F401  (loads the PETSc libraries petsc4py binds to)
        from petsc4py import PETSc
        t = time.perf_counter()
        n = A.shape[0]
        prefix = f"wcs_bddc{next(_PREFIX)}_"
        opts = PETSc.Options()
        for key, value in OPTIONS.items():
            opts[prefix + key] = value
        lg = PETSc.LGMap().create(np.concatenate(self.dofs).astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        M = PETSc.Mat().create(comm=PETSc.COMM_SELF)
        M.setSizes((n, n))
        M.setBlockSize(self.block)
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
            ok = ksp.getConvergedReason() > 0
            its = ksp.getIterationNumber()
            out = x.getArray().copy()
            x.destroy()
            rhs.destroy()
            self.timings["cg"] += time.perf_counter() - t
            return out, its, ok
        finally:
            for o in (ksp, Aa, M, local, lg, *vecs):
                o.destroy()
            for key in OPTIONS:
                del opts[prefix + key]
