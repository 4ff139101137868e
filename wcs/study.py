"""Study files: load and validate them, and address the numbers of a scene by dotted path.

`load_study(path_or_mapping)` reads a study file, or takes the mapping YAML would
parse one into, checks it with typed models and cross-reference rules, and
returns a frozen `Study` whose `scene` is the frozen `wcs.scene.spec.Scene`, resolved:
scene and material files inlined, region names and defaults filled in. The criteria,
the sweep and the uncertain entries are frozen objects too: nothing downstream of
loading reads a dict.
Every bad input raises `StudyError` naming the file (`<mapping>` for a mapping),
the dotted key path and the fault.

A file a study names (scene, material library, mesh) is found relative to the
folder of the file that names it; the study's own names relative to `base_dir`
when given (the current directory for a mapping). A material library not found
there is looked up among the libraries shipped in the package (`wcs/library/`).

Dotted paths are relative to the scene (`materials.rubber.E`,
`loads.pad_top.traction.1`, ...); `get_path` reads them (a key is a field's name as the
file writes it, `lambda` included).

A Lipschitz friction profile (`uncertain: {contacts.<c>.friction.slip_limit:
{range, lipschitz, points}}`) is `points` parameters named `<path>[0]` ...
`<path>[points-1]`: values of g at equally spaced points along the contact
(`wcs.coefficients` interpolates them onto the contact nodes). The slope bound |g[i+1] - g[i]| <= C*ds
needs the contact length (ds = length / (points - 1)), so it is only stored here. In 3D a
profile is a Lipschitz function on the contact surface: `points: [nu, nv]` values on a grid over
the slave face in its two principal directions (`wcs.contact.frame`), bilinear in between,
named `<path>[i,j]`, the slope bound in both directions.
"""
from __future__ import annotations

import hashlib
import math
import os
import re
import stat
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Annotated, Any, Literal, Optional

import numpy as np
import yaml
from pydantic import (
    AfterValidator,
    BaseModel,
    Field,
    TypeAdapter,
    ValidationError,
    field_validator,
    model_validator,
)

from .choose import MeshFacts, mesh_size
from .criteria import KINDS
from .errors import StudyError
from .options import CONFIG as _CONFIG
from .options import MAX_SOLVES
from .options import DomainDecomposition, LocalSearch, Options, SampleDesign, Search, Solver  # noqa: F401 - the schema's blocks
from .options import Strict as _Strict
from .options import did_you_mean as _did_you_mean
from .scene import spec3d
from .scene.estimate import (bytes_per_cell, DEFAULT_MAX_CELLS, ESTIMATE_EXCESS, estimate_cells, estimate_cells3d, machine_memory,
                             shape_box, solid_box)
from .scene.spec import (BODY_FORCE, COEFFICIENT, CONDUCTIVITY, EXPANSION, KELVIN, LAME, LENGTH, MAX_NAME, MODULUS,
                         POISSON, RIGID_HINT, SLIP, SOURCE, STRESS, WEIGHT, Coordinate, Frozen, GroupBoundary, Material,
                         Name, Point, Scene, lame_admissible)

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


MAX_FILE_BYTES = 4 * 2**20     # a study, scene or material file: a few hundred lines at most


