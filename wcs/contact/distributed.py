"""The Krylov solves of the iterative contact method spread by rows over the ranks of a group
(`solver.ranks_per_evaluation`, `wcs.group.spanning`).

Every rank of the group holds the same replicated data (the model, the Newton step's reduced
operator A and right-hand side b); rank r owns the contiguous rows `rows(n, size, r)` of A,
of the vectors and of the near-nullspace, as PETSc's MatMPIAIJ / VecMPI on the group's
communicator, so CG and GAMG run on the group. The answer is gathered to every rank
(`gather`): the active-set logic then acts on identical bits on every rank of the group and
takes the same decisions. With one rank (`comm` None) these are the sequential objects. A
rank that fails building its rows raises on every rank of the group (`wcs.group.together`)
before PETSc's collective assembly.
"""
from __future__ import annotations

import numpy as np

from wcs.group import rows, together


class RowBlocks:
    """An n × n matrix given by the function `rows(lo, hi)` of its rows lo:hi (scipy CSR), so
    that each rank builds only its share."""

    def __init__(self, n: int, rows):
        self.shape, self.rows = (n, n), rows


class Layout:
    """The row split of n unknowns over `comm` (an mpi4py communicator; None: one process), in
    whole blocks of `block` consecutive unknowns (a node's: PETSc's block size)."""

    def __init__(self, comm, n: int, PETSc, block: int = 1):
        self.comm, self.n, self.block = comm, n, block
        self.petsc = PETSc.COMM_SELF if comm is None else PETSc.Comm(comm)
        size, rank = (1, 0) if comm is None else (comm.size, comm.rank)
        starts = [block * rows(n // block, size, r)[0] for r in range(size)]
        self.counts = np.diff(starts + [n])     # rows of each rank
        self.lo, self.hi = starts[rank], n if rank == size - 1 else starts[rank + 1]

    def matrix(self, A, PETSc):
        """The SPD A (scipy CSR, replicated, or `RowBlocks`) as a PETSc AIJ matrix holding this rank's rows
        (on one process PETSc's matrix is these rows' own arrays, kept alive by it: no second copy)."""
        if isinstance(A, RowBlocks):
            A = together(A.rows, self.lo, self.hi)
        elif (self.lo, self.hi) != (0, self.n):
            A = A[self.lo:self.hi].tocsr()
        A.sort_indices()
        m = self.hi - self.lo
        M = PETSc.Mat().createAIJWithArrays(size=((m, self.n), (m, self.n)),
                                            csr=(A.indptr.astype(PETSc.IntType, copy=False),
                                                 A.indices.astype(PETSc.IntType, copy=False), A.data),
                                            comm=self.petsc)
        M.setBlockSize(self.block)      # (createAIJWithArrays' own bsize is not applied)
        M.setOption(PETSc.Mat.Option.SPD, True)
        return M

    def vector(self, x, PETSc):
        """This rank's part of the replicated x as a PETSc vector (a copy)."""
        return PETSc.Vec().createWithArray(np.array(x[self.lo:self.hi], dtype=float), size=(self.hi - self.lo, self.n),
                                           comm=self.petsc)

    def gather(self, local: np.ndarray) -> np.ndarray:
        """The whole vector on every rank from each rank's rows (the same bits everywhere)."""
        if self.comm is None:
            return local.copy()
        out = np.empty(self.n)
        self.comm.Allgatherv(np.ascontiguousarray(local, dtype=float), [out, self.counts])
        return out
