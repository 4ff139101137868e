"""Study files: load and validate them, and address the numbers of a scene by dotted path.

`load_study(path_or_mapping)` reads a study file, or takes the mapping YAML would
parse one into, checks it with typed models and cross-reference rules, and
returns a `Study` whose `scene` is plain dicts and lists in the YAML shape,
resolved: scene and material files inlined, region names and defaults filled in.
Every bad input raises `StudyError` naming the file (`<mapping>` for a mapping),
the dotted key path and the fault.

A file a study names (scene, material library, mesh) is found relative to the
folder of the file that names it; the study's own names relative to `base_dir`
when given (the current directory for a mapping). A material library not found
there is looked up among the libraries shipped in the package (`wcs/library/`).

Dotted paths are relative to the scene (`materials.rubber.E`,
`loads.pad_top.traction.1`, ...). `get_path` / `set_path` read and write them.

A Lipschitz friction profile (`uncertain: {contacts.<c>.friction.slip_limit:
{range, lipschitz, points}}`) is `points` parameters named `<path>[0]` ...
`<path>[points-1]`: values of g at equally spaced points along the contact.
`scene_with` stores them as `friction.slip_limit_profile: [g0, ...]` and sets
`friction.slip_limit` to their mean. The slope bound |g[i+1] - g[i]| <= C*ds
needs the contact length (ds = length / (points - 1)), so it is only stored here.
"""
from __future__ import annotations

import copy
import difflib
import hashlib
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal, Optional

import numpy as np
import yaml
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    TypeAdapter,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from .criteria import KINDS
from .errors import StudyError

LIBRARIES = Path(__file__).resolve().parent / "library"     # shipped material libraries
MAPPING = Path("<mapping>")                                     # the file name of a study given as a mapping

# ---------------------------------------------------------------- reading YAML


class _Loader(yaml.SafeLoader):
    """SafeLoader that rejects duplicate keys and reads `1e7` as a number (as YAML 1.2 does)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                if key_node.value in seen:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key '{key_node.value}'", key_node.start_mark)
                seen.add(key_node.value)
        return super().construct_mapping(node, deep)


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def _read_yaml(path: Path) -> tuple[Any, str]:
    """The parsed content and the text of a YAML file; StudyError if unreadable or not YAML."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise StudyError("file not found", file=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise StudyError(f"cannot read the file: {exc}", file=str(path)) from None
    return _parse_yaml(text, path), text


def _parse_yaml(text: str, path: Path) -> Any:
    """The parsed content of YAML text read from `path`; StudyError naming `path` if not YAML."""
    try:
        doc = yaml.load(text, Loader=_Loader)
    except RecursionError:                          # the parser recurses per level
        raise StudyError(f"the file nests deeper than {MAX_NESTING} levels", file=str(path)) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise StudyError(f"YAML syntax error{where}: {exc.problem or exc.context}",
                         file=str(path)) from None
    except yaml.YAMLError as exc:
        raise StudyError(f"YAML syntax error: {exc}", file=str(path)) from None
    if _depth(doc) > MAX_NESTING:
        raise StudyError(f"the file nests deeper than {MAX_NESTING} levels", file=str(path))
    return doc


def _mapping_yaml(mapping: Mapping) -> tuple[Any, str]:
    """A study given as a mapping, as YAML text and parsed back from it: it loads exactly
    as the file with that text would, and the text is what the results record."""
    file = str(MAPPING)
    if _depth(mapping) > MAX_NESTING:
        raise StudyError(f"the mapping nests deeper than {MAX_NESTING} levels", file=file)
    try:
        text = yaml.safe_dump(mapping, sort_keys=False, allow_unicode=True)
    except yaml.YAMLError as exc:
        raise StudyError(f"not YAML data (numbers, strings, booleans, null, lists, mappings): {exc}",
                         file=file) from None
    return _parse_yaml(text, MAPPING), text


def _depth(doc) -> int:
    """Levels of nested mappings and lists (a scalar is level 0), without recursion."""
    deepest, stack, seen = 0, [(doc, 0)], set()
    while stack:
        node, level = stack.pop()
        if isinstance(node, (dict, list)) and (id(node), level) not in seen:   # aliases: once
            seen.add((id(node), level))
            deepest = max(deepest, level + 1)
            if level + 1 > MAX_NESTING:
                break
            stack += [(child, level + 1) for child in (node.values() if isinstance(node, dict) else node)]
    return deepest


def _locate(name: str, src: _Source, key: str, shipped: bool = False) -> Path:
    """A file named at `key`: relative to the referencing file's folder, then (`shipped`)
    among the package's material libraries."""
    places = (src.base / name,) + ((LIBRARIES / name,) if shipped else ())
    for candidate in places:
        if candidate.is_file():
            return candidate
    raise src.error((key,), f"file '{name}' not found (looked for {' and '.join(map(str, places))})")


# ---------------------------------------------------------------- errors


def _did_you_mean(word: str, choices) -> str:
    choices = sorted(str(c) for c in choices)
    close = difflib.get_close_matches(str(word), choices, n=1)
    if close:
        return f" (did you mean '{close[0]}'?)"
    return f" (expected one of: {', '.join(choices)})" if choices else ""


def _fault(err: dict) -> str:
    """A pydantic error in plain words, with the offending value when it is short."""
    if err["type"] == "missing":
        return "required key is missing"
    message = err["msg"].removeprefix("Value error, ").replace("Input should be", "must be")
    message = re.sub(r"^(List|Dictionary) should have (.*) after validation", r"must have \2", message)
    message = re.sub(r" or instance of \w+$", "", message)
    value = err.get("input")
    if err["type"] != "unknown_key" and isinstance(value, (bool, int, float, str, type(None))):
        message += f" (got {value!r})"
    return message


@dataclass(frozen=True)
class _Source:
    """Where a piece of input lives: the file to name, the key path of the piece in it, and
    the folder the names it gives are relative to (default: the file's folder)."""

    file: Path
    prefix: tuple = ()
    folder: Path | None = None

    @property
    def base(self) -> Path:
        return self.file.parent if self.folder is None else self.folder

    def error(self, path, message: str) -> StudyError:
        keys = self.prefix + tuple(path)
        return StudyError(message, file=str(self.file), path=".".join(map(str, keys)) or None)

    def validate(self, schema: TypeAdapter, data, path=()):
        """`data` checked and converted by `schema`; the first fault as a StudyError."""
        try:
            return schema.validate_python(data)
        except ValidationError as exc:
            errors = exc.errors()
            first = errors[0]
            loc = [k for k in first["loc"] if k != "[key]"]
            if first["type"] == "unknown_key":
                loc.append(first["ctx"]["key"])
            more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
            raise self.error(tuple(path) + tuple(loc), _fault(first) + more) from None


# ---------------------------------------------------------------- typed models

