"""A contact surface's own coordinates (3D): the two principal directions of its slave nodes,
and a grid over it for a slip limit given as a Lipschitz function on the surface.

`surface_frame` is the centroid and the principal directions (largest spread first) of the
points; `surface_grid` maps each point to (u, v) ∈ [0, 1]² over the bounding rectangle of the
points in that frame, with the rectangle's side lengths; `grid_weights` are the bilinear
weights of an nu × nv grid of values (index i·nv + j for the value at u_i, v_j), so that
g(x) = Σ w_k(x) g_k interpolates the grid values and reproduces every bilinear function."""
from __future__ import annotations

import numpy as np


def surface_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(origin, e1, e2): the centroid of the points (k, 3) and their two principal directions,
    signs fixed so that the largest component of each is positive (a deterministic frame)."""
    c = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c, full_matrices=False)
    e = vt[:2]
    e = e * np.sign(e[np.arange(2), np.argmax(np.abs(e), axis=1)])[:, None]
    return c, e[0], e[1]


def surface_grid(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(uv, lengths): each point's coordinates (k, 2) in [0, 1]² over the bounding rectangle of
    the points in their `surface_frame`, and the rectangle's two side lengths."""
    origin, e1, e2 = surface_frame(points)
    q = np.column_stack([(points - origin) @ e1, (points - origin) @ e2])
    lo, hi = q.min(axis=0), q.max(axis=0)
    lengths = hi - lo
    return np.clip((q - lo) / np.where(lengths > 0, lengths, 1.0), 0.0, 1.0), lengths


def hat_weights(s: np.ndarray, n: int) -> np.ndarray:
    """(k, n) the piecewise linear hat functions of n equally spaced nodes on [0, 1] at s."""
    return np.array([np.interp(s, np.linspace(0.0, 1.0, n), e) for e in np.eye(n)]).T


def grid_weights(uv: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(k, nu·nv) bilinear weights of the grid values at the points uv (k, 2) ∈ [0, 1]²."""
    nu, nv = shape
    return np.einsum("ki,kj->kij", hat_weights(uv[:, 0], nu), hat_weights(uv[:, 1], nv)).reshape(len(uv), nu * nv)
