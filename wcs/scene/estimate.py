"""The size of a scene's mesh, estimated from the study before any meshing (the resource guard).

A triangle of side h has area sqrt(3)/4 h^2, so a surface of area A meshed at size h has
about A / (sqrt(3)/4 h^2) = 2.31 A / h^2 cells, and a mesh whose size varies as h(x) about
2.31 times the integral of 1 / h(x)^2. A refine zone of size s < h (area A_r, perimeter P_r)
sets h(x) = s + g d(x) (g = `mesh.grading`, d the distance to the zone) until it reaches h at
d = (h - s) / g, so it adds the integral of 1/h(x)^2 - 1/h^2 over the zone and that halo:
A_r (1/s^2 - 1/h^2) and the integral over d of (P_r + 2 pi d) (1/(s + g d)^2 - 1/h^2), each
counted for the share of it inside the body (`_refined`: a zone at a body's corner has three
quarters of its halo outside). Shape areas are those of the primitives (a `minus` is not
subtracted); nodes are about half the cells, and a P1 vector field has two unknowns per node.
"""
from __future__ import annotations

import importlib.util
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import spec3d

CELLS_PER_H2 = 4.0 / math.sqrt(3.0)     # cells per unit area at size 1
HALO_POINTS = 65                        # distances a halo's integral is summed at (`_halo`)
# The share of a zone (and of its halo's curve or surface at distance d) inside a body:
# deterministic samples of the zone's area or volume and of its boundary with outward normals,
# each boundary sample moved out by d; a sample counts where it lies in a bounding box of one of
# the body's regions (a superset of the body: the share is not under-counted)
SAMPLES = 16                            # samples along a side or an axis (a circle: 4x, a sphere: 4x^2)
CURVATURE_ELEMENTS = 24                 # Mesh.MeshSizeFromCurvature (the mesher's): elements per 2*pi of arc
DEFAULT_MAX_CELLS = 1_000_000           # `mesh.max_cells` when the study gives none
DEFAULT_GRADING = 0.5                   # size growth per unit distance away from a refine zone (the mesher's)
# Peak memory of `wcs check` a cell, above the ~0.2 GB of the loaded modules: 2.8 GB at 5.4e5
# triangles (the two-blocks demo at size 0.0033: thermal step, contact, monolithic), 1.1 GB at
# 6.7e4 tetrahedra (block-on-block-3d at size 0.04, its dense contact condensation included)
BYTES_PER_CELL = {2: 5.2e3, 3: 1.6e4}
# The same with the iterative method on a 3D contact scene (no dense W, no direct factor): the peak of
# tests/bench/test_bench_iterative.py's measure (meshing, assembly, the cold and the warm contact solve),
# 1.80 GB at 2.9e5 unknowns (0.045/0.01, 5.06e5 tetrahedra: 3.6 kB a cell; 5.2 kB before the solve held
# one copy of K: 9.33 GB at 1.02e6 unknowns); 2D is not measured: the direct figure bounds it (the
# iterative method holds O(nnz), below the direct factor's fill)
ITERATIVE_BYTES_PER_CELL = {2: BYTES_PER_CELL[2], 3: 4.0e3}
# Peak memory of meshing and assembling a cell (VmHWM after `Evaluator`, above the ~0.2 GB of the loaded
# modules): 3D, 1.5 kB on the shipped 3D tunnel (2.5e4 tetrahedra), 3.0 kB on the 3D patch at 1.1e6 (6e5
# unknowns, its reduction's peak; 4.0 and 6.3 kB while the cell matrices were held, 7.0-7.6 kB on the 3D
# tunnel at 7e4-2.2e5 before that); 2D, 3.4 kB on the two-blocks demo at 2.3e5 triangles (thermal): what
# the cells made must fit before assembly; the solve's own memory, which depends on the method, is
# estimated after assembly (`evaluation_cost`)
MODEL_BYTES_PER_CELL = {2: 3.5e3, 3: 3.5e3}
# How far beyond the machine's memory an estimate may go before meshing: the cells made are held
# to the memory itself (`memory_fault`), but meshing 5.8e6 triangles takes 5 min, so an estimate
# is refused at the memory. It is at least 0.65x the cells gmsh makes in 2D and 0.9x in 3D
# (tests/scene/test_estimate.py), and a cell takes at least 5.2 kB in 2D and 4 kB in 3D
# (ITERATIVE_BYTES_PER_CELL): a scene admitted has at most memory / 3.4 kB cells, whose meshing
# fits (`memory_fault` then holds the cells made to MODEL_BYTES_PER_CELL before assembly).
ESTIMATE_EXCESS = {2: 1.0, 3: 1.0}


def machine_memory() -> float:
    """Bytes of memory of this machine: its physical memory (`os.sysconf`), or the control group's
    limit (cgroup v2 `memory.max`) where that is lower."""
    memory = float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
    except OSError:
        return memory
    return min(memory, float(limit)) if limit.isdigit() else memory


def machine_ranks() -> int:
    """Processes of this `mpiexec` launch on this machine, each with its own model and its own
    evaluations (MPICH's MPI_LOCALNRANKS, Open MPI's OMPI_COMM_WORLD_LOCAL_SIZE; 1 without one)."""
    for name in ("MPI_LOCALNRANKS", "OMPI_COMM_WORLD_LOCAL_SIZE"):
        if os.environ.get(name, "").isdigit():
            return max(1, int(os.environ[name]))
    return 1