def _read_yaml(path: Path) -> tuple[Any, str]:
    """The parsed content and the text of a YAML file; StudyError if it is not a regular file
    (a device or a FIFO never ends), is larger than MAX_FILE_BYTES, is unreadable or is not YAML."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)        # a FIFO: no wait for a writer
        _check_regular(fd, path)
        with os.fdopen(fd, "rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
        if len(data) > MAX_FILE_BYTES:                        # grew while read
            raise StudyError(f"the file has more than the {MAX_FILE_BYTES} bytes a study, scene or material "
                             "file may have", file=str(path))
        text = data.decode("utf-8")
    except FileNotFoundError:
        raise StudyError("file not found", file=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise StudyError(f"cannot read the file: {exc}", file=str(path)) from None
    return _parse_yaml(text, path), text


def _check_regular(fd: int, path: Path) -> None:
    """StudyError (`fd` closed) unless `fd` is a regular file of at most MAX_FILE_BYTES."""
    info = os.fstat(fd)
    fault = None
    if not stat.S_ISREG(info.st_mode):
        kind = ("a directory" if stat.S_ISDIR(info.st_mode) else "a FIFO" if stat.S_ISFIFO(info.st_mode)
                else "a device" if stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode) else "a socket")
        fault = f"not a regular file ({kind}): study, scene and material files are YAML files"
    elif info.st_size > MAX_FILE_BYTES:
        fault = (f"the file has {info.st_size} bytes, more than the {MAX_FILE_BYTES} a study, scene or material "
                 "file may have")
    if fault is not None:
        os.close(fd)
        raise StudyError(fault, file=str(path))


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
    if _expanded_size(doc) > MAX_NODES:
        raise StudyError(f"the file holds more than {MAX_NODES} values once its aliases (*name) are expanded",
                         file=str(path))
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


def _expanded_size(doc) -> int:
    """Values (scalars, lists, mappings) of the document with every alias expanded: an alias
    repeats its anchor's whole subtree, so a few lines can stand for 1e7 shapes. Each distinct
    node is counted once and its count reused (bounded time, depth checked by `_depth` first)."""
    sizes: dict[int, int] = {}

    def size(node) -> int:
        if not isinstance(node, (dict, list)):
            return 1
        if id(node) not in sizes:
            sizes[id(node)] = 1 + sum(map(size, node.values() if isinstance(node, dict) else node))
        return sizes[id(node)]
    return size(doc)


def _locate(name: str, src: _Source, key: str, shipped: bool = False) -> Path:
    """A file named at `key`: relative to the referencing file's folder, then (`shipped`)
    among the package's material libraries."""
    places = (src.base / name,) + ((LIBRARIES / name,) if shipped else ())
    for candidate in places:
        if candidate.exists():                  # not a regular file: `_read_yaml` says what it is
            return candidate
    raise src.error((key,), f"file '{name}' not found (looked for {' and '.join(map(str, places))})")


# ---------------------------------------------------------------- errors


def _fault(err: dict) -> str:
    """A pydantic error in plain words, with the offending value when it is short."""
    if err["type"] == "missing":
        return "required key is missing"
    message = err["msg"].removeprefix("Value error, ").replace("Input should be", "must be")
    message = re.sub(r"^(List|Dictionary) should have (.*) after validation", r"must have \2", message)
    message = re.sub(r" or instance of \w+$", "", message)
    value = err.get("input")
    if (err["type"] != "unknown_key" and isinstance(value, (bool, int, float, str, type(None)))
            and len(repr(value)) <= 80 and f"got {value!r}" not in message):
        message += f" (got {value!r})"
    return message


def _shown_key(key) -> str:
    """A key or name as a message shows it: a control character or a lone surrogate escaped
    (`\x00`), past MAX_NAME characters cut (the fault itself is reported at its own key)."""
    text = str(key)
    if not text.isprintable():
        text = ascii(text)[1:-1]
    return text if len(text) <= MAX_NAME else f"{text[:MAX_NAME]}... ({len(text)} characters)"


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
        return StudyError(message, file=str(self.file), path=".".join(map(_shown_key, keys)) or None)

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

MAX_NESTING = 50                                   # levels of a study file (shapes nest)
MAX_NODES = 1_000_000                              # values of a study file, aliases expanded
MAX_PROFILE_POINTS = 1000

CriterionKind = Literal[tuple(KINDS)]
Coordinates = Annotated[list[Coordinate], Field(min_length=2, max_length=3)]   # the scene's dimension: _check_criteria


def _nonzero_direction(direction: list[float]) -> list[float]:
    if not any(direction):
        raise ValueError(f"the direction must not be {[0] * len(direction)}")
    return direction


class Criterion(Frozen):
    name: Name
    kind: CriterionKind
    regions: Annotated[list[str], Field(min_length=1)]
    point: Optional[Coordinates] = None
    direction: Optional[Annotated[Coordinates, AfterValidator(_nonzero_direction)]] = None
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


class Fuzzy(Options):
    levels: Annotated[list[Annotated[float, Field(ge=0, le=1)]], Field(min_length=1),
                      AfterValidator(_distinct_levels)] = Field(
        list(DEFAULT_LEVELS), description="the α-levels whose cuts are searched (membership ≥ α)")


