"""The typed scene (`wcs.scene.spec.Scene`) -> gmsh (OpenCASCADE) -> :class:`SceneMesh`.

``build_mesh(scene)`` takes the ``scene:`` block of a study, validated by the loader,
and returns one ``skfem.MeshTri`` holding every body.

How it is done
--------------
* Every region shape of every body is created with the OCC kernel
  (``wcs.scene.geometry``), then ALL surfaces go through one ``occ.fragment``:
  the result is a conforming partition, each curve shared by two pieces is
  meshed once, so regions of one body share nodes and touching bodies have
  matching nodes on their common curves.
* Regions of interest given by a box, disc or polygon (those a criterion integrates
  over, ``build_mesh(scene, rois)``) go into the same fragment: their outlines become
  curves of the mesh, so G_r is exactly a union of cells (a disc: the mesh's polygon,
  as a disc body) and means over it are exact (``SceneMesh.roi_cells``); their parts
  outside every body are removed before meshing.
* Ownership of fragment pieces: a piece belongs to the region whose shape
  covers it.  A piece covered by two bodies is an overlap -> ``StudyError`` at
  ``scene.bodies.<later body>``; by two regions of one body -> ``StudyError`` at
  ``scene.bodies.<body>.regions.<later>``.  A region left with no piece (an empty shape) ->
  ``StudyError`` at ``scene.bodies.<body>.regions.<i>[.shape]``.
* Sizes: a ``gmsh.model.mesh.setSizeCallback`` (``Mesh.MeshSizeMax`` for a uniform size) returns
  ``min(lc_gmsh, size, min_r (size_r + grading * dist_r(x)))`` where ``r``
  runs over ``mesh.refine`` entries, ``dist_r`` is the distance to the
  refine selector's geometric set (0 inside a box/disc/polygon; for
  ``boundary: NAME`` the distance to that boundary's segment / circle / box;
  refinement is purely geometric: a zone takes no ``body:`` key), and ``grading`` (``mesh.grading``, default 0.5) lets
  the size grow linearly away from the refined zone instead of jumping.
  ``lc_gmsh`` carries ``Mesh.MeshSizeFromCurvature = 24`` (elements per 2π
  of arc): a full circle always gets >= 24 segments however coarse ``size``.
  Without ``mesh.size`` the size is 1/20 of the scene's bounding-box diagonal.
* Per-body and per-region sizes: ``bodies.<b>.mesh: {size, refine}`` and
  ``regions[i].mesh: {size}``.  A region size applies to its surfaces and the
  curves / points around them (smallest size of the adjacent regions), so
  regions stay conforming.  If ANY body has its own ``mesh:``, every body is
  meshed in a gmsh model of its own after the global fragment (which still
  decides ownership and overlaps): the body's regions are fragmented together,
  its size is ``bodies.<b>.mesh.size`` (else ``scene.mesh.size``) with the
  scene's and the body's ``refine`` entries, and curves shared with other
  bodies are meshed once per body -- nonmatching sides (mortar contact / glue).
* Determinism: one gmsh session per build (initialize/finalize, or a fresh
  model if the caller already runs gmsh, with our options restored after),
  ``General.NumThreads = 1``, Frontal-Delaunay (``Mesh.Algorithm = 6``), no
  config files, no randomness on our side; nodes and cells are numbered from
  gmsh's own (deterministic) order.
* Output numbering: cells are grouped by body, then region, then gmsh surface;
  nodes are grouped by body (each body has its own copy of nodes on curves
  shared with another body), then gmsh node order.  Nodes not used by any
  cell are dropped.  Cells are counter-clockwise.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.sparse as sp
import skfem
from pydantic import BaseModel
from scipy.sparse.csgraph import connected_components

from ..choose import MeshFacts, mesh_size
from ..errors import StudyError
from . import selectors
from .estimate import DEFAULT_GRADING
from .geometry import make_shape
from .meshdata import SceneMesh
from .meshfile import read_mesh_file
from .pieces import fragment_pieces, piece_owners, refuse_roi_apart, region_entity_sizes, region_names
from .session import OPTIONS, Session, gmsh
from .spec import Shape

ROI_SHAPES = {"box": "rectangle", "disc": "disc", "polygon": "polygon"}   # region of interest -> shape


# ---------------------------------------------------------------------------
# sizes


def _scalar_distance(spec, path: str):
    """A fast scalar ``d(x, y)`` for the size callback (called ~1e5 times): the distance to
    a refine selector's set (`kind` of `spec`, a validated model)."""
    kind = selectors._kind(spec, ("box", "disc", "polygon", "segment", "circle"), path)
    val = getattr(spec, kind)
    p = f"{path}.{kind}"
    hypot = math.hypot
    if kind == "box":
        x0, y0, x1, y1 = (float(v) for v in selectors._box(val, p))

        def d(x, y):
            dx = max(x0 - x, x - x1, 0.0)
            dy = max(y0 - y, y - y1, 0.0)
            return hypot(dx, dy)
        return d
    if kind in ("disc", "circle"):
        c, r = selectors._circle(val, p)
        cx, cy = float(c[0]), float(c[1])
        if kind == "disc":
            return lambda x, y: max(hypot(x - cx, y - cy) - r, 0.0)
        return lambda x, y: abs(hypot(x - cx, y - cy) - r)
    if kind == "segment":
        a, b = selectors._segment(val, p)
        ax, ay, dx, dy = float(a[0]), float(a[1]), float(b[0] - a[0]), float(b[1] - a[1])
        dd = dx * dx + dy * dy

        def d(x, y):
            s = min(max(((x - ax) * dx + (y - ay) * dy) / dd, 0.0), 1.0)
            return hypot(x - ax - s * dx, y - ay - s * dy)
        return d
    pts = selectors._polygon(val, p)
    return lambda x, y: float(selectors.dist_polygon(x, y, pts))


