"""A 3D scene (plain dicts) -> gmsh (OpenCASCADE) solids -> :class:`SceneMesh` with a MeshTet.

``build_mesh3d(scene)`` takes a dict of the form (the study schema comes later)::

    {"bodies": {NAME: {"regions": [{"name": REGION, "shape": SOLID}, ...], "mesh": {"size": h}}, ...},
     "boundaries": {NAME: FACE_SELECTOR, ...},
     "regions_of_interest": {NAME: REGION_SELECTOR, ...},
     "mesh": {"size": h}}

(``name``, a body's ``mesh`` and the scene's ``mesh`` are optional.)

Solids (``SOLID``), each with optional, recursive ``intersect: [SOLID, ...]`` (applied
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

How it is done (as the 2D ``wcs.scene.mesher``): every region solid and every embedded region
of interest goes through one ``occ.fragment``, so regions of a body share nodes and touching
bodies have matching triangles on their common faces; a piece belongs to the last region (scene
order) covering it; a piece covered by two bodies is an overlap (``StudyError`` at
``scene.bodies.<later body>``); a region left with no volume is a ``StudyError`` at its path.
Each body gets its own copy of the nodes on faces shared with another body. The size is uniform,
``mesh.size`` (``Mesh.MeshSizeMax``; default: the rule of ``wcs.choose.mesh_size`` with the
bounding-box diagonal), with ``Mesh.MeshSizeFromCurvature`` elements per 2π of arc. If any body
has its own ``bodies.<b>.mesh: {size}``, every body is meshed in a gmsh model of its own after the
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

import gmsh
import numpy as np
import scipy.sparse as sp
import skfem
from pydantic import ValidationError
from scipy.sparse.csgraph import connected_components

from ..choose import MeshFacts, mesh_size
from ..errors import StudyError
from . import selectors
from .geometry import kernel, make_shape, number_list
from .meshdata import SceneMesh
from .mesher import fragment_pieces
from .session import Session
from .spec import Shape

SOLID_KINDS = ("box", "cylinder", "sphere", "extrude", "halfspace")
FACE_KINDS = ("plane", "box", "cylinder", "sphere")
ROI_SOLIDS = {"box": "box", "ball": "sphere", "cylinder": "cylinder"}   # embedded region -> solid
ALGORITHM_3D = 1                 # Delaunay
REL_TOL = 1e-3
ABS_TOL = 1e-12

DimTags = list[tuple[int, int]]


# ---------------------------------------------------------------------------
# solids


def _vector(value, path: str, what: str) -> np.ndarray:
    return np.array(number_list(value, 3, path, what))


def _mapping(spec, keys: tuple[str, ...], path: str, kind: str) -> dict:
    if not isinstance(spec, dict) or any(k not in spec for k in keys):
        raise StudyError(f"{kind} needs {{{', '.join(keys)}}}", path=path)
    return spec


def _positive(value, path: str, what: str) -> float:
    (r,) = number_list([value], 1, path, what)
    if not r > 0:
        raise StudyError(f"{what} must be > 0, got {r}", path=path)
    return r


def _box(spec, path: str, solid: bool = True) -> np.ndarray:
    """A solid box needs min < max; a face selector's box may be flat (min ≤ max)."""
    b = np.array(number_list(spec, 6, path, "box"))
    if not (np.all(b[3:] > b[:3]) if solid else np.all(b[3:] >= b[:3])):
        raise StudyError(f"box [xmin, ymin, zmin, xmax, ymax, zmax] needs min {'<' if solid else '<='} max, "
                         f"got {spec}", path=path)
    return b


def _cylinder(spec, path: str) -> tuple[np.ndarray, np.ndarray, float]:
    _mapping(spec, ("start", "end", "radius"), path, "cylinder")
    a, b = _vector(spec["start"], f"{path}.start", "start"), _vector(spec["end"], f"{path}.end", "end")
    if not np.linalg.norm(b - a) > 0:
        raise StudyError("cylinder start and end must differ", path=path)
    return a, b, _positive(spec["radius"], f"{path}.radius", "radius")


