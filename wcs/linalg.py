"""Sparse direct factorizations with reusable analysis.

`factorize(A)` returns a `Factor` with `.solve(b)` (b of shape (n,) or (n, k))
and `.refactor(A_new)` for a matrix with the same sparsity pattern (the
symbolic analysis is reused where the backend allows it).

Backends: PARDISO through pypardiso (MKL, fast; x86_64 wheels) and scipy's
SuperLU tuned for symmetric matrices (portable fallback). `WCS_SOLVER=superlu`
forces the fallback.
"""
from __future__ import annotations

import os

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

try:  # pragma: no cover - depends on the platform
    import pypardiso as _pardiso
except Exception:  # noqa: BLE001 - any import failure means: no PARDISO here
    _pardiso = None


def backend() -> str:
    if os.environ.get("WCS_SOLVER", "").lower() == "superlu" or _pardiso is None:
        return "superlu"
    return "pardiso"


class SuperLUFactor:
    name = "superlu"

    def __init__(self, A: sp.spmatrix):
        self.refactor(A)

    def refactor(self, A: sp.spmatrix) -> "SuperLUFactor":
        A = sp.csc_matrix(A)
        self.n = A.shape[0]
        self._lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                             options={"SymmetricMode": True})
        return self

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.asarray(b, dtype=float))


class PardisoFactor:
    """PARDISO with the phases called directly: analysis once, numeric refactor per matrix."""

    name = "pardiso"

    def __init__(self, A: sp.spmatrix, mtype: int = 11):
        self._s = _pardiso.PyPardisoSolver(mtype=mtype)
        self._s.set_statistical_info_off()
        A = self._prep(A)
        self._pattern = (A.indptr.copy(), A.indices.copy())
        self._s._check_A(A) if hasattr(self._s, "_check_A") else None
        self._s.set_phase(12)  # analysis + numeric factorization
        self._s._call_pardiso(A, np.zeros((A.shape[0], 1)))
        self._A = A

    @staticmethod
    def _prep(A):
        A = sp.csr_matrix(A, dtype=np.float64)
        A.sort_indices()
        return A

    def refactor(self, A: sp.spmatrix) -> "PardisoFactor":
        A = self._prep(A)
        same = (A.indptr.shape == self._pattern[0].shape and A.indices.shape == self._pattern[1].shape
                and np.array_equal(A.indptr, self._pattern[0]) and np.array_equal(A.indices, self._pattern[1]))
        self._s.set_phase(22 if same else 12)
        if not same:
            self._pattern = (A.indptr.copy(), A.indices.copy())
        self._s._call_pardiso(A, np.zeros((A.shape[0], 1)))
        self._A = A
        return self

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        one = b.ndim == 1
        B = np.asfortranarray(b.reshape(b.shape[0], -1))
        self._s.set_phase(33)
        x = self._s._call_pardiso(self._A, B)
        return x.ravel() if one else x

    def __del__(self):  # release PARDISO's memory
        try:
            self._s.free_memory(everything=True)
        except Exception:  # noqa: BLE001
            pass


def factorize(A: sp.spmatrix, kind: str | None = None):
    """Factor a square sparse matrix; `kind` overrides the backend choice."""
    kind = kind or backend()
    if kind == "pardiso":
        return PardisoFactor(A)
    return SuperLUFactor(A)


def solve(A: sp.spmatrix, b: np.ndarray) -> np.ndarray:
    return factorize(A).solve(b)