# Physical ranges, shared by the models and by the boxes of uncertain data. The bounds lie
# beyond any solid (moduli from gels, ~1e2 Pa, to diamond, 1.2e12 Pa; conductivities from
# aerogels to diamond; expansions of polymers, ~1e-3/K) yet keep every product of the solve
# (u ~ load * length / E) far inside double precision: E = 1e-300 would give u ~ 1e306.
_MODULUS = {"ge": 1.0, "le": 1e13}                 # E, mu [Pa]
_LAME = {"ge": -1e13, "le": 1e17}                  # lambda [Pa] (nu -> 0.5 makes it ~1e3 E)
_POISSON = {"gt": -1, "lt": 0.5}
_CONDUCTIVITY = {"ge": 1e-6, "le": 1e6}           # [W/(m K)]
_EXPANSION = {"ge": -1e-2, "le": 1e-2}            # [1/K]
_WEIGHT = {"ge": 0, "le": 1e7}                     # density_weight [N/m^3]
_STRESS = {"ge": -1e12, "le": 1e12}               # pressure, traction [Pa]
_SLIP = {"ge": 0, "le": 1e12}                      # Tresca slip limit [Pa]
_COEFFICIENT = {"ge": 0, "le": 10}                 # Coulomb friction coefficient
_BODY_FORCE = {"ge": -1e10, "le": 1e10}           # [N/m^3]
_SOURCE = {"ge": -1e12, "le": 1e12}               # heat source [W/m^3]
_LENGTH = {"ge": -1e6, "le": 1e6}                 # coordinates, prescribed displacements [m]
_KELVIN = {"gt": 0, "le": 1e5}
# OpenCASCADE merges points closer than its tolerance (1e-7): sides, radii, edges and mesh
# sizes below FEATURE_MIN fail inside gmsh ("Could not create line")
FEATURE_MIN = 1e-6
_FEATURE = {"ge": FEATURE_MIN, "le": 1e6}
MAX_NESTING = 50                                   # levels of a study file (shapes nest)
MAX_PROFILE_POINTS = 1000

_CONFIG = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


def _valid_name(name: str) -> str:
    if not name or re.search(r"[.\s\[\]]", name):
        raise ValueError("a name may not contain dots, spaces or brackets")
    return name


Name = Annotated[str, AfterValidator(_valid_name)]
Point = Annotated[list[float], Field(min_length=2, max_length=2)]
Coordinate = Annotated[float, Field(**_LENGTH)]
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


Polygon = Annotated[list[XY], Field(min_length=3), AfterValidator(_simple)]


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


class _Strict(BaseModel):
    """A mapping with a fixed set of keys; an unknown key is an error with a hint."""

    model_config = _CONFIG

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data):
        if isinstance(data, dict):
            allowed = [f.alias or name for name, f in cls.model_fields.items()]
            for key in data:
                if key not in allowed:
                    raise PydanticCustomError(
                        "unknown_key", "unknown key '{key}'{hint}",
                        {"key": str(key), "hint": _did_you_mean(key, allowed)})
        return data


class Material(_Strict):
    E: Optional[float] = Field(None, **_MODULUS)
    nu: Optional[float] = Field(None, **_POISSON)
    lam: Optional[float] = Field(None, alias="lambda", **_LAME)
    mu: Optional[float] = Field(None, **_MODULUS)
    conductivity: Optional[float] = Field(None, **_CONDUCTIVITY)
    expansion: Optional[float] = Field(None, **_EXPANSION)
    density_weight: Optional[float] = Field(None, **_WEIGHT)

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
        if self.lam is not None and self.lam + self.mu <= 0:
            raise ValueError("lambda + mu must be > 0 (positive bulk modulus)")
        return self


class Disc(_Strict):
    center: XY
    radius: float = Field(**_FEATURE)


class Shape(_Strict):
    rectangle: Optional[Rectangle] = None
    polygon: Optional[Polygon] = None
    disc: Optional[Disc] = None
    minus: Optional[list[Shape]] = None
    intersect: Optional[list[Shape]] = None

    @model_validator(mode="after")
    def _one_primitive(self):
        _exactly_one(self, ("rectangle", "polygon", "disc"))
        return self


class RegionMesh(_Strict):
    size: float = Field(**_FEATURE)        # target element size inside the region


class Region(_Strict):
    material: str
    shape: Optional[Shape] = None          # required unless the scene's mesh is a file
    name: Optional[Name] = None
    mesh: Optional[RegionMesh] = None


class BodyMesh(_Strict):
    """A body's own mesh sizes: the body is meshed on its own (nodes on curves it shares
    with other bodies do not match theirs: contacts and glue there use mortar)."""
    size: Optional[float] = Field(None, **_FEATURE)
    refine: list["Refinement"] = []


class Body(_Strict):
    regions: Annotated[list[Region], Field(min_length=1)]
    mesh: Optional[BodyMesh] = None


class Boundary(_Strict):
    body: Optional[str] = None
    segment: Optional[Segment] = None
    circle: Optional[Disc] = None
    box: Optional[BoxCorners] = None

    @model_validator(mode="after")
    def _one_selector(self):
        _exactly_one(self, ("segment", "circle", "box"))
        return self


class Support(_Strict):
    u: Optional[Annotated[list[Optional[Coordinate]], Field(min_length=2, max_length=2)]] = None
    normal: Optional[float] = Field(None, **_LENGTH)

    @model_validator(mode="after")
    def _holds_something(self):
        _exactly_one(self, ("u", "normal"))
        if self.u is not None and all(c is None for c in self.u):
            raise ValueError("u: [null, null] holds nothing; give at least one component")
        return self


class Load(_Strict):
    pressure: Optional[float] = Field(None, **_STRESS)
    traction: Optional[Annotated[list[Annotated[float, Field(**_STRESS)]], Field(min_length=2, max_length=2)]] = None

    @model_validator(mode="after")
    def _one_kind(self):
        _exactly_one(self, ("pressure", "traction"))
        return self


class Friction(_Strict):
    slip_limit: Optional[float] = Field(None, **_SLIP)
    coefficient: Optional[float] = Field(None, **_COEFFICIENT)

    @model_validator(mode="after")
    def _one_law(self):
        _exactly_one(self, ("slip_limit", "coefficient"))
        return self


class Contact(_Strict):
    slave: str
    master: str
    friction: Optional[Friction] = None
    # node-to-node (paired nodes) | mortar (dual mortar) | auto: node-to-node when the sides match
    discretization: Literal["auto", "node-to-node", "mortar"] = "auto"


class Glue(_Strict):
    """Two sides of different bodies tied together (mortar: the slave side follows the master)."""
    slave: str
    master: str


class Thermal(_Strict):
    reference: float = Field(**_KELVIN)
    temperature: Annotated[dict[str, Annotated[float, Field(**_KELVIN)]], Field(min_length=1)]
    sources: dict[str, Annotated[float, Field(**_SOURCE)]] = {}


