"""The typed scene: frozen pydantic models of a study's `scene:` block (shapes, materials,
bodies and their regions, boundaries, supports, loads, contacts, glue, thermal data, regions
of interest, the mesh), the physical range of every number, and the geometric checks of a
shape. The loader (`wcs.study`) validates a scene into a `Scene`; everything below it (mesher,
model, parameter map, criteria) reads the same frozen objects by attribute. A dynamic study's
keys (a load's time function, point sources, absorbing boundaries) are here too, so that the
scene's schema is one module (over 500 lines for that reason: its models refer to each other,
and the numbers they give the time levels are `wcs.dynamics`)."""
from __future__ import annotations

import re
from typing import Annotated, Literal, Optional

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, field_validator, model_validator

from ..options import CONFIG
from ..options import Strict


class Frozen(Strict):
    """A strict model that cannot be changed once validated."""

    model_config = ConfigDict(**CONFIG, frozen=True)

# Physical ranges, shared by the models and by the boxes of uncertain data. The bounds lie
# beyond any solid (moduli from gels, ~1e2 Pa, to diamond, 1.2e12 Pa; conductivities from
# aerogels to diamond; expansions of polymers, ~1e-3/K) yet keep every product of the solve
# (u ~ load * length / E) far inside double precision: E = 1e-300 would give u ~ 1e306.
# Moduli reach far beyond diamond: a rigid foundation is modelled as a body of E = 1e14 to
# 1e17 Pa (code_aster's SSNV128: 1.3e16 Pa), and a body in contact is factored on its own
# (K is block diagonal over bodies, W = Σ_bodies C K_b⁻¹ Cᵀ), so its contrast with the
# bodies it touches costs no digit (tests/acceptance/test_stiff_bodies.py: to E = 1e20 Pa). Regions
# bonded in one body (or glued) share one factorization, and their contrast has its own
# bound (`wcs.model.evaluation.BONDED_CONTRAST_MAX`).
MODULUS = {"ge": 1.0, "le": 1e20}                 # E, mu [Pa]
LAME = {"ge": -1e20, "le": 1e24}                  # lambda [Pa] (nu -> 0.5 makes it ~1e3 E)
RIGID_HINT = ("for a rigid body, make it the master of its contact and hold its contact side fixed with a support "
              "(`u: [0, 0]`, in 3D `[0, 0, 0]`) "
              "instead of raising its modulus")
POISSON = {"gt": -1, "lt": 0.5}
CONDUCTIVITY = {"ge": 1e-6, "le": 1e6}           # [W/(m K)]
EXPANSION = {"ge": -1e-2, "le": 1e-2}            # [1/K]
WEIGHT = {"ge": 0, "le": 1e7}                     # density_weight [N/m^3]
DENSITY = {"gt": 0, "le": 1e6}                    # density [kg/m^3] (dynamics)
VISCOSITY_RATIO = {"ge": 0, "le": 1e3}            # c1 = ratio * c0 [s] (dynamics)
VISCOUS_MODULUS = {"ge": 0, "le": 1e20}           # E of c1 [Pa s] (dynamics)
STRESS = {"ge": -1e12, "le": 1e12}               # pressure, traction [Pa]
SLIP = {"ge": 0, "le": 1e12}                      # Tresca slip limit [Pa]
COEFFICIENT = {"ge": 0, "le": 10}                 # Coulomb friction coefficient
BODY_FORCE = {"ge": -1e10, "le": 1e10}           # [N/m^3]
SOURCE = {"ge": -1e12, "le": 1e12}               # heat source [W/m^3]
LENGTH = {"ge": -1e6, "le": 1e6}                 # coordinates, prescribed displacements [m]
KELVIN = {"gt": 0, "le": 1e5}
# OpenCASCADE merges points closer than its tolerance (1e-7): sides, radii, edges and mesh
# sizes below FEATURE_MIN fail inside gmsh ("Could not create line")
FEATURE_MIN = 1e-6
FEATURE = {"ge": FEATURE_MIN, "le": 1e6}

MAX_NAME = 100      # characters of a name (it becomes part of file names, e.g. the study's output)


