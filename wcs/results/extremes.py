"""The extremes a results file holds, as one list of `wcs.search.ranges.Extreme` records.

Each end of each criterion's range: `kind` "worst" (the maximum, `worst_*` variables) or
"best" (the minimum, `best_*`, when a criterion's sense asks for it), per α-level when the
study is fuzzy. What comes after a search (the drivers, the mesh check) takes the extremes of
the widest box (`support_extremes`).
"""
from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np

from ..search.ranges import Extreme

if TYPE_CHECKING:
    import xarray as xr


KINDS = ("worst", "best")


def kinds(ds: xr.Dataset) -> list[str]:
    """The kinds of extreme the file holds, in KINDS order."""
    return [k for k in KINDS if f"{k}_value" in ds and f"{k}_x" in ds]


def extremes(ds: xr.Dataset) -> list[Extreme]:
    """Every end of every range a results file holds (worst_* and best_*, per level when the
    study is fuzzy), in the order level, criterion, max before min; ends a criterion's sense
    does not ask for are left out. What the checks after a search iterate over."""
    levels = [None] if "level" not in ds.coords else [float(a) for a in ds["level"].values]
    out = []
    for i, level in enumerate(levels):
        for j, c in enumerate(ds["criterion"].values):
            for sense, prefix, cert in (("max", "worst", "certificate"), ("min", "best", "best_certificate")):
                if f"{prefix}_value" not in ds:
                    continue
                pick = {"criterion": j} if level is None else {"level": i, "criterion": j}
                certificate = str(ds[cert].isel(pick).values)
                if certificate == "not-searched":
                    continue
                note = f"{cert}_note" if prefix == "best" else "certificate_note"
                out.append(Extreme(str(c), sense, level, float(ds[f"{prefix}_value"].isel(pick)),
                                   ds[f"{prefix}_x"].isel(pick).values.astype(float), certificate,
                                   str(ds[note].isel(pick).values) if note in ds else "",
                                   int(ds[f"{prefix}_eval"].isel(pick))))
    return out


def support_extremes(ds: xr.Dataset) -> list[Extreme]:
    """The extremes over the widest box: U_ad of a crisp study, the support (the lowest α-level,
    holding every other level's extremes) of a fuzzy one. What the drivers and the mesh check
    take."""
    if "level" not in ds.coords:
        return extremes(ds)
    lowest = float(np.min(ds["level"].values))
    return [e for e in extremes(ds) if e.level == lowest]


def pairs(ds: xr.Dataset) -> Iterator[tuple[str, str, dict]]:
    """(kind, criterion, selection) of every extreme of the variables added after the search
    (dims `extreme`, `criterion`), kind by kind."""
    for kind in map(str, ds["extreme"].values):
        for c in map(str, ds["criterion"].values):
            yield kind, c, {"extreme": kind, "criterion": c}
