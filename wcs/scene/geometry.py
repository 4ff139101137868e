"""Shapes of study files -> OpenCASCADE surfaces in the current gmsh model.

A shape is one of

    {rectangle: [x0, y0, x1, y1]}
    {polygon: [[x, y], ...]}
    {disc: {center: [x, y], radius: r}}

with optional, recursive ``minus: [shape, ...]`` (cut by the union of the
listed shapes) and ``intersect: [shape, ...]`` (intersected with each listed
shape in turn).  ``intersect`` is applied before ``minus`` (they commute).

Everything here works on the gmsh model that is current when it is called;
``wcs.scene.mesher2d`` owns the gmsh session.
"""
from __future__ import annotations

import math


from ..errors import StudyError
from .session import gmsh

DimTags = list[tuple[int, int]]

SHAPE_KINDS = ("rectangle", "polygon", "disc")


def number_list(value, n: int | None, path: str, what: str) -> list[float]:
    try:
        out = [float(v) for v in value]
    except (TypeError, ValueError):
        raise StudyError(f"{what} must be a list of numbers, got {value!r}", path=path) from None
    if n is not None and len(out) != n:
        raise StudyError(f"{what} must have {n} numbers, got {len(out)}", path=path)
    if not all(math.isfinite(v) for v in out):
        raise StudyError(f"{what} must be finite numbers, got {value!r}", path=path)
    return out


def _primitive(shape, path: str) -> DimTags:
    occ = gmsh.model.occ
    kinds = [k for k in SHAPE_KINDS if getattr(shape, k) is not None]
    if len(kinds) != 1:
        raise StudyError(f"a shape needs exactly one of {', '.join(SHAPE_KINDS)}; got {shape!r}", path=path)
    kind = kinds[0]
    spec = getattr(shape, kind)
    if kind == "rectangle":
        x0, y0, x1, y1 = number_list(spec, 4, f"{path}.rectangle", "rectangle")
        if not (x1 > x0 and y1 > y0):
            raise StudyError(f"rectangle [x0, y0, x1, y1] needs x0 < x1 and y0 < y1, got {spec}",
                             path=f"{path}.rectangle")
        return [(2, occ.addRectangle(x0, y0, 0.0, x1 - x0, y1 - y0))]
    if kind == "disc":
        cx, cy = number_list(spec.center, 2, f"{path}.disc.center", "center")
        (r,) = number_list([spec.radius], 1, f"{path}.disc.radius", "radius")
        if r <= 0:
            raise StudyError(f"disc radius must be > 0, got {r}", path=f"{path}.disc.radius")
        return [(2, occ.addDisk(cx, cy, 0.0, r, r))]
    # polygon
    try:
        pts = [number_list(p, 2, f"{path}.polygon.{i}", "polygon vertex") for i, p in enumerate(spec)]
    except TypeError:
        raise StudyError("polygon must be a list of [x, y] points", path=f"{path}.polygon") from None
    if len(pts) >= 2 and pts[0] == pts[-1]:
        pts = pts[:-1]                              # tolerate a closed ring
    if len(pts) < 3:
        raise StudyError("polygon needs at least 3 distinct vertices", path=f"{path}.polygon")
    area2 = sum(pts[i][0] * pts[i - 1][1] - pts[i - 1][0] * pts[i][1] for i in range(len(pts)))
    if abs(area2) == 0.0:
        raise StudyError("polygon has zero area", path=f"{path}.polygon")
    ptags = [occ.addPoint(x, y, 0.0) for x, y in pts]
    ltags = [occ.addLine(ptags[i], ptags[(i + 1) % len(ptags)]) for i in range(len(ptags))]
    loop = occ.addCurveLoop(ltags)
    return [(2, occ.addPlaneSurface([loop]))]


def make_shape(shape, path: str) -> DimTags:
    """Create ``shape`` (a validated `Shape`) in the current OCC model; return its surfaces
    (dim 2 dimtags).

    Raises StudyError (with ``path``) on an empty shape, and on a shape the geometry kernel
    refuses (gmsh raises a bare Exception, e.g. "Could not create line").
    """
    occ = gmsh.model.occ
    out = kernel(path, _primitive, shape, path)
    for i, sub in enumerate(shape.intersect or []):
        tool = make_shape(sub, f"{path}.intersect.{i}")
        out, _ = kernel(f"{path}.intersect.{i}", occ.intersect, out, tool, removeObject=True, removeTool=True)
        out = [dt for dt in out if dt[0] == 2]
        if not out:
            raise StudyError("the intersection is empty", path=f"{path}.intersect.{i}")
    minus = shape.minus or []
    if minus:
        tools: DimTags = []
        for i, sub in enumerate(minus):
            tools += make_shape(sub, f"{path}.minus.{i}")
        out, _ = kernel(f"{path}.minus", occ.cut, out, tools, removeObject=True, removeTool=True)
        out = [dt for dt in out if dt[0] == 2]
        if not out:
            raise StudyError("the shape is empty after `minus`", path=path)
    return out


def kernel(path: str, call, *args, **kwargs):
    """``call(*args, **kwargs)``; an exception of the geometry kernel as a StudyError at ``path``."""
    try:
        return call(*args, **kwargs)
    except StudyError:
        raise
    except Exception as exc:  # noqa: BLE001 - gmsh raises a bare Exception
        raise StudyError(f"the geometry kernel (OpenCASCADE) cannot build this shape: {exc}",
                         path=path) from None
