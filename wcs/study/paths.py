"""Dotted paths into a scene (`materials.rubber.E`, `loads.pad_top.traction.1`, ...): `get_path`
reads them (a key is a field's name as the file writes it, `lambda` included); `_ADDRESSES` says
which numbers can vary (be uncertain or swept) and each one's physical range."""
from __future__ import annotations

from pydantic import BaseModel

from ..model.dynamic_numbers import DYNAMIC_ADDRESSES
from ..options import did_you_mean as _did_you_mean
from ..scene.spec import (BODY_FORCE, COEFFICIENT, CONDUCTIVITY, EXPANSION, KELVIN, LAME, LENGTH, MODULUS, POISSON,
                          RIGID_HINT, SLIP, SOURCE, STRESS, WEIGHT, Scene)
from .source import _Source


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
    **DYNAMIC_ADDRESSES,
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
