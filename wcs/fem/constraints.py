"""Nodal linear constraints a · u(node) = c eliminated by a change of basis.

u = T w + U0 c: `T` spans the free directions (a Dirichlet component removes
one axis, a roller `u · n = c` removes the normal and keeps the tangent, two
independent constraints fix the node), `U0` maps the prescribed values `c`
to the displacement they impose. Both depend only on geometry, so the
reduced operators Tᵀ K T stay affine in the data and keep one pattern.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True)
class Constraint:
    nodes: np.ndarray        # (k,) node ids
    directions: np.ndarray   # (k, ncomp) unit vectors a
    value: int               # index of the prescribed value c in the value vector


@dataclass(frozen=True)
class Elimination:
    T: sp.csr_matrix         # (ndof, nfree)
    U0: sp.csr_matrix        # (ndof, nvalues)
    fixed_dofs: np.ndarray   # dofs with no free direction left (for reporting)

    def expand(self, w: np.ndarray, values: np.ndarray) -> np.ndarray:
        return self.T @ w + self.U0 @ values


def eliminate(nnodes: int, ncomp: int, constraints: list[Constraint], nvalues: int) -> Elimination:
    """Build T and U0 for constraints on the node-interleaved dofs (dof = ncomp·node + comp)."""
    rows_of: dict[int, list[tuple[np.ndarray, int]]] = {}
    for c in constraints:
        for node, a in zip(c.nodes.tolist(), c.directions):
            rows_of.setdefault(node, []).append((np.asarray(a, float), c.value))

    T_rows, T_cols, T_vals = [], [], []
    U_rows, U_cols, U_vals = [], [], []
    fixed = []
    ncols = 0
    constrained = np.zeros(nnodes, bool)
    of_matrix: dict[bytes, tuple] = {}    # one SVD per distinct A (a support's nodes share theirs)
    for node in sorted(rows_of):
        constrained[node] = True
        A = np.array([a for a, _ in rows_of[node]])
        idx = [v for _, v in rows_of[node]]
        key = A.tobytes()
        if key not in of_matrix:
            _, s, vt = np.linalg.svd(A)
            rank = int(np.sum(s > 1e-8 * s[0]))
            # u_c = A⁺ c (consistent data: exact); vt[rank:]: the orthonormal free directions
            of_matrix[key] = rank, np.linalg.pinv(A, rcond=1e-8), vt[rank:]
        rank, pinv, free = of_matrix[key]
        for comp in range(ncomp):
            for j, v in enumerate(idx):
                if pinv[comp, j] != 0.0:
                    U_rows.append(ncomp * node + comp); U_cols.append(v); U_vals.append(pinv[comp, j])
        for t in free:
            for comp in range(ncomp):
                if t[comp] != 0.0:
                    T_rows.append(ncomp * node + comp); T_cols.append(ncols); T_vals.append(t[comp])
            ncols += 1
        if rank == ncomp:
            fixed.extend(ncomp * node + np.arange(ncomp))
    # unconstrained nodes: identity columns, in dof order after the constrained ones' columns
    free_nodes = np.flatnonzero(~constrained)
    dofs = (ncomp * free_nodes[:, None] + np.arange(ncomp)).ravel()
    rows = np.concatenate([np.array(T_rows, dtype=np.int64), dofs])
    cols = np.concatenate([np.array(T_cols, dtype=np.int64), np.arange(ncols, ncols + dofs.size)])
    vals = np.concatenate([np.array(T_vals, dtype=float), np.ones(dofs.size)])
    ndof = ncomp * nnodes
    T = sp.csr_matrix((vals, (rows, cols)), shape=(ndof, ncols + dofs.size))
    T = _order_columns_by_dof(T)
    U0 = sp.csr_matrix((U_vals, (U_rows, U_cols)), shape=(ndof, nvalues))
    return Elimination(T=T, U0=U0, fixed_dofs=np.array(sorted(fixed), dtype=np.int64))


def _order_columns_by_dof(T: sp.csr_matrix) -> sp.csr_matrix:
    """Number the free unknowns in the order of their first dof: keeps the reduced matrix banded like K."""
    Tc = T.tocsc()
    Tc.sort_indices()
    first = Tc.indices[Tc.indptr[:-1]]            # every column has at least one entry
    return sp.csr_matrix(Tc[:, np.argsort(first, kind="stable")])


PRODUCTS_CHUNK = 1 << 16       # entries of K (or of the pattern) handled at once (`_products`, `Reduction`)


def _unit_columns(T: sp.csr_matrix) -> np.ndarray:
    """(ndof,) for each row of T that is a unit row e_i whose column i has no other entry (a dof
    no support or glue touches), that column i; −1 for every other row."""
    count = np.diff(T.indptr)
    first = np.minimum(T.indptr[:-1], max(T.nnz - 1, 0))
    col = T.indices[first].astype(np.int64) if T.nnz else np.zeros(T.shape[0], dtype=np.int64)
    alone = np.bincount(T.indices, minlength=T.shape[1]) == 1
    unit = (count == 1) & (T.data[first] == 1.0) & alone[col] if T.nnz else np.zeros(T.shape[0], bool)
    return np.where(unit, col, -1)


def _chunks(size: int) -> list[slice]:
    """Consecutive slices of at most PRODUCTS_CHUNK covering range(size)."""
    return [slice(lo, min(lo + PRODUCTS_CHUNK, size)) for lo in range(0, size, PRODUCTS_CHUNK)]


def _rows(K: sp.csr_matrix, e) -> np.ndarray:
    """The rows of K's entries e: an increasing index array, or a nonempty slice."""
    if isinstance(e, slice):
        lo, hi = np.searchsorted(K.indptr, [e.start, e.stop - 1], side="right") - 1
        ptr = np.clip(K.indptr[lo:hi + 2], e.start, e.stop)
        return np.repeat(np.arange(lo, hi + 1), np.diff(ptr))
    return np.searchsorted(K.indptr, e, side="right") - 1


