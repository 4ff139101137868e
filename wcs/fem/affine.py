"""Parameter-affine P1 operators: K(c) = Σ_cells c[group(cell)] · K_cell, assembled once.

The cell matrices of every piece are computed once (P1: exact, one point);
a new coefficient table costs one weighted scatter into a fixed pattern
(O(cells), no quadrature), and every K(c) has the same CSR pattern so a
sparse factorization reuses its symbolic analysis.

Cells are triangles (p of shape (2, n)) or tetrahedra (p of shape (3, n), `wcs.geometry.tet`).
Vector fields use d×d node blocks (dof = d·node + component, scikit-fem's
order for ElementVector(ElementTriP1 / ElementTetP1)): the pattern is built on node pairs
(9 per triangle, 16 per tetrahedron) and expanded through a block-sparse (BSR) matrix.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..geometry import tet
from ..group import evaluation_comm, rows, share, together
from .stress import gradient_operator


def gradients(p: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ncells, n, d) gradients ∇N_a of the P1 shape functions and (ncells,) cell measures:
    triangles in 2D, tetrahedra in 3D (the dimension is p's first axis)."""
    if p.shape[0] == 3:
        return tet.gradient_operator(p, t)
    (dx, dy), area = gradient_operator(p, t)
    return np.stack([dx, dy], axis=-1), area