def bytes_per_cell(scene, method: str) -> float:
    """Peak memory a cell of one evaluation of `scene` with `solver.method` `method`, before meshing:
    ITERATIVE_BYTES_PER_CELL for the iterative method on a scene with contact, and for `auto` there
    where PETSc is installed (auto picks it where the direct method would not fit, `wcs.choose`);
    BYTES_PER_CELL otherwise (without contact every method is one direct factor)."""
    iterative = scene.contacts and (method == "iterative" or method == "auto" and iterative_installed())
    return (ITERATIVE_BYTES_PER_CELL if iterative else BYTES_PER_CELL)[scene.dimension]


def iterative_installed() -> bool:
    """Whether the iterative method's PETSc (the wheel dolfinx-solver-real, petsc4py) is importable."""
    return all(importlib.util.find_spec(m) is not None for m in ("dolfinx_solver", "petsc4py"))


def memory_fault(cells: int, dimension: int) -> str | None:
    """Why a mesh of `cells` cells cannot be assembled on this machine (None if it can): its cells
    times MODEL_BYTES_PER_CELL beyond `machine_memory()`, where assembling on would swap (the
    solve is held to the memory after assembly, by the method's `evaluation_cost`)."""
    need, memory = cells * MODEL_BYTES_PER_CELL[dimension], machine_memory()
    if need <= memory:
        return None
    return (f"the mesh has {cells} cells, which need about {need / 1e9:.3g} GB to assemble "
            f"({MODEL_BYTES_PER_CELL[dimension]:g} bytes a cell, measured), more than this machine's "
            f"{memory / 1e9:.3g} GB of memory; coarsen the mesh (`mesh.size`, `refine`) or lower `mesh.max_cells`")


def shape_box(shape) -> tuple[float, float, float, float]:
    """Bounding box (x0, y0, x1, y1) of a validated `Shape` (intersections narrow it)."""
    if shape.rectangle is not None:
        box = tuple(shape.rectangle)
    elif shape.disc is not None:
        (cx, cy), r = shape.disc.center, shape.disc.radius
        box = (cx - r, cy - r, cx + r, cy + r)
    else:
        xs, ys = zip(*shape.polygon)
        box = (min(xs), min(ys), max(xs), max(ys))
    for other in shape.intersect or []:
        o = shape_box(other)
        box = (max(box[0], o[0]), max(box[1], o[1]), min(box[2], o[2]), min(box[3], o[3]))
    return box


def _primitive_area(shape) -> float:
    if shape.rectangle is not None:
        x0, y0, x1, y1 = shape.rectangle
        area = (x1 - x0) * (y1 - y0)
    elif shape.disc is not None:
        area = math.pi * shape.disc.radius ** 2
    else:
        area = abs(_shoelace(shape.polygon))
    return min([area] + [_primitive_area(o) for o in shape.intersect or []])


def _shoelace(points) -> float:
    return 0.5 * sum(points[i - 1][0] * points[i][1] - points[i][0] * points[i - 1][1]
                     for i in range(len(points)))


def _perimeter(points) -> float:
    return sum(math.dist(points[i - 1], points[i]) for i in range(len(points)))


def _zone(selector, scene) -> tuple[float, float]:
    """Area and perimeter of a refine selector (a boundary: no area, both sides of its length)."""
    if selector.box is not None:
        x0, y0, x1, y1 = selector.box
        return (x1 - x0) * (y1 - y0), 2 * ((x1 - x0) + (y1 - y0))
    if selector.disc is not None:
        r = selector.disc.radius
        return math.pi * r * r, 2 * math.pi * r
    if selector.polygon is not None:
        return abs(_shoelace(selector.polygon)), _perimeter(selector.polygon)
    spec = scene.boundaries[selector.boundary]
    if spec.segment is not None:
        return 0.0, 2 * math.dist(*spec.segment)
    if spec.circle is not None:
        return 0.0, 4 * math.pi * spec.circle.radius
    x0, y0, x1, y1 = spec.box
    return 0.0, 4 * ((x1 - x0) + (y1 - y0))


def _halo(s: float, h: float, g: float) -> np.ndarray:
    """The distances at which a halo's integrand is summed (trapezoids): where the size s + g d
    takes HALO_POINTS values from s to h in geometric progression, so that the integrand, which
    falls as 1/(s + g d)^dim, is resolved where it is large (uniform steps of (h - s) / g put
    one step across it where s << h)."""
    return (np.geomspace(s, h, HALO_POINTS) - s) / g


def _refined(selector, scene, s: float, h: float, g: float, body_area: float, boxes) -> float:
    """Cells a zone of size s adds to a body meshed at h (whose own count at h is the body's):
    2.31 times the integral over the body of 1/h(x)^2 - 1/h^2, h(x) = s + g d(x): the zone's area
    at s, and the halo 0 < d < (h - s) / g whose curve at distance d is P + 2 pi d long, each the
    share of it inside the body's bounding `boxes` (`_samples2d`: a zone at a corner of the body
    has most of its halo outside); clipped to the body's area at s. With g = 0, one layer of
    cells along the perimeter, P / s."""
    area, perimeter = _zone(selector, scene)
    surface, interior = _samples2d(selector, scene)
    inside = min(area * _share(interior, boxes), body_area) * (1 / s**2 - 1 / h**2)
    if g > 0:
        d = _halo(s, h, g)
        share = _offset_share(surface, d, boxes)
        halo = float(np.trapezoid((perimeter + 2 * math.pi * d) * share * (1 / (s + g * d) ** 2 - 1 / h**2), d))
    else:
        halo = perimeter * float(_offset_share(surface, np.zeros(1), boxes)[0]) / s
    return CELLS_PER_H2 * min(inside + halo, body_area / s**2)


