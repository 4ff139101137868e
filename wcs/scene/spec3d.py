"""The typed 3D scene (`scene.dimension: 3`): frozen pydantic models beside the 2D ones of
`wcs.scene.spec`, with three-component vectors (`u`, `traction`, `body_forces`, `point`,
`normal`), solids (box, cylinder, sphere, extrude, halfspace, with `minus` / `intersect`), face
selectors (plane, box, cylinder, sphere) and region selectors (box, ball, cylinder, boundary).
Materials, a region's `mesh: {size}`, contacts, glue and thermal data are the 2D models. `wcs.scene.mesher3d` reads these
objects by attribute."""
from __future__ import annotations

from typing import Annotated, Literal, Optional

import numpy as np
from pydantic import AfterValidator, Field, model_validator


from .spec import (BODY_FORCE, FEATURE, FEATURE_MIN, LENGTH, STRESS, Contact, Coordinate, Frozen, Glue,
                   Absorbing, Material, Name, RegionMesh, Shape, Source, Thermal, TimeFunction, _exactly_one)

XYZ = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]
Six = Annotated[list[Coordinate], Field(min_length=6, max_length=6)]


def _nonzero(v: list[float]) -> list[float]:
    if np.linalg.norm(v) < FEATURE_MIN:
        raise ValueError(f"the vector must not be zero (its length is below {FEATURE_MIN:g})")
    return v


Vector = Annotated[XYZ, AfterValidator(_nonzero)]


def _ordered(b: list[float], strict: bool) -> list[float]:
    lo, hi = np.array(b[:3]), np.array(b[3:])
    if (np.any(hi - lo < FEATURE_MIN) if strict else np.any(hi < lo)):
        relation = "<" if strict else "<="
        raise ValueError(f"a box is [xmin, ymin, zmin, xmax, ymax, zmax] with min {relation} max"
                         + (f" (sides of at least {FEATURE_MIN:g})" if strict else ""))
    return b


SolidBox = Annotated[Six, AfterValidator(lambda b: _ordered(b, strict=True))]
FlatBox = Annotated[Six, AfterValidator(lambda b: _ordered(b, strict=False))]


class Cylinder(Frozen):
    """The solid (or the lateral surface) of radius `radius` about the axis from start to end."""
    start: XYZ
    end: XYZ
    radius: float = Field(**FEATURE)

    @model_validator(mode="after")
    def _has_length(self):
        if np.linalg.norm(np.subtract(self.end, self.start)) < FEATURE_MIN:
            raise ValueError(f"cylinder start and end must differ (by at least {FEATURE_MIN:g})")
        return self


class Sphere(Frozen):
    center: XYZ
    radius: float = Field(**FEATURE)


class Plane(Frozen):
    """The plane through `point` with normal `normal`; as a halfspace, (p − point)·normal ≤ 0."""
    point: XYZ
    normal: Vector


class FacePlane(Plane):
    tolerance: Optional[float] = Field(None, gt=0, le=LENGTH["le"])   # distance of a facet's nodes


class Extrude(Frozen):
    shape: Shape                           # a 2D shape in the plane z = 0
    vector: Vector

    @model_validator(mode="after")
    def _leaves_the_plane(self):
        if abs(self.vector[2]) < FEATURE_MIN:
            raise ValueError("the 2D shape lies in the plane z = 0: the vector needs a z component "
                             f"of at least {FEATURE_MIN:g}")
        return self


class Solid(Frozen):
    box: Optional[SolidBox] = None
    cylinder: Optional[Cylinder] = None
    sphere: Optional[Sphere] = None
    extrude: Optional[Extrude] = None
    halfspace: Optional[Plane] = None      # only as a tool of `minus` / `intersect`
    minus: list[Solid] = []
    intersect: list[Solid] = []

    @model_validator(mode="after")
    def _one_primitive(self):
        _exactly_one(self, ("box", "cylinder", "sphere", "extrude", "halfspace"))
        if self.halfspace is not None and (self.minus or self.intersect):
            raise ValueError("a halfspace is unbounded: it cannot have `minus` or `intersect` of its own")
        return self


class Region(Frozen):
    material: str
    shape: Optional[Solid] = None          # required unless the scene's mesh is a file
    name: Optional[Name] = None
    mesh: Optional[RegionMesh] = None      # the size inside the region's volume (and on its faces)


