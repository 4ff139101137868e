"""Cell-wise strains and stresses of P1 displacements, and their invariants.

Stress components are ordered (xx, yy, zz, xy). Plane strain:
τ = λ div u I + 2μ e − β ΔT I, τzz = λ div u − β ΔT. Plane stress uses the
effective λ* (the caller passes it) and τzz = 0.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

COMPONENTS = ("xx", "yy", "zz", "xy")


def gradient_operator(p: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P1 shape-function gradients per cell: (dN/dx, dN/dy), each (ncells, 3), and cell areas."""
    x, y = p[0, t], p[1, t]                                   # (3, ncells)
    area2 = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0])
    dx = np.array([y[1] - y[2], y[2] - y[0], y[0] - y[1]]) / area2
    dy = np.array([x[2] - x[1], x[0] - x[2], x[1] - x[0]]) / area2
    return (dx.T, dy.T), 0.5 * np.abs(area2)


def strain_operator(p: np.ndarray, t: np.ndarray) -> sp.csr_matrix:
    """G with (G u) reshaped (3, ncells) = (e_xx, e_yy, γ_xy = 2 e_xy); u node-interleaved.

    Built as sorted CSR directly: row c of each block holds cell c's dofs in increasing order
    (its nodes sorted; dof 2n is x, 2n + 1 is y), as a COO build with summed duplicates gives it."""
    (dx, dy), _ = gradient_operator(p, t)
    nc = t.shape[1]
    order = np.argsort(t.T, axis=1)                              # (ncells, 3) the nodes by number
    node = np.take_along_axis(t.T, order, axis=1)
    dx, dy = np.take_along_axis(dx, order, axis=1), np.take_along_axis(dy, order, axis=1)
    ux, uy = 2 * node, 2 * node + 1
    cols = np.concatenate([ux.ravel(), uy.ravel(), np.stack([ux, uy], axis=2).ravel()])
    vals = np.concatenate([dx.ravel(), dy.ravel(), np.stack([dy, dx], axis=2).ravel()])
    indptr = np.concatenate([np.arange(2 * nc) * 3, 6 * nc + np.arange(nc + 1) * 6])
    return sp.csr_matrix((vals, cols, indptr), shape=(3 * nc, 2 * p.shape[1]))


def cell_mean(t: np.ndarray, nodal: np.ndarray) -> np.ndarray:
    """Mean of a P1 field over each cell (exact: the average of the vertex values)."""
    return nodal[t].mean(axis=0)


def stresses(strain: np.ndarray, lam: np.ndarray, mu: np.ndarray, beta: np.ndarray,
             dT: np.ndarray, plane: str) -> np.ndarray:
    """(4, ncells) stress from strain (3, ncells) and cell-wise λ (or λ*), μ, β, ΔT."""
    exx, eyy, gxy = strain
    tr = exx + eyy
    th = beta * dT
    sxx = lam * tr + 2 * mu * exx - th
    syy = lam * tr + 2 * mu * eyy - th
    szz = lam * tr - th if plane == "strain" else np.zeros_like(tr)
    return np.array([sxx, syy, szz, mu * gxy])


def shear_intensity(s: np.ndarray) -> np.ndarray:
    """I₂² = τᴰ:τᴰ = (2/3)[τ11²+τ22²+τ33² − (τ11τ22+τ11τ33+τ22τ33) + 3τ12²]."""
    xx, yy, zz, xy = s
    return (2.0 / 3.0) * (xx**2 + yy**2 + zz**2 - (xx * yy + xx * zz + yy * zz) + 3 * xy**2)


def von_mises(s: np.ndarray) -> np.ndarray:
    return np.sqrt(1.5 * shear_intensity(s))


def principal(s: np.ndarray) -> np.ndarray:
    """(ncells, 2) in-plane principal stresses, largest first."""
    xx, yy, _, xy = s
    c, r = 0.5 * (xx + yy), np.sqrt((0.5 * (xx - yy)) ** 2 + xy**2)
    return np.stack([c + r, c - r], axis=1)