class RegionSelector(_Strict):
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
    size: float = Field(**_FEATURE)


BodyMesh.model_rebuild()
Body.model_rebuild()


class Mesh(_Strict):
    size: Optional[float] = Field(None, **_FEATURE)
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


class Scene(_Strict):
    dimension: int = 2
    plane: Literal["strain", "stress"] = "strain"
    mesh: Mesh
    materials: Annotated[dict[Name, Material], Field(min_length=1)]
    bodies: Annotated[dict[Name, Body], Field(min_length=1)]
    boundaries: dict[Name, Boundary] = {}
    supports: dict[str, Support] = {}
    loads: dict[str, Load] = {}
    body_forces: dict[str, Annotated[list[Annotated[float, Field(**_BODY_FORCE)]],
                                     Field(min_length=2, max_length=2)]] = {}
    contacts: dict[Name, Contact] = {}
    glue: dict[Name, Glue] = {}
    thermal: Optional[Thermal] = None
    regions_of_interest: dict[Name, RegionOfInterest] = {}

    @field_validator("dimension")
    @classmethod
    def _two_dimensional(cls, dimension):
        if dimension != 2:
            raise ValueError("only dimension 2 is supported")
        return dimension


CriterionKind = Literal[tuple(KINDS)]


class Criterion(_Strict):
    name: Name
    kind: CriterionKind
    regions: Annotated[list[str], Field(min_length=1)]
    point: Optional[XY] = None
    direction: Optional[Direction] = None
    sense: Literal["max", "min", "both"] = Field(
        "max", description="which end of the range the search finds: the maximum (the worst "
        "scenario), the minimum (the best), or both")

    @model_validator(mode="after")
    def _options_of_the_kind(self):
        for key in ("point", "direction"):
            if getattr(self, key) is not None and key not in KINDS[self.kind].options:
                raise ValueError(f"'{key}' applies only to kind "
                                 + ", ".join(k for k, v in KINDS.items() if key in v.options))
        return self


# Counts of the search and the solver: a million solves is weeks of work at the sizes wcs
# runs; every count fits the results file's int64 (a budget of 1e30 did not).
MAX_SOLVES = 1_000_000


class _Options(_Strict):
    """Options of the search or the solver: frozen; every field documented with its one default."""

    model_config = ConfigDict(**_CONFIG, frozen=True)

    @classmethod
    def of(cls, options):
        """These options as the model: `options` itself, or a mapping (None: {}) validated by it."""
        return options if isinstance(options, cls) else cls.model_validate(options or {})


class SampleDesign(_Options):
    design: Literal["lhs", "sobol", "vertices", "grid"] = Field(
        "lhs", description="space-filling design of the sample")
    n: int = Field(32, ge=1, le=MAX_SOLVES, description="points of the sample (local: of its "
                   "starting sample; auto: the most of its first sample)")
    seed: int = Field(0, ge=0, le=2**32 - 1, description="seed of every random draw of the search")


class LocalSearch(_Options):
    starts: int = Field(3, ge=1, le=1000, description="best sample points per criterion the local ascent starts from")


class Search(_Options):
    method: Literal["auto", "sample", "local", "global"] = Field("auto", description="search strategy")
    sample: SampleDesign = Field(default_factory=SampleDesign, description="the sample design")
    budget: int = Field(200, ge=1, le=MAX_SOLVES, description="most forward solves of the search")
    local: LocalSearch = Field(default_factory=LocalSearch, description="the local ascent")
    kkt_tol: float = Field(1e-6, gt=0, lt=1, description="relative Frank–Wolfe gap below which a point is "
                           "certified (corner-kkt, local-kkt)")
    safeguard: Optional[int] = Field(None, ge=0, le=MAX_SOLVES, description="points of auto's first sample "
                                     "besides the centre; null: min(2n + 1, sample.n), n the parameters")


class DomainDecomposition(_Options):
    subdomains: int = Field(8, ge=1, le=4096, description="subdomains of the partition")
    pair_size: float = Field(1.0, gt=0, le=100, description="unknowns of the band around a contact "
                             "side, in mean subdomain shares n/subdomains")
    relaxation: Literal["aitken", "anderson"] | Annotated[float, Field(gt=0, le=2)] = Field(
        "aitken", description="update of the successive approximations: Aitken's dynamic ω, "
        "Anderson acceleration, or a fixed ω (1 = the seed)")
    patience: int = Field(8, ge=1, le=10_000, description="steps with contraction q ≥ 1 before \"stagnated\"")
    step: Literal["auto", "newton", "seed", "glued"] = Field(
        "auto", description="outer iteration: interface Newton (S0 + the pairs linearised at the current "
        "active set), the seed's successive steps with S0, or with S0 + the glued pairs; auto: the seed's "
        "where the power estimate of ρ(S0⁻¹ dS_con) at the start is below seed_rho, else Newton")
    seed_rho: float = Field(0.5, gt=0, le=1, description="step auto takes the seed's step below this "
                            "estimate of its contraction ρ(S0⁻¹ dS_con) (margin below 1: the estimate is a "
                            "lower bound, and is taken at the start, not at the solution)")
    rho_steps: int = Field(5, ge=1, le=100, description="power steps of the ρ estimate (each one PCG2 "
                           "solve to 1e-2)")
    pcg_tolerance: Optional[float] = Field(None, gt=0, lt=1, description="relative tolerance of PCG1 "
                                           "(the glued start U⁰); null: max(solver.tolerance, 1e-8)")
    pcg_max_iterations: int = Field(500, ge=1, le=100_000, description="iteration budget of each PCG solve")
    inner_tolerance: Optional[float] = Field(None, gt=0, lt=1, description="floor of PCG2's relative "
                                             "tolerance; null: solver.tolerance / 10")
    forcing: float = Field(0.1, ge=0, le=1, description="PCG2 stops at forcing × the last relative "
                           "increment (inexact inner solves); Newton: the largest Eisenstat–Walker tolerance")
    contact_tolerance: float = Field(1e-10, gt=0, lt=1, description="tolerance of the local contact solves")
    anderson: int = Field(5, ge=1, le=100, description="history of Anderson acceleration, in steps")
    anderson_restart: float = Field(0.0, ge=0, le=1e6, description="clear Anderson's history when the "
                                    "residual grows by this factor; 0: never")
    mixing: float = Field(1.0, gt=0, le=2, description="Anderson's mixing β: the damped map U + β(T(U) − U)")

    @field_validator("relaxation", mode="wrap")
    @classmethod
    def _one_message(cls, value, handler):
        try:
            return handler(value)
        except ValidationError:
            raise ValueError("must be 'aitken', 'anderson' or a fixed ω in (0, 2]") from None