class Refinement(Frozen):
    """A zone meshed finer: `size` inside the box, ball or cylinder, or on the named boundary;
    away from it the size grows by `mesh.grading` per unit distance."""
    box: Optional[SolidBox] = None
    ball: Optional[Sphere] = None
    cylinder: Optional[Cylinder] = None
    boundary: Optional[str] = None
    size: float = Field(**FEATURE)

    @model_validator(mode="after")
    def _one_selector(self):
        _exactly_one(self, ("box", "ball", "cylinder", "boundary"))
        return self


class SceneRefinement(Refinement):
    """A zone of `mesh.refine`; with `body`, only in that body (its volumes and their faces,
    edges and corners)."""
    body: Optional[str] = None


class BodyMesh(Frozen):
    """A body's own mesh size (and refinement zones): the body is meshed on its own (faces it
    shares with other bodies are nonmatching)."""
    size: float = Field(**FEATURE)
    refine: list[Refinement] = []


class Body(Frozen):
    regions: Annotated[list[Region], Field(min_length=1)]
    mesh: Optional[BodyMesh] = None


class Boundary(Frozen):
    """Boundary facets whose three nodes lie on the set (a box: inside it)."""
    body: Optional[str] = None
    plane: Optional[FacePlane] = None
    box: Optional[FlatBox] = None
    cylinder: Optional[Cylinder] = None
    sphere: Optional[Sphere] = None

    @model_validator(mode="after")
    def _one_selector(self):
        _exactly_one(self, ("plane", "box", "cylinder", "sphere"))
        return self


class RegionOfInterest(Frozen):
    """Cells inside a box, ball or cylinder (embedded in the mesh), or the facets of a boundary."""
    box: Optional[SolidBox] = None
    ball: Optional[Sphere] = None
    cylinder: Optional[Cylinder] = None
    boundary: Optional[str] = None
    body: Optional[str] = None

    @model_validator(mode="after")
    def _one_selector(self):
        _exactly_one(self, ("box", "ball", "cylinder", "boundary"))
        return self


class Support(Frozen):
    u: Optional[Annotated[list[Optional[Coordinate]], Field(min_length=3, max_length=3)]] = None
    normal: Optional[float] = Field(None, **LENGTH)

    @model_validator(mode="after")
    def _holds_something(self):
        _exactly_one(self, ("u", "normal"))
        if self.u is not None and all(c is None for c in self.u):
            raise ValueError("u: [null, null, null] holds nothing; give at least one component")
        return self


class Load(Frozen):
    pressure: Optional[float] = Field(None, **STRESS)
    traction: Optional[Annotated[list[Annotated[float, Field(**STRESS)]], Field(min_length=3, max_length=3)]] = None
    time: Optional[TimeFunction] = None            # a dynamic study's factor in time

    @model_validator(mode="after")
    def _one_kind(self):
        _exactly_one(self, ("pressure", "traction"))
        return self


class Mesh(Frozen):
    size: Optional[float] = Field(None, **FEATURE)      # default: wcs.choose.mesh_size of the diagonal
    grading: Optional[float] = Field(None, ge=0, le=1e3)   # size growth per unit distance from a refine zone
    refine: list[SceneRefinement] = []
    file: Optional[str] = None             # a 3D mesh file (gmsh .msh, ...) instead of solids
    max_cells: Optional[int] = Field(None, ge=1, le=10**10)   # the resource guard's limit

    @model_validator(mode="after")
    def _file_as_it_is(self):
        if self.file is not None and (self.size is not None or self.refine or self.grading is not None
                                      or self.max_cells is not None):
            raise ValueError("a mesh `file` is used as it is: drop `size`, `grading`, `refine` and `max_cells`")
        return self


class Scene(Frozen):
    dimension: Literal[3]
    mesh: Mesh = Mesh()
    materials: Annotated[dict[Name, Material], Field(min_length=1)]
    bodies: Annotated[dict[Name, Body], Field(min_length=1)]
    boundaries: dict[Name, Boundary] = {}
    supports: dict[str, Support] = {}
    loads: dict[str, Load] = {}
    body_forces: dict[str, Annotated[list[Annotated[float, Field(**BODY_FORCE)]],
                                     Field(min_length=3, max_length=3)]] = {}
    contacts: dict[Name, Contact] = {}
    glue: dict[Name, Glue] = {}
    thermal: Optional[Thermal] = None
    regions_of_interest: dict[Name, RegionOfInterest] = {}
    sources: dict[Name, Source] = {}               # a dynamic study's point sources
    absorbing: Optional[Absorbing] = None          # its absorbing boundaries