def _samples2d(selector, scene):
    """((boundary points, outward normals, weights), interior points) of a 2D refine zone (as
    `_samples3d`); a boundary piece is both its sides; a polygon's interior without samples."""
    t = (np.arange(SAMPLES) + 0.5) / SAMPLES
    circle = selector.disc
    if selector.boundary is not None:
        spec = scene.boundaries[selector.boundary]
        circle = spec.circle
        if spec.segment is not None:
            corners = [spec.segment[0], spec.segment[1]]
        elif spec.box is not None:
            x0, y0, x1, y1 = spec.box
            corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]
    elif selector.box is not None:
        x0, y0, x1, y1 = selector.box
        corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]
    elif selector.polygon is not None:
        corners = list(selector.polygon) + [selector.polygon[0]]
    if circle is not None:
        angle = 2 * math.pi * (np.arange(4 * SAMPLES) + 0.5) / (4 * SAMPLES)
        u = np.stack([np.cos(angle), np.sin(angle)], axis=1)
        c, r = np.asarray(circle.center, float), circle.radius
        surface = (c + r * u, u, np.ones(len(u)))
        interior = (c + r * np.sqrt(t)[:, None, None] * u[None]).reshape(-1, 2)
    else:
        c = np.asarray(corners, float)
        sign = 1.0 if _shoelace(corners[:-1] or corners) >= 0 else -1.0      # counter-clockwise: outward is right
        a, b = c[:-1], c[1:]
        edge = b - a
        length = np.linalg.norm(edge, axis=1)
        normal = sign * np.stack([edge[:, 1], -edge[:, 0]], axis=1) / length[:, None]
        points = (a[:, None] + t[None, :, None] * edge[:, None]).reshape(-1, 2)
        surface = (points, np.repeat(normal, SAMPLES, axis=0), np.repeat(length / SAMPLES, SAMPLES))
        interior = None
        if selector.box is not None:
            grid = np.stack(np.meshgrid(t, t, indexing="ij"), axis=-1).reshape(-1, 2)
            interior = c[0] + grid * (c[2] - c[0])
    if selector.boundary is not None:
        return _both_sides(surface), None
    return surface, interior


def _both_sides(surface):
    """A boundary's surface samples (points, outward normals, weights) on both its sides: a
    boundary piece or face bounds no volume of its own."""
    points, normals, weights = surface
    return np.concatenate([points, points]), np.concatenate([normals, -normals]), np.concatenate([weights] * 2)


def estimate_cells(scene) -> tuple[float, str]:
    """About how many cells the scene's mesh will have, and the key path of the size that
    contributes most, relative to the scene (to name in a refusal). `scene` is a validated
    `Scene` of shapes (not a mesh file)."""
    mesh = scene.mesh
    grading = DEFAULT_GRADING if mesh.grading is None else mesh.grading
    parts = []
    for body, spec in scene.bodies.items():
        own = spec.mesh
        h = own.size if own is not None and own.size is not None else mesh.size
        h_path = f"bodies.{body}.mesh.size" if own is not None and own.size is not None else "mesh.size"
        area = sum(_primitive_area(r.shape) for r in spec.regions)
        parts.append((CELLS_PER_H2 * area / h**2, h_path))
        for i, region in enumerate(spec.regions):
            s = h if region.mesh is None else region.mesh.size
            if s < h:
                parts.append((CELLS_PER_H2 * _primitive_area(region.shape) * (1 / s**2 - 1 / h**2),
                              f"bodies.{body}.regions.{i}.mesh.size"))
        zones = [(r, f"mesh.refine.{i}.size") for i, r in enumerate(mesh.refine)]
        zones += [(r, f"bodies.{body}.mesh.refine.{i}.size") for i, r in enumerate(own.refine if own else [])]
        boxes = [shape_box(r.shape) for r in spec.regions]
        parts += [(_refined(ref, scene, ref.size, h, grading, area, boxes), path) for ref, path in zones if ref.size < h]
    return sum(c for c, _ in parts), max(parts)[1]


# 3D: a regular tetrahedron of side h has volume h^3 / (6 sqrt 2), so a solid of volume V meshed
# at size h has about 6 sqrt(2) V / h^3 = 8.49 V / h^3 cells (volumes of the primitives, a `minus`
# not subtracted, an intersection the smallest of its solids': an upper estimate). A curved
# surface of radius r (every sphere and cylinder of the scene, also inside `minus` / `intersect`,
# and the embedded balls and cylinders of interest) is meshed at s = min(h, 2 pi r / N), N =
# Mesh.MeshSizeFromCurvature: the solid's volume at s, and a halo outside where the size grows
# as s + d up to h, whose surface at distance d has area A(d): 8.49 * integral of A(d) / (s + d)^3.
# A region's own size s < h is a refine zone of size s on the region's sphere or cylinder (else
# its bounding box) whose halo grows by REGION_GRADING: gmsh carries the size of the region's
# faces into the neighbouring volumes at about that rate (measured: the estimate is 1.2-2.5x
# the meshed count with a box, slab, ball or cylinder region at s = h/2.5 to h/5, whatever
# `mesh.grading`; tests/fem/test_glue_3d.py checks it).
# A refine zone's halo is counted for the share of it inside the body, as in 2D (`_refined3d`).
# Regular tetrahedra are 1.8x the cells gmsh makes (its Delaunay edges are 1.2-1.3x the target:
# 6.8e4 against 37105 in a unit cube at 0.05), so on fine meshes the estimate is an upper one.
CELLS_PER_H3 = 6.0 * math.sqrt(2.0)
REGION_GRADING = DEFAULT_GRADING


