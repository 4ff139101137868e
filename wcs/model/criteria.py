"""Criterion functionals Φ1–Φ6 [68, (4.29)–(4.34)]: each a maximum over regions of
interest G_r of a mean over G_r — and beyond the seed, `contact_pressure_peak`: the largest
nodal contact pressure in G_r (`in_words` says which reduction a criterion is).

`KINDS` is the one registry of criterion kinds: a `Kind` holds everything the code
knows of a kind (its value on a region, its partial derivatives for the adjoint,
units, label, the scene block it needs, the options it takes, where it reads its
regions). The schema, the adjoint and the report read it; a new kind is one entry.

Linear criteria (temperature, normal displacement) keep their functional as
a vector ℓ_r (Φ_r = ℓ_r · field), which is also the adjoint load of the
criterion. Stress criteria average a cell density ψ(τ) over G_r; contact
criteria a nodal quantity along the contact (Φ6: the mean of the interpolated pressure
over Γc ∩ G_r, again a vector ℓ_r, on λ_n).

The mesh gives the dimension: triangles (areas, edges, stresses xx yy zz xy) or tetrahedra
(volumes, triangular faces with the normal from the face, stresses xx yy zz yz xz xy, two
tangent components of the slip per contact node).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..contact.zone import slave_segments
from ..errors import StudyError
from ..fem import stress
from ..geometry import tet
from ..geometry.facets import boundary_facets, facet_lengths, facet_normals
from ..scene.selectors import Selection, dist_segments, distance_function, select_region

CORNER = np.cos(np.radians(30.0))   # boundary edges nearest X_r turning by more: a corner, n(X_r) undefined
REL_TOL = 1e-7       # "within reach" for the non-smoothness flags, relative


@dataclass
class Partials:
    """Explicit partial derivatives of one criterion at a solution."""
    u: np.ndarray | None = None          # ∂Φ/∂u (full dofs)
    theta: np.ndarray | None = None      # ∂Φ/∂θ (heat nodes)
    lam_n: np.ndarray | None = None      # ∂Φ/∂λ_n (contact nodes)
    lam_t: np.ndarray | None = None      # ∂Φ/∂λ_t (tangent rows, stacked as Bt)
    coef: dict | None = None             # field -> ∂Φ/∂c (explicit dependence, e.g. of stresses)


@dataclass(frozen=True)
class Kind:
    """One criterion kind. `value(criterion, model, state, r)` is Φ_r; `partials(...)` its
    explicit partials at region r and whether Φ_r is not differentiable within reach."""
    label: str
    units: str
    value: Callable
    partials: Callable
    reads: str = "cells"                 # "cells": G_r embedded in the mesh; "contact": the contact rows next to G_r
    functional: Callable | None = None   # (smesh, spec, selection, path, roi) -> ℓ_r of a linear kind
    contact_functional: Callable | None = None   # (smesh, scene, zone, roi, selection, path) -> (ℓ_r on λ_n, meas)
    needs: str | None = None             # the scene block the kind needs: "thermal", "contacts"
    options: tuple[str, ...] = ()        # criterion keys beyond name, kind, regions


@dataclass
class Criterion:
    name: str
    kind: str
    rois: list[str]
    selections: list[Selection]
    functionals: list[np.ndarray] | None     # linear kinds: one ℓ_r per region of interest
    measures: np.ndarray                      # meas G_r (contact kinds: of Γc ∩ G_r, slip: of its rows)
    contact_masks: list[np.ndarray] | None = None   # contact kinds: contact rows next to G_r

    @property
    def units(self) -> str:
        return KINDS[self.kind].units

    def region_values(self, model, state) -> np.ndarray:
        value = KINDS[self.kind].value
        return np.array([value(self, model, state, r) for r in range(len(self.rois))])

    def value(self, model, state) -> float:
        return float(np.max(self.region_values(model, state)))


def build_criteria(study_criteria, scene, smesh, zone=None) -> list[Criterion]:
    """The study's criteria (validated specs: name, kind, regions, options) on the mesh."""
    rois = scene.regions_of_interest
    out = []
    for k, spec in enumerate(study_criteria):
        path, kind = f"criteria.{k}", KINDS[spec.kind]
        if kind.reads == "contact":             # only the contact rows next to G_r matter
            sels = [_roi_selection(smesh, r, rois[r], f"scene.regions_of_interest.{r}")
                    if rois[r].boundary is not None else Selection("cells", np.zeros(0, dtype=np.int64))
                    for r in spec.regions]
            masks = [_contact_rows_in(smesh, scene, zone, r, s, f"scene.regions_of_interest.{r}")
                     for r, s in zip(spec.regions, sels)]
            measures = np.array([zone.weight[m].sum() for m in masks])
            functionals = None
            if kind.contact_functional is not None:
                lm = [kind.contact_functional(smesh, scene, zone, r, s, f"scene.regions_of_interest.{r}")
                      for r, s in zip(spec.regions, sels)]
                functionals, measures = [ell for ell, _ in lm], np.array([m for _, m in lm])
            out.append(Criterion(spec.name, spec.kind, list(spec.regions), sels, functionals, measures,
                                 masks))
            continue
        sels = [_roi_selection(smesh, r, rois[r], f"scene.regions_of_interest.{r}") for r in spec.regions]
        functionals = None if kind.functional is None else \
            [kind.functional(smesh, spec, s, path, r) for r, s in zip(spec.regions, sels)]
        measures = np.array([_measure(smesh.mesh, s) for s in sels])
        out.append(Criterion(spec.name, spec.kind, list(spec.regions), sels, functionals, measures))
    return out