def _valid_name(name: str) -> str:
    """A name: 1 to MAX_NAME printable characters (no control character such as NUL, no lone
    surrogate: it is written to results files and file names), no dots, spaces or brackets."""
    if not name or re.search(r"[.\s\[\]]", name):
        raise ValueError("a name may not contain dots, spaces or brackets")
    if len(name) > MAX_NAME:
        raise ValueError(f"a name has at most {MAX_NAME} characters, got {len(name)}")
    bad = next((c for c in name if not c.isprintable()), None)
    if bad is not None:
        raise ValueError(f"a name may contain printable characters only, got {ascii(bad)} at "
                         f"position {name.index(bad)}")
    return name


Name = Annotated[str, AfterValidator(_valid_name)]
Point = Annotated[list[float], Field(min_length=2, max_length=2)]
Coordinate = Annotated[float, Field(**LENGTH)]
XY = Annotated[list[Coordinate], Field(min_length=2, max_length=2)]
Corners = Annotated[list[Coordinate], Field(min_length=4, max_length=4)]


def _ordered(corners: list[float], strict: bool) -> list[float]:
    x0, y0, x1, y1 = corners
    if (x0 >= x1 or y0 >= y1) if strict else (x0 > x1 or y0 > y1):
        relation = "<" if strict else "<="
        raise ValueError(f"corners must be [x0, y0, x1, y1] with x0 {relation} x1 and y0 {relation} y1")
    if strict and min(x1 - x0, y1 - y0) < FEATURE_MIN:
        raise ValueError(f"a side of {min(x1 - x0, y1 - y0):.3g} is below {FEATURE_MIN:g}, "
                         "the smallest length the geometry kernel resolves")
    return corners


Rectangle = Annotated[Corners, AfterValidator(lambda v: _ordered(v, strict=True))]
BoxCorners = Annotated[Corners, AfterValidator(lambda v: _ordered(v, strict=False))]


def _simple(points: list[list[float]]) -> list[list[float]]:
    """A simple polygon: no repeated vertex, no edge shorter than FEATURE_MIN, no two edges
    crossing or touching (other than neighbours at their common vertex), nonzero area."""
    ring = points[:-1] if len(points) > 3 and points[0] == points[-1] else points   # a closed ring
    P = np.array(ring, dtype=float)
    A, B = P, np.roll(P, -1, axis=0)
    n = len(P)
    short = np.flatnonzero(np.hypot(*(B - A).T) < FEATURE_MIN)
    if short.size:
        i = int(short[0])
        raise ValueError(f"vertices {i} and {(i + 1) % n} coincide (a repeated vertex) or are closer "
                         f"than {FEATURE_MIN:g}")
    i, j = np.triu_indices(n, 1)
    far = (j - i > 1) & ~((i == 0) & (j == n - 1))            # non-neighbouring edges
    i, j = i[far], j[far]

    def orient(a, b, c):
        return np.sign((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
                       - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))
    d1, d2 = orient(A[j], B[j], A[i]), orient(A[j], B[j], B[i])
    d3, d4 = orient(A[i], B[i], A[j]), orient(A[i], B[i], B[j])
    cross = (d1 * d2 <= 0) & (d3 * d4 <= 0)
    collinear = (d1 == 0) & (d2 == 0)                          # overlap only if the spans meet
    lo = lambda a, b: np.minimum(a, b)                          # noqa: E731
    hi = lambda a, b: np.maximum(a, b)                          # noqa: E731
    span = np.all((lo(A[i], B[i]) <= hi(A[j], B[j])) & (lo(A[j], B[j]) <= hi(A[i], B[i])), axis=1)
    hit = np.flatnonzero(cross & (~collinear | span))
    if hit.size:
        k = int(hit[0])
        raise ValueError(f"the polygon is self-intersecting (edge {i[k]}-{(i[k] + 1) % n} meets "
                         f"edge {j[k]}-{(j[k] + 1) % n})")
    xs, ys = P.T
    if np.dot(xs, np.roll(ys, -1)) == np.dot(ys, np.roll(xs, -1)):
        raise ValueError("the polygon has zero area")
    return points


MAX_VERTICES = 1000     # of a polygon: its simplicity check compares every pair of edges (1 s at 1000)
Polygon = Annotated[list[XY], Field(min_length=3, max_length=MAX_VERTICES), AfterValidator(_simple)]


def _has_length(ends: list[list[float]]) -> list[list[float]]:
    if np.hypot(ends[1][0] - ends[0][0], ends[1][1] - ends[0][1]) < FEATURE_MIN:
        raise ValueError(f"the segment's two ends coincide (closer than {FEATURE_MIN:g})")
    return ends


Segment = Annotated[list[XY], Field(min_length=2, max_length=2), AfterValidator(_has_length)]