def solid_box(solid) -> tuple[float, ...]:
    """Bounding box (xmin, ymin, zmin, xmax, ymax, zmax) of a validated 3D `Solid` that is not a
    halfspace (intersections narrow it)."""
    if solid.box is not None:
        box = tuple(solid.box)
    elif solid.sphere is not None:
        c, r = solid.sphere.center, solid.sphere.radius
        box = tuple(x - r for x in c) + tuple(x + r for x in c)
    elif solid.cylinder is not None:
        a, b, r = solid.cylinder.start, solid.cylinder.end, solid.cylinder.radius
        box = tuple(min(p, q) - r for p, q in zip(a, b)) + tuple(max(p, q) + r for p, q in zip(a, b))
    else:
        x0, y0, x1, y1 = shape_box(solid.extrude.shape)
        v = solid.extrude.vector
        lo, hi = (x0, y0, 0.0), (x1, y1, 0.0)
        box = tuple(min(p, p + d) for p, d in zip(lo, v)) + tuple(max(p, p + d) for p, d in zip(hi, v))
    for other in solid.intersect:
        if other.halfspace is None:
            o = solid_box(other)
            box = tuple(max(box[i], o[i]) for i in range(3)) + tuple(min(box[i], o[i]) for i in range(3, 6))
    return box


def _primitive_volume(solid) -> float:
    if solid.box is not None:
        b = solid.box
        volume = (b[3] - b[0]) * (b[4] - b[1]) * (b[5] - b[2])
    elif solid.sphere is not None:
        volume = 4 / 3 * math.pi * solid.sphere.radius ** 3
    elif solid.cylinder is not None:
        volume = math.pi * solid.cylinder.radius ** 2 * math.dist(solid.cylinder.start, solid.cylinder.end)
    else:
        volume = _primitive_area(solid.extrude.shape) * abs(solid.extrude.vector[2])
    return min([volume] + [_primitive_volume(o) for o in solid.intersect if o.halfspace is None])


def _curved(solid):
    """Every sphere and cylinder of a solid's tree."""
    if solid.sphere is not None or solid.cylinder is not None:
        yield solid
    for other in solid.minus + solid.intersect:
        yield from _curved(other)


def _curved_cells(solid, h: float) -> float:
    """Cells a sphere or cylinder adds at its curvature size (see above)."""
    if solid.sphere is not None:
        r, length = solid.sphere.radius, None
    else:
        r, length = solid.cylinder.radius, math.dist(solid.cylinder.start, solid.cylinder.end)
    s = min(h, 2 * math.pi * r / CURVATURE_ELEMENTS)
    if s >= h:
        return 0.0
    volume = 4 / 3 * math.pi * r**3 if length is None else math.pi * r**2 * length
    d = _halo(s, h, 1.0)
    area = 4 * math.pi * (r + d) ** 2 if length is None else 2 * math.pi * (r + d) * length
    return CELLS_PER_H3 * (volume * (1 / s**3 - 1 / h**3) + float(np.trapezoid(area / (s + d) ** 3, d)))


def _zone3d(ref, scene) -> tuple[float, object]:
    """(volume, A) of a 3D refine zone: its volume and the area A(d) of the surface at distance
    d outside it (Steiner's formula for a box, ball, cylinder; a face: both sides of its area,
    a plane taken as the scene's largest bounding-box face)."""
    if ref.box is not None:
        a, b, c = (ref.box[i + 3] - ref.box[i] for i in range(3))
        return a * b * c, lambda d: 2 * (a * b + b * c + c * a) + 2 * math.pi * (a + b + c) * d + 4 * math.pi * d**2
    if ref.ball is not None:
        r = ref.ball.radius
        return 4 / 3 * math.pi * r**3, lambda d: 4 * math.pi * (r + d) ** 2
    if ref.cylinder is not None:
        r, L = ref.cylinder.radius, math.dist(ref.cylinder.start, ref.cylinder.end)
        return math.pi * r**2 * L, lambda d: (2 * math.pi * r * L + 2 * math.pi * r**2
                                              + 2 * (math.pi**2 * r + math.pi * L) * d + 4 * math.pi * d**2)
    face = scene.boundaries[ref.boundary]
    if face.cylinder is not None:
        area = 2 * math.pi * face.cylinder.radius * math.dist(face.cylinder.start, face.cylinder.end)
    elif face.sphere is not None:
        area = 4 * math.pi * face.sphere.radius ** 2
    else:
        boxes = [solid_box(r.shape) for b in scene.bodies.values() for r in b.regions]
        box = np.concatenate([np.min(boxes, axis=0)[:3], np.max(boxes, axis=0)[3:]])
        if face.box is not None:
            a, b, c = sorted(face.box[i + 3] - face.box[i] for i in range(3))
            area = c * b
        else:
            area = plane_box_area(face.plane.point, face.plane.normal, box)
    return 0.0, lambda d: 2 * area + 4 * math.pi * d**2