class Solver(_Options):
    method: Literal["auto", "monolithic", "dd", "qp"] = Field(
        "auto", description="contact solver (qp: the cvxpy reference)")
    tolerance: float = Field(1e-8, gt=0, le=1e-2, description="relative tolerance of the contact solve "
                             "(above 1e-2 a \"solved\" state is not a solution)")
    max_iterations: int = Field(200, ge=1, le=100_000, description="iteration budget of the contact solve "
                                "(dd: of the successive approximations)")
    max_fixed_point_iterations: int = Field(100, ge=1, le=100_000, description="most solves of the "
                                            "Coulomb fixed point (slip bound from the last pressures)")
    dd: DomainDecomposition = Field(default_factory=DomainDecomposition, description="the domain decomposition")
    fallback: bool = Field(True, description="a failed dd solve falls back to the monolithic solver (visibly)")


class Limit(_Strict):
    lower: Optional[float] = Field(None, description="the criterion must not fall below it (needs sense min or both)")
    upper: Optional[float] = Field(None, description="the criterion must not exceed it (needs sense max or both)")

    @model_validator(mode="after")
    def _some_bound(self):
        if self.lower is None and self.upper is None:
            raise ValueError("give lower, upper or both")
        if self.lower is not None and self.upper is not None and self.lower > self.upper:
            raise ValueError(f"lower limit {self.lower} is above upper limit {self.upper}")
        return self


DEFAULT_LEVELS = (0.0, 0.25, 0.5, 0.75, 1.0)


def _distinct_levels(levels: list[float]) -> tuple[float, ...]:
    if len(set(levels)) != len(levels):
        raise ValueError("the levels must be distinct")
    return tuple(sorted(levels))


class Fuzzy(_Options):
    levels: Annotated[list[Annotated[float, Field(ge=0, le=1)]], Field(min_length=1),
                      AfterValidator(_distinct_levels)] = Field(
        list(DEFAULT_LEVELS), description="the α-levels whose cuts are searched (membership ≥ α)")


class Sweep(_Strict):
    grid: Annotated[dict[str, Annotated[list[float], Field(min_length=1)]], Field(min_length=1)]


class StudyFile(_Strict):
    study: Optional[Name] = None
    scene: Any = Field(description="inline mapping, or a file name relative to the study file")
    uncertain: dict[str, Any] = {}                       # none: a run evaluates the nominal data
    criteria: list[Criterion] = []                       # none: a warning (a run measures nothing)
    limits: dict[str, Any] = {}                          # a number (an upper limit) or a `Limit`
    fuzzy: Optional[Fuzzy] = None                        # α-levels; default levels when a number is fuzzy
    search: Search = Field(default_factory=Search)
    solver: Solver = Field(default_factory=Solver)
    sweep: Optional[Sweep] = None
    output: Optional[str] = None

    @field_validator("scene")
    @classmethod
    def _mapping_or_file(cls, scene):
        if not isinstance(scene, (dict, str)):
            raise ValueError("must be a mapping (the scene) or the name of a scene file")
        return scene


class FuzzyNumber(_Strict):
    support: Point
    core: Point


class Profile(_Strict):
    range: Optional[Point] = None
    support: Optional[Point] = None
    core: Optional[Point] = None
    lipschitz: float = Field(gt=0)
    points: int = Field(ge=2, le=MAX_PROFILE_POINTS)

    @model_validator(mode="after")
    def _crisp_or_fuzzy(self):
        if (self.range is None) == (self.support is None) or (self.support is None) != (self.core is None):
            raise ValueError("give either range: [lower, upper] or support: [a, b] with core: [c, d]")
        return self


_STUDY = TypeAdapter(StudyFile)
_SCENE = TypeAdapter(Scene)
_PROFILE = TypeAdapter(Profile)
_FUZZY = TypeAdapter(FuzzyNumber)
_LIMIT = TypeAdapter(Limit)
_NUMBER = TypeAdapter(float, config=_CONFIG)
_BOX = TypeAdapter(Point, config=_CONFIG)
_LIBRARY = TypeAdapter(Annotated[dict[Name, Material], Field(min_length=1)], config=_CONFIG)


def _dump(model) -> Any:
    if isinstance(model, BaseModel):
        return model.model_dump(by_alias=True, exclude_none=True)
    return {k: _dump(v) for k, v in model.items()}


# ---------------------------------------------------------------- the scene


def _load_scene(raw, study_src: _Source) -> tuple[dict, _Source, list[tuple[Path, str]]]:
    """The validated scene, where it lives, and the extra files it came from."""
    extra = []
    src = _Source(study_src.file, ("scene",), study_src.folder)
    if isinstance(raw, str):
        path = _locate(raw, study_src, "scene")
        raw, text = _read_yaml(path)
        src = _Source(path)
        extra.append((path, text))
    if isinstance(raw, dict) and isinstance(raw.get("materials"), str):
        raw = dict(raw)
        raw["materials"], library = _load_materials(raw["materials"], src)
        extra.append(library)
    scene = _dump(src.validate(_SCENE, raw))
    if "file" in scene["mesh"]:                # regions come from the file's physical groups
        from .scene.meshfile import prepare_scene
        scene["mesh"]["notes"] = prepare_scene(scene, src.base, src.error)  # popped by load_study
    else:
        _require_shapes(scene, src)
    _name_regions(scene)
    return scene, src, extra


def _require_shapes(scene: dict, src: _Source) -> None:
    for body, spec in scene["bodies"].items():
        for i, region in enumerate(spec["regions"]):
            if "shape" not in region:
                raise src.error(("bodies", body, "regions", i, "shape"),
                                "required key is missing (a region needs a shape unless the "
                                "scene's mesh is a file: `mesh: {file: ...}`)")


def _load_materials(name: str, src: _Source) -> tuple[dict, tuple[Path, str]]:
    path = _locate(name, src, "materials", shipped=True)
    raw, text = _read_yaml(path)
    materials = _dump(_Source(path).validate(_LIBRARY, raw))
    return materials, (path, text)


def _name_regions(scene: dict) -> None:
    for body, spec in scene["bodies"].items():
        for i, region in enumerate(spec["regions"]):
            region.setdefault("name", f"{body}_{i}")


def _region_names(scene: dict) -> list[str]:
    return [r["name"] for spec in scene["bodies"].values() for r in spec["regions"]]


def _require(name: str, known, what: str, src: _Source, path) -> None:
    if name not in known:
        raise src.error(path, f"unknown {what} '{name}'{_did_you_mean(name, known)}")


def _check_regions(scene: dict, src: _Source) -> None:
    """Materials exist; region names are unique and differ from other bodies' names."""
    seen = set()
    for body, spec in scene["bodies"].items():
        for i, region in enumerate(spec["regions"]):
            path = ("bodies", body, "regions", i)
            _require(region["material"], scene["materials"], "material", src, path + ("material",))
            name = region["name"]
            if name in seen:
                raise src.error(path + ("name",), f"region name '{name}' is used twice")
            own_name = name == body and len(spec["regions"]) == 1
            if name in scene["bodies"] and not own_name:
                raise src.error(path + ("name",), f"region name '{name}' is also a body's name")
            seen.add(name)