def _sphere(spec, path: str) -> tuple[np.ndarray, float]:
    _mapping(spec, ("center", "radius"), path, "sphere")
    return _vector(spec["center"], f"{path}.center", "center"), _positive(spec["radius"], f"{path}.radius", "radius")


def _plane(spec, path: str) -> tuple[np.ndarray, np.ndarray]:
    """(point, unit normal)."""
    _mapping(spec, ("point", "normal"), path, "a plane")
    n = _vector(spec["normal"], f"{path}.normal", "normal")
    if not np.linalg.norm(n) > 0:
        raise StudyError("normal must not be zero", path=f"{path}.normal")
    return _vector(spec["point"], f"{path}.point", "point"), n / np.linalg.norm(n)


def _halfspace(spec, path: str, cut: DimTags) -> DimTags:
    """{(p − point)·n ≤ 0} as a box of side 2L, one face on the plane, L ≥ the distance from
    `point` to every point of the solids `cut` (their bounding box)."""
    occ = gmsh.model.occ
    point, n = _plane(spec, path)
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


def _primitive(shape: dict, path: str) -> DimTags:
    occ = gmsh.model.occ
    kinds = [k for k in SOLID_KINDS if shape.get(k) is not None]
    if len(kinds) != 1:
        raise StudyError(f"a solid needs exactly one of {', '.join(SOLID_KINDS)}; got keys {sorted(shape)}",
                         path=path)
    kind = kinds[0]
    spec, p = shape[kind], f"{path}.{kind}"
    if kind == "box":
        b = _box(spec, p)
        return [(3, occ.addBox(*b[:3], *(b[3:] - b[:3])))]
    if kind == "cylinder":
        a, b, r = _cylinder(spec, p)
        return [(3, occ.addCylinder(*a, *(b - a), r))]
    if kind == "sphere":
        c, r = _sphere(spec, p)
        return [(3, occ.addSphere(*c, r))]
    if kind == "extrude":
        _mapping(spec, ("shape", "vector"), p, "extrude")
        v = _vector(spec["vector"], f"{p}.vector", "vector")
        try:
            shape2d = Shape.model_validate(spec["shape"])
        except ValidationError as err:
            first = err.errors()[0]
            where = ".".join(str(k) for k in (f"{p}.shape", *first["loc"]))
            raise StudyError(f"not a 2D shape: {first['msg']}", path=where) from None
        base = make_shape(shape2d, f"{p}.shape")
        out = kernel(p, occ.extrude, base, *v)
        return [dt for dt in out if dt[0] == 3]
    raise StudyError("a halfspace is unbounded: use it inside `intersect` or `minus` of a solid", path=p)


def _shape_list(value, path: str) -> list:
    """`intersect` / `minus`: a list of solids (one solid alone is accepted too)."""
    if value is None:
        return []
    if isinstance(value, dict):
        return [value]
    if not isinstance(value, list):
        raise StudyError(f"expected a list of solids, got {value!r}", path=path)
    return value


def _tool(shape, path: str, cut: DimTags) -> DimTags:
    """A solid used to intersect or cut `cut`: a halfspace is sized to cover `cut`."""
    if isinstance(shape, dict) and shape.get("halfspace") is not None and not (set(shape) - {"halfspace"}):
        return _halfspace(shape["halfspace"], f"{path}.halfspace", cut)
    return make_solid(shape, path)


def make_solid(shape: dict, path: str) -> DimTags:
    """Create the solid ``shape`` in the current OCC model; return its volumes (dim 3 dimtags)."""
    if not isinstance(shape, dict):
        raise StudyError(f"a solid must be a mapping, got {shape!r}", path=path)
    occ = gmsh.model.occ
    out = kernel(path, _primitive, shape, path)
    for i, sub in enumerate(_shape_list(shape.get("intersect"), f"{path}.intersect")):
        tool = _tool(sub, f"{path}.intersect.{i}", out)
        out, _ = kernel(f"{path}.intersect.{i}", occ.intersect, out, tool, removeObject=True, removeTool=True)
        out = [dt for dt in out if dt[0] == 3]
        if not out:
            raise StudyError("the intersection is empty", path=f"{path}.intersect.{i}")
    minus = _shape_list(shape.get("minus"), f"{path}.minus")
    if minus:
        tools = [dt for i, sub in enumerate(minus) for dt in _tool(sub, f"{path}.minus.{i}", out)]
        out, _ = kernel(f"{path}.minus", occ.cut, out, tools, removeObject=True, removeTool=True)
        out = [dt for dt in out if dt[0] == 3]
        if not out:
            raise StudyError("the solid is empty after `minus`", path=path)
    return out