def _nonzero(direction: list[float]) -> list[float]:
    if direction == [0, 0]:
        raise ValueError("the direction must not be [0, 0]")
    return direction


Direction = Annotated[XY, AfterValidator(_nonzero)]


def _exactly_one(model: BaseModel, keys: tuple[str, ...]) -> None:
    given = [k for k in keys if getattr(model, k) is not None]
    if len(given) != 1:
        found = f"got {', '.join(given)}" if given else "got none"
        raise ValueError(f"give exactly one of {', '.join(keys)} ({found})")


class Viscosity(Frozen):
    """c⁽¹⁾ of the Kelvin–Voigt law [101, (1)]: `ratio` η (c⁽¹⁾ = η c⁽⁰⁾) or isotropic `E`, `nu` [Pa s]."""
    ratio: Optional[float] = Field(None, **VISCOSITY_RATIO)
    E: Optional[float] = Field(None, **VISCOUS_MODULUS)
    nu: Optional[float] = Field(None, **POISSON)

    @model_validator(mode="after")
    def _ratio_or_moduli(self):
        if (self.ratio is None) == (self.E is None and self.nu is None) or (self.E is None) != (self.nu is None):
            raise ValueError("give the viscosity as `ratio` or as `E` and `nu` (exactly one)")
        return self


class Material(Frozen):
    E: Optional[float] = Field(None, ge=MODULUS["ge"])
    nu: Optional[float] = Field(None, **POISSON)
    lam: Optional[float] = Field(None, alias="lambda", **LAME)
    mu: Optional[float] = Field(None, ge=MODULUS["ge"])
    conductivity: Optional[float] = Field(None, **CONDUCTIVITY)
    expansion: Optional[float] = Field(None, **EXPANSION)
    density_weight: Optional[float] = Field(None, **WEIGHT)
    density: Optional[float] = Field(None, **DENSITY)         # [kg/m^3]: the mass of a dynamic study
    viscosity: Optional[Viscosity] = None                     # Kelvin–Voigt c1 of a dynamic study

    @field_validator("E", "mu")
    def _not_beyond_rigid(cls, value):
        if value is not None and value > MODULUS["le"]:
            raise ValueError(f"must be less than or equal to {MODULUS['le']:g} Pa; {RIGID_HINT}")
        return value

    @model_validator(mode="after")
    def _one_elastic_pair(self):
        engineering = {"E": self.E, "nu": self.nu}
        lame = {"lambda": self.lam, "mu": self.mu}
        uses = [pair for pair in (engineering, lame) if any(v is not None for v in pair.values())]
        if len(uses) != 1:
            raise ValueError("give the elastic constants as E, nu or as lambda, mu (exactly one pair)")
        missing = [k for k, v in uses[0].items() if v is None]
        if missing:
            raise ValueError(f"'{missing[0]}' is missing: {' and '.join(uses[0])} go together")
        if self.lam is not None and not lame_admissible(self.lam, self.mu):
            raise ValueError(f"3 lambda + 2 mu = {3 * self.lam + 2 * self.mu:.4g} must be > 0 (a positive "
                             "bulk modulus; equivalently Poisson's ratio above -1)")
        return self


def lame_admissible(lam: float, mu: float) -> bool:
    """Whether Hooke's law tau = lambda tr(e) I + 2 mu e is positive definite: mu > 0 and
    3 lambda + 2 mu > 0 (the shear and bulk moduli positive; E > 0 and -1 < nu < 1/2).

    - 3D: e : C e = 2 mu |dev e|^2 + (lambda + 2 mu / 3) (tr e)^2, positive for every e != 0
      exactly when mu > 0 and 3 lambda + 2 mu > 0.
    - Plane strain: the 2D form alone needs only mu > 0 and lambda + mu > 0, but the slice is of
      a 3D material (tau_33 = lambda div u, the thermal modulus beta = (3 lambda + 2 mu) alpha,
      [68]), so the 3D condition holds; it implies lambda + mu > 0.
    - Plane stress: lambda* = 2 lambda mu / (lambda + 2 mu) and
      lambda* + mu = mu (3 lambda + 2 mu) / (lambda + 2 mu) > 0 under the same condition
      (which also gives lambda + 2 mu > 0).
    Both bounds are linear in (lambda, mu): over a box they hold at every point when they hold
    at its lowest corner."""
    return mu > 0 and 3 * lam + 2 * mu > 0


class Disc(Frozen):
    center: XY
    radius: float = Field(**FEATURE)