def plane_box_area(point, normal, box) -> float:
    """The area of the polygon where a plane cuts the box [xmin, ymin, zmin, xmax, ymax, zmax]
    (its corners: where the plane crosses the box's 12 edges, ordered about their centroid)."""
    lo, hi = np.asarray(box[:3], float), np.asarray(box[3:], float)
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    corners = np.array([[(lo, hi)[i >> k & 1][k] for k in range(3)] for i in range(8)])
    d = (corners - np.asarray(point, float)) @ n
    pts = [corners[a] + d[a] / (d[a] - d[b]) * (corners[b] - corners[a])
           for a in range(8) for b in range(a + 1, 8)
           if bin(a ^ b).count("1") == 1 and d[a] * d[b] < 0]
    pts += [corners[a] for a in range(8) if d[a] == 0]
    if len(pts) < 3:
        return 0.0
    p = np.array(pts)
    c = p.mean(axis=0)
    e1 = p[np.argmax(np.linalg.norm(p - c, axis=1))] - c
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    p = p[np.argsort(np.arctan2((p - c) @ e2, (p - c) @ e1))]
    return 0.5 * float(np.abs(sum(np.cross(p[i] - c, p[(i + 1) % len(p)] - c) @ n for i in range(len(p)))))


def _refined3d(ref, scene, h: float, g: float, body_volume: float, boxes) -> float:
    """Tetrahedra a refine zone of size s < h adds to a body meshed at h (the body's own count
    at h is the scene's): 8.49 times the integral over the body of 1/h(x)^3 - 1/h^3, h(x) =
    s + g d(x) the graded size: the zone's volume at s, and the halo 0 < d < (h - s) / g whose
    surface at distance d has area A(d) (`_zone3d`), each the share of it inside the body's
    bounding `boxes` (`_share3d`: a zone at a corner of the body has most of its halo outside),
    clipped to the body's volume at s."""
    s = ref.size
    volume, A = _zone3d(ref, scene)
    surface, interior = _samples3d(ref, scene)
    inside = min(volume * _share(interior, boxes), body_volume) * (1 / s**3 - 1 / h**3)
    if g > 0:
        d = _halo(s, h, g)
        share = _offset_share(surface, d, boxes)
        halo = float(np.trapezoid(A(d) * share * (1 / (s + g * d) ** 3 - 1 / h**3), d))
    else:
        halo = 0.0
    return CELLS_PER_H3 * min(inside + halo, body_volume / s**3)


def _share(points: np.ndarray | None, boxes) -> float:
    """The share of `points` (k, dim) inside any of `boxes` ((lo..., hi...) each); 1 without points."""
    if points is None:
        return 1.0
    return float(_in_boxes(points, boxes).mean())


def _in_boxes(points: np.ndarray, boxes) -> np.ndarray:
    b = np.asarray(boxes, float)
    dim = points.shape[-1]
    lo, hi = b[:, :dim], b[:, dim:]
    return ((points[..., None, :] >= lo) & (points[..., None, :] <= hi)).all(axis=-1).any(axis=-1)


def _offset_share(surface, d: np.ndarray, boxes) -> np.ndarray:
    """At each distance d: the weighted share of the surface samples (points, outward normals,
    weights) moved out by d that lie in `boxes` (1 everywhere without samples)."""
    if surface is None:
        return np.ones_like(d)
    points, normals, weights = surface
    moved = points[None, :, :] + d[:, None, None] * normals[None, :, :]
    return (_in_boxes(moved, boxes) * weights).sum(axis=1) / weights.sum()


