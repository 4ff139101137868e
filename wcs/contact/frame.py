"""A contact surface's own coordinates (3D): the two principal directions of its slave nodes,
and a grid over it for a slip limit given as a Lipschitz function on the surface.

`surface_frame` is the centroid and the principal directions (largest spread first) of the
points; `surface_grid` maps each point to (u, v) ∈ [0, 1]² over the smallest rectangle that
encloses the points in their plane (long side first), with the rectangle's side lengths: on a
rectangular face that is the face itself, however its nodes are spread (the principal
directions of the nodes are not its sides where the mesh is finer on one side: on the 3D
tunnel's fault they turned by 5.6e-4 rad and made the 144.222 × 10 m fault a 144.228 ×
10.081 m grid); `grid_weights` are the bilinear
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
    """(uv, lengths): each point's coordinates (k, 2) in [0, 1]² over the smallest rectangle
    enclosing the points in the plane of their `surface_frame` (`enclosing_sides`), u along
    its long side, and the rectangle's two side lengths (long first)."""
    origin, e1, e2 = surface_frame(points)
    q = np.column_stack([(points - origin) @ e1, (points - origin) @ e2])
    a = enclosing_sides(q)
    sides = a.T @ np.vstack([e1, e2])                                # the sides' directions in space
    flip = np.sign(sides[np.arange(2), np.argmax(np.abs(sides), axis=1)])
    q = (q @ a) * flip                                               # largest component positive, as the frame's
    lo, hi = q.min(axis=0), q.max(axis=0)
    lengths = hi - lo
    return np.clip((q - lo) / np.where(lengths > 0, lengths, 1.0), 0.0, 1.0), lengths


def enclosing_sides(q: np.ndarray) -> np.ndarray:
    """(2, 2) the unit directions (columns, the longer side first) of the smallest-area
    rectangle enclosing the planar points q (k, 2): one of its sides lies along an edge of
    their convex hull (Freeman & Shapira, CACM 18 (1975)), so each hull edge is tried; the
    first of equal areas (to 1e-12) is kept. Collinear or coincident points: the frame's axes."""
    from scipy.spatial import ConvexHull, QhullError      # lazy: scipy.spatial is only needed here
    try:
        corners = q[ConvexHull(q).vertices]
    except (QhullError, ValueError):
        return np.eye(2)
    edges = np.roll(corners, -1, axis=0) - corners
    d = edges / np.linalg.norm(edges, axis=1)[:, None]
    n = np.column_stack([-d[:, 1], d[:, 0]])
    along, across = corners @ d.T, corners @ n.T                     # (corner, edge)
    extent = np.stack([np.ptp(along, axis=0), np.ptp(across, axis=0)])
    area = extent[0] * extent[1]
    best = int(np.argmax(area <= area.min() * (1 + 1e-12)))
    a = np.column_stack([d[best], n[best]])
    return a if extent[0, best] >= extent[1, best] else a[:, ::-1]


def hat_weights(s: np.ndarray, n: int) -> np.ndarray:
    """(k, n) the piecewise linear hat functions of n equally spaced nodes on [0, 1] at s."""
    return np.array([np.interp(s, np.linspace(0.0, 1.0, n), e) for e in np.eye(n)]).T


def grid_weights(uv: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(k, nu·nv) bilinear weights of the grid values at the points uv (k, 2) ∈ [0, 1]²."""
    nu, nv = shape
    return np.einsum("ki,kj->kij", hat_weights(uv[:, 0], nu), hat_weights(uv[:, 1], nv)).reshape(len(uv), nu * nv)