class Sweep(Frozen):
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

    @field_validator("output")
    @classmethod
    def _file_name(cls, output):
        """A name the filesystem takes: no NUL, no lone surrogate (YAML's "\ud800" escape)."""
        try:
            name = os.fsencode(output)
        except UnicodeEncodeError as e:
            raise ValueError(f"the output name holds {ascii(e.object[e.start:e.end])}, not a character of a "
                             "file name") from None
        if b"\0" in name:
            raise ValueError("the output name holds a NUL character")
        return output

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
    points: Any                 # an integer (2D), or [nu, nv] (a grid on a 3D contact surface)

    @model_validator(mode="after")
    def _crisp_or_fuzzy(self):
        if (self.range is None) == (self.support is None) or (self.support is None) != (self.core is None):
            raise ValueError("give either range: [lower, upper] or support: [a, b] with core: [c, d]")
        return self

    @field_validator("points")
    @classmethod
    def _count_or_grid(cls, p):
        whole = lambda v: isinstance(v, int) and not isinstance(v, bool)      # noqa: E731
        if not (whole(p) or (isinstance(p, list) and len(p) == 2 and all(whole(v) for v in p))):
            raise ValueError(f"points must be an integer (2D) or [nu, nv] (3D), got {p!r}")
        if min(p if isinstance(p, list) else [p]) < 2 or math.prod(p if isinstance(p, list) else [p]) > MAX_PROFILE_POINTS:
            raise ValueError(f"points needs at least 2 values per direction and at most {MAX_PROFILE_POINTS} "
                             f"in all, got {p!r}")
        return p


_STUDY = TypeAdapter(StudyFile)
_SCENE = TypeAdapter(Scene)
_SCENE3D = TypeAdapter(spec3d.Scene)
_PROFILE = TypeAdapter(Profile)
_FUZZY = TypeAdapter(FuzzyNumber)
_LIMIT = TypeAdapter(Limit)
_NUMBER = TypeAdapter(float, config=_CONFIG)
_NUMBERS = TypeAdapter(list[float], config=_CONFIG)
_BOX = TypeAdapter(Point, config=_CONFIG)
_LIBRARY = TypeAdapter(Annotated[dict[Name, Material], Field(min_length=1)], config=_CONFIG)


# ---------------------------------------------------------------- the scene


def _load_scene(raw, study_src: _Source) -> tuple[Scene, _Source, list[tuple[Path, str]], list[str]]:
    """The validated scene, where it lives, the extra files it came from, and notes on it."""
    extra = []
    src = _Source(study_src.file, ("scene",), study_src.folder)
    if isinstance(raw, str):
        path = _locate(raw, study_src, "scene")
        raw, text = _read_yaml(path)
        src = _Source(path)
        extra.append((path, text))
    if isinstance(raw, dict) and isinstance(raw.get("materials"), str):
        raw = dict(raw)
        raw["materials"], library = _load_materials(raw["materials"], src)   # validated Material models
        extra.append(library)
    three = isinstance(raw, dict) and raw.get("dimension") == 3
    try:
        scene = src.validate(_SCENE3D if three else _SCENE, raw)
    except StudyError:
        if isinstance(raw, dict) and "dimension" not in raw and _reads_as_3d(raw):
            raise src.error(("dimension",), "required key is missing: the scene is a 3D one (its shapes, "
                                            "vectors and selectors are those of dimension: 3)") from None
        raise
    notes = []
    if scene.mesh.file is not None:   # regions come from the file's physical groups
        from .scene.meshfile import prepare_scene   # scikit-fem loads only for a scene meshed by a file
        file, names, groups, notes = prepare_scene(scene, src.base, src.error)
        scene = scene.model_copy(update={
            "mesh": scene.mesh.model_copy(update={"file": file}),
            "bodies": {b: _named(body, names[b]) for b, body in scene.bodies.items()},
            "boundaries": scene.boundaries | {piece: GroupBoundary(group=group, body=body)
                                              for piece, group, body in groups}})
    else:
        _require_shapes(scene, src)
        scene = scene.model_copy(update={"bodies": {
            b: _named(body, [r.name or f"{b}_{i}" for i, r in enumerate(body.regions)])
            for b, body in scene.bodies.items()}})
    return scene, src, extra, notes


def _reads_as_3d(raw: dict) -> bool:
    """Whether a scene without `dimension` is a valid 3D scene (a 2D scene is the default)."""
    try:
        _SCENE3D.validate_python({**raw, "dimension": 3})
    except ValidationError:
        return False
    return True


def _named(body, names: list[str]):
    """The body with its regions named `names` (in order)."""
    return body.model_copy(update={"regions": [r.model_copy(update={"name": n}) for r, n in zip(body.regions, names)]})


def _require_shapes(scene: Scene, src: _Source) -> None:
    for name, body in scene.bodies.items():
        for i, region in enumerate(body.regions):
            if region.shape is None:
                raise src.error(("bodies", name, "regions", i, "shape"),
                                "required key is missing (a region needs a shape unless the "
                                "scene's mesh is a file: `mesh: {file: ...}`)")


