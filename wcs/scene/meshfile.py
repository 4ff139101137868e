"""Scenes from the user's own mesh: ``scene.mesh: {file: knee.msh}``, in 2D and in 3D.

A gmsh ``.msh`` file (any version gmsh reads), or any file meshio reads, gives
the bodies, regions and boundary pieces of the scene by the NAMES of its
physical groups; the study only assigns materials and boundary conditions.

Naming rule (a scene of dimension d = 2 or 3: its cells are the d-dimensional elements,
its facets the (d-1)-dimensional ones)
-----------
* dD physical group ``BODY``          -> body ``BODY`` with a single region, also named ``BODY``;
* dD physical group ``BODY:REGION``   -> region ``REGION`` of body ``BODY`` (a body is glued
  from its regions; a body uses either the plain form or the ``BODY:REGION`` form);
* (d-1)D physical group ``NAME``      -> boundary piece ``NAME``: the boundary facets (of any
  body) lying on the group's elements;
* (d-1)D physical group ``BODY:NAME`` -> boundary piece ``NAME``, only the facets of body
  ``BODY`` -- needed where two bodies touch: put the common curve (2D) or surface (3D) into
  two groups, e.g. ``pad:pad_bottom`` and ``base:base_top``, the two sides of a contact.

In 2D only 3-node triangles (2D) and 2-node lines (1D) are used, in 3D only 4-node
tetrahedra (3D) and 3-node triangles (2D); groups of lower dimension (points; in 3D also
lines) are ignored.  Every cell must be in a physical group of a body listed in the study,
and every body and region the study lists must be in the file.  Boundary pieces may
still be chosen geometrically in ``scene.boundaries`` (2D: segment / circle / box; 3D: plane
/ box / cylinder / sphere), by names that are not also group names.

Where two bodies share nodes in the file, each body gets its own copy (as
``build_mesh`` and ``build_mesh3d`` do), so the bodies touch and contact couples them.

Checks (``StudyError`` naming the study file or the mesh file and the key path):
missing or unreadable file, planar coordinates (2D), unsupported element types, groups the
study names that the file lacks (and bodies of the file the study forgets), degenerate
cells (zero area or volume: an error), clockwise triangles and negatively oriented
tetrahedra (reoriented, with a note in ``Study.notes``), overlapping cells (a cell centroid
inside a cell of another region or body, or overlapping cells inside one region: an error),
and a facet group that lies on no boundary facet (of its body).

Over 500 lines for one job: a user's mesh read (gmsh or meshio), checked, and its physical groups
turned into the scene's bodies, regions and boundaries, in 2D and in 3D.
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import math
import mmap
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import skfem

from ..errors import StudyError
from ..geometry.facets import boundary_facets
from ..geometry.near import within
from . import selectors
from .meshdata import SceneMesh
from .spec import MAX_NAME, GroupBoundary, _valid_name

AREA_TOL = 1e-12            # |area| (|volume|) <= AREA_TOL * (bounding-box diagonal)^d -> degenerate
INSIDE_TOL = 1e-9           # a point is inside a tetrahedron when its barycentric coordinates exceed this


@dataclass(frozen=True)
class Kind:
    """What a mesh file of a d-dimensional scene holds, and the words its messages use."""

    dim: int
    cell_type: int              # gmsh element type of the cells (2 triangle, 4 tetrahedron)
    facet_type: int             # ... and of the facets (1 line, 2 triangle)
    meshio: dict[str, int]      # meshio cell type -> dimension
    ignored: tuple[str, ...]    # meshio cell types of lower dimension, skipped
    supported: str
    cells: str                  # the cells, plural
    counted: str                # "<n> <counted>"
    measure: str
    facet: str                  # a boundary facet
    reoriented: str
    mesh_type: type


KINDS = {
    2: Kind(2, 2, 1, {"triangle": 2, "line": 1}, ("vertex",), "3-node triangles (2D) and 2-node lines (1D)",
            "triangles", "triangle(s)", "area", "edge", "clockwise triangle(s) reoriented counter-clockwise",
            skfem.MeshTri),
    3: Kind(3, 4, 2, {"tetra": 3, "triangle": 2}, ("vertex", "line"),
            "4-node tetrahedra (3D) and 3-node triangles (2D)", "tetrahedra", "tetrahedron(s)", "volume",
            "face", "negatively oriented tetrahedron(s) reoriented", skfem.MeshTet),
}


@dataclass(frozen=True, eq=False)
class RawMesh:
    """The file's cells and facet groups, in the file's node numbering."""

    x: np.ndarray                       # (n, d) node coordinates
    cells: np.ndarray                   # (m, d + 1) node indices, positively oriented
    cell_group: np.ndarray              # (m,) index into groups
    groups: list[str]                   # dD physical group names
    facets: dict[str, np.ndarray]       # (d-1)D group name -> (k, d) node indices
    reoriented: int                     # cells turned from negative orientation
    file: str

    @property
    def kind(self) -> Kind:
        return KINDS[self.x.shape[1]]


_CACHE: dict[tuple, RawMesh] = {}


# ---------------------------------------------------------------------------
# reading


def _fail(file, message, path="scene.mesh.file"):
    return StudyError(message, file=str(file), path=path)


def _read_gmsh(path: Path, kind: Kind):
    """(xyz, [(group, dim, (k, dim + 1) node indices)]) of the groups of dimensions d and
    d - 1, via the gmsh API."""
    import gmsh                     # gmsh loads only to read a gmsh file

    from .session import Session
    with Session():
        try:
            gmsh.merge(str(path))
        except Exception as exc:  # gmsh raises a bare Exception with its last error, which may be empty
            why = " ".join(str(exc).split())
            raise _fail(path, f"gmsh cannot read the file: {why}" if why else
                        "gmsh cannot read the file and gives no reason (not a mesh file gmsh parses)") from None
        ntags, coords, _ = gmsh.model.mesh.getNodes()
        ntags = np.asarray(ntags, dtype=np.int64)
        xyz = np.asarray(coords, dtype=float).reshape(-1, 3)
        groups = []
        for dim, tag in gmsh.model.getPhysicalGroups():
            if dim not in (kind.dim - 1, kind.dim):
                continue
            name = gmsh.model.getPhysicalName(dim, tag) or str(tag)
            want = kind.cell_type if dim == kind.dim else kind.facet_type
            blocks = []
            for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
                types, _, nodes = gmsh.model.mesh.getElements(dim, ent)
                for t, nd in zip(types, nodes):
                    if t != want:
                        props = gmsh.model.mesh.getElementProperties(t)
                        raise _fail(path, f"physical group {name!r} holds {props[0]!r} elements; "
                                          f"only {kind.supported} are supported")
                    blocks.append(np.asarray(nd, dtype=np.int64).reshape(-1, dim + 1))
            conn = np.concatenate(blocks) if blocks else np.zeros((0, dim + 1), np.int64)
            groups.append((name, dim, conn))
    if ntags.size == 0:
        raise _fail(path, "the file holds no mesh nodes")
    groups = [(n, d, _node_indices(ntags, c)) for n, d, c in groups]
    return xyz, groups


def _msh_header(path: Path) -> list[bytes]:
    """A .msh file's format line: [version, file type (0 ASCII, 1 binary), data size], or []."""
    with path.open("rb") as f:
        head = f.read(64).split()
    return head[1:4] if len(head) > 3 and head[0] == b"$MeshFormat" else []


