"""What a scene will cost before it is meshed: the estimated cells (`wcs.scene.estimate`) within
`mesh.max_cells` and this machine's memory, mesh sizes fine enough to resolve the fields, a
bounded number of shapes; and the warning where P1 elements lock (a Poisson ratio near 1/2)."""
from __future__ import annotations

import numpy as np

from ..choose import MeshFacts, mesh_size
from ..scene import spec3d
from ..scene.estimate import (bytes_per_cell, DEFAULT_MAX_CELLS, ESTIMATE_EXCESS, estimate_cells, estimate_cells3d, machine_memory,
                              shape_box, solid_box)
from ..scene.spec import Scene
from .scene import _used_materials
from .source import _Source
from .uncertain import Uncertain


MIN_CELLS_ALONG = 4     # a mesh size gives at least this many cells along the longest side


def _check_mesh(scene: Scene, src: _Source, method: str = "auto") -> float | None:
    """The estimated cell count (wcs.scene.estimate) of a scene meshed from shapes; StudyError
    when it exceeds `mesh.max_cells`, or when a mesh size leaves fewer than MIN_CELLS_ALONG
    cells along the longest side of the scene (or of a body with its own size)."""
    if scene.mesh.file is not None:
        return None
    _refuse_many_shapes(scene, src)
    if scene.dimension == 3:
        return _check_mesh3d(scene, src, method)
    boxes = {b: [shape_box(r.shape) for r in spec.regions] for b, spec in scene.bodies.items()}
    sizes = [(("mesh", "size"), scene.mesh.size, "the scene", sum(boxes.values(), []))]
    sizes += [(("bodies", b, "mesh", "size"), spec.mesh.size, f"body '{b}'", boxes[b])
              for b, spec in scene.bodies.items() if spec.mesh is not None and spec.mesh.size]
    _refuse_coarse([(where, h, what, max(max(b[2] for b in bx) - min(b[0] for b in bx),
                                         max(b[3] for b in bx) - min(b[1] for b in bx)))
                    for where, h, what, bx in sizes], src)
    cells, path = estimate_cells(scene)
    _refuse_many(scene, cells, path, f"{cells:.3g} cells ({cells:.3g} unknowns)", src, method)
    return cells


MAX_SHAPES = 1000       # shapes of a scene, `minus` and `intersect` included: the demo's base minus 400
                        # rectangles meshed in 3.4 s, and meshing grows with them


def _refuse_many_shapes(scene, src: _Source) -> None:
    """StudyError at the region shape past which the scene holds more than MAX_SHAPES shapes
    (each primitive of a `minus` / `intersect` tree, an extruded 2D shape's included)."""
    total = 0
    for b, spec in scene.bodies.items():
        for i, region in enumerate(spec.regions):
            stack = [region.shape]
            while stack and total <= MAX_SHAPES:
                shape = stack.pop()
                total += 1
                stack += (shape.minus or []) + (shape.intersect or [])
                if getattr(shape, "extrude", None) is not None:
                    stack.append(shape.extrude.shape)
            if total > MAX_SHAPES:
                raise src.error(("bodies", b, "regions", i, "shape"), f"the scene's shapes number more than "
                                f"{MAX_SHAPES} (each of a `minus` or `intersect` counts): meshing grows with them")


def _refuse_coarse(sizes, src: _Source) -> None:
    """StudyError where a mesh size (where, h, what, longest side) leaves fewer than
    MIN_CELLS_ALONG cells along the longest side."""
    for where, h, what, longest in sizes:
        if h > longest / MIN_CELLS_ALONG:
            raise src.error(where, f"size {h:g} leaves fewer than {MIN_CELLS_ALONG} cells along the longest "
                                   f"side of {what} ({longest:.3g}): P1 cells that coarse do not resolve the fields")


