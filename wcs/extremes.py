"""The extremes a run found, as one list: (criterion, kind, data set, value, row).

`kind` is "worst" (the maximum, `worst_*` variables) or "best" (the minimum, `best_*`, when
the results file has it). With fuzzy levels (a `level` dimension) the extremes are those of
the support, the lowest level: the widest box, holding every other level's extremes.
What comes after a search (the mesh check, the drivers) loops over this list.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import xarray as xr

KINDS = ("worst", "best")


@dataclass(frozen=True)
class Extreme:
    criterion: str
    kind: str                  # "worst" | "best"
    x: np.ndarray              # the data set, physical units (NaN where none was solved)
    value: float               # the criterion there, on the study's mesh
    row: int                   # its evaluation index (eval), -1 if unknown

    @property
    def found(self) -> bool:
        return bool(np.all(np.isfinite(self.x))) and bool(np.isfinite(self.value))


def _support(v: xr.DataArray) -> xr.DataArray:
    return v.isel(level=int(np.argmin(v["level"].values))) if "level" in v.dims else v


def kinds(ds: xr.Dataset) -> list[str]:
    """The kinds of extreme the file holds, in KINDS order."""
    return [k for k in KINDS if f"{k}_value" in ds and f"{k}_x" in ds]


def extremes(ds: xr.Dataset) -> list[Extreme]:
    """Every extreme of the results file, kind by kind, criteria in file order."""
    out = []
    for kind in kinds(ds):
        value, x = _support(ds[f"{kind}_value"]), _support(ds[f"{kind}_x"])
        row = _support(ds[f"{kind}_eval"]) if f"{kind}_eval" in ds else None
        for j, c in enumerate(map(str, ds["criterion"].values)):
            out.append(Extreme(c, kind, np.asarray(x.sel(criterion=c).values, float),
                               float(value.sel(criterion=c)), -1 if row is None else int(row.values[j])))
    return out


def pairs(ds: xr.Dataset) -> Iterator[tuple[str, str, dict]]:
    """(kind, criterion, selection) of every extreme of the variables added after the search
    (dims `extreme`, `criterion`), kind by kind."""
    for kind in map(str, ds["extreme"].values):
        for c in map(str, ds["criterion"].values):
            yield kind, c, {"extreme": kind, "criterion": c}