def _check_references(scene: dict, src: _Source) -> None:
    """Every boundary, body and region a scene key refers to exists."""
    bodies, boundaries = scene["bodies"], scene["boundaries"]
    parts = set(bodies) | set(_region_names(scene))
    for name, spec in boundaries.items():
        if "body" in spec:
            _require(spec["body"], bodies, "body", src, ("boundaries", name, "body"))
    for block in ("supports", "loads"):
        for name in scene[block]:
            _require(name, boundaries, "boundary", src, (block, name))
    for name in scene["body_forces"]:
        _require(name, parts, "body or region", src, ("body_forces", name))
    for i, refinement in enumerate(scene["mesh"]["refine"]):
        if "boundary" in refinement:
            _require(refinement["boundary"], boundaries, "boundary", src, ("mesh", "refine", i, "boundary"))
    for body, spec in bodies.items():
        for i, refinement in enumerate((spec.get("mesh") or {}).get("refine", [])):
            if "boundary" in refinement:
                _require(refinement["boundary"], boundaries, "boundary", src,
                         ("bodies", body, "mesh", "refine", i, "boundary"))
        if "file" in scene["mesh"]:
            if "mesh" in spec:
                raise src.error(("bodies", body, "mesh"), "the scene's mesh is a file: a body "
                                "cannot have its own mesh sizes")
            for i, region in enumerate(spec["regions"]):
                if "mesh" in region:
                    raise src.error(("bodies", body, "regions", i, "mesh"), "the scene's mesh is a "
                                    "file: a region cannot have its own mesh size")
    for name, roi in scene["regions_of_interest"].items():
        path = ("regions_of_interest", name)
        if "boundary" in roi:
            _require(roi["boundary"], boundaries, "boundary", src, path + ("boundary",))
        if "body" in roi:
            _require(roi["body"], bodies, "body", src, path + ("body",))


def _check_contacts(scene: dict, src: _Source) -> None:
    """Both sides of a contact (or a glued interface) are boundaries, of two different
    bodies when they say which; a side is not both contact and glue."""
    boundaries = scene["boundaries"]
    glued = {}
    for name, glue in scene.get("glue", {}).items():
        for side in ("slave", "master"):
            glued.setdefault(glue[side], name)
    for name, contact in scene["contacts"].items():
        for side in ("slave", "master"):
            if contact[side] in glued:
                raise src.error(("contacts", name, side), f"boundary '{contact[side]}' is glued "
                                f"(glue '{glued[contact[side]]}'); a side is either in contact or glued")
    blocks = [("contacts", n, c) for n, c in scene["contacts"].items()]
    blocks += [("glue", n, g) for n, g in scene.get("glue", {}).items()]
    for block, name, contact in blocks:
        path = (block, name)
        for side in ("slave", "master"):
            _require(contact[side], boundaries, "boundary", src, path + (side,))
        slave, master = boundaries[contact["slave"]], boundaries[contact["master"]]
        if contact["slave"] == contact["master"]:
            raise src.error(path + ("master",), "slave and master are the same boundary")
        if "body" in slave and slave.get("body") == master.get("body"):
            raise src.error(path + ("master",),
                            f"slave and master both belong to body '{slave['body']}'; "
                            f"a {'contact' if block == 'contacts' else 'glue'} joins two different bodies")


def _check_thermal(scene: dict, src: _Source) -> list[str]:
    """Thermal references exist and used materials conduct; notes on materials without expansion."""
    thermal = scene.get("thermal")
    if thermal is None:
        return []
    for name in thermal["temperature"]:
        _require(name, scene["boundaries"], "boundary", src, ("thermal", "temperature", name))
    parts = set(scene["bodies"]) | set(_region_names(scene))
    for name in thermal["sources"]:
        _require(name, parts, "body or region", src, ("thermal", "sources", name))
    used = dict.fromkeys(r["material"] for b in scene["bodies"].values() for r in b["regions"])
    notes = []
    for name in used:
        material = scene["materials"][name]
        if "conductivity" not in material:
            raise src.error(("materials", name),
                            "needs 'conductivity' because the scene has a thermal block")
        if "expansion" not in material:
            notes.append(f"material '{name}' has no 'expansion': no thermal strain in it")
    return notes


# ---------------------------------------------------------------- mesh size and resources

MIN_CELLS_ALONG = 4     # a mesh size gives at least this many cells along the longest side


def _check_mesh(scene: dict, src: _Source) -> float | None:
    """The estimated cell count (wcs.scene.estimate) of a scene meshed from shapes; StudyError
    when it exceeds `mesh.max_cells`, or when a mesh size leaves fewer than MIN_CELLS_ALONG
    cells along the longest side of the scene (or of a body with its own size)."""
    if "file" in scene["mesh"]:
        return None
    from .scene.estimate import DEFAULT_MAX_CELLS, estimate_cells, shape_box
    boxes = {b: [shape_box(r["shape"]) for r in spec["regions"]] for b, spec in scene["bodies"].items()}
    sizes = [(("mesh", "size"), scene["mesh"]["size"], "the scene", sum(boxes.values(), []))]
    sizes += [(("bodies", b, "mesh", "size"), spec["mesh"]["size"], f"body '{b}'", boxes[b])
              for b, spec in scene["bodies"].items() if (spec.get("mesh") or {}).get("size")]
    for where, h, what, bx in sizes:
        longest = max(max(b[2] for b in bx) - min(b[0] for b in bx), max(b[3] for b in bx) - min(b[1] for b in bx))
        if h > longest / MIN_CELLS_ALONG:
            raise src.error(where, f"size {h:g} leaves fewer than {MIN_CELLS_ALONG} cells along the longest "
                                   f"side of {what} ({longest:.3g}): P1 cells that coarse do not resolve the fields")
    cells, path = estimate_cells(scene)
    limit = scene["mesh"].get("max_cells", DEFAULT_MAX_CELLS)
    if cells > limit:
        raise src.error(tuple(path.split(".")), f"the mesh would have about {cells:.3g} cells "
                        f"({cells:.3g} unknowns), more than mesh.max_cells = {limit:g} (this size contributes "
                        "most); coarsen the mesh or raise `mesh.max_cells`")
    return cells


LOCKING_NU = 0.45       # P1 triangles lock as nu -> 0.5
NO_CRITERIA = "no criteria: `run` and `sweep` solve but measure nothing (`solve` writes the fields)"