def _unit_keys(K: sp.csr_matrix, col: np.ndarray, unit: np.ndarray, n: int):
    """The keys col[k]·n + col[l] of K's unit entries (`unit`) with the entries, in increasing
    order of key, PRODUCTS_CHUNK entries at a time: in the order of K's entries where T's
    columns are numbered by first dof (`_order_columns_by_dof`: col increases with k), else
    sorted here."""
    def made(c):
        e = c.start + np.flatnonzero(unit[c])
        return col[_rows(K, e)] * n + col[K.indices[e]], e
    chunks = _chunks(K.nnz)
    last, ordered = -1, True
    for c in chunks:
        key = made(c)[0]
        if key.size:
            ordered &= bool(key[0] > last) and bool(np.all(key[1:] > key[:-1]))
            last = key[-1]
        if not ordered:
            break
    if ordered:
        return map(made, chunks)
    key, e = (np.concatenate(a) for a in zip(*map(made, chunks)))
    order = np.argsort(key)
    key, e = key[order], e[order]
    return ((key[c], e[c]) for c in _chunks(key.size))


def _products(K: sp.csr_matrix, T: sp.csr_matrix, which: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The terms T_ki K_kl T_lj of Tᵀ K T of the entries e = (k, l) of K in `which` (increasing;
    K, T sorted CSR), entry by entry: for each, the key i·n + j of the entry of Tᵀ K T it adds to,
    its weight T_ki T_lj and e. Made PRODUCTS_CHUNK entries at a time into the three results,
    so that only those outlive a chunk."""
    count = np.diff(T.indptr)
    start = T.indptr[:-1]
    rows = _rows(K, which)
    chunks = _chunks(which.size)
    sizes = [int((count[rows[c]] * count[K.indices[which[c]]]).sum()) for c in chunks]
    total = sum(sizes)
    keys = np.empty(total, dtype=np.int64)
    weights = np.empty(total)
    e_all = np.empty(total, dtype=np.int32 if K.nnz < 2**31 else np.int64)
    at = 0
    for c, size in zip(chunks, sizes):
        k, l = rows[c], K.indices[which[c]]
        nl = count[l]
        rep = count[k] * nl                               # nnz(T_k) · nnz(T_l) terms per entry
        e = np.repeat(np.arange(c.stop - c.start), rep)
        ptr = np.zeros(c.stop - c.start + 1, dtype=np.int64)
        np.cumsum(rep, out=ptr[1:])
        r, q = np.divmod(np.arange(e.size) - ptr[e], nl[e])
        a, b = start[k][e] + r, start[l][e] + q
        keys[at:at + size] = T.indices[a].astype(np.int64) * T.shape[1] + T.indices[b]
        weights[at:at + size] = T.data[a] * T.data[b]
        e_all[at:at + size] = which[c][e]
        at += size
    return keys, weights, e_all


class Reduction:
    """Tᵀ K T on one structural pattern, as a fixed linear map of K's values.

    A sparse product drops entries that happen to vanish for some data, so its
    pattern — and a factorization's ordering — would depend on the data. Here the
    pattern is built once from the structure of K and T, and Kr.data = M @ K.data
    (each entry K_kl contributes T_ki T_lj to Kr_ij: M has nnz(T_k) · nnz(T_l)
    entries per entry of K — up to four for supports, more where mortar gluing ties a
    slave dof to several master dofs). Every Kr shares the pattern's index arrays (read-only:
    one copy of the structure however many Kr are alive).

    Held: most entries of Tᵀ K T are one entry of K with weight 1 (an entry K_kl whose rows
    k and l of T are unit rows e_i, e_j of columns with no other entry — the dofs no support or
    glue touches — is the one term of Kr_ij), and M's row there sums 0 + 1·K_kl; those rows are
    kept as the index of their entry of K (`source`, 4 bytes an entry, not M's 12–16), and M
    only for the other rows (`rest`): the same sums, the same bits. Only the other entries' terms
    are enumerated and sorted; the unit entries are placed by their keys i·n + j, made a chunk at
    a time (a byte an entry of K beside the results while the pattern is built; the terms of every
    entry, made and sorted at once, took 70: 1.06 GB against 0.30 GB traced at 6.3e5 unknowns).
    K's structure is checked by its row pointers and a CRC-32 of its column indices (a copy of
    them took 4 bytes an entry of K)."""

    def __init__(self, K: sp.csr_matrix, T: sp.csr_matrix):
        K = sp.csr_matrix(K)
        K.sort_indices()
        T = sp.csr_matrix(T)
        T.sort_indices()
        self.K_indptr, self.K_nnz, self.K_crc = K.indptr.copy(), K.nnz, _crc(K.indices)
        n = T.shape[1]
        col = _unit_columns(T)
        unit = np.empty(K.nnz, dtype=bool)
        per_row = np.zeros(K.shape[0], dtype=np.int64)       # unit entries in each row of K
        for c in _chunks(K.nnz):
            r = _rows(K, c)
            np.logical_and(col[r] >= 0, col[K.indices[c]] >= 0, out=unit[c])
            per_row[r[0]:r[-1] + 1] += np.bincount(r[unit[c]] - r[0], minlength=r[-1] - r[0] + 1)
        # the other entries' terms by key (stable: each key's terms by increasing e, as M's CSR stores them)
        keys, weights, e = _products(K, T, np.flatnonzero(~unit))
        order = np.argsort(keys, kind="stable")
        keys, weights, e = keys[order], weights[order], e[order]
        del order
        new = np.r_[True, keys[1:] != keys[:-1]] if keys.size else np.zeros(0, bool)
        ptr = np.r_[np.flatnonzero(new), keys.size]
        other = keys[new]                                   # their entries of Tᵀ K T, increasing
        self.M = sp.csr_matrix((weights, e, ptr), shape=(other.size, K.nnz))
        # each unit entry K_kl is the one term of its own entry of Tᵀ K T (of no other entry's):
        # placed by its key i·n + j among the others' keys
        size = other.size + int(per_row.sum())
        index = np.int32 if max(size, n) < 2**31 else np.int64
        self.source = np.empty(size, dtype=np.int32 if K.nnz < 2**31 else np.int64)
        self.indices = np.empty(size, dtype=index)
        # unit keys below each other key: counted where a chunk's keys span it, else a step at the chunk's end
        below, step = np.zeros(other.size, dtype=np.int64), np.zeros(other.size + 1, dtype=np.int64)
        done = 0
        for key, entry in _unit_keys(K, col, unit, n):
            if not key.size:
                continue
            at = done + np.arange(key.size) + np.searchsorted(other, key)
            self.source[at] = entry
            self.indices[at] = key % n
            lo, hi = np.searchsorted(other, [key[0], key[-1]], side="right")    # the others within the chunk's keys
            below[lo:hi] += np.searchsorted(key, other[lo:hi])
            step[hi] += key.size
            done += key.size
        self.rest = np.arange(other.size) + below + np.cumsum(step[:-1])
        self.source[self.rest] = e[ptr[:-1]]               # in range; M's rows overwrite these
        self.indices[self.rest] = other % n
        count = np.bincount(other // n, minlength=n)        # entries in each row of Tᵀ K T
        count[col[col >= 0]] += per_row[col >= 0]
        self.indptr = np.r_[0, np.cumsum(count)].astype(index)
        self.indices.flags.writeable = self.indptr.flags.writeable = False
        self.shape, self.nnz = (n, n), size

    @property
    def pattern(self) -> sp.csr_matrix:
        """The structural pattern of Tᵀ K T with zero values (made when asked: its values took 8
        bytes an entry held), over the index arrays every Kr shares."""
        return sp.csr_matrix((np.zeros(self.nnz), self.indices, self.indptr), shape=self.shape)

    def __call__(self, K: sp.csr_matrix) -> sp.csr_matrix:
        K = sp.csr_matrix(K)
        K.sort_indices()
        if not (K.nnz == self.K_nnz and np.array_equal(K.indptr, self.K_indptr) and _crc(K.indices) == self.K_crc):
            raise ValueError("K does not have the structural pattern the reduction was built for")
        data = K.data[self.source]
        data += 0.0                     # M's row sums 0 + 1·K_kl: −0 becomes +0 there too
        data[self.rest] = self.M @ K.data
        return sp.csr_matrix((data, self.indices, self.indptr), shape=self.shape)


def _crc(a: np.ndarray) -> int:
    """CRC-32 of an array's bytes (and its dtype)."""
    return zlib.crc32(np.ascontiguousarray(a).view(np.uint8), zlib.crc32(a.dtype.str.encode()))