class Shape(Frozen):
    rectangle: Optional[Rectangle] = None
    polygon: Optional[Polygon] = None
    disc: Optional[Disc] = None
    minus: Optional[list[Shape]] = None
    intersect: Optional[list[Shape]] = None

    @model_validator(mode="after")
    def _one_primitive(self):
        _exactly_one(self, ("rectangle", "polygon", "disc"))
        return self


class RegionMesh(Frozen):
    size: float = Field(**FEATURE)        # target element size inside the region


class Region(Frozen):
    material: str
    shape: Optional[Shape] = None          # required unless the scene's mesh is a file
    name: Optional[Name] = None
    mesh: Optional[RegionMesh] = None


class BodyMesh(Frozen):
    """A body's own mesh sizes: the body is meshed on its own (nodes on curves it shares
    with other bodies do not match theirs: contacts and glue there use mortar)."""
    size: Optional[float] = Field(None, **FEATURE)
    refine: list["Refinement"] = []


class Body(Frozen):
    regions: Annotated[list[Region], Field(min_length=1)]
    mesh: Optional[BodyMesh] = None


class Boundary(Frozen):
    body: Optional[str] = None
    segment: Optional[Segment] = None
    circle: Optional[Disc] = None
    box: Optional[BoxCorners] = None

    @model_validator(mode="after")
    def _one_selector(self):
        _exactly_one(self, ("segment", "circle", "box"))
        return self


class GroupBoundary(Frozen):
    """A boundary that is a 1D physical group of the scene's mesh file (`NAME` or `BODY:NAME`):
    the loader adds one per group; a study does not write it."""
    group: str
    body: Optional[str] = None


class Support(Frozen):
    u: Optional[Annotated[list[Optional[Coordinate]], Field(min_length=2, max_length=2)]] = None
    normal: Optional[float] = Field(None, **LENGTH)

    @model_validator(mode="after")
    def _holds_something(self):
        _exactly_one(self, ("u", "normal"))
        if self.u is not None and all(c is None for c in self.u):
            raise ValueError("u: [null, null] holds nothing; give at least one component")
        return self


class Load(Frozen):
    pressure: Optional[float] = Field(None, **STRESS)
    traction: Optional[Annotated[list[Annotated[float, Field(**STRESS)]], Field(min_length=2, max_length=2)]] = None
    time: Optional[TimeFunction] = None            # a dynamic study's factor in time (`wcs.dynamics.time_functions`)

    @model_validator(mode="after")
    def _one_kind(self):
        _exactly_one(self, ("pressure", "traction"))
        return self


class Friction(Frozen):
    slip_limit: Optional[float] = Field(None, **SLIP)
    coefficient: Optional[float] = Field(None, **COEFFICIENT)

    @model_validator(mode="after")
    def _one_law(self):
        _exactly_one(self, ("slip_limit", "coefficient"))
        return self


class Contact(Frozen):
    slave: str
    master: str
    friction: Optional[Friction] = None
    # node-to-node (paired nodes) | mortar (dual mortar) | auto: node-to-node when the sides match
    discretization: Literal["auto", "node-to-node", "mortar"] = "auto"


class Glue(Frozen):
    """Two sides of different bodies tied together (mortar: the slave side follows the master)."""
    slave: str
    master: str


class Thermal(Frozen):
    reference: float = Field(**KELVIN)
    temperature: Annotated[dict[str, Annotated[float, Field(**KELVIN)]], Field(min_length=1)]
    sources: dict[str, Annotated[float, Field(**SOURCE)]] = {}


class RegionSelector(Frozen):
    box: Optional[Rectangle] = None
    disc: Optional[Disc] = None
    polygon: Optional[Polygon] = None
    boundary: Optional[str] = None

    @model_validator(mode="after")
    def _one_selector(self):
        _exactly_one(self, ("box", "disc", "polygon", "boundary"))
        return self


class RegionOfInterest(RegionSelector):
    body: Optional[str] = None


class Refinement(RegionSelector):
    size: float = Field(**FEATURE)