def _locking_warnings(scene: dict, uncertain: list[dict]) -> list[str]:
    """A warning per material whose Poisson ratio (nominal or anywhere in its box) is >= LOCKING_NU:
    P1 triangles lock (Hertz peak-pressure error 2 % at nu = 0.45, 8 % at 0.49, 135 % at 0.4999)."""
    box = {e["path"]: (e["lower"], e["upper"]) for e in uncertain}
    used = dict.fromkeys(r["material"] for b in scene["bodies"].values() for r in b["regions"])
    out = []
    for name in used:
        m = scene["materials"][name]
        if "nu" in m:
            top = box.get(f"materials.{name}.nu", (m["nu"], m["nu"]))[1]
        else:                                      # nu = lambda / (2 (lambda + mu)), largest at max lambda, min mu
            lam = box.get(f"materials.{name}.lambda", (m["lambda"], m["lambda"]))[1]
            mu = box.get(f"materials.{name}.mu", (m["mu"], m["mu"]))[0]
            top = lam / (2 * (lam + mu))
        if top >= LOCKING_NU:
            out.append(f"material '{name}': Poisson ratio up to {top:.4g} (>= {LOCKING_NU}): P1 triangles "
                       "lock as nu -> 0.5: results there are too stiff (wcs's Hertz benchmark: peak-pressure "
                       "error 2 % at 0.45, 8 % at 0.49, 135 % at 0.4999)")
    return out


# ---------------------------------------------------------------- dotted paths


def get_path(scene: dict, path: str):
    """The value at a dotted path of the scene; KeyError (with a hint) if there is none."""
    node = scene
    keys = path.split(".")
    for depth, key in enumerate(keys):
        node = _child(node, key, ".".join(keys[:depth]) or "the scene")
    return node


def set_path(scene: dict, path: str, value) -> None:
    """Put `value` at a dotted path of the scene (in place); KeyError if its parent is missing."""
    parent, _, key = path.rpartition(".")
    node = get_path(scene, parent) if parent else scene
    if isinstance(node, list) and key.isdigit() and int(key) < len(node):
        node[int(key)] = value
    elif isinstance(node, dict):
        node[key] = value
    else:
        raise KeyError(f"cannot set '{key}' under '{parent}'")


def _child(node, key: str, where: str):
    if isinstance(node, dict):
        if key in node:
            return node[key]
        raise KeyError(f"no '{key}' under '{where}'{_did_you_mean(key, node)}")
    if isinstance(node, list) and key.isdigit() and int(key) < len(node):
        return node[int(key)]
    raise KeyError(f"no '{key}' under '{where}'")


# What can be uncertain (or swept), each with its physical range.
# `<i>` is a vector component (0 or 1), any other `<...>` a name.
_ADDRESSES = {
    "materials.<m>.E": _MODULUS,
    "materials.<m>.nu": _POISSON,
    "materials.<m>.lambda": _LAME,  # lambda + mu > 0 is checked on the pair
    "materials.<m>.mu": _MODULUS,
    "materials.<m>.conductivity": _CONDUCTIVITY,
    "materials.<m>.expansion": _EXPANSION,
    "materials.<m>.density_weight": _WEIGHT,
    "loads.<boundary>.pressure": _STRESS,
    "loads.<boundary>.traction.<i>": _STRESS,
    "body_forces.<body or region>.<i>": _BODY_FORCE,
    "supports.<boundary>.u.<i>": _LENGTH,
    "supports.<boundary>.normal": _LENGTH,
    "contacts.<c>.friction.slip_limit": _SLIP,
    "contacts.<c>.friction.coefficient": _COEFFICIENT,
    "thermal.reference": _KELVIN,
    "thermal.temperature.<boundary>": _KELVIN,
    "thermal.sources.<body or region>": _SOURCE,
}
_PROFILE_ADDRESS = "contacts.<c>.friction.slip_limit"


def _address(path: str) -> str | None:
    """The `_ADDRESSES` pattern a dotted path matches, or None."""
    keys = path.split(".")
    for pattern in _ADDRESSES:
        parts = pattern.split(".")
        if len(parts) == len(keys) and all(map(_matches, parts, keys)):
            return pattern
    return None


def _matches(part: str, key: str) -> bool:
    if part == "<i>":
        return key.isdigit()
    return part.startswith("<") or part == key


def _in_range(value: float, bounds: dict) -> bool:
    return ((value > bounds["gt"]) if "gt" in bounds else True) and \
        ((value >= bounds["ge"]) if "ge" in bounds else True) and \
        ((value < bounds["lt"]) if "lt" in bounds else True) and \
        ((value <= bounds["le"]) if "le" in bounds else True)


def _range_text(bounds: dict) -> str:
    words = {"gt": ">", "ge": ">=", "lt": "<", "le": "<="}
    return " and ".join(f"{words[k]} {v:g}" for k, v in bounds.items())


def _nominal_number(scene: dict, path: str, src: _Source, where) -> float:
    """The scene's number at an addressable path, or a StudyError at `where`."""
    if _address(path) is None:
        forms = ", ".join(_ADDRESSES)
        raise src.error(where, f"'{path}' is not a number that can vary; these can: {forms}")
    try:
        value = get_path(scene, path)
    except KeyError as exc:
        raise src.error(where, f"the scene has no number at '{path}': {exc.args[0]}") from None
    if value is None:
        raise src.error(where, f"'{path}' is null in the scene (a free component), not a number")
    return value


def _check_values(path: str, values, src: _Source, where) -> None:
    bounds = _ADDRESSES[_address(path)]
    for value in values:
        if not _in_range(value, bounds):
            raise src.error(where, f"{value!r} is outside the physical range of '{path}' "
                                   f"({_range_text(bounds)})")


# ---------------------------------------------------------------- uncertain data, sweep


def _parse_uncertain(doc: dict, scene: dict, src: _Source) -> list[dict]:
    """The boxes of `uncertain:` in file order, each checked against the scene."""
    entries = [_parse_box(path, spec, scene, src) for path, spec in doc.items()]
    _check_bulk_modulus(entries, scene, src)
    return entries