def _read_msh(path: Path, kind: Kind):
    """`_read_gmsh`'s answer without gmsh (its library and OpenMP runtime, 87 MB, not loaded),
    for an MSH 4.1 file (read by meshio) or an ASCII MSH 2.2 one (`_read_msh22`) whose groups
    of dimensions d and d - 1 hold only the supported cells; None for any other file (gmsh
    reads it, and words what is wrong with it).

    gmsh's answer, as it reads these files (tests/scene/test_meshfile_read.py compares the
    two): a physical group is a set of entities (4.1: as the file's entities name them; 2.2:
    the elementary tags of its elements), the groups in the order of (dimension, tag), each
    group's elements those of its entities (ascending tags) in the file's order, so that in
    2.2 an element is in every group of its entity (gmsh writes an element of two groups
    twice: it comes twice). The nodes: 4.1 in the file's order; 2.2 entity by entity, each
    node in the lowest (dimension, tag) entity of the elements that use it, by ascending tag.
    An unnamed group is called by its tag."""
    head = _msh_header(path)
    if head[:2] == [b"2.2", b"0"]:
        read = _read_msh22(path)
    elif head[:1] == [b"4.1"] and _dense_tags(path, head):    # meshio indexes node tags by an array
        read = _read_msh41(path)                              # of the largest tag's length
    else:
        return None
    if read is None:
        return None
    xyz, names, blocks, members = read
    groups = []
    for dim, tag in sorted(members):
        if dim not in (kind.dim - 1, kind.dim):
            continue
        want = kind.cell_type if dim == kind.dim else kind.facet_type
        conn = []
        for e in sorted(members[(dim, tag)]):
            for d, gtype, cells, entity in blocks:          # the entity's elements, block by block
                if d != dim or not (entity == e).any():
                    continue
                if gtype != want:
                    return None     # gmsh names the element type in its message
                conn.append(cells[entity == e])
        groups.append((names.get((dim, tag), str(tag)), dim,
                       np.concatenate(conn) if conn else np.zeros((0, dim + 1), np.int64)))
    return xyz, groups