class Mesh(Frozen):
    size: Optional[float] = Field(None, **FEATURE)
    grading: Optional[float] = Field(None, ge=0, le=1e3)
    refine: list[Refinement] = []
    file: Optional[str] = None             # a mesh file (gmsh .msh, ...) instead of shapes
    max_cells: Optional[int] = Field(None, ge=1, le=10**10)   # the resource guard's limit

    @model_validator(mode="after")
    def _size_or_file(self):
        if self.file is None and self.size is None:
            raise ValueError("give `size` (the target element size) or `file` (a mesh file)")
        if self.file is not None and (self.size is not None or self.refine or self.grading is not None
                                      or self.max_cells is not None):
            raise ValueError("a mesh `file` is used as it is: drop `size`, `grading`, `refine` and `max_cells`")
        return self


class Scene(Frozen):
    dimension: int = 2
    plane: Literal["strain", "stress"] = "strain"
    mesh: Mesh
    materials: Annotated[dict[Name, Material], Field(min_length=1)]
    bodies: Annotated[dict[Name, Body], Field(min_length=1)]
    boundaries: dict[Name, Boundary] = {}           # and a GroupBoundary per 1D group of a mesh file
    supports: dict[str, Support] = {}
    loads: dict[str, Load] = {}
    body_forces: dict[str, Annotated[list[Annotated[float, Field(**BODY_FORCE)]],
                                     Field(min_length=2, max_length=2)]] = {}
    contacts: dict[Name, Contact] = {}
    glue: dict[Name, Glue] = {}
    thermal: Optional[Thermal] = None
    regions_of_interest: dict[Name, RegionOfInterest] = {}
    sources: dict[Name, Source] = {}               # a dynamic study's point sources (`wcs.dynamics.sources`)
    absorbing: Optional[Absorbing] = None          # its absorbing boundaries (`wcs.dynamics.absorbing`)

    @field_validator("dimension")
    @classmethod
    def _two_dimensional(cls, dimension):
        if dimension != 2:             # a 3D scene is `wcs.scene.spec3d.Scene` (the loader's choice)
            raise ValueError("the dimension is 2 (plane) or 3")
        return dimension



# ---------------------------------------------------------------- a dynamic study's loads (`wcs.dynamics`)
# Their models are scene keys: a load's time function, point sources with a Ricker wavelet, absorbing
# boundaries; the levels' numbers from them are `wcs.dynamics.time_functions`, `.sources`, `.absorbing`.

TIME = {"ge": 0.0, "le": 1e6}          # a time of a study [s]: from 0 to ~12 days
FACTOR = {"ge": -1e6, "le": 1e6}       # a load factor (keeps factor * load far inside double precision)
MAX_ROWS = 100_000

TimeRow = Annotated[list[float], Field(min_length=2, max_length=2)]


class TimeFunction(Frozen):
    """A load's time function: exactly one of `ramp` (its duration t_r [s]) or `table` (rows [t, factor])."""
    ramp: Optional[float] = Field(None, gt=0, le=TIME["le"])
    table: Optional[Annotated[list[TimeRow], Field(min_length=1, max_length=MAX_ROWS),
                              AfterValidator(lambda rows: check_table(rows))]] = None

    @model_validator(mode="after")
    def _one_kind(self):
        _exactly_one(self, ("ramp", "table"))
        return self


def check_table(rows: list[list[float]]) -> list[list[float]]:
    """The rows, or a ValueError naming the row when a time is outside TIME or the times do not
    strictly increase, or a factor is outside FACTOR (non-finite numbers are refused by the schema)."""
    for i, (t, f) in enumerate(rows):
        if not TIME["ge"] <= t <= TIME["le"]:
            raise ValueError(f"row {i}: the time {t:g} s must be in [{TIME['ge']:g}, {TIME['le']:g}]")
        if not FACTOR["ge"] <= f <= FACTOR["le"]:
            raise ValueError(f"row {i}: the factor {f:g} must be in [{FACTOR['ge']:g}, {FACTOR['le']:g}]")
        if i and t <= rows[i - 1][0]:
            raise ValueError(f"row {i}: the times must increase, but {t:g} s follows {rows[i - 1][0]:g} s")
    return rows


# What of a time function can be uncertain, with its physical range (the loader's address table).
TIME_ADDRESSES = {"loads.<boundary>.time.ramp": {"gt": 0.0, "le": TIME["le"]}}


FORCE = {"ge": -1e22, "le": 1e22}       # [N] (2D: N per unit length); a great quake's forces are ~1e19
MOMENT = {"ge": -1e24, "le": 1e24}      # [N m] (2D: N m per unit length); Mw 9.9 is ~1e24 N m
FREQUENCY = {"gt": 0.0, "le": 1e9}      # [Hz]
DELAY = {"ge": 0.0, "le": 1e6}          # [s]
RICKER_ONSET = 1.0                      # delay * frequency at least: |r(0)| < 1e-3 (the wavelet starts from rest)