def embedded_rois(study_criteria) -> list[str]:
    """The regions of interest whose cells a criterion integrates over (every kind but the
    contact ones, which take the contact rows next to G_r): the mesh embeds them."""
    return sorted({r for c in study_criteria if KINDS[c.kind].reads == "cells" for r in c.regions})


def _roi_selection(smesh, name: str, spec, path: str) -> Selection:
    """G_r as mesh entities: the cells of a box / disc / polygon embedded in the mesh (exactly
    G_r, the disc as the mesh's polygon), else `select_region` (boundary facets; on a mesh file
    the cells cut exactly by a box or polygon)."""
    if name not in smesh.roi_cells:
        return select_region(smesh, spec, path)
    sel = Selection("cells", smesh.roi_cells[name])
    if len(sel) == 0:
        where = f" of body {spec.body!r}" if spec.body is not None else ""
        raise StudyError(f"the region of interest covers no part of the scene{where}", path=path)
    return sel


def _measure(mesh, sel: Selection) -> float:
    if sel.kind == "cells":
        return float(_cell_moments(mesh, sel).sum())
    return float(_facet_measures(mesh, sel.index).sum())


def _cell_moments(mesh, sel: Selection) -> np.ndarray:
    """(vertices, n) ∫_{G ∩ T} λ_k dx of the selected cells; a 3D region of interest is embedded
    (whole tetrahedra: a quarter of the volume per vertex)."""
    if mesh.p.shape[0] == 2:
        return sel.cell_moments(mesh)
    return np.tile(tet.volumes(mesh.p, mesh.t[:, sel.index]) / 4.0, (4, 1))


def _facet_measures(mesh, facets) -> np.ndarray:
    """(n,) lengths (2D) or areas (3D) of the given facets."""
    if mesh.p.shape[0] == 2:
        return facet_lengths(mesh, facets)
    return tet.face_normals(mesh, facets)[1]


def _facet_normals(mesh, facets) -> np.ndarray:
    """(n, d) outward unit normals of boundary facets (3D: from the face's triangle)."""
    if mesh.p.shape[0] == 2:
        return facet_normals(mesh, facets)
    return tet.face_normals(mesh, facets)[0]