def _refinements(scene, entries, path0: str):
    """(size, distance function) of each refine entry (the geometry of its selector, or of the
    boundary it names; a `body:` key is ignored)."""
    refs = []
    for i, ref in enumerate(entries):
        if ref.boundary is not None:
            d = _scalar_distance(scene.boundaries[ref.boundary], f"scene.boundaries.{ref.boundary}")
        else:
            d = _scalar_distance(ref, f"{path0}.{i}")
        refs.append((float(ref.size), d))
    return refs


def default_size(scene, bbox_diag: float) -> float:
    """`mesh.size` when the study gives none: the benchmark rule of `wcs.choose.mesh_size`
    (diagonal/20, and a tenth of the smallest disc radius, e.g. a tunnel)."""
    radii = [float(r.radius) for r in _discs(scene)]
    return mesh_size(MeshFacts(diagonal=bbox_diag, feature=min(radii) if radii else None))[0]


def _discs(node):
    """Every `disc: {center, radius}` in a (nested) scene: the `disc` field of any model
    (shapes, regions of interest, refinements; a boundary's `circle` is not one)."""
    if isinstance(node, BaseModel):
        for name in type(node).model_fields:
            value = getattr(node, name)
            if name == "disc" and value is not None:
                yield value
            yield from _discs(value)
    elif isinstance(node, dict):
        for v in node.values():
            yield from _discs(v)
    elif isinstance(node, list):
        for v in node:
            yield from _discs(v)


def _size_function(scene, bbox_diag: float, body: str | None = None, entity_size=None):
    """The size and the size callback (None when the size is uniform). ``body``: a body meshed
    on its own (its ``mesh: {size, refine}`` overrides / adds to the scene's). ``entity_size``:
    {(dim, tag): size} of entities inside regions with their own ``mesh: {size}``."""
    mspec = scene.mesh
    size = float(mspec.size) if mspec.size is not None else default_size(scene, bbox_diag)
    grading = float(DEFAULT_GRADING if mspec.grading is None else mspec.grading)
    refs = _refinements(scene, mspec.refine, "scene.mesh.refine")
    if body is not None:
        bmesh = scene.bodies[body].mesh
        if bmesh is not None and bmesh.size is not None:
            size = float(bmesh.size)
        refs += _refinements(scene, bmesh.refine if bmesh else [], f"scene.bodies.{body}.mesh.refine")
    entity_size = entity_size or {}
    if not refs and not entity_size:
        return size, None

    def callback(dim, tag, x, y, z, lc):
        h = min(lc, size, entity_size.get((dim, tag), size))
        for s, d in refs:
            if s < h:
                h = min(h, s + grading * d(x, y))
        return h
    return size, callback


