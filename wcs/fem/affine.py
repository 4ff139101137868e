"""Parameter-affine sparse operators: K(c) = Σ_k c_k K_k on one fixed pattern.

Every piece is assembled once; a new coefficient vector costs one pass over
the nonzeros (no quadrature), and every combination shares one CSR pattern so
a sparse factorization can reuse its symbolic analysis.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class AffineOperator:
    def __init__(self, pieces: list[sp.spmatrix]):
        if not pieces:
            raise ValueError("an affine operator needs at least one piece")
        shape = pieces[0].shape
        csr = [sp.csr_matrix(p) for p in pieces]
        for p in csr:
            p.sum_duplicates()
            p.sort_indices()
        pattern = sum(abs(p) for p in csr).tocsr()
        pattern.sort_indices()
        pattern.data[:] = 0.0
        keys = self._keys(pattern)
        self.shape = shape
        self.pattern = pattern
        self.positions = [np.searchsorted(keys, self._keys(p)) for p in csr]
        self.values = [p.data.copy() for p in csr]

    @staticmethod
    def _keys(m: sp.csr_matrix) -> np.ndarray:
        rows = np.repeat(np.arange(m.shape[0], dtype=np.int64), np.diff(m.indptr))
        return rows * m.shape[1] + m.indices

    def __len__(self) -> int:
        return len(self.values)

    def data(self, coefficients) -> np.ndarray:
        out = np.zeros(self.pattern.nnz)
        for c, pos, val in zip(coefficients, self.positions, self.values):
            if c != 0.0:
                _scatter_add(out, pos, c * val)
        return out

    def __call__(self, coefficients) -> sp.csr_matrix:
        if len(coefficients) != len(self.values):
            raise ValueError(f"expected {len(self.values)} coefficients, got {len(coefficients)}")
        m = self.pattern.copy()
        m.data = self.data(coefficients)
        return m

    def transformed(self, T: sp.spmatrix) -> "AffineOperator":
        """The operator Tᵀ K(c) T (for eliminated constraints), again affine."""
        Tt = sp.csr_matrix(T.T)
        return AffineOperator([(Tt @ self.piece(k) @ T) for k in range(len(self))])

    def piece(self, k: int) -> sp.csr_matrix:
        m = self.pattern.copy()
        m.data = np.zeros(m.nnz)
        m.data[self.positions[k]] = self.values[k]
        return m


def _scatter_add(out: np.ndarray, pos: np.ndarray, val: np.ndarray) -> None:
    # positions within one piece are unique (the piece had its duplicates summed)
    out[pos] += val