def _sphere_directions(n: int) -> np.ndarray:
    """n nearly uniform unit vectors (a Fibonacci lattice)."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = math.pi * (1 + math.sqrt(5)) * k
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _axis_frame(a, b):
    """Unit axis of the segment a -> b and two unit vectors normal to it."""
    axis = np.asarray(b, float) - np.asarray(a, float)
    axis /= np.linalg.norm(axis)
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return axis, e1, np.cross(axis, e1)


def _samples3d(ref, scene):
    """((surface points, outward normals, weights), interior points) of a 3D refine zone; a
    face's surface is both its sides, a plane or a flat box face without samples (share 1)."""
    t = (np.arange(SAMPLES) + 0.5) / SAMPLES
    if ref.ball is not None or ref.boundary is not None and scene.boundaries[ref.boundary].sphere is not None:
        sphere = ref.ball or scene.boundaries[ref.boundary].sphere
        c, r, u = np.asarray(sphere.center, float), sphere.radius, _sphere_directions(4 * SAMPLES**2)
        surface = (c + r * u, u, np.ones(len(u)))
        interior = (c + r * np.cbrt(t)[:, None, None] * u[None]).reshape(-1, 3)
    elif ref.cylinder is not None or ref.boundary is not None and scene.boundaries[ref.boundary].cylinder is not None:
        cyl = ref.cylinder or scene.boundaries[ref.boundary].cylinder
        a, b, r = np.asarray(cyl.start, float), np.asarray(cyl.end, float), cyl.radius
        axis, e1, e2 = _axis_frame(a, b)
        angle = 2 * math.pi * (np.arange(2 * SAMPLES) + 0.5) / (2 * SAMPLES)
        radial = np.cos(angle)[:, None] * e1 + np.sin(angle)[:, None] * e2            # (2S, 3)
        along = a + t[:, None] * (b - a)                                               # (S, 3)
        side = (along[:, None] + r * radial[None]).reshape(-1, 3)
        normals = np.tile(radial, (SAMPLES, 1))
        length = float(np.linalg.norm(b - a))
        weights = np.full(len(side), 2 * math.pi * r * length / len(side))
        disc = (r * np.sqrt(t)[:, None, None] * radial[None]).reshape(-1, 3)         # a cap's points about its centre
        caps = np.concatenate([a + disc, b + disc])
        cap_normals = np.concatenate([np.tile(-axis, (len(disc), 1)), np.tile(axis, (len(disc), 1))])
        surface = (np.concatenate([side, caps]), np.concatenate([normals, cap_normals]),
                   np.concatenate([weights, np.full(len(caps), math.pi * r * r / len(disc))]))
        interior = (along[:, None, None] + r * np.sqrt(t)[None, :, None, None] * radial[None, None]).reshape(-1, 3)
    elif ref.box is not None:
        lo, hi = np.asarray(ref.box[:3], float), np.asarray(ref.box[3:], float)
        grid = np.stack(np.meshgrid(t, t, t, indexing="ij"), axis=-1).reshape(-1, 3)
        interior = lo + grid * (hi - lo)
        points, normals, weights = [], [], []
        for k in range(3):
            for end, sign in ((lo, -1.0), (hi, 1.0)):
                face = interior[np.isclose(grid[:, k], t[0])].copy()
                face[:, k] = end[k]
                points.append(face)
                normals.append(np.tile(sign * np.eye(3)[k], (len(face), 1)))
                weights.append(np.full(len(face), np.prod(np.delete(hi - lo, k)) / len(face)))
        surface = (np.concatenate(points), np.concatenate(normals), np.concatenate(weights))
    else:
        return None, None
    if ref.boundary is not None:                      # a face: both sides, no volume
        return _both_sides(surface), None
    return surface, interior


def estimate_cells3d(scene, size: float) -> tuple[float, str]:
    """About how many tetrahedra a 3D scene's mesh will have at the scene size `size`, and the
    key path of the size that contributes most (relative to the scene)."""
    parts = []
    grading = DEFAULT_GRADING if scene.mesh.grading is None else scene.mesh.grading
    rois = [spec3d.Solid(sphere=roi.ball) if roi.ball is not None else spec3d.Solid(cylinder=roi.cylinder)
            for roi in scene.regions_of_interest.values() if roi.ball is not None or roi.cylinder is not None]
    volumes = {body: sum(_primitive_volume(r.shape) for r in spec.regions) for body, spec in scene.bodies.items()}
    # a box, ball or cylinder of mesh.refine without `body` is meshed once, wherever bodies lie in
    # it: counted once, clipped to all the bodies' volume (counted in every body it was 2× over on
    # a tunnel whose refined ring the fault cuts into two bodies); a boundary zone is a face with a
    # halo on either side, counted in each body as before
    once = [r.body is None and r.boundary is None for r in scene.mesh.refine]
    coarsest = max([size] + [spec.mesh.size for spec in scene.bodies.values() if spec.mesh is not None])
    boxes = {body: [solid_box(r.shape) for r in spec.regions] for body, spec in scene.bodies.items()}
    everywhere = sum(boxes.values(), [])
    parts += [(_refined3d(r, scene, coarsest, grading, sum(volumes.values()), everywhere), f"mesh.refine.{i}.size")
              for i, r in enumerate(scene.mesh.refine) if once[i] and r.size < coarsest]
    for body, spec in scene.bodies.items():
        h, path = (size, "mesh.size") if spec.mesh is None else (spec.mesh.size, f"bodies.{body}.mesh.size")
        volume = volumes[body]
        cells = CELLS_PER_H3 * volume / h**3
        # one surface once: a region's sphere or cylinder is also cut out of the region around it
        curved = list({(c.sphere or c.cylinder).model_dump_json(): c
                       for r in spec.regions for c in _curved(r.shape)}.values()) + rois
        parts.append((cells + sum(_curved_cells(c, h) for c in curved), path))
        zones = [(r, f"mesh.refine.{i}.size") for i, r in enumerate(scene.mesh.refine)
                 if not once[i] and r.body in (None, body)]
        zones += [(r, f"bodies.{body}.mesh.refine.{i}.size") for i, r in enumerate(spec.mesh.refine if spec.mesh else [])]
        parts += [(_refined3d(ref, scene, h, grading, volume, boxes[body]), p) for ref, p in zones
                  if ref.size < h and (ref.boundary is None or ref.boundary in scene.boundaries)]
        parts += [(_refined3d(_region_zone(r.shape, r.mesh.size), scene, h, REGION_GRADING, volume, boxes[body]),
                   f"bodies.{body}.regions.{i}.mesh.size") for i, r in enumerate(spec.regions)
                  if r.mesh is not None and r.mesh.size < h]
    return sum(c for c, _ in parts), max(parts)[1]