def _set_sizes(size: float, callback) -> None:
    """A uniform size is gmsh's own bound ``Mesh.MeshSizeMax``: the same mesh as the callback
    ``min(lc, size)``, without its ~5e4 calls into Python (~5% of the meshing time)."""
    gmsh.option.setNumber("Mesh.MeshSizeMax", size if callback is None else OPTIONS["Mesh.MeshSizeMax"])
    if callback is not None:
        gmsh.model.mesh.setSizeCallback(callback)


# ---------------------------------------------------------------------------
# gmsh session


# ---------------------------------------------------------------------------
# build


def _extract(owner: dict, inside: dict, offset: int = 0):
    """Nodes (k, 2) and, per owned surface in (body, region, tag) order, its cells (global
    numbering = offset + gmsh node order), body and region indices, and (n_roi, cells)
    flags: the cell lies in region of interest j (``inside[tag]``: the j covering the piece)."""
    ntags, coords, _ = gmsh.model.mesh.getNodes()
    ntags = np.asarray(ntags, dtype=np.int64)
    xy = np.asarray(coords, dtype=float).reshape(-1, 3)[:, :2]
    lookup = np.full(int(ntags.max()) + 1, -1, dtype=np.int64)
    lookup[ntags] = np.arange(ntags.size)
    tris, cb, cr, ci = [], [], [], []
    for tag in sorted(owner, key=lambda t: (owner[t], t)):
        _, nt = gmsh.model.mesh.getElementsByType(2, tag)
        tri = lookup[np.asarray(nt, dtype=np.int64)].reshape(-1, 3)
        tris.append(np.where(tri >= 0, tri + offset, -1))
        cb.append(np.full(len(tri), owner[tag][0], dtype=np.int64))
        cr.append(np.full(len(tri), owner[tag][1], dtype=np.int64))
        flags = np.zeros((len(inside[tag]), len(tri)), dtype=bool)
        flags[[j for j, hit in enumerate(inside[tag]) if hit]] = True
        ci.append(flags)
    return xy, tris, cb, cr, ci


def _roi_shapes(scene, names: list[str]) -> list:
    """Surfaces of the regions of interest ``names`` (box, disc, polygon), created in the current
    model: fragmented with the bodies, they make G_r a union of cells."""
    out = []
    for name in names:
        spec = scene.regions_of_interest[name]
        kind = next(k for k in ROI_SHAPES if getattr(spec, k) is not None)
        out.append(make_shape(Shape(**{ROI_SHAPES[kind]: getattr(spec, kind)}), f"scene.regions_of_interest.{name}"))
    return out


def area_rois(scene, names=None) -> list[str]:
    """Names of the regions of interest given by a box, disc or polygon, in scene order
    (only those in ``names`` if given)."""
    return [name for name, spec in scene.regions_of_interest.items()
            if any(getattr(spec, k) is not None for k in ROI_SHAPES)
            and (names is None or name in names)]


def _generate(splits: int) -> None:
    """gmsh's 2D mesh, then `splits` uniform refinements: every triangle split into four at its
    edge midpoints, the new nodes of a curve placed on the curve (the geometry is kept)."""
    gmsh.model.mesh.generate(2)
    for _ in range(splits):
        gmsh.model.mesh.refine()


