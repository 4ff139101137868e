"""Fuzzy admissible sets: the α-levels of a fuzzy study and the α-cut of its admissible set."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .schema import DEFAULT_LEVELS, StudyFile
from .uncertain import Uncertain

if TYPE_CHECKING:
    from .study import Study


def _levels(top: StudyFile, uncertain: list[Uncertain]) -> tuple[float, ...] | None:
    """The α-levels of a fuzzy study (None: a crisp one, no `fuzzy:` and no fuzzy number)."""
    if top.fuzzy is not None:
        return tuple(top.fuzzy.levels)
    return DEFAULT_LEVELS if any(e.core is not None for e in uncertain) else None


def alpha_cut(study: "Study", alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """The α-cut of the admissible set, the box (lower, upper) in parameter order: each fuzzy
    number {support: [a, b], core: [c, d]} gives [a + α(c − a), b − α(b − d)] (exactly the core at
    α = 1 and the support at α = 0), a crisp box itself at every level. The cuts are nested:
    the rounded formula is monotone in α."""
    lower, upper = [], []
    for entry in study.uncertain:
        a, b = entry.lower, entry.upper
        c, d = entry.core or (a, b)
        lo = c if alpha == 1 else a if alpha == 0 else min(max(a + alpha * (c - a), a), c)
        hi = d if alpha == 1 else b if alpha == 0 else max(min(b - alpha * (b - d), b), d)
        lower += [lo] * entry.points
        upper += [hi] * entry.points
    return np.array(lower, dtype=float), np.array(upper, dtype=float)