def _region_zone(solid, size: float) -> spec3d.Refinement:
    """A region's own size as a refine zone: its sphere or cylinder, else its bounding box."""
    if solid.sphere is not None and not solid.intersect:
        return spec3d.Refinement(ball=solid.sphere, size=size)
    if solid.cylinder is not None and not solid.intersect:
        return spec3d.Refinement(cylinder=solid.cylinder, size=size)
    return spec3d.Refinement(box=list(solid_box(solid)), size=size)


# ---- one evaluation's peak memory and time, from the assembled model (before any solve)
# The direct methods factor the reduced stiffness K (n unknowns, nnz entries) with PARDISO (3D:
# bordered by the contact rows C = [Bn; Bt], m of them) and condense the contact onto C: the dense
# Delassus operator W = C K⁺ Cᵀ, 8 m² bytes, held W_COPIES + u times at the peak (PARDISO's Schur
# complement, W, the Newton steps' active blocks and their factors; and one W*_u for each of the u
# units of the stiffness, wcs/contact/units.py, summed into W),
# O(m · nnz(L)) work to form and O(m³) to factor. The iterative method holds K, its GAMG
# hierarchy and Krylov vectors: O(nnz) memory, O(nnz) work a Newton step. A thermal step adds a
# direct factor of the conduction matrix (nnz / d² entries) to either.
# Measured with tests/bench/evaluation_cost.py: VmRSS after `Evaluator` and VmHWM of
# /proc/self/status after one nominal `evaluate` (the peak above the assembled model), and the
# wall time of that evaluate, 2 shared cores, on the 3D tunnel with ring/fault sizes 0.8/2.5 (the
# shipped one: 1.6e4 unknowns, 1587 contact rows), 0.6/1.5 and 0.6/1.0 (4.4e4, 6033 rows: 2.1 GB
# above the model, 66 s), block-on-block-3d at sizes 0.1 and 0.05, hertz-3d, and (time) the 2D
# tunnel, hip and two-blocks demo; the direct constants are the least-squares fits of those (the
# peak above the model within 25%, the time 0.5-1.25x the measured one; the fit gives 6.3 copies
# of W on the one-unit tunnels, and the fine tunnel of issue 25, m = 20961, died at > 14.5 GB after
# its third 3.5 GB array and was killed at 24 GB: 6 or more copies).
BASE_BYTES = 0.2e9              # the loaded modules (numpy, scipy, gmsh, PARDISO, pydantic)
MODEL_BYTES_PER_NNZ = 90.0      # the assembled model (K's pattern and its reduction, B, T, the stress operator; the
#                                 cell matrices made on demand, not held): VmRSS after `Evaluator` above BASE_BYTES, 55 bytes
#                                 a stiffness entry on block-on-block-3d at 0.05, 87 on the patch at 6e5 unknowns (250-300
#                                 while the cell matrices were held)
FACTOR_BYTES = 0.08e9           # PARDISO's own workspace
FACTOR_BYTES_PER_NNZ = 170.0    # the factor, per entry of K at 1e5 unknowns (3D: fill grows like n^(1/3))
W_COPIES = {2: 23.0, 3: 5.3}    # dense m x m arrays alive at the peak besides the units' own (2D: the dense inverse
#                                 block (K⁺)_SS on about 2m DOFs instead of the bordered factor: 22-25 in all measured
#                                 on the one-unit 2D tunnel at m = 1348 and 2692, wcs/results/meshcheck.py DENSE_BLOCKS)
EVALUATION_SECONDS = {2: 0.0, 3: 0.0}   # the direct method's fixed part: none measured (the block patch at 924
#                                         unknowns evaluates in 0.0 s; an earlier fit's intercept of 4.5 s made every
#                                         small 3D estimate 5-17x the measured time). With the constants below the
#                                         estimate is 1.5-2.4x the measured evaluate on the shipped tunnel (1.6 s),
#                                         hertz-3d (0.3 s) and the 3D patch at 1e4 unknowns with 2364 rows (2.8 s)
FACTOR_SECONDS_PER_NNZ = 2.85e-6  # factor and solves, per entry of K at 1e5 unknowns (fill as above)
SCHUR_SECONDS = 3.7e-9          # per contact row and factor entry: forming W
DENSE_SECONDS = {2: 2.0e-9,     # per m³: the Newton steps' dense factors of the active rows (2D: on the ~2m DOFs
                 3: 1.58e-10}   # of (K⁺)_SS, 40 s at m = 2692 cold, wcs/results/meshcheck.py CONDENSATION)
