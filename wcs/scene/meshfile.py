"""Scenes from the user's own mesh: ``scene.mesh: {file: knee.msh}``.

A gmsh ``.msh`` file (any version gmsh reads), or any file meshio reads, gives
the bodies, regions and boundary pieces of the scene by the NAMES of its
physical groups; the study only assigns materials and boundary conditions.

Naming rule
-----------
* 2D physical group ``BODY``        -> body ``BODY`` with a single region, also named ``BODY``;
* 2D physical group ``BODY:REGION`` -> region ``REGION`` of body ``BODY`` (a body is glued
  from its regions; a body uses either the plain form or the ``BODY:REGION`` form);
* 1D physical group ``NAME``        -> boundary piece ``NAME``: the boundary edges (of any
  body) lying on the group's line elements;
* 1D physical group ``BODY:NAME``   -> boundary piece ``NAME``, only the edges of body
  ``BODY`` -- needed where two bodies touch: put the common curve into two groups,
  e.g. ``pad:pad_bottom`` and ``base:base_top``, the two sides of a contact.

Only 3-node triangles (2D) and 2-node lines (1D) are used; points (0D groups) are
ignored.  Every 2D element must be in a physical group of a body listed in the study,
and every body and region the study lists must be in the file.  Boundary pieces may
still be chosen geometrically in ``scene.boundaries`` (segment / circle / box), by
names that are not also group names.

Where two bodies share nodes in the file, each body gets its own copy (as
``build_mesh`` does), so the bodies touch and contact couples them.

Checks (``StudyError`` naming the study file or the mesh file and the key path):
missing or unreadable file, planar coordinates, unsupported element types, groups the
study names that the file lacks (and bodies of the file the study forgets),
degenerate triangles (zero area: an error), clockwise triangles (reoriented, with a
note in ``Study.notes``), and overlapping cells (a cell centroid inside a cell of
another region or body, or overlapping cells inside one region: an error).
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import skfem

from ..errors import StudyError
from . import selectors
from .meshdata import SceneMesh
from .spec import GroupBoundary

AREA_TOL = 1e-12            # |area| <= AREA_TOL * (bounding-box diagonal)^2 -> degenerate


@dataclass(frozen=True, eq=False)
class RawMesh:
    """The file's triangles and line groups, in the file's node numbering."""

    xy: np.ndarray                      # (n, 2) node coordinates
    tris: np.ndarray                    # (m, 3) node indices, counter-clockwise
    tri_group: np.ndarray               # (m,) index into groups2d
    groups2d: list[str]                 # 2D physical group names
    lines: dict[str, np.ndarray]        # 1D group name -> (k, 2) node indices
    reoriented: int                     # triangles turned from clockwise
    file: str


_CACHE: dict[tuple, RawMesh] = {}


# ---------------------------------------------------------------------------
# reading


def _fail(file, message, path="scene.mesh.file"):
    return StudyError(message, file=str(file), path=path)


def _read_gmsh(path: Path):
    """(xy, [(group, dim, (k, nv) node tags)], tag -> index) via the gmsh API."""
    import gmsh                     # gmsh loads only to read a gmsh file

    from .session import Session    # (it loads gmsh)
    with Session():
        try:
            gmsh.merge(str(path))
        except Exception as exc:  # gmsh raises a bare Exception with its last error
            raise _fail(path, f"gmsh cannot read the file: {exc}") from None
        ntags, coords, _ = gmsh.model.mesh.getNodes()
        ntags = np.asarray(ntags, dtype=np.int64)
        xyz = np.asarray(coords, dtype=float).reshape(-1, 3)
        groups = []
        for dim, tag in gmsh.model.getPhysicalGroups():
            if dim not in (1, 2):
                continue
            name = gmsh.model.getPhysicalName(dim, tag) or str(tag)
            want = 2 if dim == 2 else 1            # gmsh element type: 2 triangle, 1 line
            blocks = []
            for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
                types, _, nodes = gmsh.model.mesh.getElements(dim, ent)
                for t, nd in zip(types, nodes):
                    if t != want:
                        props = gmsh.model.mesh.getElementProperties(t)
                        raise _fail(path, f"physical group {name!r} holds {props[0]!r} elements; "
                                          f"only 3-node triangles (2D) and 2-node lines (1D) are supported")
                    blocks.append(np.asarray(nd, dtype=np.int64).reshape(-1, 3 if dim == 2 else 2))
            conn = np.concatenate(blocks) if blocks else np.zeros((0, 3 if dim == 2 else 2), np.int64)
            groups.append((name, dim, conn))
    if ntags.size == 0:
        raise _fail(path, "the file holds no mesh nodes")
    lookup = np.full(int(ntags.max()) + 1, -1, dtype=np.int64)
    lookup[ntags] = np.arange(ntags.size)
    groups = [(n, d, lookup[c]) for n, d, c in groups]
    return xyz, groups


def _read_meshio(path: Path):
    import meshio                   # only for a mesh file gmsh does not read
    sink = io.StringIO()
    try:
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            m = meshio.read(str(path))
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - meshio may even sys.exit on a bad file
        why = str(exc) if isinstance(exc, Exception) else sink.getvalue().strip().replace("\n", " ")
        raise _fail(path, f"cannot read the mesh file ({why or type(exc).__name__})") from None
    xyz = np.asarray(m.points, dtype=float)
    if xyz.shape[1] == 2:
        xyz = np.column_stack([xyz, np.zeros(len(xyz))])
    groups: dict[tuple[str, int], list] = {}
    kinds = {"triangle": 2, "line": 1}
    names = {int(v[0]): k for k, v in (m.field_data or {}).items()}
    phys = m.cell_data.get("gmsh:physical")
    for b, block in enumerate(m.cells):
        if block.type not in kinds:
            if block.type in ("vertex",):
                continue
            if phys is not None or any(b < len(s) and s[b] is not None and len(s[b])
                                       for s in (m.cell_sets or {}).values()):
                raise _fail(path, f"the file holds {block.type!r} cells; only 3-node triangles (2D) "
                                  "and 2-node lines (1D) are supported")
            continue
        dim = kinds[block.type]
        if phys is not None:
            tags = np.asarray(phys[b], dtype=np.int64)
            for t in np.unique(tags):
                groups.setdefault((names.get(int(t), str(t)), dim), []).append(block.data[tags == t])
        for name, sets in (m.cell_sets or {}).items():
            if b < len(sets) and sets[b] is not None and len(sets[b]):
                groups.setdefault((name, dim), []).append(block.data[np.asarray(sets[b], dtype=np.int64)])
    return xyz, [(n, d, np.concatenate(c).astype(np.int64)) for (n, d), c in groups.items()]


def load_raw(path) -> RawMesh:
    """Read (and check) a mesh file; cached by path, size and modification time."""
    path = Path(path)
    try:
        st = path.stat()
    except FileNotFoundError:
        raise _fail(path, "mesh file not found") from None
    except OSError as exc:
        raise _fail(path, f"cannot read the mesh file: {exc}") from None
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    if key in _CACHE:
        return _CACHE[key]
    if not path.is_file():
        raise _fail(path, "not a file")
    if path.suffix.lower() == ".msh":
        xyz, groups = _read_gmsh(path)
    else:
        xyz, groups = _read_meshio(path)
    raw = _assemble(path, xyz, groups)
    _CACHE.clear()
    _CACHE[key] = raw
    return raw


def _assemble(path: Path, xyz: np.ndarray, groups) -> RawMesh:
    if not np.all(np.isfinite(xyz)):
        raise _fail(path, "node coordinates must be finite numbers")
    xy = np.ascontiguousarray(xyz[:, :2])
    span = float(np.hypot(*(xy.max(0) - xy.min(0)))) if len(xy) else 0.0
    if xyz.shape[1] > 2 and np.abs(xyz[:, 2]).max(initial=0.0) > 1e-9 * max(span, 1e-300):
        raise _fail(path, "the mesh is not planar (z != 0); wcs scenes are 2D in the (x, y) plane")
    names2d, tris, tgroup, lines = [], [], [], {}
    for name, dim, conn in groups:
        if (conn < 0).any():
            raise _fail(path, f"physical group {name!r} refers to unknown nodes")
        if dim == 2:
            if name in names2d:
                raise _fail(path, f"two 2D physical groups are named {name!r}")
            tris.append(conn)
            tgroup.append(np.full(len(conn), len(names2d), dtype=np.int64))
            names2d.append(name)
        else:
            if name in lines:
                raise _fail(path, f"two 1D physical groups are named {name!r}")
            lines[name] = conn
    if not names2d or sum(len(t) for t in tris) == 0:
        raise _fail(path, "the file has no 2D physical group with triangles (name the surfaces "
                          "after the bodies: `BODY` or `BODY:REGION`)")
    tri = np.concatenate(tris)
    tg = np.concatenate(tgroup)
    # -- orientation and degeneracy
    d1 = xy[tri[:, 1]] - xy[tri[:, 0]]
    d2 = xy[tri[:, 2]] - xy[tri[:, 0]]
    area2 = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    bad = np.abs(area2) <= 2 * AREA_TOL * span ** 2
    if bad.any():
        k = int(np.nonzero(bad)[0][0])
        c = xy[tri[k]].mean(0)
        raise _fail(path, f"{int(bad.sum())} degenerate triangle(s) (zero area), e.g. in group "
                          f"{names2d[tg[k]]!r} at ({c[0]:.6g}, {c[1]:.6g})")
    cw = area2 < 0
    tri = tri.copy()
    tri[cw, 1], tri[cw, 2] = tri[cw, 2], tri[cw, 1].copy()
    raw = RawMesh(xy=xy, tris=tri, tri_group=tg, groups2d=names2d, lines=lines,
                  reoriented=int(cw.sum()), file=str(path))
    _check_overlap(raw)
    return raw


def _check_overlap(raw: RawMesh) -> None:
    """No cell centroid of one group inside a cell of another; no overlap inside a group."""
    from matplotlib.tri import Triangulation    # matplotlib: only to check a mesh file's overlaps
    xy, tri, tg = raw.xy, raw.tris, raw.tri_group
    cent = xy[tri].mean(axis=1)
    for g, name in enumerate(raw.groups2d):
        own = tg == g
        if not own.any():
            continue
        sub = tri[own]
        used = np.unique(sub)
        local = np.searchsorted(used, sub)
        try:
            finder = Triangulation(xy[used, 0], xy[used, 1], local).get_trifinder()
        except (RuntimeError, ValueError):
            raise _fail(raw.file, f"the triangles of group {name!r} overlap each other "
                                  "(or repeat)") from None
        lo, hi = xy[used].min(0), xy[used].max(0)
        others = np.nonzero(~own & np.all((cent >= lo) & (cent <= hi), axis=1))[0]
        if others.size == 0:
            continue
        hit = finder(cent[others, 0], cent[others, 1]) >= 0
        if hit.any():
            k = others[np.nonzero(hit)[0][0]]
            raise _fail(raw.file, f"groups {name!r} and {raw.groups2d[tg[k]]!r} overlap (a cell of "
                                  f"{raw.groups2d[tg[k]]!r} at ({cent[k, 0]:.6g}, {cent[k, 1]:.6g}) lies "
                                  f"inside {name!r}); bodies and regions may touch but not overlap")


# ---------------------------------------------------------------------------
# the study side: names


def split_name(name: str) -> tuple[str | None, str]:
    """``'body:piece'`` -> ``('body', 'piece')``; ``'piece'`` -> ``(None, 'piece')``."""
    if ":" in name:
        body, _, rest = name.partition(":")
        return body, rest
    return None, name


def file_regions(raw: RawMesh) -> dict[str, dict[str, int]]:
    """body -> {region name: 2D group index}, in file order."""
    out: dict[str, dict[str, int]] = {}
    plain: set[str] = set()
    for g, name in enumerate(raw.groups2d):
        body, region = split_name(name)
        if body is None:
            body = region
            plain.add(body)
        if not body or not region:
            raise _fail(raw.file, f"2D physical group {name!r}: use `BODY` or `BODY:REGION`")
        regs = out.setdefault(body, {})
        if body in plain and len(regs) >= 1:
            raise _fail(raw.file, f"body {body!r} has a plain group {body!r} and other groups; "
                                  f"name every region of it `{body}:REGION`")
        regs[region] = g
    return out


def prepare_scene(scene, base_dir: Path, error) -> tuple[str, dict[str, list[str]], list[tuple], list[str]]:
    """What a validated `Scene` meshed by ``mesh.file`` takes from the file: the file's
    absolute path, each body's region names (matched with the file's 2D groups, filled in
    where the study gives none), a boundary (piece, group, body or None) for each 1D group,
    and notes for ``Study.notes``. ``error(keys, message)`` makes the StudyError of the
    study file."""
    name = scene.mesh.file
    path = Path(name) if os.path.isabs(name) else Path(base_dir) / name
    if not path.is_file():
        raise error(("mesh", "file"), f"mesh file '{name}' not found (looked for {path})")
    try:
        raw = load_raw(path)
    except StudyError as exc:
        raise error(("mesh", "file"), f"{path}: {exc.fault}") from None
    regions = file_regions(raw)
    have = ", ".join(raw.groups2d)
    names = {}
    for body, spec in scene.bodies.items():
        if body not in regions:
            raise error(("bodies", body), f"no 2D physical group '{body}' or '{body}:REGION' in "
                                          f"{path.name} (it has: {have})")
        fregs = regions[body]
        named = []
        for i, region in enumerate(spec.regions):
            if region.shape is not None:
                raise error(("bodies", body, "regions", i, "shape"),
                            "the regions come from the mesh file; drop `shape`")
            if region.name is None:
                if len(fregs) != 1 or len(spec.regions) != 1:
                    raise error(("bodies", body, "regions", i),
                                f"give the region's `name` (regions of '{body}' in {path.name}: "
                                f"{', '.join(fregs)})")
                named.append(next(iter(fregs)))
            elif region.name not in fregs:
                raise error(("bodies", body, "regions", i, "name"),
                            f"no 2D physical group '{body}:{region.name}' in {path.name} "
                            f"(regions of '{body}': {', '.join(fregs)})")
            else:
                named.append(region.name)
        names[body] = named
        missing = [r for r in fregs if r not in named]
        if missing:
            raise error(("bodies", body, "regions"),
                        f"region '{missing[0]}' of body '{body}' in {path.name} has no material; "
                        "list every region of the file")
    extra = [b for b in regions if b not in scene.bodies]
    if extra:
        raise error(("bodies",), f"the mesh file has body '{extra[0]}' (physical group) that the "
                                 "study does not list; give it a material")
    seen: dict[str, str] = {}
    groups = []
    for group in raw.lines:
        body, piece = split_name(group)
        if not piece or body == "":
            raise error(("mesh", "file"), f"{path.name}: 1D physical group {group!r}: use `NAME` or `BODY:NAME`")
        if piece in seen:
            raise error(("mesh", "file"), f"{path.name}: 1D groups {seen[piece]!r} and {group!r} both "
                                          f"make boundary '{piece}'")
        if body is not None and body not in scene.bodies:
            raise error(("mesh", "file"), f"{path.name}: 1D group {group!r} names unknown body '{body}'")
        if piece in scene.boundaries:
            raise error(("boundaries", piece), f"'{piece}' is also a 1D physical group of "
                                               f"{path.name}; use another name")
        seen[piece] = group
        groups.append((piece, group, body))
    notes = []
    if raw.reoriented:
        notes.append(f"{path.name}: {raw.reoriented} clockwise triangle(s) reoriented counter-clockwise")
    return str(path.resolve()), names, groups, notes


# ---------------------------------------------------------------------------
# the SceneMesh


def read_mesh_file(path, scene, keypath: str = "scene.mesh.file") -> SceneMesh:
    """The :class:`SceneMesh` of a prepared scene (see :func:`prepare_scene`) whose
    ``mesh.file`` is ``path``: bodies and regions in scene order, one copy of each
    node per body, counter-clockwise cells, ``boundaries`` for every scene boundary
    (1D groups and geometric selectors)."""
    try:
        raw = load_raw(path)
    except StudyError as exc:
        raise StudyError(exc.fault, file=exc.file, path=keypath) from None
    fregs = file_regions(raw)
    bodies = list(scene.bodies)
    regions, group_of = [], []
    for body in bodies:
        for i, reg in enumerate(scene.bodies[body].regions):
            rname = reg.name
            if body not in fregs or rname not in fregs[body]:
                raise StudyError(f"no 2D physical group for region '{rname}' of body '{body}'",
                                 file=raw.file, path=f"scene.bodies.{body}.regions.{i}")
            regions.append((body, rname))
            group_of.append(fregs[body][rname])
    region_of_group = np.full(len(raw.groups2d), -1, dtype=np.int64)
    region_of_group[group_of] = np.arange(len(group_of))
    reg = region_of_group[raw.tri_group]
    if (reg < 0).any():
        g = raw.groups2d[raw.tri_group[np.nonzero(reg < 0)[0][0]]]
        raise StudyError(f"2D physical group {g!r} is not a region of the scene",
                         file=raw.file, path="scene.bodies")
    body_of_region = np.array([bodies.index(b) for b, _ in regions], dtype=np.int64)
    order = np.argsort(reg, kind="stable")
    cell_region = reg[order]
    cell_body = body_of_region[cell_region]
    tri = raw.tris[order]

    # -- one copy of each node per body, unused nodes dropped (as build_mesh)
    nn = raw.xy.shape[0]
    key = cell_body[:, None] * nn + tri
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    t = inv.reshape(-1, 3).T.astype(np.int64)
    orig = uniq % nn
    p = np.ascontiguousarray(raw.xy[orig].T)
    mesh = skfem.MeshTri(p, np.ascontiguousarray(t), sort_t=False)
    sm = SceneMesh(mesh=mesh, bodies=bodies, regions=regions,
                   cell_body=cell_body, cell_region=cell_region, boundaries={})

    # -- boundaries: 1D groups by their line elements, others by selector
    bf = selectors.boundary_facets(mesh)
    fa, fb = orig[mesh.facets[0, bf]], orig[mesh.facets[1, bf]]
    fkey = np.minimum(fa, fb) * nn + np.maximum(fa, fb)
    fbody = selectors.facet_body(sm, bf)
    bnd = {}
    for name, spec in scene.boundaries.items():
        kp = f"scene.boundaries.{name}"
        if isinstance(spec, GroupBoundary):
            lines = raw.lines.get(spec.group)
            if lines is None:
                raise StudyError(f"no 1D physical group {spec.group!r}", file=raw.file, path=kp)
            lkey = np.minimum(lines[:, 0], lines[:, 1]) * nn + np.maximum(lines[:, 0], lines[:, 1])
            ok = np.isin(fkey, lkey)
            if spec.body is not None:
                ok &= fbody == bodies.index(spec.body)
            if not ok.any():
                where = f" of body '{spec.body}'" if spec.body else ""
                raise StudyError(f"1D physical group {spec.group!r} lies on no boundary edge{where}",
                                 file=raw.file, path=kp)
            bnd[name] = np.sort(bf[ok])
        else:
            bnd[name] = selectors.select_boundary(sm, spec, kp)
    return dataclasses.replace(sm, boundaries=bnd)