def _load_materials(name: str, src: _Source) -> tuple[dict[str, Material], tuple[Path, str]]:
    path = _locate(name, src, "materials", shipped=True)
    raw, text = _read_yaml(path)
    return _Source(path).validate(_LIBRARY, raw), (path, text)


def _region_names(scene: Scene) -> list[str]:
    return [r.name for body in scene.bodies.values() for r in body.regions]


def _used_materials(scene: Scene) -> list[str]:
    """The materials the regions use, each once, in scene order."""
    return list(dict.fromkeys(r.material for body in scene.bodies.values() for r in body.regions))


def _require(name: str, known, what: str, src: _Source, path) -> None:
    if name not in known:
        raise src.error(path, f"unknown {what} '{_shown_key(name)}'{_did_you_mean(name, known)}")


def _check_regions(scene: Scene, src: _Source) -> None:
    """Materials exist; region names are unique and differ from other bodies' names."""
    seen = set()
    for body, spec in scene.bodies.items():
        for i, region in enumerate(spec.regions):
            path = ("bodies", body, "regions", i)
            _require(region.material, scene.materials, "material", src, path + ("material",))
            name = region.name
            if name in seen:
                raise src.error(path + ("name",), f"region name '{name}' is used twice")
            own_name = name == body and len(spec.regions) == 1
            if name in scene.bodies and not own_name:
                raise src.error(path + ("name",), f"region name '{name}' is also a body's name")
            seen.add(name)


def _check_references(scene: Scene, src: _Source) -> None:
    """Every boundary, body and region a scene key refers to exists."""
    bodies, boundaries = scene.bodies, scene.boundaries
    parts = set(bodies) | set(_region_names(scene))
    for name, spec in boundaries.items():
        if spec.body is not None:
            _require(spec.body, bodies, "body", src, ("boundaries", name, "body"))
    for block in ("supports", "loads"):
        for name in getattr(scene, block):
            _require(name, boundaries, "boundary", src, (block, name))
    for name in scene.body_forces:
        _require(name, parts, "body or region", src, ("body_forces", name))
    _check_mesh_references(scene, src)
    for name, roi in scene.regions_of_interest.items():
        path = ("regions_of_interest", name)
        if roi.boundary is not None:
            _require(roi.boundary, boundaries, "boundary", src, path + ("boundary",))
        if roi.body is not None:
            _require(roi.body, bodies, "body", src, path + ("body",))


def _check_mesh_references(scene: Scene, src: _Source) -> None:
    """The boundaries refine zones name exist; a mesh file leaves no size to the bodies."""
    bodies, boundaries = scene.bodies, scene.boundaries
    for i, refinement in enumerate(scene.mesh.refine):
        if refinement.boundary is not None:
            _require(refinement.boundary, boundaries, "boundary", src, ("mesh", "refine", i, "boundary"))
        if getattr(refinement, "body", None) is not None:     # 3D: a zone of one body
            _require(refinement.body, bodies, "body", src, ("mesh", "refine", i, "body"))
    for body, spec in bodies.items():
        for i, refinement in enumerate(spec.mesh.refine if spec.mesh else []):
            if refinement.boundary is not None:
                _require(refinement.boundary, boundaries, "boundary", src,
                         ("bodies", body, "mesh", "refine", i, "boundary"))
        if scene.mesh.file is not None:     # (a body's own mesh: refused by prepare_scene)
            for i, region in enumerate(spec.regions):
                if region.mesh is not None:
                    raise src.error(("bodies", body, "regions", i, "mesh"), "the scene's mesh is a "
                                    "file: a region cannot have its own mesh size")


def _check_contacts(scene: Scene, src: _Source) -> None:
    """Both sides of a contact (or a glued interface) are boundaries, of two different
    bodies when they say which; a side is not both contact and glue."""
    boundaries = scene.boundaries
    glued = {}
    for name, glue in scene.glue.items():
        for side in (glue.slave, glue.master):
            glued.setdefault(side, name)
    for name, contact in scene.contacts.items():
        for key in ("slave", "master"):
            side = getattr(contact, key)
            if side in glued:
                raise src.error(("contacts", name, key), f"boundary '{side}' is glued "
                                f"(glue '{glued[side]}'); a side is either in contact or glued")
    blocks = [("contacts", n, c) for n, c in scene.contacts.items()]
    blocks += [("glue", n, g) for n, g in scene.glue.items()]
    for block, name, contact in blocks:
        path = (block, name)
        for key in ("slave", "master"):
            _require(getattr(contact, key), boundaries, "boundary", src, path + (key,))
        slave, master = boundaries[contact.slave], boundaries[contact.master]
        if contact.slave == contact.master:
            raise src.error(path + ("master",), "slave and master are the same boundary")
        if slave.body is not None and slave.body == master.body:
            raise src.error(path + ("master",),
                            f"slave and master both belong to body '{slave.body}'; "
                            f"a {'contact' if block == 'contacts' else 'glue'} joins two different bodies")


