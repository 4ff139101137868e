"""The typed models of a study file (pydantic): the top level (`StudyFile`), a criterion and its
limit, the α-levels of a fuzzy study, a sweep, a fuzzy number and a Lipschitz profile of
`uncertain:`, and the validators (`TypeAdapter`s) the loader checks each piece with. The scene's
models are `wcs.scene.spec` (2D) and `wcs.scene.spec3d` (3D); the `search` and `solver` blocks
are `wcs.options`."""
from __future__ import annotations

import math
import os
from typing import Annotated, Any, Literal, Optional

from pydantic import AfterValidator, Field, TypeAdapter, field_validator, model_validator

from ..dynamics.spec import Dynamics
from ..model.criteria import KINDS
from ..options import CONFIG as _CONFIG
from ..options import Options, Search, Solver
from ..options import Strict as _Strict
from ..scene import spec3d
from ..scene.spec import Coordinate, Frozen, Material, Name, Point, Scene

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
    over_time: Optional[Literal["max", "min", "final", "mean"]] = Field(
        None, description="a dynamic study's reduction of the criterion's history (default max)")

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
    dynamics: Optional[Dynamics] = None                  # a time-dependent study (wcs.dynamics)

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