ITERATIVE_BYTES = 0.05e9        # PETSc's libraries
ITERATIVE_BYTES_PER_NNZ = 60.0    # a Newton step's eliminated operator (PETSc's matrix on its arrays), GAMG's
#                                   hierarchy and its set-up, Krylov vectors: the peak of tests/bench/test_bench_iterative.py's
#                                   measure is 0.25 GB + 128-129 bytes an entry of K in all (0.59 GB at 2.63e6 entries,
#                                   0.07/0.02; 1.80 GB at 1.21e7, 0.045/0.01), MODEL_BYTES_PER_NNZ's share included:
#                                   estimated 1.09x and 1.14x
ITERATIVE_SECONDS = 0.1         # the iterative method's fixed part (PETSc set-up): the block patch at 924 unknowns
#                                 evaluates in 0.1 s (2 Newton steps)
ITERATIVE_STEP_SECONDS = 1.0e-6   # one Newton step (its CG iterations, the hierarchy's products) per entry of K:
#                                   0.7e-6 frictionless (block-on-block-3d at 0.1 and 0.05: 2 steps, 1.4 and 2.5 s;
#                                   hertz-3d: 19 steps, 4.9 s), 1.3e-6 with Tresca friction (the shipped tunnel)
ITERATIVE_STEPS = 20            # Newton steps of an evaluation, not known before solving: assumed (hertz-3d took
#                                 19, the patch 2: its time estimate is an upper one, up to 10x there)
CLOSED_START_STEPS = 2          # the same, frictionless, where every contact node starts closed (zero initial gap):
#                                 the glued first step has the active set unless the load opens some contact (the
#                                 block patch: 2 at every face, 0.04 to 0.01, and at 1e6 unknowns; its time estimate
#                                 at 20 steps was 7.4 s against a measured 0.4 s: bench_kratos_face0.04)
# the other direct methods' time against the monolithic one's, at least: qp (the cvxpy reference) 28-87x
# (forward_hertz.png), dd 1.1-2.3x in 2D at 1e5-4e5 unknowns (dd_cost.csv), 4-12x on tetrahedra
SLOWER = {"qp": {2: 28.0, 3: 28.0}, "dd": {2: 1.1, 3: 4.0}}
# the kernel killed the fine tunnel at 24 GB of this machine's 25.3: the rest is the system's
USABLE_SHARE = 0.9


@dataclass(frozen=True)
class EvaluationFacts:
    """What the assembled model tells of one evaluation's size."""
    dimension: int              # 2 or 3
    unknowns: int               # reduced displacement unknowns n
    stiffness_nnz: int          # entries of the reduced stiffness K
    contact_rows: int = 0       # rows m of the contact operator C = [Bn; Bt] (0: no contact)
    units: int = 1              # units of the stiffness (wcs/contact/units.py), or an upper bound of them
    thermal: bool = False       # a heat step first (a scalar conduction factor: n/d unknowns)
    newton_steps: int = ITERATIVE_STEPS     # the iterative method's Newton steps, assumed (CLOSED_START_STEPS)


def _fill(f: EvaluationFacts) -> float:
    """Factor entries per entry of K relative to 1e5 unknowns: nested dissection's fill grows
    like n^(1/3) in 3D (1 in 2D, whose fill grows like log n only)."""
    return (f.unknowns / 1e5) ** (1 / 3) if f.dimension == 3 else 1.0


def evaluation_cost(f: EvaluationFacts, method: str) -> tuple[float, float]:
    """(peak bytes, seconds) of one evaluation with `method` from the constants above: monolithic,
    qp and dd the direct factor and the dense W (dd and qp fall back to or are polished by the
    monolithic solver, so they need its memory; their time is SLOWER's multiple), iterative
    O(nnz) (a scene without contact: one direct factor, whatever the method)."""
    nnz, m, fill = float(f.stiffness_nnz), float(f.contact_rows), _fill(f)
    heat = fill * nnz / f.dimension**2 if f.thermal else 0.0       # the conduction factor's entries
    memory = BASE_BYTES + MODEL_BYTES_PER_NNZ * nnz + FACTOR_BYTES_PER_NNZ * heat
    seconds = FACTOR_SECONDS_PER_NNZ * heat
    if method == "iterative" and m > 0:
        return (memory + ITERATIVE_BYTES + ITERATIVE_BYTES_PER_NNZ * nnz,
                seconds + ITERATIVE_SECONDS + f.newton_steps * ITERATIVE_STEP_SECONDS * nnz)
    factor, d = fill * nnz, f.dimension
    slower = SLOWER[method][d] if method in SLOWER and m > 0 else 1.0
    return (memory + FACTOR_BYTES + FACTOR_BYTES_PER_NNZ * factor + (W_COPIES[d] + f.units) * 8.0 * m * m,
            seconds + slower * (EVALUATION_SECONDS[d] + FACTOR_SECONDS_PER_NNZ * factor + SCHUR_SECONDS * m * factor
                                + DENSE_SECONDS[d] * m**3))


def evaluation_memory() -> float:
    """Bytes one evaluation may take: USABLE_SHARE of `machine_memory()`, shared by the
    `machine_ranks()` processes that evaluate at once."""
    return USABLE_SHARE * machine_memory() / machine_ranks()


def evaluation_fault(f: EvaluationFacts, method: str) -> str:
    """Why one evaluation with `method` does not fit (its estimate beyond `evaluation_memory()`)."""
    need, seconds = evaluation_cost(f, method)
    ranks = machine_ranks()
    size = f"{f.unknowns} unknowns" + (f", {f.contact_rows} contact rows: the dense W alone is "
                                       f"{8e-9 * f.contact_rows**2:.3g} GB" if method != "iterative" and f.contact_rows else "")
    return (f"one evaluation with the {method} method is estimated at {cost_words(need, seconds)} ({size}), more "
            f"than the {evaluation_memory() / 1e9:.3g} GB it may take of this machine's {machine_memory() / 1e9:.3g} GB "
            f"of memory" + (f", shared by {ranks} MPI processes" if ranks > 1 else ""))


def cost_words(memory: float, seconds: float) -> str:
    """'about 3.1 GB peak and 40 s' (an estimate's words in a reason or a refusal)."""
    return f"about {memory / 1e9:.3g} GB peak and {seconds:.2g} s"