def _read_msh41(path: Path):
    """(nodes, {(dim, tag): name}, [(dim, gmsh type, cells, their entities)], {group: its
    entities}) of an MSH 4.1 file, by meshio; None where meshio fails or a group is unnamed."""
    import meshio
    from meshio._mesh import topological_dimension
    from meshio.gmsh.common import _meshio_to_gmsh_type
    sink = io.StringIO()
    try:
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            m = meshio.read(str(path), file_format="gmsh")
    except (Exception, SystemExit):  # noqa: BLE001 - gmsh reads it again, with its own message
        return None
    names = {(int(dim), int(tag)): name for name, (tag, dim) in (m.field_data or {}).items()}
    entity = m.cell_data.get("gmsh:geometrical", [])
    if not m.cells or len(entity) != len(m.cells):
        return None
    blocks = [(topological_dimension[b.type], _meshio_to_gmsh_type.get(b.type), np.asarray(b.data, np.int64),
               np.asarray(e, np.int64)) for b, e in zip(m.cells, entity)]
    named = [k for k in m.cell_sets if k in m.field_data]
    grouped = [b for b in range(len(blocks)) if any(len(m.cell_sets[k][b]) for k in named)]
    if len(m.cell_data.get("gmsh:physical", [])) != len(grouped):
        return None                 # a block of an unnamed group only: meshio does not say which
    members = {key: {int(entity[b][0]) for b, rows in enumerate(m.cell_sets[name]) if len(rows)}
               for key, name in names.items()}
    return np.asarray(m.points, dtype=float), names, blocks, members


MSH22_CELLS = {15: (0, 1), 1: (1, 2), 2: (2, 3), 4: (3, 4)}     # gmsh type -> (dimension, nodes)


def _read_msh22(path: Path):
    """`_read_msh41`'s answer for an ASCII MSH 2.2 file (points, lines, triangles and tetrahedra
    only, each element with its physical and elementary tags), the nodes in gmsh's order; None
    for any other, or a node no element uses (gmsh's place for it is not known here).

    Sections are parsed by numpy (`_numbers`, `_line_starts`), not into a Python object a number
    (a slower reading, with a higher high-water mark of memory)."""
    text = path.read_bytes()

    def section(name: bytes) -> tuple[int, bytes]:
        """A section's count (its first line) and the lines after it; (-1, b"") where absent."""
        at = text.find(b"$" + name + b"\n")
        if at < 0:
            at = text.find(b"$" + name + b"\r\n")             # a file written with CRLF line ends
        end = text.find(b"$End" + name, at)
        if not 0 <= at < end:
            return -1, b""
        head = text.find(b"\n", at) + 1
        line = text.find(b"\n", head, end)
        if line < 0:
            return -1, b""
        return int(text[head:line]), text[line + 1:end]
    try:
        count, body = section(b"PhysicalNames")
        names = {}
        for line in body.splitlines()[:max(count, 0)]:
            dim, tag, name = line.split(None, 2)
            names[(int(dim), int(tag))] = name.strip().strip(b'"').decode()
        n, body = section(b"Nodes")
        table = _numbers(body, float)
        if n < 0 or table.size != 4 * n:
            return None
        table = table.reshape(n, 4)
        count, body = section(b"Elements")
        values, first = _numbers(body, np.int64), _line_starts(body)
        if count < 1 or first is None or first.size - 1 != count or values.size != first[-1]:
            return None
        first, width = first[:-1], np.diff(first)
        if (width < 3).any() or (values[first + 2] != 2).any():
            return None                                     # each element with its two tags
        kinds = values[first + 1]
        tags = table[:, 0].astype(np.int64)
        if not np.array_equal(tags, table[:, 0]):
            return None
        blocks = []
        for gtype in dict.fromkeys(kinds.tolist()):         # the types in the order the file meets them
            if gtype not in MSH22_CELLS:
                return None
            dim, k = MSH22_CELLS[gtype]
            mine = kinds == gtype
            if (width[mine] != 5 + k).any():
                return None
            a = values[first[mine][:, None] + np.arange(3, 5 + k)]     # physical, elementary, nodes
            blocks.append((dim, gtype, _node_indices(tags, a[:, 2:]), a[:, 0], a[:, 1]))
    except (ValueError, IndexError, UnicodeDecodeError):
        return None                 # gmsh reads it again, with its own message
    if any((b[2] < 0).any() for b in blocks):
        return None
    home = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)      # dimension * 2**40 + entity tag
    for dim, _, cells, _, entity in blocks:
        np.minimum.at(home, cells.ravel(), np.repeat(dim * 2**40 + entity, cells.shape[1]))
    if (home == np.iinfo(np.int64).max).any():
        return None
    order = np.lexsort((tags, home))
    new = np.empty(n, np.int64)
    new[order] = np.arange(n)
    members: dict[tuple[int, int], set] = {}
    for dim, _, _, physical, entity in blocks:
        for tag in np.unique(physical[physical != 0]):          # 0: in no physical group
            members.setdefault((dim, int(tag)), set()).update(np.unique(entity[physical == tag]).tolist())
    return (table[order, 1:], names, [(dim, gtype, new[cells], entity) for dim, gtype, cells, _, entity in blocks],
            members)


