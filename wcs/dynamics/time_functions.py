"""Time functions of loads (a load's `time:` key): `time: {ramp: t_r}` or `time: {table: [[t, factor], ...]}`,
and a load's factor at time t. A load without `time` acts in full at every time (factor 1).

- ramp t_r: the factor rises linearly from 0 at t = 0 to 1 at t = t_r and stays 1;
- table: piecewise linear between the rows (times strictly increasing); before the first row
  the first factor holds, after the last row the last factor holds (a table [[0, 0], [1, 1]]
  is a ramp that then holds, as engineers' amplitude tables read).
"""
from __future__ import annotations

import numpy as np

from ..scene.spec import TimeFunction

def factor(fn: TimeFunction | None, t) -> np.ndarray:
    """The factor of a load with time function `fn` at the times `t` (an array, or a number)."""
    t = np.asarray(t, dtype=float)
    if fn is None:
        return np.ones_like(t)
    if fn.ramp is not None:
        return np.clip(t / fn.ramp, 0.0, 1.0)
    times, factors = np.array(fn.table, dtype=float).T
    return np.interp(t, times, factors)