def _mesh_bodies_separately(scene, bodies, inputs, regions_flat, diag, embed, splits):
    """Mesh each body in its own gmsh model (its regions fragmented together, so regions of
    a body stay conforming); returns the concatenation, bodies in scene order."""
    base = gmsh.model.getCurrent()
    xys, tris, cbs, crs, cis = [], [], [], [], []
    offset = 0
    for b, body in enumerate(bodies):
        gmsh.model.add(f"{base}_body{b}")
        mine = [(rg, make_shape(regions_flat[rg].shape, f"scene.bodies.{body}.regions.{i}.shape"))
                for i, rg in enumerate(rg for bb, rg, _ in inputs if bb == b)]
        covered, inside = fragment_pieces([dts for _, dts in mine], _roi_shapes(scene, embed))
        owner = {tag: (b, max(mine[k][0] for k in ks)) for tag, ks in covered.items()}
        _set_sizes(*_size_function(scene, diag, body, region_entity_sizes(owner, regions_flat)))
        _generate(splits)
        xy, t, c1, c2, c3 = _extract(owner, inside, offset)
        gmsh.model.mesh.removeSizeCallback()
        gmsh.model.remove()
        gmsh.model.setCurrent(base)
        offset += xy.shape[0]
        xys.append(xy); tris += t; cbs += c1; crs += c2; cis += c3
    return np.concatenate(xys), tris, cbs, crs, cis


def build_mesh(scene, rois=None, splits: int = 0) -> SceneMesh:
    """Mesh a validated `Scene` (the ``scene:`` block) into a :class:`SceneMesh`.

    ``boundaries`` of the result holds, for every entry of ``scene.boundaries``,
    the sorted facet indices its selector picks (an empty selection raises
    ``StudyError`` at ``scene.boundaries.<name>``).  The regions of interest
    ``rois`` given by a box, disc or polygon (default: all of them) are embedded
    in the mesh (their outlines are curves of the fragment) and ``roi_cells``
    holds their cells (of their ``body`` if given).  A scene with
    ``mesh: {file: ...}`` is read from that file instead (``wcs.scene.meshfile``).
    ``splits``: the mesh refined that many times by splitting every triangle into four
    (uniform refinement of the same geometry, h halved each time; not for a mesh file).
    """
    bodies_spec = scene.bodies
    if scene.mesh.file is not None:        # the user's own mesh (wcs.scene.meshfile)
        if splits:
            raise StudyError("a mesh file is used as it is: it has no geometry to refine on",
                             path="scene.mesh.file")
        return check_connected(read_mesh_file(scene.mesh.file, scene, "scene.mesh.file"), "scene.mesh.file")
    bodies = list(bodies_spec)
    regions = region_names(scene)
    embed = area_rois(scene, rois)

    with Session():
        # -- shapes: one entry (body index, region index, surfaces) per region
        inputs: list[tuple[int, int, list]] = []
        r = 0
        for b, body in enumerate(bodies):
            for i, reg in enumerate(bodies_spec[body].regions):
                inputs.append((b, r, make_shape(reg.shape, f"scene.bodies.{body}.regions.{i}.shape")))
                r += 1

        # -- one fragment of everything (regions of interest included) -> conforming pieces
        covered, inside = fragment_pieces([dts for _, _, dts in inputs], _roi_shapes(scene, embed))

        owner = piece_owners(covered, inputs, bodies, regions)

        # -- sizes and meshing
        xmin, ymin, _, xmax, ymax, _ = gmsh.model.getBoundingBox(-1, -1)
        diag = math.hypot(xmax - xmin, ymax - ymin)
        regions_flat = [reg for body in bodies for reg in bodies_spec[body].regions]
        if all(bodies_spec[body].mesh is None for body in bodies):
            _set_sizes(*_size_function(scene, diag, None, region_entity_sizes(owner, regions_flat)))
            _generate(splits)
            xy, tris, cb, cr, ci = _extract(owner, inside)
            gmsh.model.mesh.removeSizeCallback()
        else:
            # bodies with their own sizes: every body meshed in a model of its own, so
            # curves shared with other bodies are NOT shared meshes (nonmatching sides)
            xy, tris, cb, cr, ci = _mesh_bodies_separately(scene, bodies, inputs, regions_flat, diag, embed, splits)

    tri = np.concatenate(tris)
    cell_body = np.concatenate(cb)
    cell_region = np.concatenate(cr)
    in_roi = np.concatenate(ci, axis=1)
    if (tri < 0).any():
        raise RuntimeError("gmsh returned a cell with an unknown node")

    # -- one copy of each node per body, unused nodes dropped, compact numbering
    nn = xy.shape[0]
    key = cell_body[:, None] * nn + tri
    used = np.zeros(len(bodies) * nn, dtype=bool)
    used[key] = True
    uniq = np.flatnonzero(used)                    # the (body, node) keys in use, in order
    t = (np.cumsum(used) - 1)[key].T.astype(np.int64)
    p = np.ascontiguousarray(xy[uniq % nn].T)

    # -- counter-clockwise cells
    d1 = p[:, t[1]] - p[:, t[0]]
    d2 = p[:, t[2]] - p[:, t[0]]
    cw = d1[0] * d2[1] - d1[1] * d2[0] < 0
    t[1, cw], t[2, cw] = t[2, cw], t[1, cw].copy()

    mesh = _with_facets(skfem.MeshTri(p, np.ascontiguousarray(t), sort_t=False))
    sm = SceneMesh(mesh=mesh, bodies=bodies, regions=regions,
                   cell_body=cell_body, cell_region=cell_region, boundaries={})
    bnd = {}
    for name, spec in scene.boundaries.items():
        bnd[name] = selectors.select_boundary(sm, spec, f"scene.boundaries.{name}")
    roi_cells = {}
    for j, name in enumerate(embed):
        mask = in_roi[j]
        body = selectors._body_index(sm, scene.regions_of_interest[name], f"scene.regions_of_interest.{name}")
        if body is not None:
            mask = mask & (cell_body == body)
        roi_cells[name] = np.flatnonzero(mask).astype(np.int64)
    return check_connected(dataclasses.replace(sm, boundaries=bnd, roi_cells=roi_cells), "scene.bodies")


