"""Rigid motions of a set of nodes: the kernel of the strain operator."""
from __future__ import annotations

import numpy as np


def rigid_modes(p: np.ndarray, nodes: np.ndarray, nnodes: int) -> np.ndarray:
    """(2 nnodes, 3): x-translation, y-translation, rotation about the nodes' centroid; in 3D
    (p of shape (3, n)) (3 nnodes, 6): the translations along x, y, z, then the rotations
    e_k × (x − c) about the axes x, y, z through the centroid c."""
    c = p[:, nodes].mean(axis=1)
    if p.shape[0] == 3:
        R = np.zeros((3 * nnodes, 6))
        r = (p[:, nodes] - c[:, None]).T                      # (n, 3)
        for k, e in enumerate(np.eye(3)):
            R[3 * nodes + k, k] = 1.0
            R[(3 * nodes[:, None] + np.arange(3)).ravel(), 3 + k] = np.cross(e, r).ravel()
        return R
    R = np.zeros((2 * nnodes, 3))
    R[2 * nodes, 0] = 1.0
    R[2 * nodes + 1, 1] = 1.0
    R[2 * nodes, 2] = -(p[1, nodes] - c[1])
    R[2 * nodes + 1, 2] = p[0, nodes] - c[0]
    return R