def _triangle_distances(x: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(k,) distances of the points x (k, 3) to the triangles tri (k, 3 vertices, 3), pair by
    pair: to the plane where the foot of the perpendicular lies in the triangle, else to its
    nearest edge."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    nn = (n * n).sum(axis=1)
    h = ((x - a) * n).sum(axis=1) / nn                              # signed, in units of |n|
    foot = x - h[:, None] * n
    inside = np.ones(h.shape, dtype=bool)
    edge = np.full(h.shape, np.inf)
    for p, q in ((a, b), (b, c), (c, a)):
        inside &= (np.cross(q - p, foot - p) * n).sum(axis=1) >= 0
        d = q - p
        s = np.clip(((x - p) * d).sum(axis=1) / (d * d).sum(axis=1), 0.0, 1.0)
        edge = np.minimum(edge, np.linalg.norm(x - p - s[:, None] * d, axis=1))
    return np.where(inside, np.abs(h) * np.sqrt(nn), edge)


def _distance_to_facets(mesh, facets, x: np.ndarray) -> np.ndarray:
    """(k,) distance of the points x (k, d) to the nearest of the given boundary facets. 3D: the
    triangles near each point only — a triangle lies within r (its vertices' largest distance
    from its centroid) of its centroid, so with u the distance to the triangle of the nearest
    centroid, no triangle whose centroid is farther than u + r can be nearer (exact: the same
    minimum as over every triangle; over all pairs, 6e7 of them on a 1e5 shear patch's contact
    criteria, it took 25 s). The triangles are searched in classes of r within a factor 2, each
    with its own largest r: with one r for all, a graded face (3D Hertz from a .msh: r from
    0.0024 to 0.157 m) made every point collect ~2,200 of 2,438 triangles, 64 of a 72 s solve."""
    if mesh.p.shape[0] == 2:
        a, b = mesh.p[:, mesh.facets[0, facets]].T, mesh.p[:, mesh.facets[1, facets]].T
        return dist_segments(x[:, 0], x[:, 1], a, b)
    from scipy.spatial import cKDTree
    tri = np.moveaxis(mesh.p[:, mesh.facets[:, facets]], 0, -1).transpose(1, 0, 2)   # (n, 3, 3)
    if len(x) == 0 or len(tri) == 0:
        return np.full(len(x), np.inf)
    centroid = tri.mean(axis=1)
    reach = np.linalg.norm(tri - centroid[:, None], axis=2).max(axis=1)
    _, nearest = cKDTree(centroid).query(x)
    bound = _triangle_distances(x, tri[nearest])
    level = np.floor(np.log2(np.maximum(reach, 1e-300) / max(reach.max(), 1e-300))).astype(int)
    out = np.full(len(x), np.inf)
    for L in np.unique(np.maximum(level, -60)):
        members = np.flatnonzero(np.maximum(level, -60) == L)
        near = cKDTree(centroid[members]).query_ball_point(x, bound + reach[members].max())
        point = np.repeat(np.arange(len(x)), [len(j) for j in near])
        cand = members[np.concatenate([np.asarray(j, dtype=np.int64) for j in near])]
        np.minimum.at(out, point, _triangle_distances(x[point], tri[cand]))
    return out


def _region_level(spec, x: np.ndarray) -> np.ndarray:
    """(k,) signed distance of the points x (k, 3) to a 3D box, ball or cylinder region of
    interest: the distance outside, minus the distance to its boundary inside."""
    if spec.ball is not None:
        return np.linalg.norm(x - np.asarray(spec.ball.center, float), axis=1) - spec.ball.radius
    if spec.box is not None:
        b = np.asarray(spec.box, float)
        q = np.maximum(b[:3] - x, x - b[3:])
    else:
        a, e = np.asarray(spec.cylinder.start, float), np.asarray(spec.cylinder.end, float)
        axis = (e - a) / np.linalg.norm(e - a)
        s = (x - a) @ axis
        radial = np.linalg.norm(x - a - s[:, None] * axis, axis=1)
        q = np.stack([radial - spec.cylinder.radius, np.maximum(-s, s - np.linalg.norm(e - a))], axis=1)
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def _region_distance(spec, path: str, x: np.ndarray) -> np.ndarray:
    """(k,) distance of the points x (k, d) to an area (2D) or volume (3D) region of interest
    (0 inside)."""
    if x.shape[1] == 2:
        return distance_function(spec, path)(x[:, 0], x[:, 1])
    return np.maximum(_region_level(spec, x), 0.0)


def cell_weights(model, sel: Selection) -> tuple[np.ndarray, np.ndarray]:
    """(cells, meas(G ∩ T)) of the cells a cell-wise mean over G_r runs over; a boundary
    region of interest: the cells along its facets, whole."""
    if sel.kind == "facets":
        cells = np.unique(model.smesh.mesh.f2t[0, sel.index])
        return cells, model.cell_area[cells]
    if sel.moments is None:
        return sel.index, model.cell_area[sel.index]
    return sel.index, sel.moments.sum(axis=0)


def _mean_weights(mesh, sel: Selection) -> np.ndarray:
    """Nodal weights ℓ with ℓ · v = (meas G)⁻¹ ∫_G v for a P1 field v (exact)."""
    w = np.zeros(mesh.p.shape[1])
    if sel.kind == "cells":
        m = _cell_moments(mesh, sel)
        for k in range(mesh.t.shape[0]):
            np.add.at(w, mesh.t[k, sel.index], m[k])
        return w / m.sum()
    L = _facet_measures(mesh, sel.index)
    nf = mesh.facets.shape[0]
    for k in range(nf):
        np.add.at(w, mesh.facets[k, sel.index], L / nf)
    return w / L.sum()


def _direction(smesh, spec, sel: Selection, path: str, roi: str) -> np.ndarray:
    """The fixed direction n(X_r): given, the outward normal of the boundary of the region's
    body at `point` X_r (X_r must lie on it, up to half an edge; at a node between edges (3D:
    faces) that turn by at most 30° their length- (area-) weighted mean normal, at a sharper
    corner refused), or the mean outward normal of a boundary region of interest."""
    mesh = smesh.mesh
    if spec.direction is not None:
        d = np.asarray(spec.direction, float)
        return d / np.linalg.norm(d)
    if spec.point is not None:
        X = np.asarray(spec.point, float)
        facets = boundary_facets(mesh)
        owners = smesh.cell_body[sel.index] if sel.kind == "cells" else smesh.cell_body[mesh.f2t[0, sel.index]]
        facets = facets[np.isin(smesh.cell_body[mesh.f2t[0, facets]], owners)]   # the ROI's own body
        dist, L, what = _point_to_facets(mesh, facets, X)
        k = int(np.argmin(dist))
        bodies = ", ".join(smesh.bodies[i] for i in np.unique(owners))
        if dist[k] > 0.5 * L[k]:
            raise StudyError(f"point {X.tolist()} is not on the boundary of body {bodies} (region "
                             f"'{roi}'): the nearest boundary {what} is {dist[k]:.6g} away; X_r must lie "
                             "on the boundary", path=f"{path}.point")
        tied = dist <= dist[k] + 1e-3 * L[k]
        n = _facet_normals(mesh, facets[tied])
        if np.min(n @ n.T) < CORNER:
            raise StudyError(f"point {X.tolist()} is equally near boundary {what}s of body {bodies} "
                             f"whose outward normals differ by more than 30° (a corner, or the two "
                             "sides of an interface): n(X_r) is not defined there; move the point "
                             "or give `direction`",
                             path=f"{path}.point")
        weight = L[tied] if mesh.p.shape[0] == 2 else _facet_measures(mesh, facets[tied])
        m = (n * weight[:, None]).sum(axis=0)
        return m / np.linalg.norm(m)
    if sel.kind == "facets":
        n = (_facet_normals(mesh, sel.index) * _facet_measures(mesh, sel.index)[:, None]).sum(axis=0)
        return n / np.linalg.norm(n)
    raise StudyError(f"a mean normal displacement over an {'area' if mesh.p.shape[0] == 2 else 'volume'} "
                     f"(region '{roi}') needs `point` (X_r) or `direction`", path=path)


def _point_to_facets(mesh, facets, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """(distance of X to each facet, the facet's size: length or longest edge, its name)."""
    if mesh.p.shape[0] == 2:
        a, b = mesh.p[:, mesh.facets[0, facets]], mesh.p[:, mesh.facets[1, facets]]
        e = b - a
        s = np.clip(((X[:, None] - a) * e).sum(axis=0) / (e * e).sum(axis=0), 0.0, 1.0)
        return np.hypot(*(X[:, None] - a - s * e)), np.hypot(*e), "edge"
    tri = np.moveaxis(mesh.p[:, mesh.facets[:, facets]], 0, -1).transpose(1, 0, 2)   # (n, 3, 3)
    size = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    return _triangle_distances(np.repeat(X[None], len(tri), axis=0), tri), size, "face"


def _cell_mean(model, sel: Selection, density: np.ndarray) -> float:
    cells, a = cell_weights(model, sel)
    return float(a @ density[cells] / a.sum())


def _contact_rows_in(smesh, scene, zone, roi: str, sel: Selection, path: str) -> np.ndarray:
    """Contact rows (slave nodes) next to G_r: the slave node x or its master projection
    x + gap·n lies in G_r, so a region on either side of a contact, open or closed, matching
    or not, catches the same rows. A boundary G_r is its facets; an area (volume) one its shape."""
    normal = np.concatenate([p.normal for p in zone.pairs])
    pts = np.vstack([zone.coords, zone.coords + zone.gap[:, None] * normal])
    if sel.kind == "facets":
        dist = _distance_to_facets(smesh.mesh, sel.index, pts)
    else:
        dist = _region_distance(scene.regions_of_interest[roi], path, pts)
    scale = max(np.ptp(pts, axis=0).max(), 1e-300)
    size = zone.weight if pts.shape[1] == 2 else np.sqrt(zone.weight)    # a length: the row's extent
    near = dist <= 1e-6 * scale + 1e-3 * np.tile(size, 2)
    mask = near[:zone.gap.size] | near[zone.gap.size:]
    if not mask.any():
        raise StudyError(f"region of interest '{roi}' holds no contact node nor its master "
                         "projection: a contact pressure criterion needs a region next to a contact",
                         path=path)
    return mask


def _crossings(spec, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(s, K) parameters t ∈ [0, 1] where the edges a + t (b − a) cross the boundary of a box,
    disc or polygon (NaN: none); between two of them an edge is wholly inside or outside."""
    d = b - a
    if spec.disc is not None:
        c, r = np.asarray(spec.disc.center, float), float(spec.disc.radius)
        e = a - c
        qa, qb, qc = (d * d).sum(axis=1), 2 * (d * e).sum(axis=1), (e * e).sum(axis=1) - r * r
        disc = qb * qb - 4 * qa * qc
        root = np.sqrt(np.where(disc > 0, disc, np.nan))
        t = np.stack([(-qb - root) / (2 * qa), (-qb + root) / (2 * qa)], axis=1)
    else:
        if spec.box is not None:
            x0, y0, x1, y1 = map(float, spec.box)
            pts = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        else:
            pts = np.asarray(spec.polygon, float)
        c, e = np.roll(pts, 1, axis=0), pts - np.roll(pts, 1, axis=0)       # the polygon's edges c + u e
        det = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
        w = c[None] - a[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[..., 0] * e[None, :, 1] - w[..., 1] * e[None, :, 0]) / det
            u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / det
        t = np.where((u >= 0) & (u <= 1), t, np.nan)                       # parallel edges: NaN
    return np.where((t > 0) & (t < 1), t, np.nan)


def _pressure_functional(smesh, scene, zone, roi: str, sel: Selection, path: str):
    """(ℓ_r, meas Γc ∩ G_r) with ℓ_r · λ_n = (meas Γc ∩ G_r)⁻¹ ∫_{Γc ∩ G_r} p_h ds, Φ6 [68, (4.34)]:
    p_h the piecewise linear interpolant along the slave side of the nodal pressures
    p_i = λ_i / w_i (w_i: the row's weight, node-to-node or mortar), integrated exactly.
    A point of a slave edge lies in G_r when it or its master projection does (the projection
    of x_i is x_i + gap_i n_i, interpolated along the edge), so a region on either side of a
    contact, open or closed, catches the same part of it. Each edge is cut where it or its
    projection crosses the boundary of G_r (a boundary G_r: at its facets' ends), and each piece
    is in or out by its midpoint: in G_r up to 1e-6 of the contact's extent (round-off), next
    to a boundary G_r up to a tenth of the edge more (the chord between two projections on a
    curved master side leaves it by about L²/8R). 3D: `_pressure_functional_3d`."""
    if smesh.mesh.p.shape[0] == 3:
        return _pressure_functional_3d(smesh, scene, zone, roi, sel, path)
    seg = slave_segments(zone, scene, smesh)
    normal = np.concatenate([p.normal for p in zone.pairs])
    ends = [(zone.coords[seg[:, 0]], zone.coords[seg[:, 1]]),
            (zone.coords[seg[:, 0]] + (zone.gap[:, None] * normal)[seg[:, 0]],
             zone.coords[seg[:, 1]] + (zone.gap[:, None] * normal)[seg[:, 1]])]
    length = np.hypot(*(ends[0][1] - ends[0][0]).T)
    tol = 1e-6 * max(np.ptp(np.vstack([zone.coords, ends[1][0], ends[1][1]]), axis=0).max(), 1e-300)
    if sel.kind == "facets":
        mesh = smesh.mesh
        fa, fb = mesh.p[:, mesh.facets[0, sel.index]].T, mesh.p[:, mesh.facets[1, sel.index]].T
        corners, tol = np.vstack([fa, fb]), tol + 0.1 * length[:, None]

        def dist(x, y):
            return dist_segments(x, y, fa, fb)

        def cuts(a, b):                         # where the facets' ends project on the edge
            d = b - a
            return ((corners[None] - a[:, None]) * d[:, None]).sum(axis=2) / (d * d).sum(axis=1)[:, None]
    else:
        spec = scene.regions_of_interest[roi]
        dist = distance_function(spec, path)

        def cuts(a, b):
            return _crossings(spec, a, b)
    t = np.hstack([np.zeros((len(seg), 1)), np.ones((len(seg), 1))] + [cuts(a, b) for a, b in ends])
    t = np.sort(np.where((t >= 0) & (t <= 1), t, np.nan), axis=1)           # NaN last
    t0, t1 = t[:, :-1], t[:, 1:]
    mid = np.nan_to_num(0.5 * (t0 + t1))
    inside = np.zeros(mid.shape, dtype=bool)
    real = ~np.isnan(t1)                        # the pieces (the NaN-padded ones have no length)
    e, tol = np.nonzero(real)[0], np.broadcast_to(tol, mid.shape)[real]
    for a, b in ends:
        x = a[e] + mid[real][:, None] * (b - a)[e]
        inside[real] |= dist(x[:, 0], x[:, 1]) <= tol
    piece = np.where(inside, np.nan_to_num(t1 - t0), 0.0) * length[:, None]
    meas = float(piece.sum())
    if meas <= 0:
        raise StudyError(f"region of interest '{roi}' covers no length of a contact's slave side "
                         "(nor of its master projection): a contact pressure criterion needs one",
                         path=path)
    ell = np.zeros(zone.gap.size)
    np.add.at(ell, seg[:, 0], (piece * (1 - mid)).sum(axis=1))
    np.add.at(ell, seg[:, 1], (piece * mid).sum(axis=1))
    return ell / zone.weight / meas, meas


def _pressure_functional_3d(smesh, scene, zone, roi: str, sel: Selection, path: str):
    """Φ6 on tetrahedra: (ℓ_r, meas Γc ∩ G_r) with ℓ_r · λ_n the mean over Γc ∩ G_r of the P1
    interpolant on the slave triangles of the nodal pressures λ_i / w_i, exact over whole
    triangles (∫_T p_h = |T|/3 Σ p_i). The slave triangles are not cut: a triangle is in G_r
    when its three vertices are, or the three vertices of its master projection (x_i + gap_i n_i)
    are, up to 1e-6 of the contact's extent (a boundary G_r: its vertices and centroid within that
    plus a tenth of its longest edge of G_r's faces). A box, ball or cylinder region is embedded in
    the mesh of a scene built from shapes (a ball, a cylinder as the mesh's polyhedron, whose
    vertices lie on the true surface), so every slave triangle is wholly in or out of it; a
    triangle with vertices clearly inside and clearly outside (on the slave side and on its
    projection) would need the integral over a curved cut and is refused."""
    tri = slave_segments(zone, scene, smesh)                    # (s, 3) rows of each slave triangle
    normal = np.concatenate([p.normal for p in zone.pairs])
    sides = [zone.coords[tri], (zone.coords + zone.gap[:, None] * normal)[tri]]   # (s, 3, 3) each
    e = sides[0] - np.roll(sides[0], 1, axis=1)
    area = 0.5 * np.linalg.norm(np.cross(e[:, 1], e[:, 2]), axis=1)
    tol = 1e-6 * max(np.ptp(np.vstack([s.reshape(-1, 3) for s in sides]), axis=0).max(), 1e-300)
    inside = np.zeros(len(tri), dtype=bool)
    cut = np.zeros(len(tri), dtype=bool)
    for x in sides:
        if sel.kind == "facets":
            pts = np.concatenate([x, x.mean(axis=1, keepdims=True)], axis=1)     # vertices, centroid
            near = tol + 0.1 * np.linalg.norm(e, axis=2).max(axis=1)
            d = _distance_to_facets(smesh.mesh, sel.index, pts.reshape(-1, 3)).reshape(len(tri), 4)
            inside |= (d <= near[:, None]).all(axis=1)
        else:
            level = _region_level(scene.regions_of_interest[roi], x.reshape(-1, 3)).reshape(len(tri), 3)
            inside |= (level <= tol).all(axis=1)
            cut |= (level < -tol).any(axis=1) & (level > tol).any(axis=1)
    cut &= ~inside
    if cut.any():
        c = zone.coords[tri[np.flatnonzero(cut)[0]]].mean(axis=0)
        raise StudyError(f"region of interest '{roi}' cuts {int(cut.sum())} slave triangles of the contact "
                         f"(one at {np.round(c, 6).tolist()}): its surface crosses them, and the mean "
                         "pressure over a curved cut is not integrated exactly; a region of a scene built "
                         "from shapes is embedded in the mesh and cuts none", path=path)
    meas = float(area[inside].sum())
    if meas <= 0:
        raise StudyError(f"region of interest '{roi}' covers no area of a contact's slave side "
                         "(nor of its master projection): a contact pressure criterion needs one",
                         path=path)
    ell = np.zeros(zone.gap.size)
    for k in range(3):
        np.add.at(ell, tri[:, k], np.where(inside, area, 0.0) / 3.0)
    return ell / zone.weight / meas, meas


# ---------------------------------------------------------------- the kinds

def _normal_functional(smesh, spec, sel: Selection, path: str, roi: str) -> np.ndarray:
    """ℓ_r with ℓ_r · u = mean over G_r of u · n(X_r)."""
    d = _direction(smesh, spec, sel, path, roi)
    nodal = _mean_weights(smesh.mesh, sel)
    ell = np.zeros(d.size * nodal.size)
    for i in range(d.size):
        ell[i::d.size] = nodal * d[i]
    return ell


def _stress_partials(model, state, sel: Selection, dpsi: np.ndarray) -> Partials:
    """Partials of Φ = Σ_c a_c ψ(τ_c) / Σ a_c given ∂ψ/∂τ per cell (4 or 6, nc);
    τ = D(λ, μ) e − β ΔT m."""
    sm, mesh = model.smesh, model.smesh.mesh
    cells, a = cell_weights(model, sel)
    weight = np.zeros(mesh.t.shape[1])
    weight[cells] = a / a.sum()
    d = dpsi * weight                                          # ∂Φ/∂τ per cell
    c = state.coefficients
    reg = sm.cell_region
    lam, mu, beta = c.lam[reg], c.mu[reg], c.beta[reg]
    if mesh.p.shape[0] == 3:                                   # τ_ii = λ tr e + 2μ e_ii − βΔT, τ_ij = μ γ_ij
        strain = (model.G @ state.u).reshape(6, -1)
        trace_load = d[0] + d[1] + d[2]
        de = np.vstack([lam * trace_load + 2 * mu * d[:3], mu * d[3:]])
        dlam = trace_load * strain[:3].sum(axis=0)
        dmu = 2 * (strain[:3] * d[:3]).sum(axis=0) + (strain[3:] * d[3:]).sum(axis=0)
    else:
        exx, eyy, gxy = (model.G @ state.u).reshape(3, -1)
        dz = d[2] if model.plane == "strain" else np.zeros_like(d[2])
        trace_load = d[0] + d[1] + dz                          # ∂Φ/∂(λ tr − βΔT) along m
        de = np.array([(lam + 2 * mu) * d[0] + lam * (d[1] + dz),
                       lam * (d[0] + dz) + (lam + 2 * mu) * d[1],
                       mu * d[3]])
        dlam, dmu = trace_load * (exx + eyy), 2 * exx * d[0] + 2 * eyy * d[1] + gxy * d[3]
    nr = len(model.region_cells)
    per_region = lambda v: np.bincount(reg, weights=v, minlength=nr)   # noqa: E731
    dT = (np.zeros(reg.size) if state.T is None
          else state.T[mesh.t].mean(axis=0) - c.reference)
    coef = {"lam": per_region(dlam),
            "mu": per_region(dmu),
            "beta": per_region(-dT * trace_load),
            "reference": np.array([np.sum(beta * trace_load)])}
    theta = None
    if state.T is not None:
        nodal = np.zeros(mesh.p.shape[1])
        nv = mesh.t.shape[0]
        for k in range(nv):
            np.add.at(nodal, mesh.t[k], -beta * trace_load / nv)
        theta = model.P.T @ nodal
    return Partials(u=model.G.T @ de.ravel(), theta=theta, coef=coef)


def _invariants(s: np.ndarray):
    """The stress module of the components s: `wcs.fem.stress` (4: xx yy zz xy) or
    `wcs.geometry.tet` (6: xx yy zz yz xz xy)."""
    return tet if len(s) == 6 else stress


def _shear_intensity(s: np.ndarray) -> np.ndarray:
    return _invariants(s).shear_intensity(s)


def _von_mises(s: np.ndarray) -> np.ndarray:
    return _invariants(s).von_mises(s)


def _dI2(s: np.ndarray) -> np.ndarray:
    """∂I₂²/∂τ (4 or 6, nc), each shear component counted twice (τ_xy = τ_yx)."""
    xx, yy, zz = s[:3]
    dI = (2.0 / 3.0) * np.vstack([[2 * xx - yy - zz, 2 * yy - xx - zz, 2 * zz - xx - yy], 3 * s[3:]])
    dI[3:] *= 2.0                                             # ∂I₂²/∂τ_xy = 4 τ_xy
    return dI


def _dvon_mises(s: np.ndarray) -> np.ndarray:
    """∂σ_vM/∂τ = (3/4) ∂I₂²/∂τ / σ_vM (σ_vM = √(3/2 I₂²)); 0 where σ_vM = 0."""
    vm = np.sqrt(1.5 * _shear_intensity(s))
    return _dI2(s) * np.where(vm > 0, 0.75 / np.where(vm > 0, vm, 1.0), 0.0)


def _principal_max(s: np.ndarray) -> np.ndarray:
    """σ₁, the largest principal stress (in 2D the in-plane one: the field `principal_stress`,
    first column)."""
    return _invariants(s).principal(s)[:, 0]


def _dprincipal_max(s: np.ndarray) -> np.ndarray:
    """∂σ₁/∂τ. 2D: σ₁ = (τxx+τyy)/2 + r, r = √(((τxx−τyy)/2)² + τxy²); at r = 0 (σ₁ = σ₂,
    a kink) the mean of the one-sided derivatives, (½, ½, 0, 0). 3D: σ₁ = vᵀτv with v the
    unit eigenvector of σ₁, ∂σ₁/∂τ = v vᵀ (a shear component twice); where σ₁ is a multiple
    eigenvalue (a kink, `_principal_kink`) the mean of the tied eigenvectors' projectors."""
    if len(s) == 6:
        w, V = np.linalg.eigh(tet.tensor(s))                  # ascending
        tied = (w[:, 2:] - w) <= REL_TOL * np.abs(s).max(axis=0)[:, None]
        P = np.einsum("cik,cjk,ck->cij", V, V, tied) / tied.sum(axis=1)[:, None, None]
        return np.array([P[:, 0, 0], P[:, 1, 1], P[:, 2, 2], 2 * P[:, 1, 2], 2 * P[:, 0, 2], 2 * P[:, 0, 1]])
    xx, yy, _, xy = s
    r = np.sqrt((0.5 * (xx - yy)) ** 2 + xy**2)
    q = np.where(r > 0, 1.0 / np.where(r > 0, r, 1.0), 0.0)
    return np.array([0.5 + 0.25 * (xx - yy) * q, 0.5 - 0.25 * (xx - yy) * q, np.zeros_like(r), xy * q])


def _principal_kink(s: np.ndarray) -> np.ndarray:
    """Cells where σ₁ ≈ σ₂ (relative to the cell's stress): σ₁ is not differentiable there."""
    if len(s) == 6:
        p = tet.principal(s)
        return p[:, 0] - p[:, 1] <= REL_TOL * np.abs(s).max(axis=0)
    xx, yy, _, xy = s
    return np.sqrt((0.5 * (xx - yy)) ** 2 + xy**2) <= REL_TOL * np.abs(s).max(axis=0)


def _area_kind(label: str, units: str, density: Callable, ddensity: Callable,
               kink: Callable | None = None) -> Kind:
    """A mean over G_r of a cell density ψ(τ) (as Φ5): value and partials from ψ and ∂ψ/∂τ;
    `kink(τ)`: the cells where ψ is not differentiable."""
    def partials(crit, model, state, r):
        sel = crit.selections[r]
        nonsmooth = kink is not None and bool(kink(state.stress)[cell_weights(model, sel)[0]].any())
        return _stress_partials(model, state, sel, ddensity(state.stress)), nonsmooth
    return Kind(label, units, partials=partials,
                value=lambda crit, model, state, r: _cell_mean(model, crit.selections[r], density(state.stress)))


def node_norm(v: np.ndarray, m: int) -> np.ndarray:
    """(m,) the norm of each contact node's tangent components (rows j·m + i; one in 2D: its
    absolute value)."""
    return np.abs(v) if v.size == m else np.linalg.norm(v.reshape(-1, m), axis=0)


def _slip_mean(crit, model, state, r) -> float:
    """Mean |relative tangential displacement| over the contact nodes next to G_r: Σ w|s| / Σ w
    (3D: |s| the length of the node's two-component slip)."""
    mask, c = crit.contact_masks[r], state.contact
    return float(c.weight[mask] @ node_norm(c.slip, mask.size)[mask] / c.weight[mask].sum())


def _slip_partials(crit, model, state, r):
    """∂Φ/∂u = Btᵀ (w ν) / Σ w over the rows next to G_r (s = Bt u, ν = s/|s|: sign(s) in 2D).
    |s| has a kink at s = 0, which matters only where s can cross 0: a stuck node keeps s fixed
    on its active set (and a stick/slip switch is flagged with the active set), and a node whose
    reduced tangential rows vanish or are round-off (`Model.held`: held by supports on both
    sides) has s fixed by them; any other node in G_r with s ≈ 0 makes the point non-smooth."""
    mask, c = crit.contact_masks[r], state.contact
    m = mask.size
    k = c.slip.size // m
    norm = node_norm(c.slip, m)
    w = np.where(mask, c.weight, 0.0)
    nu = np.divide(c.slip, np.tile(norm, k), out=np.zeros_like(c.slip), where=np.tile(norm > 0, k))
    dslip = np.tile(w, k) * nu / w.sum()
    stuck = state.raw.free[m:2 * m] if state.raw is not None else np.zeros(m, dtype=bool)
    scale = max(np.abs(c.slip).max(), np.abs(state.u).max(), 1e-300)
    moves = (~model.held[m:]).reshape(k, m).any(axis=0)
    kink = mask & ~stuck & moves & (norm <= REL_TOL * scale)
    return Partials(u=model.zone.Bt.T @ dslip), bool(kink.any())


def _pressure_partials(ell: np.ndarray, model, state) -> Partials:
    """∂(ℓ · λn)/∂λ of the solver's multipliers through the reported λn (`wcs.contact.zone.
    canonical_split`'s jacobian): a tied node's canonical λn + κ λt, a dependent node's least
    |λt| split, 0 on a held normal or a tied node pulled apart. Each is a function of the
    combination that acts, so its derivative holds whichever split the solver's path found."""
    jac = state.contact.jacobian
    if jac is None:
        return Partials(lam_n=ell.copy())
    dn, dt = jac
    lam_t = np.tile(ell, dt.size // ell.size) * dt
    return Partials(lam_n=ell * dn, lam_t=lam_t if lam_t.any() else None)


def _peak_pressure(crit, model, state, r) -> float:
    """The largest nodal contact pressure λ_i / w_i over the contact rows next to G_r."""
    return float(state.contact.pressure[crit.contact_masks[r]].max())


def _peak_partials(crit, model, state, r):
    """∂Φ/∂λ of the maximising row k's pressure λ_k / w_k (as Φ6's, `_pressure_partials`). The
    maximum is differentiable where k is the only maximiser; another row in reach of it (within
    REL_TOL of the peak, as the other kinds' ties) makes the point non-smooth, unless the peak is
    0: then every row in G_r is open or unloaded and the active set decides."""
    mask, p = crit.contact_masks[r], state.contact.pressure
    rows = np.flatnonzero(mask)
    k = rows[int(np.argmax(p[rows]))]
    ell = np.zeros(p.size)
    ell[k] = 1.0 / state.contact.weight[k]
    tied = bool((p[rows] >= p[k] - REL_TOL * abs(p[k])).sum() > 1 and p[k] > 0)
    return _pressure_partials(ell, model, state), tied


def in_words(kind: str, regions: list[str]) -> str:
    """What a criterion is, in words: its kind's reduction over its region of interest, or the
    largest over several regions of the reduction over each ([68, (4.29)–(4.34)])."""
    label = KINDS[kind].label if kind in KINDS else (kind or "criterion")
    if not regions:
        return label
    if len(regions) == 1:
        return f"{label} over {regions[0]}"
    return f"the largest over {', '.join(regions)} of the {label} over each"


KINDS: dict[str, Kind] = {
    "mean_temperature": Kind(
        "mean temperature (Φ1/Φ2)", "K",
        value=lambda crit, model, state, r: crit.functionals[r] @ state.T,
        partials=lambda crit, model, state, r: (Partials(theta=model.P.T @ crit.functionals[r]), False),
        functional=lambda smesh, spec, sel, path, roi: _mean_weights(smesh.mesh, sel), needs="thermal"),
    "mean_normal_displacement": Kind(
        "mean normal displacement (Φ3/Φ4)", "m",
        value=lambda crit, model, state, r: crit.functionals[r] @ state.u,
        partials=lambda crit, model, state, r: (Partials(u=crit.functionals[r].copy()), False),
        functional=_normal_functional, options=("point", "direction")),
    "shear_stress_intensity": _area_kind("mean shear stress intensity I₂² (Φ5)", "Pa^2", _shear_intensity, _dI2),
    "contact_pressure": Kind(
        "mean contact pressure (Φ6)", "Pa",
        value=lambda crit, model, state, r: crit.functionals[r] @ state.contact.force_n,
        partials=lambda crit, model, state, r: (_pressure_partials(crit.functionals[r], model, state), False),
        contact_functional=_pressure_functional, reads="contact", needs="contacts"),
    "von_mises": _area_kind("mean von Mises stress", "Pa", _von_mises, _dvon_mises),
    "principal_stress": _area_kind("mean largest principal stress σ₁ (in-plane in 2D)", "Pa", _principal_max,
                                   _dprincipal_max, _principal_kink),
    "contact_slip": Kind("mean contact slip |relative tangential displacement|", "m",
                         value=_slip_mean, partials=_slip_partials, reads="contact", needs="contacts"),
    "contact_pressure_peak": Kind("largest nodal contact pressure", "Pa", value=_peak_pressure,
                                  partials=_peak_partials, reads="contact", needs="contacts"),
}