def _with_facets(mesh: skfem.MeshTri) -> skfem.MeshTri:
    """``mesh`` with its facets, cell-to-facet and facet-to-cell maps set: the arrays skfem's
    ``build_entities`` / ``build_inverse`` make (facets = sorted node pairs, lexicographic
    order; ``t2f`` rows = the cell edges (0,1), (1,2), (0,2); ``f2t`` = first and last cell
    in that order, -1 for one cell), from one stable sort of the pair keys instead of
    skfem's column-wise unique and two more sorts, 5x slower at 1e5 cells."""
    t = mesh.t
    n, nt = np.int64(mesh.p.shape[1]), t.shape[1]
    pairs = np.hstack([t[[0, 1]], t[[1, 2]], t[[0, 2]]]).astype(np.int64)
    e = np.vstack([pairs.min(axis=0), pairs.max(axis=0)])     # each pair sorted
    keys = e[0] * n + e[1]
    order = np.argsort(keys, kind="stable")
    new = np.r_[True, keys[order[1:]] != keys[order[:-1]]]
    start = np.flatnonzero(new)
    end = np.r_[start[1:], keys.size] - 1
    inv = np.empty(keys.size, dtype=np.int64)
    inv[order] = np.cumsum(new) - 1
    uniq = keys[order[start]]
    mesh._facets = np.ascontiguousarray(np.vstack([uniq // n, uniq % n]).astype(t.dtype))
    mesh._t2f = inv.reshape(3, nt)
    first, last = order[start] % nt, order[end] % nt
    mesh._f2t = np.vstack([first, np.where(end > start, last, -1)]).astype(np.int32)
    return mesh


def check_connected(sm: SceneMesh, path: str) -> SceneMesh:
    """A body is one connected piece of cells: two pieces of one body would each need their
    own rigid motions and supports, and the body's stiffness would be singular where one
    piece is held and the other is not. Pieces that should move apart are separate bodies."""
    t = sm.mesh.t
    n = sm.mesh.p.shape[1]
    rows = np.concatenate([t[0], t[0]])
    cols = np.concatenate([t[1], t[2]])
    graph = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    node_body = sm.node_body
    for b, name in enumerate(sm.bodies):
        pieces = np.unique(label[node_body == b]).size
        if pieces > 1:
            refuse_roi_apart(sm, label, b, sm.roi_cells)
            where = f"{path}.{name}" if path == "scene.bodies" else path
            raise StudyError(f"body {name!r} consists of {pieces} pieces that do not touch; "
                             "make each piece a body of its own (with its own support or contact)", path=where)
    return sm


