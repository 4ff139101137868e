"""Bases of the kernels and null spaces the units of the decomposition are built on: rigid
motions, the motions a constraint elimination admits, null spaces of constraint rows and
independent rows (pivoted QR and SVD, with a relative rank tolerance)."""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from wcs.fem.rigid import rigid_modes


def rigid_basis(p: np.ndarray, nodes: np.ndarray, ncomp: int) -> np.ndarray:
    """(ncomp·k, r): rigid motions of the nodes, node-interleaved — r = 1 for a scalar field,
    else the model's rigid modes (`wcs.fem.rigid.rigid_modes`: 3 in 2D, 6 in 3D) on the nodes,
    the rotations divided by the nodes' largest extent (O(1) columns)."""
    k = nodes.size
    if ncomp == 1:
        return np.ones((k, 1))
    R = rigid_modes(p[:, nodes], np.arange(k), k)
    R[:, ncomp:] /= max(np.ptp(p[:, nodes].T, axis=0).max(), 1e-300)
    return R


def admissible(M: np.ndarray, Tloc: sp.csr_matrix, rtol: float = 1e-10) -> np.ndarray:
    """Reduced coordinates of the motions in span(M) the elimination admits: M α ∈ range(T).

    T has orthonormal columns (one node each), so the defect is (I − T Tᵀ) M α.
    Returns an orthonormal basis (columns) of Tᵀ M N, N = null space of the defect.
    """
    if M.shape[1] == 0:
        return np.zeros((Tloc.shape[1], 0))
    E = M - Tloc @ (Tloc.T @ M)
    s_ref = max(np.linalg.norm(M, 2), 1e-300)
    _, s, vt = np.linalg.svd(E, full_matrices=False)     # M has ≤ 6 columns and many rows
    rank = int(np.sum(s > rtol * s_ref))
    Z = Tloc.T @ (M @ vt[rank:].T)
    return _orth(Z)


def _orth(Z: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    if Z.shape[1] == 0:
        return Z
    q, r, _ = sla.qr(Z, mode="economic", pivoting=True)
    d = np.abs(np.diag(r))
    return q[:, d > rtol * max(d.max(initial=0.0), 1e-300)]


def null_space(C: np.ndarray, Z: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of {Z α : C Z α = 0}."""
    if Z.shape[1] == 0 or C.shape[0] == 0:
        return Z
    CZ = C @ Z
    ref = max(np.linalg.norm(Z, 2) * max(np.abs(C).max(initial=0.0), 1e-300), 1e-300)
    _, s, vt = np.linalg.svd(CZ, full_matrices=True)
    rank = int(np.sum(s > rtol * ref))
    return _orth(Z @ vt[rank:].T)


def _null_basis(C: np.ndarray, rtol: float = 1e-10) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """{x : C x = 0} = {x_d = −W x_f}: a pivoted QR of C (C Π = Q [R₁ R₂]) picks rank(C)
    columns d on which C is well conditioned, W = R₁⁻¹R₂ on the rest f; the null basis is
    N = Π [−W; I]. Returns (d, f, W). A product Σ N costs one with W, rank(C) columns wide
    (Hertz's pair, 848 contact DOFs, 211 glue rows: Nᵀ Σ⁰_cc N 132 → 41 ms against an
    orthonormal basis from the complete Q of Cᵀ)."""
    n = C.shape[1]
    if C.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), np.arange(n), np.zeros((0, n))
    _, r, piv = sla.qr(C, mode="economic", pivoting=True)
    dg = np.abs(np.diag(r))
    k = int(np.sum(dg > rtol * max(dg.max(initial=0.0), 1e-300)))
    return piv[:k], piv[k:], sla.solve_triangular(r[:k, :k], r[:k, k:])


def independent_rows(C: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """Rows of C forming a basis of its row space (pivoted QR of Cᵀ), ascending.

    Glue rows can be dependent (e.g. a contact node on a roller support), which
    would make the saddle-point matrices singular."""
    if C.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    C = C[:, np.flatnonzero(np.abs(C).sum(axis=0))]      # the few columns the rows touch
    _, r, piv = sla.qr(C.T, mode="economic", pivoting=True)
    d = np.abs(np.diag(r))
    return np.sort(piv[: int(np.sum(d > rtol * max(d.max(initial=0.0), 1e-300)))])