# ---------------------------------------------------------------------------
# build


def embedded_rois(scene: dict) -> list[str]:
    """Names of the regions of interest given by a box, ball or cylinder, in scene order."""
    return [name for name, spec in (scene.get("regions_of_interest") or {}).items()
            if isinstance(spec, dict) and any(spec.get(k) is not None for k in ROI_SOLIDS)]


def _roi_solid(spec: dict, path: str) -> DimTags:
    kind = next(k for k in ROI_SOLIDS if spec.get(k) is not None)
    return make_solid({ROI_SOLIDS[kind]: spec[kind]}, path)


def _owners(covered: dict, inputs: list, bodies: list, regions: list) -> dict:
    """piece -> (body, region): the last region covering it; two bodies on a piece: an overlap."""
    owner = {}
    for tag in sorted(covered):
        ks = sorted(covered[tag])
        bs = sorted({inputs[k][0] for k in ks})
        if len(bs) > 1:
            raise StudyError(
                f"body {bodies[bs[1]]!r} overlaps body {bodies[bs[0]]!r} (common volume "
                f"{gmsh.model.occ.getMass(3, tag):.6g}); bodies may touch but not overlap",
                path=f"scene.bodies.{bodies[bs[1]]}")
        owner[tag] = (bs[0], max(inputs[k][1] for k in ks))
    used = {rg for _, rg in owner.values()}
    for b, rg, _ in inputs:
        if rg not in used:
            i = [j for j, (bb, _) in enumerate(regions) if bb == bodies[b]].index(rg)
            raise StudyError(f"region {regions[rg][1]!r} has no volume left (empty solid, or covered "
                             "by later regions of the body)", path=f"scene.bodies.{bodies[b]}.regions.{i}")
    return owner


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


def _size(value, path: str) -> float:
    (h,) = number_list([value], 1, path, "mesh size")
    if not h > 0:
        raise StudyError(f"mesh size must be > 0, got {h}", path=path)
    return h


def _mesh_bodies_separately(scene: dict, bodies: list, size: float, embed: list):
    """Each body meshed in a gmsh model of its own (its regions and the embedded regions of
    interest fragmented together), with its ``mesh.size`` or the scene's; the concatenation,
    bodies in scene order, as `_extract` gives it."""
    base = gmsh.model.getCurrent()
    parts, offset, r = [], 0, 0
    for b, body in enumerate(bodies):
        gmsh.model.add(f"{base}_body{b}")
        bspec = scene["bodies"][body]
        solids = [make_solid(reg["shape"], f"scene.bodies.{body}.regions.{i}.shape")
                  for i, reg in enumerate(bspec["regions"])]
        covered, inside = fragment_pieces(solids, [_roi_solid(scene["regions_of_interest"][n], f"scene.regions_of_interest.{n}")
                                                   for n in embed], dim=3)
        owner = {tag: (b, r + max(ks)) for tag, ks in covered.items()}
        own = (bspec.get("mesh") or {}).get("size")
        gmsh.option.setNumber("Mesh.MeshSizeMax", size if own is None else _size(own, f"scene.bodies.{body}.mesh.size"))
        gmsh.model.mesh.generate(3)
        xyz, tet, cb, cr, ci = _extract(owner, inside)
        gmsh.model.remove()
        gmsh.model.setCurrent(base)
        parts.append((xyz, tet + offset, cb, cr, ci))
        offset += xyz.shape[0]
        r += len(solids)
    xyz, tet, cb, cr, ci = zip(*parts)
    return np.concatenate(xyz), np.concatenate(tet), np.concatenate(cb), np.concatenate(cr), np.concatenate(ci, axis=1)



# The 3D scene is still given as plain mappings (its typed schema is the next step of the 3D
# work); these read them as the 2D helpers read the typed 2D scene.

