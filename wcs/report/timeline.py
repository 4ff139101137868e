"""A dynamic study in the report: each criterion against time at its worst data, and the words
that say how its history was reduced (`over_time`).

A run of a dynamic study holds `phi_history` (eval, criterion, time) and `over_time`
(criterion); a solve holds `phi_history` (criterion, time). `read` takes each criterion's
history at its worst evaluation; `defining_level` is the level whose value the reduction
returns (the peak for `max`), which the figure (`wcs.report.plots.history_figure`) marks and
whose nearest output time the worst-case fields are drawn at.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import dataclass

import numpy as np

if TYPE_CHECKING:
    import xarray as xr


PHRASE = {"max": "the peak over time of {}", "min": "the least over time of {}",
          "final": "{} at the end time", "mean": "the mean over time of {}"}


@dataclass
class Histories:
    time: np.ndarray               # (T,) s
    values: np.ndarray             # (criterion, T) each criterion's history at its worst data (NaN: none)
    over: list[str]                # per criterion: max | min | final | mean
    output_time: np.ndarray | None  # times of the fields kept (None: none)


def in_time(what: str, over: str) -> str:
    """A criterion in words with its reduction over time ("the peak over time of …")."""
    return PHRASE.get(over, "{}").format(what)


def defining_level(h: np.ndarray, over: str) -> int | None:
    """The level whose value the reduction returns: the largest (max), the least (min), the last
    (final); None for the mean (no one level) or a history without a finite value."""
    if not np.isfinite(h).any():
        return None
    return {"max": lambda: int(np.nanargmax(h)), "min": lambda: int(np.nanargmin(h)),
            "final": lambda: len(h) - 1}.get(over, lambda: None)()


def read(ds: xr.Dataset, worst_eval: list[int | None]) -> Histories | None:
    """The histories of a results file at each criterion's worst evaluation (None: a static file)."""
    if "phi_history" not in ds:
        return None
    v = ds["phi_history"]
    k = v.sizes["criterion"]
    over = ([str(o) for o in ds["over_time"].values] if "over_time" in ds else
            [s.split(": ")[1] for s in str(ds["phi"].attrs.get("over_time", "")).split(", ")] if
            "over_time" in ds["phi"].attrs else ["max"] * k)
    if "eval" in v.dims:
        values = np.full((k, v.sizes["time"]), np.nan)
        data = v.transpose("eval", "criterion", "time").values
        for j, e in enumerate(worst_eval):
            if e is not None and 0 <= e < data.shape[0]:
                values[j] = data[e, j]
    else:
        values = v.transpose("criterion", "time").values.astype(float)
    out = ds["output_time"].values.astype(float) if "output_time" in ds.coords else None
    return Histories(ds["time"].values.astype(float), values, over, out)


def output_index(hist: Histories, j: int) -> int:
    """The output time nearest the level that defines criterion j's value (the last output time
    where no one level does)."""
    n = defining_level(hist.values[j], hist.over[j])
    t = hist.time[n] if n is not None else hist.time[-1]
    return int(np.argmin(np.abs(hist.output_time - t)))


def when(hist: Histories, j: int) -> str:
    """The time criterion j's worst-case fields are drawn at, in words: the defining level's own
    time where it is an output level, else the nearest output time and the level's."""
    t = hist.output_time[output_index(hist, j)]
    n = defining_level(hist.values[j], hist.over[j])
    what = {"max": "peak", "min": "least value", "final": "end"}.get(hist.over[j])
    if n is None:
        return f"at t = {t:.4g} s (the mean over time has no one level: the last output time)"
    if np.isclose(t, hist.time[n], rtol=0, atol=1e-9 * hist.time[-1]):
        return f"at t = {t:.4g} s, the level of its {what}"
    return (f"at t = {t:.4g} s, the output time nearest its {what} at t = {hist.time[n]:.4g} s "
            "(fields are kept every `output_every` levels)")