def elastic_cell_matrices(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(2, ncells, n, n, d, d): the λ-piece |T| div φ_a div φ_b and the μ-piece
    |T| 2 e(φ_a) : e(φ_b), by node pair (a, b) and components (i, j)."""
    return _elastic_pieces(*gradients(p, t))


def _elastic_pieces(g: np.ndarray, area: np.ndarray) -> np.ndarray:
    """`elastic_cell_matrices` from the cells' gradients (ncells, n, d) and measures."""
    nc, n, d = g.shape
    a = area[:, None, None, None, None]
    out = np.empty((2, nc, n, n, d, d))                       # written in place: no stacked copy
    np.multiply(a * g[:, :, None, :, None], g[:, None, :, None, :], out=out[0])
    # 2 e(φ_ai):e(φ_bj) = δ_ij ∇N_a·∇N_b + ∂_j N_a ∂_i N_b, added in place component by component
    # (no temporary of the pieces' size: 25 MB at 8.6e4 cells); δ_ij ∇N_a·∇N_b also where i ≠ j,
    # as the ±0 it is there, so that the sums are the same to the bit
    np.multiply(g[:, :, None, None, :], g[:, None, :, :, None], out=out[1])
    dot = np.einsum("eak,ebk->eab", g, g)
    for i in range(d):
        for j in range(d):
            out[1, ..., i, j] += dot * (i == j)
    out[1] *= a
    return out


def conduction_cell_matrices(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(1, ncells, n, n, 1, 1): |T| ∇N_a · ∇N_b."""
    return _conduction_pieces(*gradients(p, t))


def _conduction_pieces(g: np.ndarray, area: np.ndarray) -> np.ndarray:
    """`conduction_cell_matrices` from the cells' gradients and measures."""
    dot = g[:, :, None, 0] * g[:, None, :, 0]
    for i in range(1, g.shape[2]):                            # in order: the 2D bits are kept
        dot = dot + g[:, :, None, i] * g[:, None, :, i]
    k = area[:, None, None] * dot
    return k[None, :, :, :, None, None]


class CellMatrices:
    """The cell matrices (npieces, ncells, n, n, b, b) of an affine operator, made for the cells
    asked (`of`) from the cells' P1 gradients and measures, which are all it holds: elasticity's
    matrices held take 2.3 kB a tetrahedron (4.1 GB of the 1.8e6 at 1e6 unknowns), the gradients
    104 bytes. The same arithmetic cell by cell as `elastic_cell_matrices`: the same bits."""

    def __init__(self, p: np.ndarray, t: np.ndarray, pieces):
        self.g, self.measure = gradients(p, t)
        self._pieces = pieces
        probe = pieces(self.g[:0], self.measure[:0])
        self.npieces, self.block = probe.shape[0], probe.shape[-1]

    def of(self, cells) -> np.ndarray:
        """(npieces, len(cells), n, n, b, b) for an index array or a slice of cells."""
        return self._pieces(self.g[cells], self.measure[cells])


class HeldCells:
    """Cell matrices given as an array (npieces, ncells, n, n, b, b), held (`CellMatrices`' protocol)."""

    def __init__(self, local: np.ndarray):
        self.local = np.asarray(local)
        self.npieces, self.block = self.local.shape[0], self.local.shape[-1]

    def of(self, cells) -> np.ndarray:
        return self.local[:, cells]


def elastic_cells(p: np.ndarray, t: np.ndarray) -> CellMatrices:
    """Elasticity's cell matrices on demand (`elastic_cell_matrices`)."""
    return CellMatrices(p, t, _elastic_pieces)


def conduction_cells(p: np.ndarray, t: np.ndarray) -> CellMatrices:
    """Conduction's cell matrices on demand (`conduction_cell_matrices`)."""
    return CellMatrices(p, t, _conduction_pieces)


CHUNK = 4096        # cells whose matrices are made at once (elasticity: 9.4 MB, with their weighted sum 4.7 MB)


def chunks(ncells: int):
    """Consecutive slices of at most CHUNK cells covering range(ncells)."""
    return [slice(s, min(s + CHUNK, ncells)) for s in range(0, ncells, CHUNK)]


class CellAffineOperator:
    """K(c) = Σ_k Σ_cells c[group(cell), k] · local[k, cell]; `local` a `CellMatrices` (made
    chunk by chunk, `chunks`) or an array of them."""

    def __init__(self, t: np.ndarray, nnodes: int, local, group: np.ndarray):
        self.local = local if isinstance(local, (CellMatrices, HeldCells)) else HeldCells(local)
        self._t = np.asarray(t)
        self.group = np.asarray(group)
        self.block = self.local.block
        n, nc = t.shape                                       # n nodes per cell
        rows = np.repeat(t.T, n, axis=1).ravel().astype(np.int64)   # (nc·n²,) node a
        cols = np.tile(t.T, (1, n)).ravel().astype(np.int64)        # node b
        nodes = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(nnodes, nnodes))
        nodes.sum_duplicates()                                 # sorted node-pair pattern
        number = sp.csr_array((np.arange(nodes.nnz), nodes.indices, nodes.indptr), shape=nodes.shape)
        self.position = number[rows, cols]                     # each pair's place in it (a per-row lookup)
        if nodes.nnz < 2**31:                                  # 64 bytes a tetrahedron instead of 128
            self.position = self.position.astype(np.int32)
        self.indptr, self.indices = nodes.indptr, nodes.indices
        self.nblocks = nodes.nnz
        self.shape = (self.block * nnodes,) * 2
        self.ncells = nc

    @property
    def npieces(self) -> int:
        return self.local.npieces

    def pattern(self) -> sp.csr_matrix:
        """The sorted CSR pattern every K(c) has, with zero values (no assembly)."""
        b = self.block
        K = sp.bsr_matrix((np.zeros((self.nblocks, b, b)), self.indices, self.indptr), shape=self.shape).tocsr()
        K.sort_indices()
        return K

    def __call__(self, coefficients) -> sp.csr_matrix:
        """`coefficients`: (ngroups, npieces) — e.g. per region (λ, μ). The cells' terms are
        summed into each entry in cell order, chunk after chunk (`np.add.at` adds in order, as
        one `np.bincount` over all cells would). Spanning a group of ranks (`wcs.group`), each
        rank sums the entries of its share of the node rows only, from the cells that touch them,
        and the group gathers them: every entry the same sum in the same order, so K(c) has the
        same bits on every layout."""
        c = np.asarray(coefficients, dtype=float).reshape(-1, self.npieces)[self.group]   # (nc, npieces)
        lo, hi = (int(self.indptr[i]) for i in share(len(self.indptr) - 1))    # this rank's node pairs
        data = together(self._entries, c, lo, hi)
        comm = evaluation_comm()
        if comm is not None:
            counts = np.diff([self.indptr[rows(len(self.indptr) - 1, comm.size, r)[0]] for r in range(comm.size)]
                             + [self.nblocks]) * self.block ** 2
            whole = np.empty((self.nblocks, self.block, self.block))
            comm.Allgatherv(data, [whole, counts])
            data = whole
        K = sp.bsr_matrix((data, self.indices, self.indptr), shape=self.shape).tocsr()
        K.sort_indices()
        return K

    def _entries(self, c: np.ndarray, lo: int, hi: int) -> np.ndarray:
        """(hi − lo, b, b): the node-pair blocks lo:hi of K(c), the cells' coefficients c (nc, npieces)."""
        b, n = self.block, self._t.shape[0]
        data = np.zeros((hi - lo, b, b))
        for cells in chunks(self.ncells):
            position = self.position[cells.start * n * n:cells.stop * n * n]
            if (lo, hi) == (0, self.nblocks):
                cell = np.einsum("ek,keabij->eabij", c[cells], self.local.of(cells)).reshape(-1, b, b)
            else:                   # the chunk's cells with a term in the blocks lo:hi, and those terms
                mine = ((position >= lo) & (position < hi)).reshape(-1, n * n)
                which = cells.start + np.flatnonzero(mine.any(axis=1))
                keep = mine[which - cells.start].ravel()
                cell = np.einsum("ek,keabij->eabij", c[which], self.local.of(which)).reshape(-1, b, b)[keep]
                position = position.reshape(-1, n * n)[which - cells.start].ravel()[keep] - lo
            for i in range(b):
                for j in range(b):
                    np.add.at(data[:, i, j], position, cell[:, i, j])
        return data

    def apply(self, coefficients, x: np.ndarray) -> np.ndarray:
        """K(c) x without assembling K(c): summed over the cells on which x is not zero only
        (for a support's displacement, the cells along the support)."""
        b = self.block
        X = np.asarray(x, dtype=float).reshape(-1, b)[self._t.T]                 # (nc, n, b)
        cells = np.flatnonzero(X.reshape(X.shape[0], -1).any(axis=1))
        c = np.asarray(coefficients, dtype=float).reshape(-1, self.npieces)[self.group[cells]]
        y = np.einsum("ek,keabij,ebj->eai", c, self.local.of(cells), X[cells], optimize=True)
        dofs = b * self._t[:, cells].T[:, :, None] + np.arange(b)                  # (cells, n, b)
        return np.bincount(dofs.ravel(), weights=y.ravel(), minlength=self.shape[0])

    def sensitivities(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(ngroups, npieces): Σ over the cells of each group of a_cellᵀ K^k_cell b_cell, i.e.
        the derivative of aᵀ K(c) b with respect to each coefficient (K is affine in c)."""
        bl = self.block
        t = self._t
        ae = np.asarray(a).reshape(-1, bl)[t.T]              # (nc, n, b)
        be = np.asarray(b).reshape(-1, bl)[t.T]
        per_cell = np.concatenate([np.einsum("keabij,eai,ebj->ek", self.local.of(s), ae[s], be[s])
                                   for s in chunks(self.ncells)])
        ngroups = int(self.group.max()) + 1
        return np.array([np.bincount(self.group, weights=per_cell[:, k], minlength=ngroups)
                         for k in range(self.npieces)]).T