def region_names(scene: dict) -> list[tuple[str, str]]:
    """(body, region name) in scene order; default name ``<body>_<i>`` (0-based i)."""
    return [(body, reg.get("name") or f"{body}_{i}")
            for body, bspec in (scene.get("bodies") or {}).items()
            for i, reg in enumerate(bspec.get("regions") or [])]


def _kind(spec: dict, kinds, path: str) -> str:
    """The one of `kinds` a selector mapping gives."""
    found = [k for k in kinds if isinstance(spec, dict) and spec.get(k) is not None]
    if len(found) != 1:
        raise StudyError(f"a selector needs exactly one of {', '.join(kinds)}; got {spec!r}", path=path)
    return found[0]


def _body_index(sm: SceneMesh, spec: dict, path: str) -> int | None:
    body = spec.get("body") if isinstance(spec, dict) else None
    if body is None:
        return None
    if body not in sm.bodies:
        raise StudyError(f"unknown body {body!r} (bodies: {', '.join(sm.bodies)})", path=f"{path}.body")
    return sm.bodies.index(body)


def build_mesh3d(scene: dict) -> SceneMesh:
    """Mesh a 3D scene dict (see the module docstring) into a :class:`SceneMesh` holding one
    ``skfem.MeshTet``; ``boundaries`` and ``roi_cells`` as in 2D (``boundaries``: sorted indices
    into ``mesh.facets``; an empty face selection is a ``StudyError`` at its path)."""
    bodies_spec = scene.get("bodies") or {}
    if not bodies_spec:
        raise StudyError("the scene has no bodies", path="scene.bodies")
    bodies = list(bodies_spec)
    regions = region_names(scene)
    embed = embedded_rois(scene)
    with Session():
        previous = gmsh.option.getNumber("Mesh.Algorithm3D")
        try:
            gmsh.option.setNumber("Mesh.Algorithm3D", ALGORITHM_3D)
            inputs, r = [], 0
            for b, body in enumerate(bodies):
                regs = bodies_spec[body].get("regions") or []
                if not regs:
                    raise StudyError("a body needs at least one region", path=f"scene.bodies.{body}.regions")
                for i, reg in enumerate(regs):
                    if not isinstance(reg, dict) or "shape" not in reg:
                        raise StudyError("a region needs a `shape`", path=f"scene.bodies.{body}.regions.{i}")
                    inputs.append((b, r, make_solid(reg["shape"], f"scene.bodies.{body}.regions.{i}.shape")))
                    r += 1
            roi_solids = [_roi_solid(scene["regions_of_interest"][n], f"scene.regions_of_interest.{n}")
                          for n in embed]
            covered, inside = fragment_pieces([dts for _, _, dts in inputs], roi_solids, dim=3)
            owner = _owners(covered, inputs, bodies, regions)
            lo, hi = np.array(gmsh.model.getBoundingBox(-1, -1)).reshape(2, 3)
            size = (scene.get("mesh") or {}).get("size")
            size = (_size(size, "scene.mesh.size") if size is not None
                    else mesh_size(MeshFacts(diagonal=float(np.linalg.norm(hi - lo))))[0])
            if not any(bodies_spec[body].get("mesh") for body in bodies):
                gmsh.option.setNumber("Mesh.MeshSizeMax", size)
                gmsh.model.mesh.generate(3)
                xyz, tet, cell_body, cell_region, in_roi = _extract(owner, inside)
            else:       # every body in a gmsh model of its own: faces shared with other bodies nonmatching
                xyz, tet, cell_body, cell_region, in_roi = _mesh_bodies_separately(scene, bodies, size, embed)
        finally:
            gmsh.option.setNumber("Mesh.Algorithm3D", previous)
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

    sm = check_connected(SceneMesh(mesh=skfem.MeshTet(p, np.ascontiguousarray(t), sort_t=False), bodies=bodies,
                                   regions=regions, cell_body=cell_body, cell_region=cell_region))
    bnd = {name: select_faces(sm, spec, f"scene.boundaries.{name}")
           for name, spec in (scene.get("boundaries") or {}).items()}
    roi_cells = {}
    for j, name in enumerate(embed):
        mask = in_roi[j]
        body = _body_index(sm, scene["regions_of_interest"][name], f"scene.regions_of_interest.{name}")
        if body is not None:
            mask = mask & (cell_body == body)
        roi_cells[name] = np.flatnonzero(mask).astype(np.int64)
        if roi_cells[name].size == 0:
            raise StudyError("the region of interest holds no cell (of its body)", path=f"scene.regions_of_interest.{name}")
    return dataclasses.replace(sm, boundaries=bnd, roi_cells=roi_cells)


