"""Time functions of loads (a load's `time:` key): `time: {ramp: t_r}` or `time: {table: [[t, factor], ...]}`,
and a load's factor at time t. A load without `time` acts in full at every time (factor 1).

- ramp t_r: the factor rises linearly from 0 at t = 0 to 1 at t = t_r and stays 1;
- table: piecewise linear between the rows (times strictly increasing); before the first row
  the first factor holds, after the last row the last factor holds (a table [[0, 0], [1, 1]]
  is a ramp that then holds, as engineers' amplitude tables read).
"""
from __future__ import annotations

from typing import Annotated, Optional

import numpy as np
from pydantic import AfterValidator, Field, model_validator

from ..scene.spec import Frozen, _exactly_one

TIME = {"ge": 0.0, "le": 1e6}          # a time of a study [s]: from 0 to ~12 days
FACTOR = {"ge": -1e6, "le": 1e6}       # a load factor (keeps factor * load far inside double precision)
MAX_ROWS = 100_000

Row = Annotated[list[float], Field(min_length=2, max_length=2)]


class TimeFunction(Frozen):
    """A load's time function: exactly one of `ramp` (its duration t_r [s]) or `table` (rows [t, factor])."""
    ramp: Optional[float] = Field(None, gt=0, le=TIME["le"])
    table: Optional[Annotated[list[Row], Field(min_length=1, max_length=MAX_ROWS),
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


def factor(fn: TimeFunction | None, t) -> np.ndarray:
    """The factor of a load with time function `fn` at the times `t` (an array, or a number)."""
    t = np.asarray(t, dtype=float)
    if fn is None:
        return np.ones_like(t)
    if fn.ramp is not None:
        return np.clip(t / fn.ramp, 0.0, 1.0)
    times, factors = np.array(fn.table, dtype=float).T
    return np.interp(t, times, factors)


# What of a time function can be uncertain, with its physical range (the loader's address table).
ADDRESSES = {"loads.<boundary>.time.ramp": {"gt": 0.0, "le": TIME["le"]}}