def _parse_box(path: str, spec, scene: dict, src: _Source) -> dict:
    where = ("uncertain", path)
    nominal = _nominal_number(scene, path, src, where)
    if isinstance(spec, dict) and not {"range", "lipschitz", "points"} & set(spec):
        fuzzy = src.validate(_FUZZY, spec, where)
        entry = {"path": path, "lower": fuzzy.support[0], "upper": fuzzy.support[1], "core": list(fuzzy.core)}
    elif isinstance(spec, dict):
        if _address(path) != _PROFILE_ADDRESS:
            raise src.error(where, "a {range, lipschitz, points} profile is only allowed "
                                   f"on {_PROFILE_ADDRESS}")
        profile = src.validate(_PROFILE, spec, where)
        bounds = profile.range or profile.support
        entry = {"path": path, "lower": bounds[0], "upper": bounds[1],
                 "lipschitz": profile.lipschitz, "points": profile.points}
        if profile.core is not None:
            entry["core"] = list(profile.core)
    elif isinstance(spec, list):
        lower, upper = src.validate(_BOX, spec, where)
        entry = {"path": path, "lower": lower, "upper": upper}
    else:
        raise src.error(where, "must be [lower, upper], {support: [a, b], core: [c, d]} or "
                               "{range: [lower, upper], lipschitz, points}")
    if entry["lower"] > entry["upper"]:
        raise src.error(where, f"lower bound {entry['lower']} is above upper bound {entry['upper']}")
    _check_values(path, (entry["lower"], entry["upper"]), src, where)
    if "core" in entry:
        c, d = entry["core"]
        if not entry["lower"] <= c <= d <= entry["upper"]:
            raise src.error(where + ("core",), f"the core [{c}, {d}] must be an interval inside the "
                                               f"support [{entry['lower']}, {entry['upper']}]")
        if not c <= nominal <= d:
            raise src.error(where, f"the scene's value {nominal} lies outside the core [{c}, {d}] "
                                   "(the nominal data must have membership 1)")
    elif not entry["lower"] <= nominal <= entry["upper"]:
        raise src.error(where, f"the scene's value {nominal} lies outside the box "
                               f"[{entry['lower']}, {entry['upper']}]")
    return entry


def _check_bulk_modulus(entries: list[dict], scene: dict, src: _Source) -> None:
    """Lame boxes keep lambda + mu > 0 at their lowest corner."""
    lowest = {e["path"]: e["lower"] for e in entries}
    for name, material in scene["materials"].items():
        if "lambda" not in material:
            continue
        lam_path, mu_path = f"materials.{name}.lambda", f"materials.{name}.mu"
        if lowest.get(lam_path, material["lambda"]) + lowest.get(mu_path, material["mu"]) <= 0:
            where = lam_path if lam_path in lowest else mu_path
            raise src.error(("uncertain", where), "the box allows lambda + mu <= 0 "
                                                  "(the bulk modulus must stay positive)")


def _check_sweep(sweep: dict | None, scene: dict, src: _Source) -> None:
    for path, values in (sweep or {}).get("grid", {}).items():
        where = ("sweep", "grid", path)
        _nominal_number(scene, path, src, where)
        _check_values(path, values, src, where)


# ---------------------------------------------------------------- criteria, limits


def _check_criteria(criteria: list[dict], scene: dict, src: _Source) -> None:
    names = set()
    for i, criterion in enumerate(criteria):
        if criterion["name"] in names:
            raise src.error(("criteria", i, "name"), f"criterion name '{criterion['name']}' is used twice")
        names.add(criterion["name"])
        for j, roi in enumerate(criterion["regions"]):
            _require(roi, scene["regions_of_interest"], "region of interest", src,
                     ("criteria", i, "regions", j))
        needs = KINDS[criterion["kind"]].needs
        if needs == "thermal" and "thermal" not in scene:
            raise src.error(("criteria", i, "kind"), f"{criterion['kind']} needs a thermal block in the scene")
        if needs == "contacts" and not scene["contacts"]:
            raise src.error(("criteria", i, "kind"), f"{criterion['kind']} needs a contact in the scene")


def _split_limits(limits: dict, criteria: list[dict], src: _Source) -> tuple[dict, dict]:
    """(upper limits, lower limits) by criterion name. A bound is checked against the end of the
    range the criterion's search finds: an upper limit needs sense max or both, a lower one min
    or both (otherwise the verdict would read a value nobody searched for)."""
    senses = {c["name"]: c.get("sense", "max") for c in criteria}
    upper, lower = {}, {}
    for name, limit in limits.items():
        _require(name, list(senses), "criterion", src, ("limits", name))
        if isinstance(limit, dict):
            limit = src.validate(_LIMIT, limit, ("limits", name))
            bounds = {k: v for k, v in (("lower", limit.lower), ("upper", limit.upper)) if v is not None}
        else:
            bounds = {"upper": src.validate(_NUMBER, limit, ("limits", name))}
        for side, value in bounds.items():
            needs = "max" if side == "upper" else "min"
            if senses[name] not in (needs, "both"):
                where = ("limits", name) if isinstance(limit, float) else ("limits", name, side)
                raise src.error(where, f"{'an' if side == 'upper' else 'a'} {side} limit needs the {'maximum' if needs == 'max' else 'minimum'} "
                                       f"of '{name}': give the criterion sense: {needs} or both "
                                       f"(it is {senses[name]})")
            (upper if side == "upper" else lower)[name] = value
    return upper, lower


# ---------------------------------------------------------------- fuzzy admissible sets


def _levels(top: StudyFile, uncertain: list[dict]) -> tuple[float, ...] | None:
    """The α-levels of a fuzzy study (None: a crisp one, no `fuzzy:` and no fuzzy number)."""
    if top.fuzzy is not None:
        return tuple(top.fuzzy.levels)
    return DEFAULT_LEVELS if any("core" in e for e in uncertain) else None