ForceVector = Annotated[list[Annotated[float, Field(**FORCE)]], Field(min_length=2, max_length=3)]
MomentRow = Annotated[list[Annotated[float, Field(**MOMENT)]], Field(min_length=2, max_length=3)]


class Ricker(Frozen):
    """The Ricker wavelet of peak frequency `frequency` [Hz] peaking (at 1) at `delay` [s]."""
    frequency: float = Field(**FREQUENCY)
    delay: float = Field(**DELAY)

    @model_validator(mode="after")
    def _starts_from_rest(self):
        check_ricker(self.frequency, self.delay)
        return self


class Wavelet(Frozen):
    ricker: Ricker


class Source(Frozen):
    """A point source: `point`, exactly one of `force` or `moment` (d×d), and its `wavelet`."""
    point: Annotated[list[Coordinate], Field(min_length=2, max_length=3)]
    force: Optional[ForceVector] = None
    moment: Optional[Annotated[list[MomentRow], Field(min_length=2, max_length=3)]] = None
    wavelet: Wavelet

    @model_validator(mode="after")
    def _force_or_moment(self):
        _exactly_one(self, ("force", "moment"))
        d = len(self.point)
        if self.force is not None and len(self.force) != d:
            raise ValueError(f"the force has {len(self.force)} components, the point {d}")
        if self.moment is not None and (len(self.moment) != d or any(len(r) != d for r in self.moment)):
            raise ValueError(f"the moment tensor must be {d}×{d} (the point has {d} coordinates)")
        return self


def check_ricker(frequency: float, delay: float) -> None:
    """ValueError unless delay * frequency >= RICKER_ONSET: an earlier peak cuts the wavelet at
    t = 0, a jump of |r(0)| of the peak (2 % at delay * frequency = 0.7)."""
    if delay * frequency < RICKER_ONSET:
        raise ValueError(f"the delay {delay:g} s is less than {RICKER_ONSET:g}/frequency = {RICKER_ONSET / frequency:g} s: "
                         f"the wavelet would start with a jump of {abs(ricker(0.0, frequency, delay)):.2g} of its "
                         "peak instead of from rest")


def ricker(t, frequency: float, delay: float) -> np.ndarray:
    """r(t) = (1 − 2τ²) exp(−τ²), τ = π f (t − t₀): peak 1 at t = t₀ (so `force` / `moment` is the
    peak value), zero mean; its amplitude spectrum (2/√π)(ν²/f³) exp(−ν²/f²) peaks at ν = f."""
    tau2 = (np.pi * frequency * (np.asarray(t, dtype=float) - delay)) ** 2
    return (1.0 - 2.0 * tau2) * np.exp(-tau2)


# What of a source can be uncertain, with its physical range (the loader's address table).
SOURCE_ADDRESSES = {
    "sources.<s>.point.<i>": LENGTH,
    "sources.<s>.force.<i>": FORCE,
    "sources.<s>.moment.<i>.<j>": MOMENT,
    "sources.<s>.wavelet.ricker.frequency": FREQUENCY,
    "sources.<s>.wavelet.ricker.delay": DELAY,
}


DAMPING = {"gt": 0.0, "le": 1e9}        # α [1/s]


class Layer(Frozen):
    """The seed's damping layer: mass-proportional damping `damping` [1/s] in the cells within
    `thickness` [m] of the named `boundaries`."""
    boundaries: Annotated[list[Name], Field(min_length=1)]
    thickness: float = Field(**FEATURE)
    damping: float = Field(**DAMPING)


class Absorbing(Frozen):
    """A damping `layer`, Lysmer–Kuhlemeyer `dashpots` on named boundaries, or both."""
    layer: Optional[Layer] = None
    dashpots: list[Name] = []

    @model_validator(mode="after")
    def _something(self):
        if self.layer is None and not self.dashpots:
            raise ValueError("give a `layer`, `dashpots` or both")
        for key, names in (("dashpots", self.dashpots), ("layer.boundaries", self.layer.boundaries if self.layer else [])):
            twice = sorted({n for n in names if names.count(n) > 1})
            if twice:
                raise ValueError(f"{key} names boundary '{twice[0]}' twice")
        return self


ABSORBING_ADDRESSES = {"absorbing.layer.thickness": FEATURE, "absorbing.layer.damping": DAMPING}
