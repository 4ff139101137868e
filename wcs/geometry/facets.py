"""Geometry of a bare triangle mesh (scikit-fem's ``MeshTri``): boundary facets, facet lengths,
outward facet and nodal normals, cell areas, and a polygon clipped by a triangle. Vectors are
ROWS: ``n`` normals have shape ``(n, 2)``. The 3D forms are in `wcs.geometry.tet`."""
from __future__ import annotations

import numpy as np


def boundary_facets(mesh) -> np.ndarray:
    """Sorted indices of facets with exactly one adjacent cell."""
    return np.nonzero(mesh.f2t[1] == -1)[0].astype(np.int64)


def facet_lengths(mesh, facets) -> np.ndarray:
    """(n,) lengths of the given facets."""
    f = mesh.facets[:, np.asarray(facets, dtype=np.int64)]
    d = mesh.p[:, f[1]] - mesh.p[:, f[0]]
    return np.hypot(d[0], d[1])


def facet_normals(mesh, facets) -> np.ndarray:
    """(n, 2) outward unit normals of boundary facets, outward w.r.t. the owning cell
    (``mesh.f2t[0]``; for an interior facet that is the first adjacent cell)."""
    facets = np.asarray(facets, dtype=np.int64)
    a, b = mesh.facets[0, facets], mesh.facets[1, facets]
    pa, pb = mesh.p[:, a], mesh.p[:, b]
    d = pb - pa
    n = np.vstack([d[1], -d[0]])
    n /= np.hypot(n[0], n[1])
    cell = mesh.t[:, mesh.f2t[0, facets]]
    # the vertex of the owning cell that is not on the facet
    other = np.where((cell[0] != a) & (cell[0] != b), cell[0],
                     np.where((cell[1] != a) & (cell[1] != b), cell[1], cell[2]))
    flip = np.einsum("ij,ij->j", mesh.p[:, other] - pa, n) > 0.0
    n[:, flip] *= -1.0
    return n.T.copy()


def nodal_normals(mesh, facets) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals at the nodes of a set of boundary facets.

    Length-weighted average of the outward normals of the (one or two) facets
    of the set adjacent to each node, normalised.  Returns ``(nodes, normals)``
    with ``nodes`` sorted unique node ids and ``normals`` of shape (k, 2).
    """
    facets = np.asarray(facets, dtype=np.int64)
    nodes, inv = np.unique(mesh.facets[:, facets], return_inverse=True)
    inv = inv.reshape(2, -1)
    w = facet_normals(mesh, facets) * facet_lengths(mesh, facets)[:, None]
    acc = np.zeros((nodes.size, 2))
    for k in range(2):
        acc[:, 0] += np.bincount(inv[k], weights=w[:, 0], minlength=nodes.size)
        acc[:, 1] += np.bincount(inv[k], weights=w[:, 1], minlength=nodes.size)
    acc /= np.hypot(acc[:, 0], acc[:, 1])[:, None]
    return nodes, acc


def cell_areas(mesh, cells) -> np.ndarray:
    """(n,) areas of the given cells."""
    p, t = mesh.p, mesh.t[:, np.asarray(cells, dtype=np.int64)]
    d1, d2 = p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]
    return 0.5 * np.abs(d1[0] * d2[1] - d1[1] * d2[0])


def _clip(poly: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """The counter-clockwise polygon ``poly`` clipped by the counter-clockwise triangle ``tri``
    (Sutherland–Hodgman; exact area integrals also for a non-convex ``poly``)."""
    for i in range(3):
        a, b = tri[i], tri[(i + 1) % 3]
        e = b - a
        side = e[0] * (poly[:, 1] - a[1]) - e[1] * (poly[:, 0] - a[0])      # >= 0: inside
        out = []
        for j in range(len(poly)):
            p, q, sp_, sq = poly[j - 1], poly[j], side[j - 1], side[j]
            if (sp_ >= 0) != (sq >= 0):
                out.append(p + (q - p) * (sp_ / (sp_ - sq)))
            if sq >= 0:
                out.append(q)
        if not out:
            return np.zeros((0, 2))
        poly = np.array(out)
    return poly