def alpha_cut(study: "Study", alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """The α-cut of the admissible set, the box (lower, upper) in parameter order: each fuzzy
    number {support: [a, b], core: [c, d]} gives [a + α(c − a), b − α(b − d)] (exactly the core at
    α = 1 and the support at α = 0), a crisp box itself at every level. The cuts are nested:
    the rounded formula is monotone in α."""
    lower, upper = [], []
    for entry in study.uncertain:
        a, b = entry["lower"], entry["upper"]
        c, d = entry.get("core", (a, b))
        lo = c if alpha == 1 else a if alpha == 0 else min(max(a + alpha * (c - a), a), c)
        hi = d if alpha == 1 else b if alpha == 0 else max(min(b - alpha * (b - d), b), d)
        count = entry.get("points", 1)
        lower += [lo] * count
        upper += [hi] * count
    return np.array(lower, dtype=float), np.array(upper, dtype=float)


# ---------------------------------------------------------------- the study


@dataclass(frozen=True)
class Parameters:
    """The uncertain numbers as one vector: names (dotted paths) and the box."""

    names: list[str]
    lower: np.ndarray
    upper: np.ndarray

    def __len__(self) -> int:
        return len(self.names)


def _parameters(uncertain: list[dict]) -> Parameters:
    names, lower, upper = [], [], []
    for entry in uncertain:
        if "points" in entry:
            names += [f"{entry['path']}[{i}]" for i in range(entry["points"])]
        else:
            names.append(entry["path"])
        count = entry.get("points", 1)
        lower += [entry["lower"]] * count
        upper += [entry["upper"]] * count
    return Parameters(names, np.array(lower, dtype=float), np.array(upper, dtype=float))


@dataclass
class Study:
    """A validated study. `scene` is resolved plain data in the YAML shape."""

    name: str
    file: Path                                          # Path("<mapping>") for a study given as a mapping
    text: str
    sha256: str
    scene: dict
    uncertain: list[dict]
    criteria: list[dict]
    limits: dict                                        # criterion -> upper limit
    search: Search
    solver: Solver
    sweep: dict | None
    output: str
    parameters: Parameters
    notes: list[str]
    warnings: list[str] = field(default_factory=list)   # results to distrust (e.g. P1 locking)
    estimated_cells: float | None = None                # before meshing; None for a mesh file
    lower_limits: dict = field(default_factory=dict)    # criterion -> lower limit
    levels: tuple[float, ...] | None = None             # α-levels of a fuzzy study, ascending; None: crisp
    _evaluator: Any = field(default=None, repr=False, compare=False)

    def evaluate(self, values, gradients: bool = False):
        """One forward solve at a data vector (or {dotted path: value}); the mesh and the
        assembled model are built on the first call and reused. With `gradients`, the
        evaluation also carries dΦ/dx of every criterion (adjoint)."""
        from .evaluation import Evaluator
        if self._evaluator is None:
            self._evaluator = Evaluator(self)
        return self._evaluator.evaluate(values, gradients=gradients)

    def nominal(self) -> np.ndarray:
        """The scene's own values in parameter order (a profile repeats the constant value)."""
        values = []
        for entry in self.uncertain:
            values += [get_path(self.scene, entry["path"])] * entry.get("points", 1)
        return np.array(values, dtype=float)


def _recorded_text(base: Path, text: str, extra: list[tuple[Path, str]]) -> str:
    """The study text followed by each file it pulled in (named relative to `base`; a shipped
    library by its name, so the record does not depend on where wcs is installed), as
    further YAML documents."""
    for path, more in extra:
        shipped = path.resolve().parent == LIBRARIES.resolve()
        name = f"shipped library {path.name}" if shipped else os.path.relpath(path, base)
        text = f"{text.rstrip()}\n---\n# {name}\n{more}"
    return text


def load_study(path_or_mapping, base_dir=None) -> Study:
    """Read and validate a study file, or a study given as the mapping its YAML parses to;
    StudyError names the file (`<mapping>`), key path and fault. The files the study names
    are relative to `base_dir` (default: the study file's folder; for a mapping, the current
    directory)."""
    if isinstance(path_or_mapping, Mapping):
        file, folder = MAPPING, Path.cwd()
        doc, text = _mapping_yaml(path_or_mapping)
    else:
        file = Path(path_or_mapping)
        folder = file.parent
        doc, text = _read_yaml(file)
    src = _Source(file, (), folder if base_dir is None else Path(base_dir))
    if not isinstance(doc, dict):
        got = "an empty file" if doc is None else type(doc).__name__
        raise src.error((), f"a study file is a mapping of keys (got {got})")
    top = src.validate(_STUDY, doc)
    scene, scene_src, extra = _load_scene(top.scene, src)
    _check_regions(scene, scene_src)
    _check_references(scene, scene_src)
    _check_contacts(scene, scene_src)
    notes = scene["mesh"].pop("notes", []) + _check_thermal(scene, scene_src)
    cells = _check_mesh(scene, scene_src)
    uncertain = _parse_uncertain(top.uncertain, scene, src)
    criteria = [_dump(c) for c in top.criteria]
    _check_criteria(criteria, scene, src)
    upper_limits, lower_limits = _split_limits(top.limits, criteria, src)
    sweep = _dump(top.sweep) if top.sweep else None
    _check_sweep(sweep, scene, src)
    name = top.study or ("study" if file is MAPPING else file.stem)
    text = _recorded_text(src.base, text, extra)
    return Study(
        name=name, file=file, text=text, sha256=hashlib.sha256(text.encode()).hexdigest(),
        scene=scene, uncertain=uncertain, criteria=criteria, limits=upper_limits,
        search=top.search, solver=top.solver, sweep=sweep,
        output=top.output or f"results/{name}.nc", parameters=_parameters(uncertain), notes=notes,
        warnings=_locking_warnings(scene, uncertain) + ([] if criteria else [NO_CRITERIA]), estimated_cells=cells,
        lower_limits=lower_limits, levels=_levels(top, uncertain),
    )


# ---------------------------------------------------------------- applying data


def scene_with(study: Study, values) -> dict:
    """A deep copy of the scene with data applied.

    `values` is a vector in the order of `study.parameters`, or a mapping from
    dotted path to value: a parameter name (`...slip_limit[2]`), an uncertain
    path (a profile takes one value for all points or a list of `points`
    values), or any other addressable number of the scene (e.g. a sweep path).
    Parameters a mapping leaves out keep their nominal value.
    """
    if isinstance(values, Mapping):
        x, others = _split_mapping(study, values)
    else:
        x, others = np.asarray(values, dtype=float), {}
    if x.shape != (len(study.parameters),):
        raise ValueError(f"expected {len(study.parameters)} values, got shape {x.shape}")
    scene = copy.deepcopy(study.scene)
    slices = _entry_slices(study)
    for entry in study.uncertain:
        _apply(scene, entry, x[slices[entry["path"]]])
    for path, value in others.items():
        set_path(scene, path, value)
    return scene


def _apply(scene: dict, entry: dict, chunk: np.ndarray) -> None:
    if "points" in entry:
        set_path(scene, entry["path"] + "_profile", [float(v) for v in chunk])
        set_path(scene, entry["path"], float(np.mean(chunk)))
    else:
        set_path(scene, entry["path"], float(chunk[0]))


def parameter_vector(study: Study, values) -> np.ndarray:
    """The parameter vector of a data set given as a vector or a mapping (nominal where absent)."""
    if isinstance(values, Mapping):
        return _split_mapping(study, values)[0]
    x = np.asarray(values, dtype=float)
    if x.shape != (len(study.parameters),):
        raise StudyError(f"expected a vector of {len(study.parameters)} parameters "
                         f"({', '.join(study.parameters.names)}), got shape {x.shape}", file=str(study.file))
    return x


def _split_mapping(study: Study, values: Mapping) -> tuple[np.ndarray, dict]:
    """The parameter vector (nominal where not given) and the other addressed numbers."""
    x = study.nominal()
    index = {name: i for i, name in enumerate(study.parameters.names)}
    slices = _entry_slices(study)
    others = {}
    src = _Source(study.file)
    for path, value in values.items():
        if path in index:
            x[index[path]] = value
        elif path in slices:
            x[slices[path]] = value
        else:
            _nominal_number(study.scene, path, src, ("values", path))
            others[path] = float(value)
    return x, others


def _entry_slices(study: Study) -> dict[str, slice]:
    slices, start = {}, 0
    for entry in study.uncertain:
        count = entry.get("points", 1)
        slices[entry["path"]] = slice(start, start + count)
        start += count
    return slices
