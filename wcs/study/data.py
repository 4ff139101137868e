"""Applying data to a study: a data set given as a vector in the order of `study.parameters` or
as a mapping {dotted path: value} (nominal where absent), turned into the parameter vector and the
other addressed numbers. `study` is a `wcs.study.study.Study`, which asks these functions
(`Study.data_set`): they take it by what it holds, not by its class."""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..errors import StudyError
from .paths import _nominal_number
from .schema import _NUMBER, _NUMBERS
from .source import _Source


def parameter_vector(study, values) -> np.ndarray:
    """The parameter vector of a data set given as a vector or a mapping (nominal where absent)."""
    if isinstance(values, Mapping):
        return _split_mapping(study, values)[0]
    x = np.asarray(values, dtype=float)
    if x.shape != (len(study.parameters),):
        raise StudyError(f"expected a vector of {len(study.parameters)} parameters "
                         f"({', '.join(study.parameters.names)}), got shape {x.shape}", file=str(study.file))
    return x


def _split_mapping(study, values: Mapping) -> tuple[np.ndarray, dict]:
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


def _entry_slices(study) -> dict[str, slice]:
    slices, start = {}, 0
    for entry in study.uncertain:
        slices[entry.path] = slice(start, start + entry.points)
        start += entry.points
    return slices
