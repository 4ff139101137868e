"""The criteria and limits of a study checked against its scene: unique names, regions of
interest that exist, points and directions of the scene's dimension, the scene blocks a kind
needs; each limit on the end of the range its criterion's search finds."""
from __future__ import annotations

from ..model.criteria import KINDS
from ..scene.spec import Scene
from .schema import _LIMIT, _NUMBER, Criterion
from .scene import _require
from .source import _Source


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