def _numbers(body: bytes, dtype) -> np.ndarray:
    """The whitespace-separated numbers of `body` (ValueError where one is not of `dtype`)."""
    return np.fromstring(body, dtype=dtype, sep=" ") if body.strip() else np.zeros(0, dtype)


def _line_starts(body: bytes) -> np.ndarray | None:
    """Where each non-empty line's numbers start among `_numbers(body)`, and their count last
    (None where an empty line lies between two others)."""
    b = np.frombuffer(body, np.uint8)
    if not b.size:
        return np.zeros(1, np.int64)
    blank = (b == 32) | (b == 9) | (b == 13) | (b == 10)
    starts = np.flatnonzero(~blank & np.r_[True, blank[:-1]])    # each number's first byte
    ends = np.flatnonzero(b == 10)
    if b[-1] != 10:
        ends = np.r_[ends, b.size]
    per_line = np.bincount(np.searchsorted(ends, starts), minlength=ends.size)
    used = np.flatnonzero(per_line)
    if used.size and (per_line[used[0]:used[-1] + 1] == 0).any():
        return None
    return np.r_[0, np.cumsum(per_line[used])]


def _dense_tags(path: Path, head: list[bytes]) -> bool:
    """Whether an MSH 4.1 file's largest node tag is below twice its node count (plus 1,000)."""
    with path.open("rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as mm:
        at = mm.find(b"$Nodes")
        if at < 0:
            return False
        at = mm.find(b"\n", at) + 1
        if head[1] == b"0":
            counts = [int(v) for v in mm[at:mm.find(b"\n", at)].split()]
        else:
            counts = np.frombuffer(mm[at:at + 4 * int(head[2])], dtype=f"u{int(head[2])}").tolist()
    return len(counts) == 4 and counts[3] < 2 * counts[1] + 1000


def _node_indices(tags: np.ndarray, refs: np.ndarray) -> np.ndarray:
    """The positions in `tags` of the node tags `refs` (-1 for a tag not among them), through the
    sorted tags: gmsh's node tags may be sparse (a tag of 1e12 is valid), so no array of the
    largest tag's length."""
    order = np.argsort(tags, kind="stable")
    pos = np.minimum(np.searchsorted(tags[order], refs), tags.size - 1)
    return np.where(tags[order][pos] == refs, order[pos], -1)


def _read_meshio(path: Path, kind: Kind):
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
    names = {int(v[0]): k for k, v in (m.field_data or {}).items()}
    phys = m.cell_data.get("gmsh:physical")
    for b, block in enumerate(m.cells):
        if block.type not in kind.meshio:
            if block.type in kind.ignored:
                continue
            if phys is not None or any(b < len(s) and s[b] is not None and len(s[b])
                                       for s in (m.cell_sets or {}).values()):
                raise _fail(path, f"the file holds {block.type!r} cells; only {kind.supported} are supported")
            continue
        dim = kind.meshio[block.type]
        if phys is not None:
            tags = np.asarray(phys[b], dtype=np.int64)
            for t in np.unique(tags):
                groups.setdefault((names.get(int(t), str(t)), dim), []).append(block.data[tags == t])
        for name, sets in (m.cell_sets or {}).items():
            if b < len(sets) and sets[b] is not None and len(sets[b]):
                groups.setdefault((name, dim), []).append(block.data[np.asarray(sets[b], dtype=np.int64)])
    return xyz, [(n, d, np.concatenate(c).astype(np.int64)) for (n, d), c in groups.items()]


def load_raw(path, dim: int = 2) -> RawMesh:
    """Read (and check) the mesh file of a ``dim``-dimensional scene; cached by path, size,
    modification time and dimension."""
    path = Path(path)
    try:
        st = path.stat()
    except FileNotFoundError:
        raise _fail(path, "mesh file not found") from None
    except OSError as exc:
        raise _fail(path, f"cannot read the mesh file: {exc}") from None
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns, dim)
    if key in _CACHE:
        return _CACHE[key]
    if not path.is_file():
        raise _fail(path, "not a file")
    kind = KINDS[dim]
    if path.suffix.lower() == ".msh":
        xyz, groups = _read_msh(path, kind) or _read_gmsh(path, kind)
    else:
        xyz, groups = _read_meshio(path, kind)
    raw = _assemble(path, xyz, groups, kind)
    _CACHE.clear()
    _CACHE[key] = raw
    return raw