def _check_thermal(scene: Scene, src: _Source) -> list[str]:
    """Thermal references exist and used materials conduct; notes on materials without expansion."""
    thermal = scene.thermal
    if thermal is None:
        return []
    for name in thermal.temperature:
        _require(name, scene.boundaries, "boundary", src, ("thermal", "temperature", name))
    parts = set(scene.bodies) | set(_region_names(scene))
    for name in thermal.sources:
        _require(name, parts, "body or region", src, ("thermal", "sources", name))
    notes = []
    for name in _used_materials(scene):
        material = scene.materials[name]
        if material.conductivity is None:
            raise src.error(("materials", name),
                            "needs 'conductivity' because the scene has a thermal block")
        if material.expansion is None:
            notes.append(f"material '{name}' has no 'expansion': no thermal strain in it")
    return notes


# ---------------------------------------------------------------- mesh size and resources

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


# ---------------------------------------------------------------- dotted paths


def get_path(scene: Scene, path: str):
    """The value at a dotted path of the scene; KeyError (with a hint) if there is none."""
    node = scene
    keys = path.split(".")
    for depth, key in enumerate(keys):
        node = _child(node, key, ".".join(keys[:depth]) or "the scene")
    return node


def _child(node, key: str, where: str):
    """The child `key` of a model (a field the scene gives, by its name in the file), a
    mapping or a list."""
    if isinstance(node, BaseModel):
        given = {f.alias or name: getattr(node, name) for name, f in type(node).model_fields.items()
                 if getattr(node, name) is not None}
        if key in given:
            return given[key]
        raise KeyError(f"no '{key}' under '{where}'{_did_you_mean(key, given)}")
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
    "materials.<m>.E": MODULUS,
    "materials.<m>.nu": POISSON,
    "materials.<m>.lambda": LAME,  # 3 lambda + 2 mu > 0 is checked on the pair
    "materials.<m>.mu": MODULUS,
    "materials.<m>.conductivity": CONDUCTIVITY,
    "materials.<m>.expansion": EXPANSION,
    "materials.<m>.density_weight": WEIGHT,
    "loads.<boundary>.pressure": STRESS,
    "loads.<boundary>.traction.<i>": STRESS,
    "body_forces.<body or region>.<i>": BODY_FORCE,
    "supports.<boundary>.u.<i>": LENGTH,
    "supports.<boundary>.normal": LENGTH,
    "contacts.<c>.friction.slip_limit": SLIP,
    "contacts.<c>.friction.coefficient": COEFFICIENT,
    "thermal.reference": KELVIN,
    "thermal.temperature.<boundary>": KELVIN,
    "thermal.sources.<body or region>": SOURCE,
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


def _nominal_number(scene: Scene, path: str, src: _Source, where) -> float:
    """The scene's number at an addressable path, or a StudyError at `where`."""
    if _address(path) is None:
        try:
            get_path(scene, path)
            hint = ""
        except KeyError as exc:                    # a misspelt key: say which, with its "did you mean"
            hint = f": {exc.args[0]}"
        forms = ", ".join(_ADDRESSES)
        raise src.error(where, f"'{path}' is not a number that can vary{hint}; these can: {forms}")
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
            hint = f"; {RIGID_HINT}" if bounds is MODULUS and value > MODULUS["le"] else ""
            raise src.error(where, f"{value!r} is outside the physical range of '{path}' "
                                   f"({_range_text(bounds)}){hint}")


# ---------------------------------------------------------------- uncertain data, sweep


@dataclass(frozen=True)
class Uncertain:
    """One entry of `uncertain:`: the dotted path of the scene's number, its box [lower, upper]
    (a fuzzy number's support), the core (c, d) of a fuzzy number (None: crisp), and for a
    Lipschitz profile its slope bound and its number of points (else 1: one parameter)."""

    path: str
    lower: float
    upper: float
    core: tuple[float, float] | None = None
    lipschitz: float | None = None
    points: int = 1
    grid: tuple[int, int] | None = None     # a profile on a 3D contact surface: (nu, nv), points = nu·nv


