"""The report's figures of a 3D case (matplotlib, Agg), readable without ParaView and in print:
the outer surface (shaded, the supports, loads, contact surfaces and regions of interest outlined;
the whole model and the model around the regions of interest), the deformed one coloured by von
Mises, cuts through each region of interest, and maps of contact pressure and slip on each
contact surface in the coordinates of its plane.

Matplotlib renders the outer surface as one polygon per boundary triangle, painter-sorted
(no depth buffer); only the faces towards the viewer are drawn (a closed surface's back faces
are never seen), each lit by Lambert's law. The geometry functions are pure functions over arrays:
`outer_faces` (the triangles of a tetrahedral mesh that belong to one cell only, outward),
`plane_section` (the polygon where a plane cuts each tetrahedron), `selected_faces` (the outer
faces of a boundary selector, as the solver selects them), `roi_cells` (a region of interest's
cells, in its body); a contact surface is drawn in its plane's axes (`map_axes`).

Over 500 lines: the report's 3D figures, one function a figure, over the surface, cuts and regions
of interest of its first sections.
"""
from __future__ import annotations

import numpy as np
from matplotlib.collections import PolyCollection
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from matplotlib.tri import Triangulation
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

from ..contact.frame import surface_frame
from ..geometry.tet import von_mises
from .data import Results
from .plots import CONTACT_COLORS, length_scale, magnification, plt, png, stress_scale

FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])   # face k: opposite vertex k, outward for positive tets
EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
VIEWS = ((25.0, -60.0), (25.0, 120.0))       # (elevation, azimuth) of the two views of the surface
SET_COLOURS = {"support": "#1f5fbf", "load": "#e08000", "contact": CONTACT_COLORS[0], "region of interest": "#000000"}
THIN = 0.25          # an axis shorter than this share of the longest gets its two ends in its label, no ticks


