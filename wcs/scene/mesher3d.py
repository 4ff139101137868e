"""A typed 3D scene (`wcs.scene.spec3d.Scene`) -> gmsh (OpenCASCADE) solids -> :class:`SceneMesh`
with a MeshTet.

Solids (``SOLID``, `spec3d.Solid`), each with optional, recursive ``intersect: [SOLID, ...]`` (applied
first, in turn) and ``minus: [SOLID, ...]`` (cut by their union):

* ``box: [xmin, ymin, zmin, xmax, ymax, zmax]``,
* ``cylinder: {start: [x, y, z], end: [x, y, z], radius: r}`` (the axis from start to end),
* ``sphere: {center: [x, y, z], radius: r}``,
* ``extrude: {shape: <2D shape of wcs.scene.geometry in the plane z = 0>, vector: [dx, dy, dz]}``,
* ``halfspace: {point: [x, y, z], normal: [nx, ny, nz]}``: the points p with
  (p − point)·normal ≤ 0; only inside ``intersect`` / ``minus`` (it is made as a box that
  covers the solid it cuts, one face on the plane).

Face selectors (``FACE_SELECTOR``, boundary facets: after the node duplication below the faces
where two bodies touch are boundary facets of each body), each with optional ``body: NAME``;
a facet is selected when its three nodes lie on the set, within ``REL_TOL`` times the facet's
longest edge (plus ``ABS_TOL`` times the scene size) or the ``tolerance`` a plane gives:

* ``plane: {point, normal, tolerance}`` (tolerance optional): facets lying in that plane,
* ``box: [six numbers]``: facets inside the closed box,
* ``cylinder: {start, end, radius}``: facets on the lateral surface between start and end,
* ``sphere: {center, radius}``: facets on the sphere.

Region selectors (``REGION_SELECTOR``), with optional ``body``: ``box: [six numbers]``,
``ball: {center, radius}``, ``cylinder: {start, end, radius}`` are solids fragmented with the
bodies, so G_r is a union of cells (``SceneMesh.roi_cells``; a ball or cylinder: its polyhedral
mesh); ``boundary: NAME`` (the facets of a named boundary, nothing embedded) is
``wcs.scene.selectors.select_region``'s (given a typed ``RegionOfInterest``), which takes this mesh as it is.

How it is done (as the 2D ``wcs.scene.mesher2d``): every region solid and every embedded region
of interest goes through one ``occ.fragment``, so regions of a body share nodes and touching
bodies have matching triangles on their common faces; a piece belongs to the region covering it;
a piece covered by two bodies, or by two regions of one body, is an overlap (``StudyError`` at
``scene.bodies.<later body>`` / ``….regions.<later>``); a region left with no volume is a ``StudyError`` at its path.
Each body gets its own copy of the nodes on faces shared with another body. The size is
``mesh.size`` (``Mesh.MeshSizeMax``; default: the rule of ``wcs.choose.mesh_size`` with the
bounding-box diagonal), with ``Mesh.MeshSizeFromCurvature`` elements per 2π of arc, and finer
in the ``mesh.refine`` zones ``{box | ball | cylinder | boundary, size}``: the size at x is
``min(size, min_r (size_r + grading · dist_r(x)))`` (``mesh.grading``, default 0.5), as in 2D.
A region's own ``mesh: {size}`` bounds the size in its volumes and on their faces, edges and
corners (the smallest of the regions around a shared face), as in 2D: regions stay conforming.
If any body has its own ``bodies.<b>.mesh: {size, refine}``, every body is meshed in a gmsh model of its own after the
global fragment (which still decides ownership and overlaps), with its size or the scene's: the
faces it shares with other bodies are then nonmatching (mortar contact) and carry no imprint
of the other body's outline.
Deterministic: one gmsh session (``wcs.scene.session``), one thread, Delaunay 3D
(``Mesh.Algorithm3D = 1``), nodes and cells numbered from gmsh's order; cells grouped by
body, region, gmsh volume; nodes by body, then gmsh order; positively oriented cells.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.sparse as sp
import skfem
from scipy.sparse.csgraph import connected_components

from ..choose import MeshFacts, mesh_size
from ..errors import StudyError
from . import selectors
from .geometry import kernel, make_shape
from .meshdata import SceneMesh
from .meshfile import made_facets, read_mesh_file
from .pieces import closure, region_entity_sizes, fragment_pieces, piece_owners, refuse_roi_apart, region_names
from .session import Session, gmsh
from .estimate import DEFAULT_GRADING
from .spec3d import Boundary, Plane, Refinement, RegionOfInterest, Scene, Solid

FACE_KINDS = ("plane", "box", "cylinder", "sphere")
ROI_SOLIDS = {"box": "box", "ball": "sphere", "cylinder": "cylinder"}   # embedded region -> solid
ALGORITHM_3D = 1                 # Delaunay
REL_TOL = 1e-3
ABS_TOL = 1e-12

DimTags = list[tuple[int, int]]


# ---------------------------------------------------------------------------
# solids


def _halfspace(plane: Plane, cut: DimTags) -> DimTags:
    """{(p − point)·n ≤ 0} as a box of side 2L, one face on the plane, L ≥ the distance from
    `point` to every point of the solids `cut` (their bounding box)."""
    occ = gmsh.model.occ
    point, n = np.array(plane.point), np.array(plane.normal) / np.linalg.norm(plane.normal)
    lo = np.min([occ.getBoundingBox(*dt)[:3] for dt in cut], axis=0)
    hi = np.max([occ.getBoundingBox(*dt)[3:] for dt in cut], axis=0)
    L = float(np.linalg.norm(hi - lo) + np.linalg.norm(0.5 * (lo + hi) - point)) or 1.0
    box = [(3, occ.addBox(point[0] - L, point[1] - L, point[2] - 2 * L, 2 * L, 2 * L, 2 * L))]
    axis = np.cross([0.0, 0.0, 1.0], n)                       # turn e_z onto n about `point`
    if np.linalg.norm(axis) > 1e-15:
        occ.rotate(box, *point, *axis, math.atan2(np.linalg.norm(axis), n[2]))
    elif n[2] < 0:
        occ.rotate(box, *point, 1.0, 0.0, 0.0, math.pi)
    return box


def _primitive(shape: Solid, path: str) -> DimTags:
    occ = gmsh.model.occ
    if shape.box is not None:
        b = np.array(shape.box)
        return [(3, occ.addBox(*b[:3], *(b[3:] - b[:3])))]
    if shape.cylinder is not None:
        a, b = np.array(shape.cylinder.start), np.array(shape.cylinder.end)
        return [(3, occ.addCylinder(*a, *(b - a), shape.cylinder.radius))]
    if shape.sphere is not None:
        return [(3, occ.addSphere(*shape.sphere.center, shape.sphere.radius))]
    if shape.extrude is not None:
        p = f"{path}.extrude"
        base = make_shape(shape.extrude.shape, f"{p}.shape")
        out = kernel(p, occ.extrude, base, *shape.extrude.vector)
        return [dt for dt in out if dt[0] == 3]
    raise StudyError("a halfspace is unbounded: use it inside `intersect` or `minus` of a solid",
                     path=f"{path}.halfspace")


def _tool(shape: Solid, path: str, cut: DimTags) -> DimTags:
    """A solid used to intersect or cut `cut`: a halfspace is sized to cover `cut`."""
    if shape.halfspace is not None:
        return _halfspace(shape.halfspace, cut)
    return make_solid(shape, path)


def make_solid(shape: Solid, path: str) -> DimTags:
    """Create the solid ``shape`` in the current OCC model; return its volumes (dim 3 dimtags)."""
    occ = gmsh.model.occ
    out = kernel(path, _primitive, shape, path)
    for i, sub in enumerate(shape.intersect):
        tool = _tool(sub, f"{path}.intersect.{i}", out)
        out, _ = kernel(f"{path}.intersect.{i}", occ.intersect, out, tool, removeObject=True, removeTool=True)
        out = [dt for dt in out if dt[0] == 3]
        if not out:
            raise StudyError("the intersection is empty", path=f"{path}.intersect.{i}")
    if shape.minus:
        tools = [dt for i, sub in enumerate(shape.minus) for dt in _tool(sub, f"{path}.minus.{i}", out)]
        out, _ = kernel(f"{path}.minus", occ.cut, out, tools, removeObject=True, removeTool=True)
        out = [dt for dt in out if dt[0] == 3]
        if not out:
            raise StudyError("the solid is empty after `minus`", path=path)
    return out


# ---------------------------------------------------------------------------
# sizes


def _solid_distance(ref: Refinement):
    """A scalar ``d(x, y, z)``: the distance to the refine zone's box, ball or cylinder (0 inside)."""
    if ref.box is not None:
        x0, y0, z0, x1, y1, z1 = (float(v) for v in ref.box)
        return lambda x, y, z: math.sqrt(max(x0 - x, x - x1, 0.0) ** 2 + max(y0 - y, y - y1, 0.0) ** 2
                                         + max(z0 - z, z - z1, 0.0) ** 2)
    if ref.ball is not None:
        cx, cy, cz = (float(v) for v in ref.ball.center)
        r = float(ref.ball.radius)
        return lambda x, y, z: max(math.sqrt((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) - r, 0.0)
    a, b = np.array(ref.cylinder.start, dtype=float), np.array(ref.cylinder.end, dtype=float)
    length = float(np.linalg.norm(b - a))
    ax, ay, az = (float(v) for v in (b - a) / length)
    sx, sy, sz = (float(v) for v in a)
    r = float(ref.cylinder.radius)

    def d(x, y, z):
        dx, dy, dz = x - sx, y - sy, z - sz
        s = dx * ax + dy * ay + dz * az
        radial = math.sqrt(max(dx * dx + dy * dy + dz * dz - s * s, 0.0))
        return math.hypot(max(radial - r, 0.0), max(-s, s - length, 0.0))
    return d


def _refinements(scene: Scene, entries: list[Refinement], path0: str):
    """(size, distance function, body or None) of each refine entry: its solid, or the face set
    of the boundary it names (`surface_distance`), and the one body it refines (`body`)."""
    refs = []
    for i, ref in enumerate(entries):
        if ref.boundary is None:
            d = _solid_distance(ref)
        elif ref.boundary in scene.boundaries:
            spec = scene.boundaries[ref.boundary]
            d = (lambda spec: lambda x, y, z: float(surface_distance(spec, np.array([x, y, z]))))(spec)
        else:
            raise StudyError(f"unknown boundary {ref.boundary!r} (boundaries: {', '.join(scene.boundaries) or 'none'})",
                             path=f"{path0}.{i}.boundary")
        refs.append((float(ref.size), d, getattr(ref, "body", None)))
    return refs


def _set_sizes(scene: Scene, size: float, body: str | None = None, entity_size=None, owner=None) -> None:
    """The element size ``min(size, min_r (size_r + grading · dist_r(x)))`` over the refine
    zones r of the scene (and of ``body``, meshed on its own), as in 2D (`wcs.scene.mesher2d`),
    and at most a region's own size in its volumes and on their faces, edges and corners
    (``entity_size``: {(dim, tag): size}, `pieces.region_entity_sizes`); a uniform size is
    gmsh's own bound ``Mesh.MeshSizeMax``. A zone with `body` sizes only that body's volumes and
    the entities bounding them (``owner``: volume tag -> (body index, region index), the volumes
    of the model; a body meshed on its own: the zones of the other bodies are left out)."""
    grading = float(DEFAULT_GRADING if scene.mesh.grading is None else scene.mesh.grading)
    refs = [r for r in _refinements(scene, scene.mesh.refine, "scene.mesh.refine") if body is None or r[2] in (None, body)]
    if body is not None and scene.bodies[body].mesh is not None:
        refs += _refinements(scene, scene.bodies[body].mesh.refine, f"scene.bodies.{body}.mesh.refine")
    names = list(scene.bodies)
    only = {b: set(closure([(3, t) for t, (k, _) in owner.items() if names[k] == b]))
            for b in {r[2] for r in refs} - {None, body}}
    refs = [(s, d, only.get(b)) for s, d, b in refs]
    entity_size = entity_size or {}
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    if not refs and not entity_size:
        gmsh.model.mesh.removeSizeCallback()
        return

    def callback(dim, tag, x, y, z, lc):
        h = min(lc, size, entity_size.get((dim, tag), size))
        for s, d, entities in refs:
            if s < h and (entities is None or (dim, tag) in entities):
                h = min(h, s + grading * d(x, y, z))
        return h
    gmsh.model.mesh.setSizeCallback(callback)


# ---------------------------------------------------------------------------
# build


def embedded_rois(scene: Scene) -> list[str]:
    """Names of the regions of interest given by a box, ball or cylinder, in scene order."""
    return [name for name, roi in scene.regions_of_interest.items() if roi.boundary is None]


def _roi_solid(roi: RegionOfInterest, path: str) -> DimTags:
    kind = next(k for k in ROI_SOLIDS if getattr(roi, k) is not None)
    return make_solid(Solid(**{ROI_SOLIDS[kind]: getattr(roi, kind)}), path)


def _extract(owner: dict, inside: dict):
    """Nodes (k, 3); per owned volume in (body, region, tag) order its tetrahedra (gmsh node
    order), body and region indices, and (n_roi, cells) flags of the regions of interest."""
    ntags, coords, _ = gmsh.model.mesh.getNodes()
    ntags = np.asarray(ntags, dtype=np.int64)
    xyz = np.asarray(coords, dtype=float).reshape(-1, 3)
    lookup = np.full(int(ntags.max()) + 1, -1, dtype=np.int64)
    lookup[ntags] = np.arange(ntags.size)
    tets, cb, cr, ci = [], [], [], []
    for tag in sorted(owner, key=lambda t: (owner[t], t)):
        _, nt = gmsh.model.mesh.getElementsByType(4, tag)     # 4-node tetrahedra
        tet = lookup[np.asarray(nt, dtype=np.int64)].reshape(-1, 4)
        tets.append(tet)
        cb.append(np.full(len(tet), owner[tag][0], dtype=np.int64))
        cr.append(np.full(len(tet), owner[tag][1], dtype=np.int64))
        ci.append(np.repeat(np.array(inside[tag], dtype=bool).reshape(-1, 1), len(tet), axis=1))
    return xyz, np.concatenate(tets), np.concatenate(cb), np.concatenate(cr), np.concatenate(ci, axis=1)


def _generate(splits: int) -> None:
    """gmsh's 3D mesh, then `splits` uniform refinements: every tetrahedron split into eight at its
    edge midpoints, the new nodes of a curve or a surface placed on it (the geometry is kept)."""
    gmsh.model.mesh.generate(3)
    for _ in range(splits):
        gmsh.model.mesh.refine()


def _mesh_bodies_separately(scene: Scene, bodies: list, size: float, embed: list, regions_flat: list,
                            splits: int):
    """Each body meshed in a gmsh model of its own (its regions and the embedded regions of
    interest fragmented together), with its ``mesh.size`` or the scene's, split `splits` times;
    the concatenation, bodies in scene order, as `_extract` gives it."""
    base = gmsh.model.getCurrent()
    parts, offset, r = [], 0, 0
    for b, body in enumerate(bodies):
        gmsh.model.add(f"{base}_body{b}")
        bspec = scene.bodies[body]
        solids = [make_solid(reg.shape, f"scene.bodies.{body}.regions.{i}.shape")
                  for i, reg in enumerate(bspec.regions)]
        covered, inside = fragment_pieces(solids, [_roi_solid(scene.regions_of_interest[n], f"scene.regions_of_interest.{n}")
                                                   for n in embed], dim=3)
        owner = {tag: (b, r + max(ks)) for tag, ks in covered.items()}
        _set_sizes(scene, size if bspec.mesh is None else bspec.mesh.size, body,
                   region_entity_sizes(owner, regions_flat, dim=3))
        _generate(splits)
        xyz, tet, cb, cr, ci = _extract(owner, inside)
        gmsh.model.remove()
        gmsh.model.setCurrent(base)
        parts.append((xyz, tet + offset, cb, cr, ci))
        offset += xyz.shape[0]
        r += len(solids)
    xyz, tet, cb, cr, ci = zip(*parts)
    return np.concatenate(xyz), np.concatenate(tet), np.concatenate(cb), np.concatenate(cr), np.concatenate(ci, axis=1)



def _body_index(sm: SceneMesh, body: str | None, path: str) -> int | None:
    if body is None:
        return None
    if body not in sm.bodies:
        raise StudyError(f"unknown body {body!r} (bodies: {', '.join(sm.bodies)})", path=f"{path}.body")
    return sm.bodies.index(body)


def build_mesh3d(scene: Scene, splits: int = 0) -> SceneMesh:
    """Mesh a typed 3D scene (regions named, as the loader gives it) into a :class:`SceneMesh` holding one
    ``skfem.MeshTet``; ``boundaries`` and ``roi_cells`` as in 2D (``boundaries``: sorted indices
    into ``mesh.facets``; an empty face selection is a ``StudyError`` at its path). A scene with
    ``mesh: {file: ...}`` is read from that file instead (``wcs.scene.meshfile``).
    ``splits``: the mesh refined that many times by splitting every tetrahedron into eight
    (uniform refinement of the same geometry, h halved each time; not for a mesh file)."""
    if scene.mesh.file is not None:
        if splits:
            raise StudyError("a mesh file is used as it is: it has no geometry to refine on",
                             path="scene.mesh.file")
        return _from_file(scene)
    bodies = list(scene.bodies)
    regions = region_names(scene)
    embed = embedded_rois(scene)
    with Session():
        previous = gmsh.option.getNumber("Mesh.Algorithm3D")
        try:
            gmsh.option.setNumber("Mesh.Algorithm3D", ALGORITHM_3D)
            inputs, r = [], 0
            for b, body in enumerate(bodies):
                for i, reg in enumerate(scene.bodies[body].regions):
                    inputs.append((b, r, make_solid(reg.shape, f"scene.bodies.{body}.regions.{i}.shape")))
                    r += 1
            roi_solids = [_roi_solid(scene.regions_of_interest[n], f"scene.regions_of_interest.{n}")
                          for n in embed]
            covered, inside = fragment_pieces([dts for _, _, dts in inputs], roi_solids, dim=3)
            owner = piece_owners(covered, inputs, bodies, regions, dim=3)
            lo, hi = np.array(gmsh.model.getBoundingBox(-1, -1)).reshape(2, 3)
            size = (scene.mesh.size if scene.mesh.size is not None
                    else mesh_size(MeshFacts(diagonal=float(np.linalg.norm(hi - lo))))[0])
            regions_flat = [reg for body in bodies for reg in scene.bodies[body].regions]
            if not any(scene.bodies[body].mesh for body in bodies):
                _set_sizes(scene, size, entity_size=region_entity_sizes(owner, regions_flat, dim=3), owner=owner)
                _generate(splits)
                xyz, tet, cell_body, cell_region, in_roi = _extract(owner, inside)
            else:       # every body in a gmsh model of its own: faces shared with other bodies nonmatching
                xyz, tet, cell_body, cell_region, in_roi = _mesh_bodies_separately(scene, bodies, size, embed,
                                                                                   regions_flat, splits)
        finally:
            gmsh.option.setNumber("Mesh.Algorithm3D", previous)
            gmsh.model.mesh.removeSizeCallback()
    if (tet < 0).any():
        raise RuntimeError("gmsh returned a cell with an unknown node")

    # -- one copy of each node per body, unused nodes dropped, compact numbering
    nn = xyz.shape[0]
    uniq, inv = np.unique((cell_body[:, None] * nn + tet).ravel(), return_inverse=True)
    t = inv.reshape(-1, 4).T.astype(np.int64)
    p = np.ascontiguousarray(xyz[uniq % nn].T)
    # -- positively oriented cells
    e = p[:, t[1:]] - p[:, t[:1]]                             # (3, 3, ncells): edges from node 0
    negative = np.einsum("ie,ie->e", e[:, 0], np.cross(e[:, 1], e[:, 2], axis=0)) < 0
    t[1, negative], t[2, negative] = t[2, negative], t[1, negative].copy()

    mesh = skfem.MeshTet(p, np.ascontiguousarray(t), sort_t=False)
    made_facets(mesh)
    sm = check_connected(SceneMesh(mesh=mesh, bodies=bodies, regions=regions, cell_body=cell_body,
                                   cell_region=cell_region),
                         {name: np.flatnonzero(in_roi[j]) for j, name in enumerate(embed)})
    bnd = {name: select_faces(sm, spec, f"scene.boundaries.{name}")
           for name, spec in scene.boundaries.items()}
    roi_cells = {}
    for j, name in enumerate(embed):
        mask = in_roi[j]
        body = _body_index(sm, scene.regions_of_interest[name].body, f"scene.regions_of_interest.{name}")
        if body is not None:
            mask = mask & (cell_body == body)
        roi_cells[name] = np.flatnonzero(mask).astype(np.int64)
        if roi_cells[name].size == 0:
            raise StudyError("the region of interest holds no cell (of its body)", path=f"scene.regions_of_interest.{name}")
    return dataclasses.replace(sm, boundaries=bnd, roi_cells=roi_cells)


def _from_file(scene: Scene) -> SceneMesh:
    """The user's own mesh: bodies and regions from its 3D groups, faces from its 2D groups or
    the face selectors. A box, ball or cylinder of interest is embedded by the mesher, so a mesh
    file (whose cells cannot be cut into it exactly) refuses it."""
    for name in embedded_rois(scene):
        kind = next(k for k in ROI_SOLIDS if getattr(scene.regions_of_interest[name], k) is not None)
        raise StudyError(f"a {kind} cannot be cut from the cells of a mesh file (a mesh built from "
                         "solids embeds it): use `boundary: NAME` here, or mesh the scene from solids",
                         path=f"scene.regions_of_interest.{name}.{kind}")
    return check_connected(read_mesh_file(scene.mesh.file, scene, dim=3, select=select_faces))


def check_connected(sm: SceneMesh, rois: dict[str, np.ndarray] | None = None) -> SceneMesh:
    """A body is one connected piece of cells (as in 2D: each piece would need its own supports);
    `rois`: the cells of the embedded regions of interest, blamed when one is a piece alone."""
    t, n = sm.mesh.t, sm.mesh.p.shape[1]
    rows = np.tile(t[0], t.shape[0] - 1)
    graph = sp.coo_matrix((np.ones(rows.size), (rows, t[1:].ravel())), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    for b, name in enumerate(sm.bodies):
        pieces = np.unique(label[sm.node_body == b]).size
        if pieces > 1:
            refuse_roi_apart(sm, label, b, rois or {})
            raise StudyError(f"body {name!r} consists of {pieces} pieces that do not touch; make each "
                             "piece a body of its own (with its own support or contact)", path=f"scene.bodies.{name}")
    return sm


# ---------------------------------------------------------------------------
# selectors


def surface_distance(spec: Boundary, x: np.ndarray) -> np.ndarray:
    """Distance of the points x (3, ...) to the face selector's set (0 inside a box)."""
    col = (3,) + (1,) * (x.ndim - 1)
    if spec.plane is not None:
        n = np.array(spec.plane.normal) / np.linalg.norm(spec.plane.normal)
        return np.abs(np.einsum("i,i...->...", n, x - np.reshape(spec.plane.point, col)))
    if spec.box is not None:
        b = np.array(spec.box)
        out = np.maximum(np.maximum(b[:3].reshape(col) - x, x - b[3:].reshape(col)), 0.0)
        return np.sqrt((out**2).sum(axis=0))
    if spec.sphere is not None:
        return np.abs(np.linalg.norm(x - np.reshape(spec.sphere.center, col), axis=0) - spec.sphere.radius)
    a, b = np.array(spec.cylinder.start), np.array(spec.cylinder.end)   # lateral surface, start to end
    axis = (b - a) / np.linalg.norm(b - a)
    d = x - a.reshape(col)
    s = np.einsum("i,i...->...", axis, d)
    radial = np.linalg.norm(d - axis.reshape(col) * s, axis=0)
    beyond = np.maximum(np.maximum(-s, s - np.linalg.norm(b - a)), 0.0)
    return np.hypot(radial - spec.cylinder.radius, beyond)


def select_faces(sm: SceneMesh, spec: Boundary, path: str, *, allow_empty: bool = False) -> np.ndarray:
    """Sorted indices into ``sm.mesh.facets`` of the boundary facets whose three nodes lie on the
    face selector's set (plane / box / cylinder / sphere, optional body)."""
    mesh = sm.mesh
    body = _body_index(sm, spec.body, path)
    bf = mesh.boundary_facets()
    if body is not None:
        bf = bf[selectors.facet_body(sm, bf) == body]
    x = mesh.p[:, mesh.facets[:, bf]]                         # (3, 3 nodes, nfacets)
    edges = np.linalg.norm(x - np.roll(x, 1, axis=1), axis=0).max(axis=0)
    scale = float(np.linalg.norm(mesh.p.max(axis=1) - mesh.p.min(axis=1))) or 1.0
    tol = REL_TOL * edges + ABS_TOL * scale
    if spec.plane is not None and spec.plane.tolerance is not None:
        tol = np.full(bf.size, spec.plane.tolerance)
    ok = (surface_distance(spec, x) <= tol).all(axis=0)
    out = np.sort(bf[ok])
    if out.size == 0 and not allow_empty:
        kind = next(k for k in FACE_KINDS if getattr(spec, k) is not None)
        where = f" of body {spec.body!r}" if body is not None else ""
        raise StudyError(f"the {kind} selector selects no boundary face{where}", path=path)
    return out