def _parse_uncertain(doc: dict, scene: Scene, src: _Source) -> list[Uncertain]:
    """The boxes of `uncertain:` in file order, each checked against the scene."""
    entries = [_parse_box(path, spec, scene, src) for path, spec in doc.items()]
    _check_bulk_modulus(entries, scene, src)
    return entries


def _parse_box(path: str, spec, scene: Scene, src: _Source) -> Uncertain:
    where = ("uncertain", path)
    nominal = _nominal_number(scene, path, src, where)
    if isinstance(spec, dict) and not {"range", "lipschitz", "points"} & set(spec):
        fuzzy = src.validate(_FUZZY, spec, where)
        entry = Uncertain(path, fuzzy.support[0], fuzzy.support[1], core=tuple(fuzzy.core))
    elif isinstance(spec, dict):
        if _address(path) != _PROFILE_ADDRESS:
            raise src.error(where, "a {range, lipschitz, points} profile is only allowed "
                                   f"on {_PROFILE_ADDRESS}")
        profile = src.validate(_PROFILE, spec, where)
        bounds = profile.range or profile.support
        grid = isinstance(profile.points, list)
        if grid != (scene.dimension == 3):
            raise src.error(where + ("points",), "a slip limit on a 3D contact surface takes points: [nu, nv] "
                                                 "(a grid over the face)" if scene.dimension == 3 else
                            "points is the number of values along the contact (one integer) in 2D")
        entry = Uncertain(path, bounds[0], bounds[1], core=None if profile.core is None else tuple(profile.core),
                          lipschitz=profile.lipschitz,
                          points=profile.points[0] * profile.points[1] if grid else profile.points,
                          grid=tuple(profile.points) if grid else None)
    elif isinstance(spec, list):
        lower, upper = src.validate(_BOX, spec, where)
        entry = Uncertain(path, lower, upper)
    else:
        raise src.error(where, "must be [lower, upper], {support: [a, b], core: [c, d]} or "
                               "{range: [lower, upper], lipschitz, points}")
    if entry.lower > entry.upper:
        raise src.error(where, f"lower bound {entry.lower} is above upper bound {entry.upper}")
    _check_values(path, (entry.lower, entry.upper), src, where)
    if entry.core is not None:
        c, d = entry.core
        if not entry.lower <= c <= d <= entry.upper:
            raise src.error(where + ("core",), f"the core [{c}, {d}] must be an interval inside the "
                                               f"support [{entry.lower}, {entry.upper}]")
        if not c <= nominal <= d:
            raise src.error(where, f"the scene's value {nominal} lies outside the core [{c}, {d}] "
                                   "(the nominal data must have membership 1)")
    elif not entry.lower <= nominal <= entry.upper:
        raise src.error(where, f"the scene's value {nominal} lies outside the box "
                               f"[{entry.lower}, {entry.upper}]")
    return entry


def _check_bulk_modulus(entries: list[Uncertain], scene: Scene, src: _Source) -> None:
    """Lame boxes are admissible everywhere (`wcs.scene.spec.lame_admissible`: mu > 0 and
    3 lambda + 2 mu > 0, in 2D and 3D): the bounds are linear, so it is enough to check the lowest
    corner (a fuzzy number: its support). An E, nu box is admissible through the ranges of E and
    nu alone."""
    lowest = {e.path: e.lower for e in entries}
    for name, material in scene.materials.items():
        if material.lam is None:
            continue
        lam_path, mu_path = f"materials.{name}.lambda", f"materials.{name}.mu"
        lam, mu = lowest.get(lam_path, material.lam), lowest.get(mu_path, material.mu)
        if not lame_admissible(lam, mu):
            where = lam_path if lam_path in lowest else mu_path
            raise src.error(("uncertain", where), f"the box reaches lambda = {lam:.4g}, mu = {mu:.4g} where "
                            f"3 lambda + 2 mu = {3 * lam + 2 * mu:.4g} <= 0 (an indefinite stiffness; Poisson's "
                            "ratio below -1): raise the lower bound")


def _check_lame_sweep(sweep: Sweep | None, entries: list[Uncertain], scene: Scene, src: _Source) -> None:
    """A sweep of lambda or mu keeps every combination admissible (`lame_admissible`): its
    smallest values with the lowest corner of the boxes (the bounds increase with both)."""
    grid = sweep.grid if sweep else {}
    for name, material in scene.materials.items():
        paths = (f"materials.{name}.lambda", f"materials.{name}.mu")
        if material.lam is None or not set(paths) & set(grid):
            continue
        lam, mu = (min([get_path(scene, p)] + [e.lower for e in entries if e.path == p] + grid.get(p, []))
                   for p in paths)
        if not lame_admissible(lam, mu):
            where = next(p for p in paths if p in grid)
            raise src.error(("sweep", "grid", where), f"the sweep reaches lambda = {lam:.4g}, mu = {mu:.4g} where "
                            f"3 lambda + 2 mu = {3 * lam + 2 * mu:.4g} <= 0 (an indefinite stiffness; Poisson's "
                            "ratio below -1)")