def _signed_measure(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """d! times the signed area (2D) or volume (3D) of each cell: positive for counter-clockwise
    triangles and for tetrahedra whose edges from node 0 form a right-handed triple."""
    e = [x[cells[:, i]] - x[cells[:, 0]] for i in range(1, cells.shape[1])]
    if len(e) == 2:
        return e[0][:, 0] * e[1][:, 1] - e[0][:, 1] * e[1][:, 0]
    return np.einsum("ij,ij->i", e[0], np.cross(e[1], e[2]))


def _at(c) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in c) + ")"


def _assemble(path: Path, xyz: np.ndarray, groups, kind: Kind) -> RawMesh:
    d = kind.dim
    if not np.all(np.isfinite(xyz)):
        raise _fail(path, "node coordinates must be finite numbers")
    x = np.ascontiguousarray(xyz[:, :d])
    span = float(np.linalg.norm(x.max(0) - x.min(0))) if len(x) else 0.0
    if d == 2 and xyz.shape[1] > 2 and np.abs(xyz[:, 2]).max(initial=0.0) > 1e-9 * max(span, 1e-300):
        raise _fail(path, "the mesh is not planar (z != 0); wcs scenes are 2D in the (x, y) plane")
    names, cells, cgroup, facets = [], [], [], {}
    for name, dim, conn in groups:
        if (conn < 0).any():
            raise _fail(path, f"physical group {name!r} refers to unknown nodes")
        if dim == d:
            if name in names:
                raise _fail(path, f"two {d}D physical groups are named {name!r}")
            cells.append(conn)
            cgroup.append(np.full(len(conn), len(names), dtype=np.int64))
            names.append(name)
        else:
            if name in facets:
                raise _fail(path, f"two {d - 1}D physical groups are named {name!r}")
            facets[name] = conn
    if not names or sum(len(t) for t in cells) == 0:
        raise _fail(path, f"the file has no {d}D physical group with {kind.cells} (name the "
                          f"{'surfaces' if d == 2 else 'volumes'} after the bodies: `BODY` or `BODY:REGION`)")
    cell = np.concatenate(cells)
    cg = np.concatenate(cgroup)
    # -- orientation and degeneracy
    measure = _signed_measure(x, cell)
    bad = np.abs(measure) <= math.factorial(d) * AREA_TOL * span ** d
    if bad.any():
        k = int(np.nonzero(bad)[0][0])
        raise _fail(path, f"{int(bad.sum())} degenerate {kind.counted} (zero {kind.measure}), e.g. in group "
                          f"{names[cg[k]]!r} at {_at(x[cell[k]].mean(0))}")
    negative = measure < 0
    cell = cell.copy()
    cell[negative, 1], cell[negative, 2] = cell[negative, 2], cell[negative, 1].copy()
    raw = RawMesh(x=x, cells=cell, cell_group=cg, groups=names, facets=facets,
                  reoriented=int(negative.sum()), file=str(path))
    (_check_overlap if d == 2 else _check_overlap3d)(raw)
    return raw


def _self_overlap(raw: RawMesh, name: str) -> StudyError:
    return _fail(raw.file, f"the {raw.kind.cells} of group {name!r} overlap each other (or repeat)")


