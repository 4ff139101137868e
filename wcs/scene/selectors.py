"""Geometric selectors over a meshed scene (the geometry of a bare mesh: `wcs.geometry.facets`).

Pure functions over a :class:`~wcs.scene.meshdata.SceneMesh` (or a bare
``skfem.MeshTri`` for the helpers).  Vectors are returned as ROWS: an array of
``n`` normals has shape ``(n, 2)``.

Boundary selectors (choose boundary facets, i.e. facets with exactly one
adjacent cell -- after the node duplication of the mesher that includes the
curves where two bodies touch):

* ``segment: [[x0, y0], [x1, y1]]`` -- both end nodes of the facet lie on the
  segment,
* ``circle: {center: [x, y], radius: r}`` -- both end nodes lie on the circle,
* ``box: [x0, y0, x1, y1]`` -- both end nodes lie in the (closed) box,

each with an optional ``body: NAME`` keeping only facets of that body.
"Lie on" uses the tolerance ``REL_TOL * h`` with ``h`` the facet's length (plus
a tiny absolute tolerance relative to the scene size), so it follows the local
mesh size and is insensitive to round-off but never picks a facet that only
touches the curve at one end.

Region selectors (choose cells, or facets):

* ``box: [x0, y0, x1, y1]``, ``polygon: [[x, y], ...]`` -- the cells meeting the set,
  each cut by it exactly (``Selection.moments``: ∫ over the cut part of each hat
  function), so a mean over the selection is the mean over the set itself on any
  mesh; a scene meshed from shapes embeds its regions of interest instead
  (``SceneMesh.roi_cells``, whole cells),
* ``disc: {center, radius}`` -- only embedded (a disc cannot be cut exactly by
  straight clipping): refused here,
* ``boundary: NAME`` -- the facets of the named boundary (a facet selection),
* ``body: NAME`` with any of the above restricts the selection to that body.

Selectors are the scene's validated models (`wcs.scene.spec`), read by attribute.

A selector that selects nothing raises :class:`wcs.errors.StudyError` naming
the caller's key path.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import StudyError
from ..geometry.facets import _clip, boundary_facets, cell_areas

REL_TOL = 1e-3          # "on the curve": distance <= REL_TOL * facet length (+ ABS_TOL * scene size)
ABS_TOL = 1e-12

BOUNDARY_KINDS = ("segment", "circle", "box")
REGION_KINDS = ("box", "disc", "polygon", "boundary")


@dataclass(frozen=True, eq=False)
class Selection:
    """A set of mesh entities: cells (indices into ``mesh.t`` columns) or facets
    (indices into ``mesh.facets`` columns), sorted and unique."""

    kind: str               # "cells" | "facets"
    index: np.ndarray
    moments: np.ndarray | None = None
    # cells cut by the region: (3, n) ∫_{G ∩ T} λ_k dx per cell T and vertex k (λ_k the P1
    # hat functions); None: whole cells

    def __len__(self) -> int:
        return int(self.index.size)

    def cell_moments(self, mesh) -> np.ndarray:
        """(3, n) ∫_{G ∩ T} λ_k dx of the selected cells (a third of the area for a whole cell)."""
        if self.moments is not None:
            return self.moments
        return np.tile(cell_areas(mesh, self.index) / 3.0, (3, 1))


def cut_cells(mesh, pts: np.ndarray) -> Selection:
    """The cells meeting the polygon ``pts`` with their exact moments ∫_{G ∩ T} λ_k dx:
    each cell is clipped by the polygon, ∫_P λ_k = |P| λ_k(centroid P) (λ_k is linear)."""
    x, y = pts[:, 0], pts[:, 1]
    if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
        pts = pts[::-1]
    P = mesh.p[:, mesh.t]                                        # (2, 3, ncells)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    near = np.flatnonzero((P[0].max(0) >= lo[0]) & (P[0].min(0) <= hi[0])
                          & (P[1].max(0) >= lo[1]) & (P[1].min(0) <= hi[1]))
    e = np.roll(pts, -1, axis=0) - pts
    turns = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
    whole = np.zeros(near.size, dtype=bool)
    if np.all(turns >= 0):          # convex: a cell with its three vertices inside is inside
        whole = np.all([inside_polygon(P[0, k, near], P[1, k, near], pts) for k in range(3)], axis=0)
    cells = list(near[whole])
    moments = list(np.repeat(cell_areas(mesh, near[whole])[:, None] / 3.0, 3, axis=1))
    for c in near[~whole]:
        tri = P[:, :, c].T
        poly = _clip(pts, tri)
        if len(poly) < 3:
            continue
        px, py = poly[:, 0], poly[:, 1]
        qx, qy = np.roll(px, -1), np.roll(py, -1)
        w = px * qy - qx * py
        area = 0.5 * w.sum()
        if area <= 0.0:
            continue
        g = np.array([((px + qx) * w).sum(), ((py + qy) * w).sum()]) / (6.0 * area)
        T = np.vstack([tri.T, np.ones(3)])                         # barycentric coordinates of g
        cells.append(c)
        moments.append(area * np.linalg.solve(T, np.array([g[0], g[1], 1.0])))
    if not cells:
        return Selection("cells", np.zeros(0, dtype=np.int64))
    order = np.argsort(cells)
    return Selection("cells", np.asarray(cells, dtype=np.int64)[order], np.array(moments)[order].T.copy())


def facet_body(sm, facets) -> np.ndarray:
    """Body index of the (first) cell owning each facet."""
    return sm.cell_body[sm.mesh.f2t[0, np.asarray(facets, dtype=np.int64)]]


# ---------------------------------------------------------------------------
# point predicates / distances (vectorised over x, y arrays)


def _floats(value, n, path, what):
    try:
        out = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise StudyError(f"{what} must be numbers, got {value!r}", path=path) from None
    if n is not None and out.shape != (n,):
        raise StudyError(f"{what} must be {n} numbers, got {value!r}", path=path)
    if not np.all(np.isfinite(out)):
        raise StudyError(f"{what} must be finite, got {value!r}", path=path)
    return out


def _box(spec, path):
    x0, y0, x1, y1 = _floats(spec, 4, path, "box [x0, y0, x1, y1]")
    if x1 < x0 or y1 < y0:
        raise StudyError(f"box [x0, y0, x1, y1] needs x0 <= x1 and y0 <= y1, got {spec}", path=path)
    return x0, y0, x1, y1


def _circle(spec, path):
    c = _floats(spec.center, 2, f"{path}.center", "center")
    r = float(_floats([spec.radius], 1, f"{path}.radius", "radius")[0])
    if r <= 0:
        raise StudyError(f"radius must be > 0, got {r}", path=f"{path}.radius")
    return c, r


def _segment(spec, path):
    try:
        a = _floats(spec[0], 2, f"{path}.0", "segment end")
        b = _floats(spec[1], 2, f"{path}.1", "segment end")
        if len(spec) != 2:
            raise IndexError
    except (IndexError, TypeError, KeyError):
        raise StudyError("segment must be [[x0, y0], [x1, y1]]", path=path) from None
    if np.all(a == b):
        raise StudyError("segment has zero length", path=path)
    return a, b


def _polygon(spec, path):
    try:
        pts = np.array([_floats(p, 2, f"{path}.{i}", "polygon vertex") for i, p in enumerate(spec)])
    except TypeError:
        raise StudyError("polygon must be a list of [x, y] points", path=path) from None
    if len(pts) < 3:
        raise StudyError("polygon needs at least 3 vertices", path=path)
    return pts


def dist_segment(x, y, a, b):
    """Distance of points (x, y) to the segment ab."""
    d = b - a
    s = np.clip(((x - a[0]) * d[0] + (y - a[1]) * d[1]) / (d @ d), 0.0, 1.0)
    return np.hypot(x - a[0] - s * d[0], y - a[1] - s * d[1])


def dist_segments(x, y, a: np.ndarray, b: np.ndarray, chunk: int = 256):
    """Distance of points (x, y) to the nearest of the segments a[i] b[i] ((k, 2) each): the
    minimum of `dist_segment` over them, the same numbers, `chunk` segments at a time."""
    x, y = np.asarray(x, float)[:, None], np.asarray(y, float)[:, None]
    d = b - a
    dd = np.array([di @ di for di in d])            # as dist_segment forms it (a dot, not a sum)
    out = np.full(x.shape[0], np.inf)
    for i in range(0, len(a), chunk):
        a0, a1 = a[i:i + chunk, 0], a[i:i + chunk, 1]
        d0, d1 = d[i:i + chunk, 0], d[i:i + chunk, 1]
        s = np.clip(((x - a0) * d0 + (y - a1) * d1) / dd[i:i + chunk], 0.0, 1.0)
        out = np.minimum(out, np.hypot(x - a0 - s * d0, y - a1 - s * d1).min(axis=1))
    return out


def dist_box(x, y, box):
    """Distance to the closed box (0 inside)."""
    x0, y0, x1, y1 = box
    dx = np.maximum(np.maximum(x0 - x, x - x1), 0.0)
    dy = np.maximum(np.maximum(y0 - y, y - y1), 0.0)
    return np.hypot(dx, dy)


def inside_polygon(x, y, pts) -> np.ndarray:
    """Even-odd point-in-polygon test, vectorised over points."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    inside = np.zeros(np.broadcast(x, y).shape, dtype=bool)
    n = len(pts)
    for i in range(n):
        (xa, ya), (xb, yb) = pts[i - 1], pts[i]
        crosses = (ya > y) != (yb > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = xa + (y - ya) * (xb - xa) / (yb - ya)
        inside ^= crosses & (x < xc)
    return inside


def dist_polygon(x, y, pts):
    """Distance to the closed polygon area (0 inside)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    d = np.full(np.broadcast(x, y).shape, np.inf)
    for i in range(len(pts)):
        d = np.minimum(d, dist_segment(x, y, pts[i - 1], pts[i]))
    return np.where(inside_polygon(x, y, pts), 0.0, d)


def distance_function(spec, path: str, kinds=("box", "disc", "polygon", "segment", "circle")):
    """A vectorised ``d(x, y)``: distance to the geometric set of a selector.

    Region kinds (box, disc, polygon) are filled sets (distance 0 inside);
    boundary kinds (segment, circle) are curves.  Used for mesh refinement.
    """
    kind = _kind(spec, kinds, path)
    val = getattr(spec, kind)
    p = f"{path}.{kind}"
    if kind == "box":
        box = _box(val, p)
        return lambda x, y: dist_box(x, y, box)
    if kind == "disc":
        c, r = _circle(val, p)
        return lambda x, y: np.maximum(np.hypot(x - c[0], y - c[1]) - r, 0.0)
    if kind == "circle":
        c, r = _circle(val, p)
        return lambda x, y: np.abs(np.hypot(x - c[0], y - c[1]) - r)
    if kind == "segment":
        a, b = _segment(val, p)
        return lambda x, y: dist_segment(x, y, a, b)
    pts = _polygon(val, p)
    return lambda x, y: dist_polygon(x, y, pts)


def _kind(spec, kinds, path):
    """The one of `kinds` a selector (a validated model of the scene) gives."""
    found = [k for k in kinds if getattr(spec, k, None) is not None]
    if len(found) != 1:
        raise StudyError(f"a selector needs exactly one of {', '.join(kinds)}; got {spec!r}", path=path)
    return found[0]


def _body_index(sm, spec, path):
    body = getattr(spec, "body", None)
    if body is None:
        return None
    try:
        return sm.bodies.index(body)
    except ValueError:
        raise StudyError(f"unknown body {body!r} (bodies: {', '.join(sm.bodies)})",
                         path=f"{path}.body") from None


def _scene_scale(mesh) -> float:
    ext = mesh.p.max(axis=1) - mesh.p.min(axis=1)
    return float(np.hypot(*ext)) or 1.0


# ---------------------------------------------------------------------------
# selectors


def select_boundary(sm, spec, path: str, *, allow_empty: bool = False) -> np.ndarray:
    """Sorted indices into ``sm.mesh.facets`` of the boundary facets chosen by a
    boundary selector (a `Boundary`: segment / circle / box, optional body)."""
    mesh = sm.mesh
    kind = _kind(spec, BOUNDARY_KINDS, path)
    body = _body_index(sm, spec, path)
    bf = boundary_facets(mesh)
    if body is not None:
        bf = bf[facet_body(sm, bf) == body]
    a, b = mesh.facets[0, bf], mesh.facets[1, bf]
    xa, ya, xb, yb = mesh.p[0, a], mesh.p[1, a], mesh.p[0, b], mesh.p[1, b]
    tol = REL_TOL * np.hypot(xb - xa, yb - ya) + ABS_TOL * _scene_scale(mesh)
    val = getattr(spec, kind)
    p = f"{path}.{kind}"
    if kind == "segment":
        s0, s1 = _segment(val, p)
        ok = (dist_segment(xa, ya, s0, s1) <= tol) & (dist_segment(xb, yb, s0, s1) <= tol)
    elif kind == "circle":
        c, r = _circle(val, p)
        ok = ((np.abs(np.hypot(xa - c[0], ya - c[1]) - r) <= tol)
              & (np.abs(np.hypot(xb - c[0], yb - c[1]) - r) <= tol))
    else:
        box = _box(val, p)
        ok = (dist_box(xa, ya, box) <= tol) & (dist_box(xb, yb, box) <= tol)
    out = np.sort(bf[ok])
    if out.size == 0 and not allow_empty:
        where = f" of body {spec.body!r}" if body is not None else ""
        raise StudyError(f"the {kind} selector selects no boundary edge{where}", path=path)
    return out


def select_region(sm, spec, path: str, *, allow_empty: bool = False) -> Selection:
    """Cells or facets chosen by a region selector (a `RegionOfInterest`, optional body):
    ``box`` / ``polygon`` -> the cells they cut (`cut_cells`); ``boundary: NAME`` -> the
    facets of ``sm.boundaries[NAME]``.
    """
    mesh = sm.mesh
    kind = _kind(spec, REGION_KINDS, path)
    body = _body_index(sm, spec, path)
    val = getattr(spec, kind)
    p = f"{path}.{kind}"
    if kind == "boundary":
        if val not in sm.boundaries:
            raise StudyError(f"unknown boundary {val!r} (boundaries: {', '.join(sm.boundaries)})",
                             path=p)
        f = np.asarray(sm.boundaries[val], dtype=np.int64)
        if body is not None:
            f = f[facet_body(sm, f) == body]
        return _nonempty(Selection("facets", np.sort(f)), spec, path, allow_empty)
    if kind == "disc":
        raise StudyError("a disc cannot be cut exactly from the cells of a mesh file (scenes built "
                         "from shapes embed it in the mesh): give a polygon, whose cells are cut "
                         "exactly, or make the disc a region (2D physical group) of the file", path=p)
    if kind == "box":
        x0, y0, x1, y1 = _box(val, p)
        pts = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    else:
        pts = _polygon(val, p)
    sel = cut_cells(mesh, pts)
    if body is not None:
        keep = sm.cell_body[sel.index] == body
        sel = Selection("cells", sel.index[keep], sel.moments[:, keep] if sel.moments is not None else None)
    return _nonempty(sel, spec, path, allow_empty)


def _nonempty(sel, spec, path, allow_empty):
    if len(sel) == 0 and not allow_empty:
        raise StudyError(f"the selector {spec!r} selects no mesh {sel.kind[:-1]}", path=path)
    return sel


def arc_coordinate(mesh, facets: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Normalised arc length s ∈ [0, 1] of `nodes` along the chain of `facets`
    (from the end with the smaller (x, y); a closed chain starts at its smallest node)."""
    edges = mesh.facets[:, facets].T
    ids, inv = np.unique(edges, return_inverse=True)
    inv = inv.reshape(-1, 2)
    n = ids.size
    adj = [[] for _ in range(n)]
    for k, (a, b) in enumerate(inv):
        adj[a].append((b, k))
        adj[b].append((a, k))
    ends = [i for i in range(n) if len(adj[i]) == 1]
    key = lambda i: tuple(mesh.p[:, ids[i]])  # noqa: E731
    start = min(ends, key=key) if ends else min(range(n), key=key)
    s = np.full(n, np.nan)
    s[start] = 0.0
    seen_edges = np.zeros(len(inv), bool)
    stack = [start]
    while stack:                                   # walk the chain (a forest walk if it branches)
        i = stack.pop()
        for j, k in adj[i]:
            if not seen_edges[k]:
                seen_edges[k] = True
                if np.isnan(s[j]):
                    s[j] = s[i] + np.linalg.norm(mesh.p[:, ids[j]] - mesh.p[:, ids[i]])
                    stack.append(j)
    s = np.nan_to_num(s) / max(np.nanmax(s), 1e-300)
    return s[np.searchsorted(ids, nodes)]