def _check_sweep(sweep: Sweep | None, scene: Scene, src: _Source) -> None:
    """Each swept path is a number that can vary, its values in range; the full factorial grid
    (the product of the list lengths, in Python's exact integers) at most MAX_SOLVES points."""
    points = math.prod(len(values) for values in sweep.grid.values()) if sweep else 0
    if points > MAX_SOLVES:
        raise src.error(("sweep", "grid"), f"the grid has {points:.3g} points, more than {MAX_SOLVES} solves")
    for path, values in (sweep.grid if sweep else {}).items():
        where = ("sweep", "grid", path)
        _nominal_number(scene, path, src, where)
        _check_values(path, values, src, where)


# ---------------------------------------------------------------- criteria, limits


def _check_criteria(criteria: list[Criterion], scene: Scene, src: _Source) -> None:
    names = set()
    for i, criterion in enumerate(criteria):
        if criterion.name in names:
            raise src.error(("criteria", i, "name"), f"criterion name '{criterion.name}' is used twice")
        names.add(criterion.name)
        for j, roi in enumerate(criterion.regions):
            _require(roi, scene.regions_of_interest, "region of interest", src,
                     ("criteria", i, "regions", j))
        for key in ("point", "direction"):
            value = getattr(criterion, key)
            if value is not None and len(value) != scene.dimension:
                raise src.error(("criteria", i, key), f"{key} needs {scene.dimension} coordinates in a "
                                f"{scene.dimension}D scene, got {len(value)}")
        needs = KINDS[criterion.kind].needs
        if needs == "thermal" and scene.thermal is None:
            raise src.error(("criteria", i, "kind"), f"{criterion.kind} needs a thermal block in the scene")
        if needs == "contacts" and not scene.contacts:
            raise src.error(("criteria", i, "kind"), f"{criterion.kind} needs a contact in the scene")


def _split_limits(limits: dict, criteria: list[Criterion], src: _Source) -> tuple[dict, dict]:
    """(upper limits, lower limits) by criterion name. A bound is checked against the end of the
    range the criterion's search finds: an upper limit needs sense max or both, a lower one min
    or both (otherwise the verdict would read a value nobody searched for)."""
    senses = {c.name: c.sense for c in criteria}
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


def _levels(top: StudyFile, uncertain: list[Uncertain]) -> tuple[float, ...] | None:
    """The α-levels of a fuzzy study (None: a crisp one, no `fuzzy:` and no fuzzy number)."""
    if top.fuzzy is not None:
        return tuple(top.fuzzy.levels)
    return DEFAULT_LEVELS if any(e.core is not None for e in uncertain) else None