def _overlap(raw: RawMesh, inner: int, outer: int) -> StudyError:
    """The error for the centroid of cell `inner` lying inside cell `outer`."""
    name, other = raw.groups[raw.cell_group[outer]], raw.groups[raw.cell_group[inner]]
    if name == other:
        return _self_overlap(raw, name)
    return _fail(raw.file, f"groups {name!r} and {other!r} overlap (a cell of {other!r} at "
                           f"{_at(raw.x[raw.cells[inner]].mean(0))} lies inside {name!r}); "
                           "bodies and regions may touch but not overlap")


def _check_overlap(raw: RawMesh) -> None:
    """No cell centroid of one group inside a cell of another; no overlap inside a group."""
    from matplotlib.tri import Triangulation    # matplotlib: only to check a mesh file's overlaps
    xy, tri, tg = raw.x, raw.cells, raw.cell_group
    cent = xy[tri].mean(axis=1)
    for g, name in enumerate(raw.groups):
        own = tg == g
        if not own.any():
            continue
        sub = tri[own]
        used = np.unique(sub)
        local = np.searchsorted(used, sub)
        try:
            finder = Triangulation(xy[used, 0], xy[used, 1], local).get_trifinder()
        except (RuntimeError, ValueError):
            raise _self_overlap(raw, name) from None
        lo, hi = xy[used].min(0), xy[used].max(0)
        others = np.nonzero(~own & np.all((cent >= lo) & (cent <= hi), axis=1))[0]
        if others.size == 0:
            continue
        hit = finder(cent[others, 0], cent[others, 1]) >= 0
        if hit.any():
            k = others[np.nonzero(hit)[0][0]]
            raise _overlap(raw, k, np.nonzero(own)[0][0])


def _check_overlap3d(raw: RawMesh) -> None:
    """No cell centroid strictly inside another tetrahedron (of any group, its own included).

    The centroid of a tetrahedron is inside it, so two tetrahedra whose interiors overlap enough
    to hold either one's centroid are caught (one inside another, a repeated cell, two groups
    meshing the same volume, cells crossing each other deeply); a sliver-thin overlap that holds
    neither centroid is not. Touching cells (a shared face, edge or node) never are. The
    candidates of a tetrahedron are the centroids within the distance of its farthest vertex
    from its own centroid (`wcs.geometry.near.within`); each is tested by its barycentric
    coordinates. Of several overlaps, the one of the first tetrahedron and its first centroid
    inside is named."""
    x, tet = raw.x, raw.cells
    corners = x[tet]                                            # (m, 4, 3)
    cent = corners.mean(axis=1)
    reach = np.linalg.norm(corners - cent[:, None], axis=2).max(axis=1)
    inverse = np.linalg.inv(np.transpose(corners[:, 1:] - corners[:, :1], (0, 2, 1)))  # edges as columns
    base = corners[:, 0].copy()
    first = None
    for outer, inner, _ in within(cent, cent, reach):
        other = inner != outer
        outer, inner = outer[other], inner[other]
        lam = np.einsum("kij,kj->ki", inverse.take(outer, axis=0), cent.take(inner, axis=0) - base.take(outer, axis=0))
        inside = (lam > INSIDE_TOL).all(axis=1) & (lam.sum(axis=1) < 1 - INSIDE_TOL)
        if inside.any():
            k = np.flatnonzero(inside)
            k = k[np.lexsort((inner[k], outer[k]))[0]]
            pair = (int(outer[k]), int(inner[k]))
            first = pair if first is None else min(first, pair)
    if first is not None:
        raise _overlap(raw, first[1], first[0])


# ---------------------------------------------------------------------------
# the study side: names


def split_name(name: str) -> tuple[str | None, str]:
    """``'body:piece'`` -> ``('body', 'piece')``; ``'piece'`` -> ``(None, 'piece')``."""
    if ":" in name:
        body, _, rest = name.partition(":")
        return body, rest
    return None, name


def file_regions(raw: RawMesh) -> dict[str, dict[str, int]]:
    """body -> {region name: cell group index}, in file order."""
    out: dict[str, dict[str, int]] = {}
    plain: set[str] = set()
    for g, name in enumerate(raw.groups):
        body, region = split_name(name)
        if body is None:
            body = region
            plain.add(body)
        if not body or not region:
            raise _fail(raw.file, f"{raw.kind.dim}D physical group {name!r}: use `BODY` or `BODY:REGION`")
        regs = out.setdefault(body, {})
        if body in plain and len(regs) >= 1:
            raise _fail(raw.file, f"body {body!r} has a plain group {body!r} and other groups; "
                                  f"name every region of it `{body}:REGION`")
        regs[region] = g
    return out


