"""Worst-scenario search: maximise every criterion over the admissible box U_ad.

The contract between a search strategy and the runner that evaluates for it
is a generator (ask/tell):

    def strategy(problem: Problem, config: Search, rng: np.random.Generator)
            -> Generator[Batch, list[Outcome], Worst]

The strategy yields a `Batch` of data sets (physical units, inside the box);
the runner evaluates them (in parallel where it can, from its store when it
has seen the exact same bits before, which is how `--resume` replays a run)
and sends back one `Outcome` per point, in order. Every outcome carries every
criterion (criteria share evaluations). The strategy must stop before the
budget (`config.budget`, forward solves; `config`: the study's `wcs.options.Search`, or
a mapping it validates) is spent; the runner enforces it
as a hard cap and sends back only the outcomes it could afford (a shorter
list) when a batch would overrun, and the strategy then returns. When done, it
returns `Worst`: per criterion the best point found and its certificate.
`Problem.known` holds evaluations made before (an inner α-level's, ranges.py): a strategy
counts them as its own without asking for them, and `auto` then starts from them;
`Problem.inner` is that level's box, where those starting points sit at its bounds.
Determinism: all randomness comes from `rng`; the same problem, config and
outcomes give the same batches, bit for bit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Problem:
    names: list[str]                 # parameter names (dotted paths), the vector order
    lower: np.ndarray                # (n,) box, physical units
    upper: np.ndarray
    criteria: list[str]              # criterion names, all maximised
    A_ub: np.ndarray | None = None   # (k, n) linear constraints A x ≤ b (Lipschitz slip-limit
    b_ub: np.ndarray | None = None   #  profiles), physical units; None when there are none
    known: tuple = ()                # Outcomes already solved inside the box: reused, not charged to the budget
    inner: tuple | None = None       # (lower, upper) of the inner α-level's box, searched before (ranges.py)

    @property
    def dimension(self) -> int:
        return len(self.names)


@dataclass
class Batch:
    points: np.ndarray               # (k, n) data sets to evaluate, physical units
    stage: str                       # "sample", "corner", "local", "global", ... (recorded per evaluation)
    gradients: bool = True           # whether the strategy wants dΦ/dx (costs about one extra solve)


@dataclass
class Outcome:
    x: np.ndarray
    phi: dict[str, float]            # NaN where the evaluation failed
    status: int                      # a wcs.status.Status code (0 solved)
    grad: dict[str, np.ndarray] | None = None   # dΦ/dx (physical units) per criterion, if asked and smooth
    nonsmooth: bool = False          # the active set (or the max over regions) changes within reach


@dataclass
class Worst:
    x: dict[str, np.ndarray]         # criterion -> data set attaining the worst value found
    value: dict[str, float]
    certificate: dict[str, str]      # "corner-kkt" | "local-kkt" | "heuristic"
    notes: dict[str, str] = field(default_factory=dict)


from .registry import STRATEGIES  # noqa: E402  (strategies import the dataclasses above)