def outer_faces(cells: np.ndarray, coords: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(k, 3) vertex triples of the faces that belong to one tetrahedron only, oriented as
    that tetrahedron's outward faces, and (k,) the cell each belongs to. Without `coords` the
    orientation is read off the vertex order (right for positively numbered tetrahedra); with
    them each face is turned to point away from its cell's fourth vertex, whatever the order."""
    tri = cells[:, FACES].reshape(-1, 3)                     # (4 ncells, 3), cell-major
    key = np.sort(tri, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    once = counts[inverse.ravel()] == 1
    faces, owner = tri[once], np.flatnonzero(once) // 4
    if coords is not None:
        opposite = cells[owner, np.flatnonzero(once) % 4]    # face k is opposite vertex k
        x = coords[faces]
        n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        inward = np.einsum("ij,ij->i", n, coords[opposite] - x[:, 0]) > 0
        faces[inward] = faces[inward][:, [0, 2, 1]]
    return faces, owner


def plane_section(coords: np.ndarray, cells: np.ndarray, point, normal) -> tuple[list[np.ndarray], np.ndarray]:
    """The polygons (each (3 or 4, 3), ordered counter-clockwise in the plane's `plane_axes`) where the plane through
    `point` with normal `normal` cuts the tetrahedra, and the index of each polygon's cell.
    Cells touching the plane only in a vertex, an edge or a face are left out."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    d = (coords - np.asarray(point, float)) @ n                 # signed distance of every node
    dc = d[cells]                                                # (ncells, 4)
    cut = np.flatnonzero((dc.min(axis=1) < 0) & (dc.max(axis=1) > 0))
    a, b = cells[cut][:, EDGES[:, 0]], cells[cut][:, EDGES[:, 1]]          # (k, 6)
    da, db = d[a], d[b]
    crosses = (da < 0) != (db < 0)
    crosses &= (da != 0) | (db != 0)
    s = np.where(crosses, da / np.where(crosses, da - db, 1.0), 0.0)
    pts = coords[a] + s[..., None] * (coords[b] - coords[a])               # (k, 6, 3)
    e1, e2 = plane_axes(n)
    polygons, owner = [], []
    for k in range(cut.size):
        p = pts[k, crosses[k]]
        p = p[np.unique(np.round(p / (np.abs(p).max() + 1e-300), 12), axis=0, return_index=True)[1]]
        if len(p) < 3:
            continue
        c = p.mean(axis=0)
        angle = np.arctan2((p - c) @ e2, (p - c) @ e1)
        polygons.append(p[np.argsort(angle)])
        owner.append(cut[k])
    return polygons, np.asarray(owner, dtype=np.int64)


def plane_axes(normal) -> tuple[np.ndarray, np.ndarray]:
    """Two orthonormal directions (e1, e2) of the plane with normal `normal`, read as the
    coordinate axes are: e1 the first axis (x, y, z order) not along the normal, projected onto
    the plane, e2 the next one made orthogonal to it (a cut across z is seen in x and y)."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    axes = [a for a in np.eye(3) if abs(a @ n) < 0.9]
    e1 = axes[0] - (axes[0] @ n) * n
    e1 /= np.linalg.norm(e1)
    e2 = axes[1] - (axes[1] @ n) * n - (axes[1] @ e1) * e1
    return e1, e2 / np.linalg.norm(e2)


def _von_mises(f) -> np.ndarray | None:
    if f.von_mises is not None:
        return f.von_mises
    if f.stress is None:
        return None
    return von_mises(f.stress.T)                              # (cell, xx yy zz yz xz xy) in the file


# ---------------------------------------------------------------- regions of interest

def along(e: np.ndarray) -> str:
    """An axis label "along (a, b, c) [m]" of a unit direction, its components to 1e-3 (no round-off digits)."""
    return "along (" + ", ".join(f"{v:.2g}" for v in np.round(e, 3) + 0.0) + ") [m]"


def _thin_axis(coords: np.ndarray) -> np.ndarray:
    return np.eye(3)[int(np.argmin(np.ptp(coords, axis=0)))]


def _inside(spec: dict, x: np.ndarray) -> np.ndarray | None:
    """Points x (k, 3) inside a region selector's solid (box, ball, cylinder); None for others."""
    if "box" in spec:
        b = np.asarray(spec["box"], float)
        return np.all((x >= b[:3]) & (x <= b[3:]), axis=1)
    if "ball" in spec:
        return np.linalg.norm(x - np.asarray(spec["ball"]["center"], float), axis=1) <= spec["ball"]["radius"]
    if "cylinder" in spec:
        a, b = np.asarray(spec["cylinder"]["start"], float), np.asarray(spec["cylinder"]["end"], float)
        axis = (b - a) / np.linalg.norm(b - a)
        t = (x - a) @ axis
        radial = np.linalg.norm(x - a - t[:, None] * axis, axis=1)
        return (t >= 0) & (t <= np.linalg.norm(b - a)) & (radial <= spec["cylinder"]["radius"])
    return None


def selected_faces(res: Results, name: str, faces: np.ndarray, owner: np.ndarray) -> np.ndarray | None:
    """Mask over the outer `faces` of the boundary `name` of the scene (its selector as the solver
    reads it: the three nodes on the set within the tolerance, on its body); None when the scene
    does not define it geometrically."""
    from ..scene.mesher3d import ABS_TOL, REL_TOL, surface_distance
    from ..scene.spec3d import Boundary
    spec = (res.scene.get("boundaries") or {}).get(name)
    try:
        b = Boundary.model_validate(spec)
    except Exception:  # noqa: BLE001 - not a geometric face selector: said by the caller
        return None
    mesh = res.mesh
    keep = np.ones(len(faces), bool)
    if b.body is not None:
        if mesh.cell_body is None or b.body not in mesh.bodies:
            return None
        keep = mesh.cell_body[owner] == mesh.bodies.index(b.body)
    x = mesh.coords[faces].transpose(2, 1, 0)                    # (3 coordinates, 3 nodes, nfaces)
    edges = np.linalg.norm(x - np.roll(x, 1, axis=1), axis=0).max(axis=0)
    tol = REL_TOL * edges + ABS_TOL * float(np.linalg.norm(np.ptp(mesh.coords, axis=0)))
    if b.plane is not None and b.plane.tolerance is not None:
        tol = np.full(len(faces), b.plane.tolerance)
    return keep & (surface_distance(b, x) <= tol).all(axis=0)


def roi_cells(res: Results, name: str) -> np.ndarray | None:
    """Mask over the cells of the region of interest `name`: the cells whose centroid is inside its
    solid (box, ball, cylinder) and in its `body:`, or the cells under the faces of its boundary;
    None when neither can be read from the scene."""
    mesh = res.mesh
    roi = dict((res.scene.get("regions_of_interest") or {}).get(name) or {})
    if "boundary" in roi:
        faces, owner = outer_faces(mesh.cells, mesh.coords)
        sel = selected_faces(res, roi["boundary"], faces, owner)
        if sel is None:
            return None
        out = np.zeros(len(mesh.cells), bool)
        out[owner[sel]] = True
        return out
    inside = _inside(roi, mesh.coords[mesh.cells].mean(axis=1))
    if inside is None:
        return None
    if roi.get("body") is not None:
        if mesh.cell_body is None or roi["body"] not in mesh.bodies:
            return None
        inside &= mesh.cell_body == mesh.bodies.index(roi["body"])
    return inside


def outline(faces: np.ndarray) -> np.ndarray:
    """(k, 2) node pairs of the edges that belong to one triangle of `faces` only: the set's rim."""
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    key, counts = np.unique(e, axis=0, return_counts=True)
    return key[counts == 1]


def face_normals(x: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals of the triangles x[faces] (outward for `outer_faces`)."""
    n = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def roi_frame(res: Results) -> tuple[np.ndarray, np.ndarray] | None:
    """(lo, hi): the box around the cells of every region of interest, widened on each side by half
    its largest size and kept within the mesh's box (None: no region of interest has cells)."""
    mesh, boxes = res.mesh, []
    for name in res.scene.get("regions_of_interest") or {}:
        cells = roi_cells(res, name)
        if cells is not None and cells.any():
            p = mesh.coords[np.unique(mesh.cells[cells])]
            boxes.append((p.min(axis=0), p.max(axis=0)))
    if not boxes:
        return None
    a, b = np.min([q[0] for q in boxes], axis=0), np.max([q[1] for q in boxes], axis=0)
    pad = 0.5 * float((b - a).max())
    return np.maximum(a - pad, mesh.coords.min(axis=0)), np.minimum(b + pad, mesh.coords.max(axis=0))


def scene_sets(res: Results, faces: np.ndarray, owner: np.ndarray) -> tuple[list, list[str]]:
    """The outlined face sets of the scene: [(kind, name, mask over the outer `faces`)] for every
    support, load, contact surface (its slave side) and region of interest (where it meets the
    outer surface), and the names of those that cannot be drawn."""
    out, missing = [], []
    entries = [("support", n, n) for n in res.scene.get("supports") or {}]
    entries += [("load", n, n) for n in res.scene.get("loads") or {}]
    entries += [("contact", n, (c or {}).get("slave", "")) for n, c in (res.scene.get("contacts") or {}).items()]
    for kind, name, boundary in entries:
        sel = selected_faces(res, boundary, faces, owner)
        (out.append((kind, name, sel)) if sel is not None and sel.any() else missing.append(f"{kind} {name}"))
    for name in res.scene.get("regions_of_interest") or {}:
        cells = roi_cells(res, name)
        sel = None if cells is None else cells[owner]
        (out.append(("region of interest", name, sel)) if sel is not None and sel.any()
         else missing.append(f"region of interest {name} (inside the body: see the cuts)"))
    return out, missing


def section_plane(spec: dict, coords: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(point, normal, half width of the view) of the cut through a region of interest (or a
    face selector): a cylinder is cut across its axis at mid-length; a ball, sphere, box or
    plane through its centre, across the scene's thinnest direction."""
    thin = _thin_axis(coords)
    if "cylinder" in spec:
        a, b = np.asarray(spec["cylinder"]["start"], float), np.asarray(spec["cylinder"]["end"], float)
        return 0.5 * (a + b), (b - a) / np.linalg.norm(b - a), 1.6 * spec["cylinder"]["radius"]
    for key in ("ball", "sphere"):
        if key in spec:
            return np.asarray(spec[key]["center"], float), thin, 1.6 * spec[key]["radius"]
    if "box" in spec:
        b = np.asarray(spec["box"], float)
        return 0.5 * (b[:3] + b[3:]), thin, 0.8 * float(np.max(b[3:] - b[:3])) + 1e-9
    if "plane" in spec:
        n = np.asarray(spec["plane"]["normal"], float)
        n /= np.linalg.norm(n)
        normal = thin if abs(thin @ n) < 0.9 else np.eye(3)[int(np.argsort(np.abs(n))[0])]
        return np.asarray(spec["plane"]["point"], float), normal, 0.6 * float(np.ptp(coords, axis=0).max())
    return coords.mean(axis=0), thin, 0.6 * float(np.ptp(coords, axis=0).max())


def _roi_spec(res: Results, name: str) -> dict:
    roi = dict((res.scene.get("regions_of_interest") or {}).get(name) or {})
    if "boundary" in roi:
        return dict((res.scene.get("boundaries") or {}).get(roi["boundary"]) or {})
    return roi


# ---------------------------------------------------------------- figures

def view_direction(elev: float, azim: float) -> np.ndarray:
    """The unit vector from the scene towards the viewer of matplotlib's `view_init(elev, azim)`."""
    e, a = np.radians(elev), np.radians(azim)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def shading(normals: np.ndarray, elev: float, azim: float) -> np.ndarray:
    """Lambert's brightness 0.35 + 0.65 max(0, n·l) of faces lit from behind the viewer's left
    shoulder, above (three faces of a cube seen from a corner get three shades)."""
    d = view_direction(elev, azim)
    left = np.cross(d, [0.0, 0.0, 1.0])
    light = d + 1.2 * np.array([0.0, 0.0, 1.0]) + 0.6 * left / max(np.linalg.norm(left), 1e-12)
    return 0.35 + 0.65 * np.clip(normals @ (light / np.linalg.norm(light)), 0.0, 1.0)


def _axes_ticks(ax, lo: np.ndarray, hi: np.ndarray) -> None:
    """At most four ticks an axis; a thin axis (< THIN of the longest) shows its two ends in its
    label instead, so that no tick labels overlap."""
    span = hi - lo
    for k, (name, axis) in enumerate(zip("xyz", (ax.xaxis, ax.yaxis, ax.zaxis))):
        if span[k] < THIN * span.max():
            a, b = (0.0 if abs(v) < 1e-9 * span.max() else v for v in (lo[k], hi[k]))   # round-off of u
            axis.set_ticks([])
            axis.set_label_text(f"{name} {a:.3g} … {b:.3g} m")
        else:
            axis.set_major_locator(MaxNLocator(max(2, int(4 * span[k] / span.max()))))
            axis.set_label_text(f"{name} [m]")


def _view(ax, x: np.ndarray, faces: np.ndarray, colours: np.ndarray, view, box=None, lines=()) -> None:
    """The front faces (towards the viewer: a closed surface's back faces are never seen) of x[faces]
    in their colours, shaded; only those inside `box` (lo, hi) when given; `lines`: (segments (k, 2, 3),
    colour) drawn over them."""
    elev, azim = view
    lo, hi = (x.min(axis=0), x.max(axis=0)) if box is None else box
    n = face_normals(x, faces)
    keep = n @ view_direction(elev, azim) > 0
    c = x[faces].mean(axis=1)
    keep &= np.all((c >= lo) & (c <= hi), axis=1)
    rgba = np.array(colours, float).reshape(-1, 4)
    rgba = np.broadcast_to(rgba, (len(faces), 4)).copy()
    rgba[:, :3] *= shading(n, elev, azim)[:, None]
    ax.add_collection3d(Poly3DCollection(x[faces[keep]], facecolors=rgba[keep], edgecolors=rgba[keep],
                                         linewidths=0.3))          # edges in the face's colour: no seams
    for seg, colour in lines:
        mid = seg.mean(axis=1)
        inside = np.all((mid >= lo) & (mid <= hi), axis=1)
        if inside.any():
            ax.add_collection3d(Line3DCollection(seg[inside], colors=colour, linewidths=1.6))
    ax.set_xlim(lo[0], hi[0]), ax.set_ylim(lo[1], hi[1]), ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(np.maximum(hi - lo, 1e-3 * (hi - lo).max()))
    ax.view_init(elev=elev, azim=azim)
    _axes_ticks(ax, lo, hi)


def _views(fig, res: Results, x: np.ndarray, faces: np.ndarray, colours, lines=()) -> list[str]:
    """Two panels of the surface: the whole model and, when the regions of interest are small in
    it, the model around them from the same side; else the whole model from the two `VIEWS`.
    The panels' titles are returned (for the figure's alt text)."""
    frame = roi_frame(res)
    whole = (x.min(axis=0), x.max(axis=0))
    small = frame is not None and float(np.ptp(frame, axis=0).max()) < 0.5 * float(np.ptp(whole, axis=0).max())
    panels = ([(VIEWS[0], None, "the whole model"), (VIEWS[0], frame, "around the regions of interest")] if small
              else [(v, None, f"seen from azimuth {v[1]:g}°, elevation {v[0]:g}°") for v in VIEWS])
    for k, (view, box, title) in enumerate(panels):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        _view(ax, x, faces, colours, view, box, lines)
        ax.set_title(title)
    return [t for _, _, t in panels]


def _set_lines(res: Results, x: np.ndarray, faces: np.ndarray, owner: np.ndarray):
    """The outlines of `scene_sets` as (segments, colour), their legend handles and what is not drawn."""
    sets, missing = scene_sets(res, faces, owner)
    lines = [(x[outline(faces[mask])], SET_COLOURS[kind]) for kind, _, mask in sets]
    kinds = list(dict.fromkeys(kind for kind, _, _ in sets))
    handles = [Line2D([], [], color=SET_COLOURS[k], lw=1.6,
                      label=f"{k}: " + ", ".join(n for kk, n, _ in sets if kk == k)) for k in kinds]
    return lines, handles, missing


def scene_figure3d(res: Results) -> bytes:
    """The outer surface of the scene coloured by region (or body), shaded, with the outlines of
    the supports, loads, contact surfaces and regions of interest: the whole model and around the
    regions of interest (or from two sides)."""
    mesh = res.mesh
    faces, owner = outer_faces(mesh.cells, mesh.coords)
    if mesh.cell_region is not None and len(mesh.regions) > 1:
        labels, of = [f"region {r}" for r in mesh.regions], mesh.cell_region
    elif mesh.cell_body is not None and mesh.bodies:
        labels, of = [f"body {b}" for b in mesh.bodies], mesh.cell_body
    else:
        labels, of = ["mesh"], np.zeros(len(mesh.cells), int)
    cmap = plt.get_cmap("Pastel1" if len(labels) <= 9 else "tab20")
    lines, handles, missing = _set_lines(res, mesh.coords, faces, owner)
    fig = plt.figure(figsize=(11.0, 5.6))
    _views(fig, res, mesh.coords, faces, cmap(of[owner] % cmap.N), lines)
    fig.legend(handles=[Patch(facecolor=cmap(i % cmap.N), edgecolor="0.4", label=l) for i, l in enumerate(labels)]
               + handles, loc="lower center", ncol=2, frameon=False, fontsize=7)
    fig.suptitle(f"the scene: {len(mesh.cells)} tetrahedra, {len(faces)} outer triangles"
                 + (f"; not outlined: {', '.join(missing)}" if missing else ""), fontsize=9)
    fig.subplots_adjust(bottom=0.12 + 0.03 * len(handles))
    return png(fig)


def surface_figure(res: Results, j: int) -> tuple[bytes, float]:
    """The deformed outer surface coloured by the von Mises stress of the cell under each
    triangle, shaded: the whole model and around the regions of interest (or from two sides);
    and the magnification used."""
    mesh, f = res.mesh, res.worst_fields[j]
    u = f.displacement if f.displacement is not None else np.zeros_like(mesh.coords)
    mag = magnification(mesh, u)
    x = mesh.coords + mag * u
    faces, owner = outer_faces(mesh.cells, mesh.coords)
    vm = _von_mises(f)
    fig = plt.figure(figsize=(11.0, 5.0))
    sc, su = stress_scale(vm if vm is not None else [0.0])
    top = float(np.nanpercentile(vm, 99.5)) if vm is not None else 1.0
    cmap = plt.get_cmap("viridis")
    colours = cmap(np.clip(vm[owner] / (top or 1.0), 0, 1)) if vm is not None else np.full((len(faces), 4), 0.8)
    _views(fig, res, x, faces, colours)
    if vm is not None:
        m = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0, top * sc))
        fig.colorbar(m, ax=fig.axes, shrink=0.7, extend="max" if np.nanmax(vm) > top else "neither",
                     label=f"von Mises stress [{su}]")
    fig.suptitle(f"deformed outer surface (displacement × {mag:g}), von Mises")
    return png(fig), mag


def cut_plane(res: Results, name: str) -> tuple[np.ndarray, np.ndarray, float]:
    """(point, normal, half width of the view) of the cut through the region of interest `name`:
    `section_plane` of its selector; when that plane cuts none of the region's cells (a region
    lying on a layer of nodes), it is moved along its normal to the centroid of the region's cell
    nearest to it (a plane through a cell's centroid cuts that cell). The view is at least twice
    as wide as the cut cell nearest to the point (of the region, or of the mesh when the region
    holds no cell: smaller than the cells)."""
    mesh = res.mesh
    point, normal, half = section_plane(_roi_spec(res, name), mesh.coords)
    cells = roi_cells(res, name)
    k = np.flatnonzero(cells) if cells is not None and cells.any() else np.arange(len(mesh.cells))
    d = (mesh.coords[mesh.cells[k]] - point) @ normal                # (cells, 4) signed distances
    cut = (d.min(axis=1) < 0) & (d.max(axis=1) > 0)
    if not cut.any():
        nearest = int(np.argmin(np.abs(d.mean(axis=1))))
        point = point + d[nearest].mean() * normal
        cut[nearest] = True
    x = mesh.coords[mesh.cells[k[cut]]]
    nearest = int(np.argmin(np.linalg.norm(x.mean(axis=1) - point, axis=1)))
    return point, normal, max(half, 2.0 * float(np.ptp(x[nearest], axis=0).max()))


def cut_panel(res: Results, name: str):
    """(point, e1, e2, half, polygons, cells) of the cut through region of interest `name`
    (`cut_plane`): the cut polygons in the plane's coordinates (e1, e2) about `point` that reach into
    the square view of half width `half`, and the cell of each."""
    point, normal, half = cut_plane(res, name)
    polygons, owner = plane_section(res.mesh.coords, res.mesh.cells, point, normal)
    e1, e2 = plane_axes(normal)
    flat = [np.column_stack([(p - point) @ e1, (p - point) @ e2]) for p in polygons]
    near = [k for k, q in enumerate(flat) if np.all(q.min(axis=0) <= half) and np.all(q.max(axis=0) >= -half)]
    return point, e1, e2, half, [flat[k] for k in near], owner[near]


def cut_figure(res: Results, j: int) -> bytes | None:
    """For each region of interest of criterion j, the von Mises stress on a plane cut through
    it (undeformed), the cells of the region (`roi_cells`, in its body) outlined."""
    mesh, f = res.mesh, res.worst_fields[j]
    vm = _von_mises(f)
    names = res.criteria[j].regions or list((res.scene.get("regions_of_interest") or {}))
    if vm is None or not names:
        return None
    fig, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 4.6), squeeze=False)
    for ax, name in zip(axes[0], names):
        point, e1, e2, half, flat, owner = cut_panel(res, name)
        if not flat:
            ax.set_title(f"{name}: the cut misses the mesh")
            continue
        sc, su = stress_scale(vm[owner])
        pc = PolyCollection(flat, array=vm[owner] * sc, cmap="viridis", edgecolors="face")
        ax.add_collection(pc)
        fig.colorbar(pc, ax=ax, shrink=0.85, label=f"von Mises stress [{su}]")
        cells = roi_cells(res, name)
        inside = None if cells is None else cells[owner]
        if inside is not None and inside.any():
            ax.add_collection(PolyCollection([flat[k] for k in np.flatnonzero(inside)], facecolors="none",
                                             edgecolors="k", linewidths=0.5))
        ax.set_xlim(-half, half), ax.set_ylim(-half, half), ax.set_aspect("equal")
        ax.set_xlabel(along(e1))
        ax.set_ylabel(along(e2))
        ax.set_title(f"{name}: cut through ({point[0]:.3g}, {point[1]:.3g}, {point[2]:.3g})")
    fig.tight_layout()
    return png(fig)


