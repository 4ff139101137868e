"""Linear tetrahedra (P1 in 3D): shape-function gradients, strains, stresses and invariants.

Nodes are p (3, nnodes), cells t (4, ncells); a vector field is node-interleaved
(dof = 3·node + component, scikit-fem's order for ElementVector(ElementTetP1)).
Stress components are ordered (xx, yy, zz, yz, xz, xy):
τ = λ div u I + 2μ e − β ΔT I. The cell matrices of elasticity and conduction
are `wcs.fem.affine.elastic_cell_matrices` / `conduction_cell_matrices`, which
take tetrahedra through `gradient_operator` here.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

COMPONENTS = ("xx", "yy", "zz", "yz", "xz", "xy")
SHEAR_PAIRS = ((1, 2), (0, 2), (0, 1))          # (yz, xz, xy): the derivative pairs of γ


def gradient_operator(p: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ncells, 4, 3) gradients ∇N_a of the barycentric coordinates and (ncells,) volumes.

    With e_k = x_k − x_0, ∇N_1 = e_2×e_3 / D, ∇N_2 = e_3×e_1 / D, ∇N_3 = e_1×e_2 / D
    (the rows of the inverse Jacobian, D = e_1·(e_2×e_3) = 6·signed volume) and
    ∇N_0 = −(∇N_1 + ∇N_2 + ∇N_3)."""
    x = np.moveaxis(p[:, t], 0, -1)                           # (4, ncells, 3)
    e1, e2, e3 = x[1] - x[0], x[2] - x[0], x[3] - x[0]
    c1, c2, c3 = np.cross(e2, e3), np.cross(e3, e1), np.cross(e1, e2)
    det = np.einsum("ek,ek->e", e1, c1)
    g = np.stack([c1, c2, c3], axis=1) / det[:, None, None]
    return np.concatenate([-g.sum(axis=1, keepdims=True), g], axis=1), np.abs(det) / 6.0


