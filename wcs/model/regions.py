"""The regions of interest of a criterion on the mesh: the selection of each G_r (embedded cells,
cells cut exactly, or boundary facets) and its measure, the weights of a mean over it, the outward
direction at a point of it, the contact rows next to it and the pressure functional ℓ_r over
Γc ∩ G_r (Φ6 [68, (4.34)]). The criteria (`wcs.model.criteria`) average their densities with
these."""
from __future__ import annotations

import numpy as np

from ..contact.zone import slave_segments
from ..errors import StudyError
from ..geometry import tet
from ..geometry.facets import boundary_facets, facet_lengths, facet_normals
from ..geometry.near import within
from ..scene.selectors import Selection, dist_segments, distance_function, select_region

CORNER = np.cos(np.radians(30.0))   # boundary edges nearest X_r turning by more: a corner, n(X_r) undefined


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


def _distance_to_facets(mesh, facets, x: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """(k,) distance of the points x (k, d) to the nearest of the given boundary facets where it
    is at most cap (k,), inf where it is more (the callers compare it with cap or less). 3D: the
    triangles near each point only — a triangle lies within r (its vertices' largest distance
    from its centroid) of its centroid, so one within cap of a point has its centroid within
    cap + r of it (`wcs.geometry.near.within`; the same minimum as over every triangle, which over
    all pairs, 6e7 of them on a 1e5 shear patch's contact criteria, took 25 s). The triangles are
    searched in classes of r within a factor 2, each with its own largest r: with one r for all, a
    graded face (3D Hertz from a .msh: r from 0.0024 to 0.157 m) made every point collect ~2,200
    of 2,438 triangles, 64 of a 72 s solve."""
    cap = np.broadcast_to(np.asarray(cap, float), (len(x),))
    if mesh.p.shape[0] == 2:
        a, b = mesh.p[:, mesh.facets[0, facets]].T, mesh.p[:, mesh.facets[1, facets]].T
        d = dist_segments(x[:, 0], x[:, 1], a, b)
        return np.where(d <= cap, d, np.inf)
    tri = np.moveaxis(mesh.p[:, mesh.facets[:, facets]], 0, -1).transpose(1, 0, 2)   # (n, 3, 3)
    out = np.full(len(x), np.inf)
    if len(x) == 0 or len(tri) == 0:
        return out
    centroid = tri.mean(axis=1)
    reach = np.linalg.norm(tri - centroid[:, None], axis=2).max(axis=1)
    level = np.floor(np.log2(np.maximum(reach, 1e-300) / max(reach.max(), 1e-300))).astype(int)
    level = np.maximum(level, -60)
    for L in np.unique(level):
        members = np.flatnonzero(level == L)
        for q, k, _ in within(centroid[members], x, cap + reach[members].max()):
            d = _triangle_distances(x[q], tri[members[k]])
            np.minimum.at(out, q, np.where(d <= cap[q], d, np.inf))
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
    scale = max(np.ptp(pts, axis=0).max(), 1e-300)
    size = zone.weight if pts.shape[1] == 2 else np.sqrt(zone.weight)    # a length: the row's extent
    tol = 1e-6 * scale + 1e-3 * np.tile(size, 2)
    if sel.kind == "facets":
        dist = _distance_to_facets(smesh.mesh, sel.index, pts, tol)
    else:
        dist = _region_distance(scene.regions_of_interest[roi], path, pts)
    near = dist <= tol
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
    ends = [zone.coords, zone.coords + zone.gap[:, None] * normal]     # slave nodes, their projections
    sides = [a[tri] for a in ends]                                      # (s, 3, 3) each
    e = sides[0] - np.roll(sides[0], 1, axis=1)
    area = 0.5 * np.linalg.norm(np.cross(e[:, 1], e[:, 2]), axis=1)
    tol = 1e-6 * max(np.ptp(np.vstack([s.reshape(-1, 3) for s in sides]), axis=0).max(), 1e-300)
    inside = np.zeros(len(tri), dtype=bool)
    cut = np.zeros(len(tri), dtype=bool)
    nodes, corner = np.unique(tri, return_inverse=True)         # each node once (~6 triangles share one)
    for a, x in zip(ends, sides):
        if sel.kind == "facets":
            near = tol + 0.1 * np.linalg.norm(e, axis=2).max(axis=1)
            cap = np.zeros(len(nodes))                          # a node: the widest of its triangles'
            np.maximum.at(cap, corner.ravel(), np.repeat(near, 3))
            d = _distance_to_facets(smesh.mesh, sel.index, np.concatenate([a[nodes], x.mean(axis=1)]),
                                    np.concatenate([cap, near]))
            d = np.column_stack([d[corner.reshape(tri.shape)], d[len(nodes):]])   # vertices, centroid
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