def _surface_triangulation(q: np.ndarray) -> Triangulation:
    """Delaunay triangles of a surface's points in its own coordinates, without the long
    triangles that bridge a hole or a concave edge (longest edge > 3 × the median edge)."""
    tri = Triangulation(q[:, 0], q[:, 1])
    e = np.linalg.norm(q[tri.triangles] - q[np.roll(tri.triangles, 1, axis=1)], axis=2).max(axis=1)
    tri.set_mask(e > 3 * np.median(e))
    return tri


def map_axes(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(origin, e1, e2) of a contact surface's map: its centroid and the `plane_axes` of its mean
    plane (the normal of `surface_frame`), so that the map reads as the scene's axes do (a
    horizontal surface in x rightwards and y upwards), whatever the spread of its nodes."""
    origin, a, b = surface_frame(x)
    e1, e2 = plane_axes(np.cross(a, b))
    return origin, e1, e2


def contact_maps_figure(res: Results, j: int) -> bytes | None:
    """Contact pressure and slip of criterion j's worst case on each contact surface, in the
    coordinates of its plane (`map_axes`); slip arrows are the tangential slip vectors
    projected onto the surface's plane."""
    f = res.worst_fields[j]
    if f is None or f.contact_coords is None or "contact_pressure" not in f.contact:
        return None
    pairs = list(dict.fromkeys(f.contact_pair.tolist()))
    slip = f.contact.get("contact_slip")
    tangents = f.contact_tangents
    panels = 2 if slip is not None and tangents is not None else 1
    fig, axes = plt.subplots(panels, len(pairs), figsize=(5.4 * len(pairs), 4.4 * panels), squeeze=False)
    for c, pair in enumerate(pairs):
        idx = np.flatnonzero(f.contact_pair == pair)
        x = f.contact_coords[idx]
        origin, e1, e2 = map_axes(x)
        q = np.column_stack([(x - origin) @ e1, (x - origin) @ e2])
        tri = _surface_triangulation(q) if len(idx) >= 3 else None
        p = f.contact["contact_pressure"][idx]
        sc, su = stress_scale(p)
        ax = axes[0, c]
        if tri is not None:
            pc = ax.tripcolor(tri, p * sc, shading="gouraud", cmap="magma")
        else:
            pc = ax.scatter(q[:, 0], q[:, 1], c=p * sc, cmap="magma")
        fig.colorbar(pc, ax=ax, shrink=0.85, label=f"contact pressure [{su}]")
        ax.set_title(f"{pair}: pressure −τₙ")
        if panels == 2:
            s = slip[idx]
            vec = s[:, 0, None] * tangents[idx, 0] + s[:, 1, None] * tangents[idx, 1]
            mag = np.linalg.norm(s, axis=1)
            lsc, lsu = length_scale(mag)
            ax2 = axes[1, c]
            pc2 = (ax2.tripcolor(tri, mag * lsc, shading="gouraud", cmap="cividis") if tri is not None
                   else ax2.scatter(q[:, 0], q[:, 1], c=mag * lsc, cmap="cividis"))
            fig.colorbar(pc2, ax=ax2, shrink=0.85, label=f"slip |s| [{lsu}]")
            step = max(1, len(idx) // 150)
            ax2.quiver(q[::step, 0], q[::step, 1], (vec @ e1)[::step], (vec @ e2)[::step], color="w",
                       angles="xy", pivot="mid", width=0.004)
            ax2.set_title(f"{pair}: slip (arrows: direction)")
        span = np.ptp(q, axis=0)
        for a in axes[:, c]:            # true proportions unless the surface is a long strip
            a.set_aspect("equal" if span.max() <= 4 * max(span.min(), 1e-300) else "auto")
            a.set_xlabel(along(e1))
            a.set_ylabel(along(e2))
    fig.tight_layout()
    return png(fig)