def volumes(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(ncells,) cell volumes |T|."""
    return gradient_operator(p, t)[1]


def strain_operator(p: np.ndarray, t: np.ndarray) -> sp.csr_matrix:
    """G with (G u) reshaped (6, ncells) = (e_xx, e_yy, e_zz, γ_yz, γ_xz, γ_xy), γ_ij = 2 e_ij;
    u node-interleaved (3 per node).

    Built as sorted CSR directly (row c of each block holds cell c's dofs in increasing order:
    its nodes sorted, dof 3n + i before 3n + j), as a COO build with summed duplicates gives it,
    without its int64 triplets (36 a cell: 2.6 GB at 1.8e6 cells)."""
    g, _ = gradient_operator(p, t)
    nc = t.shape[1]
    order = np.argsort(t.T, axis=1)                           # (ncells, 4) the nodes by number
    dof = 3 * np.take_along_axis(t.T, order, axis=1)          # x-dof of each node, increasing
    g = np.take_along_axis(g, order[:, :, None], axis=1)
    index = np.int32 if 36 * nc < 2**31 else np.int64
    cols, vals = np.empty(36 * nc, dtype=index), np.empty(36 * nc)    # filled block by block: no copies
    for i in range(3):                                        # e_ii = ∂_i u_i: 4 a row
        cols[4 * i * nc:4 * (i + 1) * nc] = (dof + i).ravel()
        vals[4 * i * nc:4 * (i + 1) * nc] = g[:, :, i].ravel()
    for k, (i, j) in enumerate(SHEAR_PAIRS):                  # γ_ij = ∂_j u_i + ∂_i u_j: 8 a row
        at = slice((12 + 8 * k) * nc, (20 + 8 * k) * nc)
        cols[at] = np.stack([dof + i, dof + j], axis=2).ravel()
        vals[at] = np.stack([g[:, :, j], g[:, :, i]], axis=2).ravel()
    indptr = np.concatenate([np.arange(3 * nc) * 4, 12 * nc + np.arange(3 * nc + 1) * 8]).astype(index)
    return sp.csr_matrix((vals, cols, indptr), shape=(6 * nc, 3 * p.shape[1]))


CELLS = 16384       # cells whose strains `StrainOperator` makes at once


class StrainOperator:
    """`strain_operator`'s G applied from the cells' gradients g (ncells, 4, 3), which the
    elasticity operator holds already (`wcs.fem.affine.CellMatrices`), without G's matrix (36
    entries a cell, 432 bytes: 0.78 GB at 1.8e6 cells). `G @ u` and `G.T @ e` are the CSR
    products to the bit: the same products added in the same order (a row's entries in
    storage order from 0; the transpose into each dof by row, then entry)."""

    def __init__(self, t: np.ndarray, g: np.ndarray, nnodes: int):
        self.t, self.g = t, g
        self.shape = (6 * t.shape[1], 3 * nnodes)

    def _rows(self, cells=slice(None)):
        """Each of the 6 row blocks' (dofs, values) (ncells, entries), in G's storage order; of
        the cells given only."""
        t = self.t.T[cells]
        order = np.argsort(t, axis=1)
        dof = 3 * np.take_along_axis(t, order, axis=1)
        g = np.take_along_axis(self.g[cells], order[:, :, None], axis=1)
        for i in range(3):
            yield dof + i, g[:, :, i]
        for i, j in SHEAR_PAIRS:
            yield (np.stack([dof + i, dof + j], axis=2).reshape(len(dof), 8),
                   np.stack([g[:, :, j], g[:, :, i]], axis=2).reshape(len(dof), 8))

    def __matmul__(self, u: np.ndarray) -> np.ndarray:
        """G u, `CELLS` cells at a time (their row blocks' dofs and values made for those only:
        290 bytes a cell at once, 62 MB at 2.1e5 cells; each row its own sum)."""
        nc = self.t.shape[1]
        out = np.zeros((6, nc))
        for start in range(0, nc, CELLS):
            cells = slice(start, min(start + CELLS, nc))
            for row, (cols, vals) in zip(out[:, cells], self._rows(cells)):
                for a in range(cols.shape[1]):
                    row += vals[:, a] * u[cols[:, a]]
        return out.ravel()

    @property
    def T(self) -> "_Transposed":
        return _Transposed(self)


class _Transposed:
    """Gᵀ of a `StrainOperator`."""

    def __init__(self, G: StrainOperator):
        self.G, self.shape = G, G.shape[::-1]

    def __matmul__(self, e: np.ndarray) -> np.ndarray:
        out = np.zeros(self.shape[0])
        for e_block, (cols, vals) in zip(e.reshape(6, -1), self.G._rows()):
            np.add.at(out, cols.ravel(), (vals * e_block[:, None]).ravel())
        return out


def stresses(strain: np.ndarray, lam: np.ndarray, mu: np.ndarray, beta: np.ndarray,
             dT: np.ndarray) -> np.ndarray:
    """(6, ncells) stress (xx, yy, zz, yz, xz, xy) from strain (6, ncells) and cell-wise λ, μ, β, ΔT."""
    normal, shear = strain[:3], strain[3:]
    iso = lam * normal.sum(axis=0) - beta * dT
    return np.concatenate([iso + 2 * mu * normal, mu * shear])


def shear_intensity(s: np.ndarray) -> np.ndarray:
    """I₂² = τᴰ:τᴰ = (2/3)[τ11²+τ22²+τ33² − (τ11τ22+τ11τ33+τ22τ33) + 3(τ23²+τ13²+τ12²)]."""
    xx, yy, zz, yz, xz, xy = s
    return (2.0 / 3.0) * (xx**2 + yy**2 + zz**2 - (xx * yy + xx * zz + yy * zz)
                          + 3 * (yz**2 + xz**2 + xy**2))


def von_mises(s: np.ndarray) -> np.ndarray:
    """√(3/2 · I₂²)."""
    return np.sqrt(1.5 * shear_intensity(s))


def tensor(s: np.ndarray) -> np.ndarray:
    """(ncells, 3, 3) symmetric tensors from the (6, ncells) components."""
    xx, yy, zz, yz, xz, xy = s
    return np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1),
                     np.stack([xz, yz, zz], -1)], -2)


def principal(s: np.ndarray) -> np.ndarray:
    """(ncells, 3) principal stresses, largest first."""
    return np.linalg.eigvalsh(tensor(s))[:, ::-1]


def face_normals(mesh, facets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) outward unit normals and (n,) areas of boundary triangles of a MeshTet, outward
    w.r.t. the owning cell (``mesh.f2t[0]``)."""
    facets = np.asarray(facets, dtype=np.int64)
    f = mesh.facets[:, facets]
    x0, x1, x2 = (mesh.p[:, f[k]].T for k in range(3))
    n = np.cross(x1 - x0, x2 - x0)
    twice = np.linalg.norm(n, axis=1)
    n /= twice[:, None]
    cell = mesh.t[:, mesh.f2t[0, facets]]
    other = cell.sum(axis=0) - f.sum(axis=0)                  # the cell's vertex off the facet
    flip = np.einsum("ij,ij->i", mesh.p[:, other].T - x0, n) > 0.0
    n[flip] *= -1.0
    return n, 0.5 * twice


def nodal_normals(mesh, facets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(nodes, normals): the sorted nodes of a set of boundary triangles and their outward unit
    normals, the area-weighted mean of the adjacent triangles' normals."""
    facets = np.asarray(facets, dtype=np.int64)
    nodes, inv = np.unique(mesh.facets[:, facets], return_inverse=True)
    inv = inv.reshape(3, -1)
    n, area = face_normals(mesh, facets)
    acc = np.zeros((nodes.size, 3))
    for k in range(3):
        np.add.at(acc, inv[k], n * area[:, None])
    return nodes, acc / np.linalg.norm(acc, axis=1)[:, None]