def _refuse_many(scene, cells: float, path: str, about: str, src: _Source, method: str = "auto") -> None:
    """StudyError at the size contributing most (`path`) when the estimated `cells` exceed
    `mesh.max_cells`; `about` says what they are."""
    limit = DEFAULT_MAX_CELLS if scene.mesh.max_cells is None else scene.mesh.max_cells
    if cells > limit:
        raise src.error(tuple(path.split(".")), f"the mesh would have about {about}, more than "
                        f"mesh.max_cells = {limit:g} (this size contributes most); coarsen the mesh or raise "
                        "`mesh.max_cells`")
    per_cell, memory = bytes_per_cell(scene, method), machine_memory()
    need = cells * per_cell
    excess = ESTIMATE_EXCESS[scene.dimension]
    if need > excess * memory:                      # a raised max_cells: meshing and solving would swap
        raise src.error(tuple(path.split(".")), f"the mesh would have about {about}, which needs about "
                        f"{need / 1e9:.3g} GB ({per_cell:g} bytes a cell with solver.method {method}), more than "
                        + (f"{excess:g} times " if excess != 1 else "")
                        + f"this machine's {memory / 1e9:.3g} GB of memory (this size contributes most); coarsen "
                        "the mesh")


def _check_mesh3d(scene: spec3d.Scene, src: _Source, method: str = "auto") -> float:
    """`_check_mesh` of a 3D scene: a region shape that is a halfspace alone is refused (it is
    unbounded), sizes leave MIN_CELLS_ALONG cells along the longest side, and the estimated
    tetrahedra (wcs.scene.estimate.estimate_cells3d) stay within `mesh.max_cells`."""
    boxes = {}
    for b, spec in scene.bodies.items():
        for i, region in enumerate(spec.regions):
            if region.shape.halfspace is not None:
                raise src.error(("bodies", b, "regions", i, "shape", "halfspace"), "a halfspace is unbounded: "
                                "use it inside `intersect` or `minus` of a solid")
        boxes[b] = [solid_box(r.shape) for r in spec.regions]
    lo = lambda bx: np.min([x[:3] for x in bx], axis=0)       # noqa: E731
    hi = lambda bx: np.max([x[3:] for x in bx], axis=0)       # noqa: E731
    everything = sum(boxes.values(), [])
    size = scene.mesh.size
    if size is None:                                          # the mesher's default
        size = mesh_size(MeshFacts(diagonal=float(np.linalg.norm(hi(everything) - lo(everything)))))[0]
    sizes = [] if scene.mesh.size is None else [(("mesh", "size"), size, "the scene", everything)]
    sizes += [(("bodies", b, "mesh", "size"), spec.mesh.size, f"body '{b}'", boxes[b])
              for b, spec in scene.bodies.items() if spec.mesh is not None]
    _refuse_coarse([(where, h, what, float(np.max(hi(bx) - lo(bx)))) for where, h, what, bx in sizes], src)
    cells, path = estimate_cells3d(scene, size)
    _refuse_many(scene, cells, path, f"{cells:.3g} tetrahedra", src, method)
    return cells


LOCKING_NU = 0.45       # P1 triangles lock as nu -> 0.5
NO_CRITERIA = "no criteria: `run` and `sweep` solve but measure nothing (`solve` writes the fields)"


def _locking_warnings(scene: Scene, uncertain: list[Uncertain]) -> list[str]:
    """A warning per material whose Poisson ratio (nominal or anywhere in its box) is >= LOCKING_NU:
    P1 triangles and tetrahedra lock (the 2D Hertz peak-pressure error: 2 % at nu = 0.45, 8 % at 0.49, 135 % at
    0.4999)."""
    box = {e.path: (e.lower, e.upper) for e in uncertain}
    cells, bench = ("tetrahedra", "the 2D Hertz benchmark") if scene.dimension == 3 else ("triangles", "wcs's Hertz benchmark")
    out = []
    for name in _used_materials(scene):
        m = scene.materials[name]
        if m.nu is not None:
            top = box.get(f"materials.{name}.nu", (m.nu, m.nu))[1]
        else:                                      # nu = lambda / (2 (lambda + mu)), largest at max lambda, min mu
            lam = box.get(f"materials.{name}.lambda", (m.lam, m.lam))[1]
            mu = box.get(f"materials.{name}.mu", (m.mu, m.mu))[0]
            top = lam / (2 * (lam + mu))
        if top >= LOCKING_NU:
            out.append(f"material '{name}': Poisson ratio up to {top:.4g} (>= {LOCKING_NU}): P1 {cells} "
                       f"lock as nu -> 0.5: results there are too stiff ({bench}: peak-pressure "
                       "error 2 % at 0.45, 8 % at 0.49, 135 % at 0.4999)")
    return out