def check_connected(sm: SceneMesh) -> SceneMesh:
    """A body is one connected piece of cells (as in 2D: each piece would need its own supports)."""
    t, n = sm.mesh.t, sm.mesh.p.shape[1]
    rows = np.tile(t[0], t.shape[0] - 1)
    graph = sp.coo_matrix((np.ones(rows.size), (rows, t[1:].ravel())), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    for b, name in enumerate(sm.bodies):
        pieces = np.unique(label[sm.node_body == b]).size
        if pieces > 1:
            raise StudyError(f"body {name!r} consists of {pieces} pieces that do not touch; make each "
                             "piece a body of its own (with its own support or contact)", path=f"scene.bodies.{name}")
    return sm


# ---------------------------------------------------------------------------
# selectors


def surface_distance(kind: str, value, path: str, x: np.ndarray) -> np.ndarray:
    """Distance of the points x (3, ...) to the face selector's set (0 inside a box)."""
    if kind == "plane":
        point, n = _plane(value, path)
        return np.abs(np.einsum("i,i...->...", n, x - point.reshape(3, *[1] * (x.ndim - 1))))
    if kind == "box":
        b = _box(value, path, solid=False)
        shape = (3,) + (1,) * (x.ndim - 1)
        out = np.maximum(np.maximum(b[:3].reshape(shape) - x, x - b[3:].reshape(shape)), 0.0)
        return np.sqrt((out**2).sum(axis=0))
    if kind == "sphere":
        c, r = _sphere(value, path)
        return np.abs(np.linalg.norm(x - c.reshape(3, *[1] * (x.ndim - 1)), axis=0) - r)
    a, b, r = _cylinder(value, path)                          # lateral surface, start to end
    axis = (b - a) / np.linalg.norm(b - a)
    d = x - a.reshape(3, *[1] * (x.ndim - 1))
    s = np.einsum("i,i...->...", axis, d)
    radial = np.linalg.norm(d - axis.reshape(3, *[1] * (x.ndim - 1)) * s, axis=0)
    beyond = np.maximum(np.maximum(-s, s - np.linalg.norm(b - a)), 0.0)
    return np.hypot(radial - r, beyond)


def select_faces(sm: SceneMesh, spec: dict, path: str, *, allow_empty: bool = False) -> np.ndarray:
    """Sorted indices into ``sm.mesh.facets`` of the boundary facets whose three nodes lie on the
    face selector's set (plane / box / cylinder / sphere, optional body)."""
    mesh = sm.mesh
    kind = _kind(spec, FACE_KINDS, path)
    body = _body_index(sm, spec, path)
    bf = mesh.boundary_facets()
    if body is not None:
        bf = bf[selectors.facet_body(sm, bf) == body]
    x = mesh.p[:, mesh.facets[:, bf]]                         # (3, 3 nodes, nfacets)
    edges = np.linalg.norm(x - np.roll(x, 1, axis=1), axis=0).max(axis=0)
    scale = float(np.linalg.norm(mesh.p.max(axis=1) - mesh.p.min(axis=1))) or 1.0
    tol = REL_TOL * edges + ABS_TOL * scale
    value, p = spec[kind], f"{path}.{kind}"
    if kind == "plane" and isinstance(value, dict) and value.get("tolerance") is not None:
        tol = np.full(bf.size, _positive(value["tolerance"], f"{p}.tolerance", "tolerance"))
    ok = (surface_distance(kind, value, p, x) <= tol).all(axis=0)
    out = np.sort(bf[ok])
    if out.size == 0 and not allow_empty:
        where = f" of body {spec['body']!r}" if body is not None else ""
        raise StudyError(f"the {kind} selector selects no boundary face{where}", path=path)
    return out