def alpha_cut(study: "Study", alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """The α-cut of the admissible set, the box (lower, upper) in parameter order: each fuzzy
    number {support: [a, b], core: [c, d]} gives [a + α(c − a), b − α(b − d)] (exactly the core at
    α = 1 and the support at α = 0), a crisp box itself at every level. The cuts are nested:
    the rounded formula is monotone in α."""
    lower, upper = [], []
    for entry in study.uncertain:
        a, b = entry.lower, entry.upper
        c, d = entry.core or (a, b)
        lo = c if alpha == 1 else a if alpha == 0 else min(max(a + alpha * (c - a), a), c)
        hi = d if alpha == 1 else b if alpha == 0 else max(min(b - alpha * (b - d), b), d)
        lower += [lo] * entry.points
        upper += [hi] * entry.points
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


def _parameters(uncertain: list[Uncertain]) -> Parameters:
    names, lower, upper = [], [], []
    for entry in uncertain:
        if entry.grid is not None:
            names += [f"{entry.path}[{i},{j}]" for i in range(entry.grid[0]) for j in range(entry.grid[1])]
        elif entry.lipschitz is not None:
            names += [f"{entry.path}[{i}]" for i in range(entry.points)]
        else:
            names.append(entry.path)
        lower += [entry.lower] * entry.points
        upper += [entry.upper] * entry.points
    return Parameters(names, np.array(lower, dtype=float), np.array(upper, dtype=float))


@dataclass(frozen=True)
class Study:
    """A validated study, frozen; `scene` is the resolved typed scene. A variant is another
    study: `load_study(mapping)`."""

    name: str
    file: Path                                          # Path("<mapping>") for a study given as a mapping
    text: str
    sha256: str
    scene: Scene
    uncertain: list[Uncertain]
    criteria: list[Criterion]
    limits: dict                                        # criterion -> upper limit
    search: Search
    solver: Solver
    sweep: Sweep | None
    output: str
    parameters: Parameters
    notes: list[str]
    warnings: list[str] = field(default_factory=list)   # results to distrust (e.g. P1 locking)
    estimated_cells: float | None = None                # before meshing; None for a mesh file
    lower_limits: dict = field(default_factory=dict)    # criterion -> lower limit
    levels: tuple[float, ...] | None = None             # α-levels of a fuzzy study, ascending; None: crisp

    @cached_property
    def _evaluator(self):
        """The evaluator of this study, built on the first solve."""
        from .evaluation import Evaluator   # the solvers (gmsh, scikit-fem, PARDISO) load on the first solve
        return Evaluator(self)

    def evaluate(self, values, gradients: bool = False):
        """One forward solve at a data vector (or {dotted path: value}); the mesh and the
        assembled model are built on the first call and reused. With `gradients`, the
        evaluation also carries dΦ/dx of every criterion (adjoint)."""
        return self._evaluator.evaluate(values, gradients=gradients)

    def data_set(self, values) -> tuple[np.ndarray, dict[str, float]]:
        """A data set as (x, others): the parameter vector and any other addressed numbers.

        `values` is a vector in the order of `parameters`, or a mapping from dotted path to
        value: a parameter name (`...slip_limit[2]`), an uncertain path (a profile takes one
        value for all points or a list of `points` values), or any other addressable number
        of the scene (e.g. a sweep path). Parameters a mapping leaves out keep their nominal
        value."""
        if isinstance(values, Mapping):
            return _split_mapping(self, values)
        return parameter_vector(self, values), {}

    def nominal(self) -> np.ndarray:
        """The scene's own values in parameter order (a profile repeats the constant value)."""
        values = []
        for entry in self.uncertain:
            values += [get_path(self.scene, entry.path)] * entry.points
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


def _checked_scene(raw, src: _Source, method: str = "auto") -> tuple[Scene, list[tuple[Path, str]], list[str], float | None]:
    """The scene of a study (inline, or a file name relative to `src`), resolved and checked;
    the files it came from, the notes on it and its estimated cell count."""
    scene, scene_src, extra, notes = _load_scene(raw, src)
    _check_regions(scene, scene_src)
    _check_references(scene, scene_src)
    _check_contacts(scene, scene_src)
    notes = notes + _check_thermal(scene, scene_src)
    return scene, extra, notes, _check_mesh(scene, scene_src, method)


def load_scene(mapping: Mapping, base_dir=None) -> Scene:
    """The `scene:` block of a study given as the mapping its YAML parses to, resolved and
    checked as `load_study` does (file names relative to `base_dir`, default the current
    directory); StudyError names `<mapping>` and the key path (`scene.…`)."""
    doc, _ = _mapping_yaml(mapping)
    return _checked_scene(doc, _Source(MAPPING, (), Path.cwd() if base_dir is None else Path(base_dir)))[0]


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
    scene, extra, notes, cells = _checked_scene(top.scene, src, top.solver.method)
    uncertain = _parse_uncertain(top.uncertain, scene, src)
    criteria = top.criteria
    _check_criteria(criteria, scene, src)
    upper_limits, lower_limits = _split_limits(top.limits, criteria, src)
    sweep = top.sweep
    _check_sweep(sweep, scene, src)
    _check_lame_sweep(sweep, uncertain, scene, src)
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
        where = ("values", path)
        if path in index:
            x[index[path]] = src.validate(_NUMBER, value, where)
        elif path in slices:
            n = slices[path].stop - slices[path].start
            if np.ndim(value) == 0:
                x[slices[path]] = src.validate(_NUMBER, value, where)
            elif len(value) != n:
                raise src.error(where, f"a profile of {n} points takes one value or a list of {n}, got {len(value)}")
            else:
                x[slices[path]] = src.validate(_NUMBERS, list(value), where)
        else:
            _nominal_number(study.scene, path, src, where)
            others[path] = src.validate(_NUMBER, value, where)
    return x, others


def _entry_slices(study: Study) -> dict[str, slice]:
    slices, start = {}, 0
    for entry in study.uncertain:
        slices[entry.path] = slice(start, start + entry.points)
        start += entry.points
    return slices
