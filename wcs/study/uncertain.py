"""The uncertain data of a study and its sweep: each entry of `uncertain:` (a box, a fuzzy number
or a Lipschitz profile) checked against the scene, Lamé boxes and sweeps kept admissible, and the
`Parameters`: the uncertain numbers as one vector (names and box).

A Lipschitz friction profile (`uncertain: {contacts.<c>.friction.slip_limit:
{range, lipschitz, points}}`) is `points` parameters named `<path>[0]` ...
`<path>[points-1]`: values of g at equally spaced points along the contact
(`wcs.model.coefficients` interpolates them onto the contact nodes). The slope bound |g[i+1] - g[i]| <= C*ds
needs the contact length (ds = length / (points - 1)), so it is only stored here. In 3D a
profile is a Lipschitz function on the contact surface: `points: [nu, nv]` values on a grid over
the slave face in its two principal directions (`wcs.contact.frame`), bilinear in between,
named `<path>[i,j]`, the slope bound in both directions."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..options import MAX_SOLVES
from ..scene.spec import Scene, lame_admissible
from .paths import _PROFILE_ADDRESS, _address, _check_values, _nominal_number, get_path
from .schema import _BOX, _FUZZY, _PROFILE, Sweep
from .source import _Source


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