def _file_name(name: str, what: str, error) -> str:
    """A region or boundary name the mesh file gives, held to the study's rules for names."""
    try:
        return _valid_name(name)
    except ValueError as exc:
        shown = ascii(name) if len(name) <= MAX_NAME else f"{ascii(name[:MAX_NAME])}..."
        raise error(("mesh", "file"), f"{what} {shown}: {exc}") from None


def prepare_scene(scene, base_dir: Path, error) -> tuple[str, dict[str, list[str]], list[tuple], list[str]]:
    """What a validated `Scene` (2D or 3D) meshed by ``mesh.file`` takes from the file: the
    file's absolute path, each body's region names (matched with the file's cell groups, filled
    in where the study gives none), a boundary (piece, group, body or None) for each facet
    group, and notes for ``Study.notes``. ``error(keys, message)`` makes the StudyError of the
    study file."""
    name = scene.mesh.file
    d = scene.dimension
    path = Path(name) if os.path.isabs(name) else Path(base_dir) / name
    if not path.is_file():
        raise error(("mesh", "file"), f"mesh file '{name}' not found (looked for {path})")
    try:
        raw = load_raw(path, d)
    except StudyError as exc:
        raise error(("mesh", "file"), f"{path}: {exc.fault}") from None
    regions = file_regions(raw)
    have = ", ".join(raw.groups)
    names = {}
    for body, spec in scene.bodies.items():
        if body not in regions:
            raise error(("bodies", body), f"no {d}D physical group '{body}' or '{body}:REGION' in "
                                          f"{path.name} (it has: {have})")
        if spec.mesh is not None:
            raise error(("bodies", body, "mesh"), "the scene's mesh is a file: a body "
                        "cannot have its own mesh sizes")
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
                named.append(_file_name(next(iter(fregs)), f"{path.name}: {d}D physical group", error))
            elif region.name not in fregs:
                raise error(("bodies", body, "regions", i, "name"),
                            f"no {d}D physical group '{body}:{region.name}' in {path.name} "
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
    for group in raw.facets:
        body, piece = split_name(group)
        if not piece or body == "":
            raise error(("mesh", "file"), f"{path.name}: {d - 1}D physical group {group!r}: use `NAME` or `BODY:NAME`")
        _file_name(piece, f"{path.name}: {d - 1}D physical group", error)
        if piece in seen:
            raise error(("mesh", "file"), f"{path.name}: {d - 1}D groups {seen[piece]!r} and {group!r} both "
                                          f"make boundary '{piece}'")
        if body is not None and body not in scene.bodies:
            raise error(("mesh", "file"), f"{path.name}: {d - 1}D group {group!r} names unknown body '{body}'")
        if piece in scene.boundaries:
            raise error(("boundaries", piece), f"'{piece}' is also a {d - 1}D physical group of "
                                               f"{path.name}; use another name")
        seen[piece] = group
        groups.append((piece, group, body))
    notes = []
    if raw.reoriented:
        notes.append(f"{path.name}: {raw.reoriented} {raw.kind.reoriented}")
    return str(path.resolve()), names, groups, notes


# ---------------------------------------------------------------------------
# the SceneMesh


def _rows_in(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Which rows of ``a`` are rows of ``b`` (rows of node indices, each sorted)."""
    key = _row_keys(np.concatenate([a, b]))
    if key is None:
        _, key = np.unique(np.concatenate([a, b]), axis=0, return_inverse=True)
        key = key.ravel()
    return np.isin(key[:len(a)], key[len(a):])


def _row_keys(rows: np.ndarray) -> np.ndarray | None:
    """One int64 per row of nonnegative indices, ordered as the rows are lexicographically
    (the row's digits in base max + 1); None where they do not fit in 63 bits."""
    base = int(rows.max(initial=0)) + 1
    if base ** rows.shape[1] >= 2**63:
        return None
    return rows.astype(np.int64) @ base ** np.arange(rows.shape[1] - 1, -1, -1, dtype=np.int64)


def made_facets(mesh) -> None:
    """scikit-fem's facets and cell-to-facet map of ``mesh`` (`Mesh.build_entities`: the sorted
    node tuples of every cell's facets, their lexicographically sorted unique columns and each
    cell facet's column), made from one int64 key a facet (`_row_keys`): its np.unique over
    columns sorts structured rows, the slowest step of a 3D mesh once it is made (read from a
    file or meshed, `wcs.scene.mesher3d`); the same arrays. Left to scikit-fem where the keys
    do not fit."""
    faces = mesh.elem.refdom.facets
    sorted_nodes = np.sort(np.hstack([mesh.t[ix] for ix in faces]), axis=0)
    key = _row_keys(sorted_nodes.T)
    if key is None:
        return
    uniq, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    mesh._facets = np.ascontiguousarray(sorted_nodes[:, first])
    mesh._t2f = inverse.reshape(len(faces), mesh.t.shape[1])


def read_mesh_file(path, scene, keypath: str = "scene.mesh.file", dim: int = 2,
                   select=selectors.select_boundary) -> SceneMesh:
    """The :class:`SceneMesh` of a prepared ``dim``-dimensional scene (see :func:`prepare_scene`)
    whose ``mesh.file`` is ``path``: bodies and regions in scene order, one copy of each
    node per body, positively oriented cells (a ``MeshTri`` or a ``MeshTet``), ``boundaries``
    for every scene boundary (facet groups, and geometric selectors by
    ``select(scene mesh, spec, key path)``)."""
    try:
        raw = load_raw(path, dim)
    except StudyError as exc:
        raise StudyError(exc.fault, file=exc.file, path=keypath) from None
    _CACHE.clear()      # the file's arrays go with the mesh made of them (another mesh of it reads it again)
    kind = raw.kind
    fregs = file_regions(raw)
    bodies = list(scene.bodies)
    regions, group_of = [], []
    for body in bodies:
        for i, reg in enumerate(scene.bodies[body].regions):
            rname = reg.name
            if body not in fregs or rname not in fregs[body]:
                raise StudyError(f"no {dim}D physical group for region '{rname}' of body '{body}'",
                                 file=raw.file, path=f"scene.bodies.{body}.regions.{i}")
            regions.append((body, rname))
            group_of.append(fregs[body][rname])
    region_of_group = np.full(len(raw.groups), -1, dtype=np.int64)
    region_of_group[group_of] = np.arange(len(group_of))
    reg = region_of_group[raw.cell_group]
    if (reg < 0).any():
        g = raw.groups[raw.cell_group[np.nonzero(reg < 0)[0][0]]]
        raise StudyError(f"{dim}D physical group {g!r} is not a region of the scene",
                         file=raw.file, path="scene.bodies")
    body_of_region = np.array([bodies.index(b) for b, _ in regions], dtype=np.int64)
    order = np.argsort(reg, kind="stable")
    cell_region = reg[order]
    cell_body = body_of_region[cell_region]
    cells = raw.cells[order]

    # -- one copy of each node per body, unused nodes dropped (as build_mesh)
    nn = raw.x.shape[0]
    key = cell_body[:, None] * nn + cells
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    t = inv.reshape(-1, dim + 1).T.astype(np.int64)
    orig = uniq % nn
    p = np.ascontiguousarray(raw.x[orig].T)
    mesh = kind.mesh_type(p, np.ascontiguousarray(t), sort_t=False)
    made_facets(mesh)
    sm = SceneMesh(mesh=mesh, bodies=bodies, regions=regions,
                   cell_body=cell_body, cell_region=cell_region, boundaries={})

    # -- boundaries: facet groups by their elements, others by selector
    bf = boundary_facets(mesh)
    fnodes = np.sort(orig[mesh.facets[:, bf]].T, axis=1)
    fbody = selectors.facet_body(sm, bf)
    bnd = {}
    for name, spec in scene.boundaries.items():
        kp = f"scene.boundaries.{name}"
        if isinstance(spec, GroupBoundary):
            elements = raw.facets.get(spec.group)
            if elements is None:
                raise StudyError(f"no {dim - 1}D physical group {spec.group!r}", file=raw.file, path=kp)
            ok = _rows_in(fnodes, np.sort(elements, axis=1))
            if spec.body is not None:
                ok &= fbody == bodies.index(spec.body)
            if not ok.any():
                where = f" of body '{spec.body}'" if spec.body else ""
                raise StudyError(f"{dim - 1}D physical group {spec.group!r} lies on no boundary "
                                 f"{kind.facet}{where}", file=raw.file, path=kp)
            bnd[name] = np.sort(bf[ok])
        else:
            bnd[name] = select(sm, spec, kp)
    return dataclasses.replace(sm, boundaries=bnd)
