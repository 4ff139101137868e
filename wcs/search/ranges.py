"""Both ends of each criterion's range, and the α-levels of a fuzzy admissible set, over any strategy.

Minimum. min Φ = −max(−Φ): a criterion of sense `min` or `both` gives the strategy the
objective `<name>.min` = −Φ with gradient −dΦ/dx (a dot never appears in a criterion name),
so the strategies and their certificates apply unchanged: the KKT sign conditions of the
minimum at a vertex are those of −Φ (∂Φ/∂x_i ≤ 0 where x_i is at its upper bound, ≥ 0 at its
lower bound). Values are handed back as Φ.

Fuzzy admissible sets (Hlaváček, Chleboun, Babuška, *Uncertain Input Data Problems and the
Worst Scenario Method*, ch. on fuzzy sets): the criterion's membership function is given by
its range over each α-cut of the data. The levels are searched from the core (the largest
α) outwards, each on its α-cut (a box; the Lipschitz rows A x ≤ b are the same at every
level). The cuts are nested, so every evaluation made so far lies in the next cut: each
level's problem carries them all (`Problem.known`, reused, not solved again) and its search
starts from the previous level's extremes; where its corners do not certify them, they are
moved out to its own bounds where they sat at the inner cut's (`Problem.inner`, the inner cut;
auto.py). The budget is one, over all levels.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..options import Search
from . import Outcome

MIN = ".min"     # suffix of the objective −Φ of a criterion's minimum


@dataclass(frozen=True)
class Extreme:
    """One end of one criterion's range over one α-cut, as the search left it."""
    criterion: str
    sense: str                 # "max" | "min"
    level: float | None        # α (None: a crisp study, the box U_ad)
    value: float               # Φ there (NaN: no successful evaluation)
    x: np.ndarray              # the data set attaining it
    certificate: str           # "corner-kkt" | "local-kkt" | "heuristic", of this end
    note: str = ""
    eval: int = -1             # row of the evaluation attaining it in the results file (-1: none)

    @property
    def kind(self) -> str:
        """"worst" (the maximum, `worst_*` variables) or "best" (the minimum, `best_*`)."""
        return "worst" if self.sense == "max" else "best"

    @property
    def found(self) -> bool:
        """A successful evaluation attains it (x and the value are numbers)."""
        return bool(np.all(np.isfinite(self.x))) and bool(np.isfinite(self.value))


def objectives(senses: dict[str, str]) -> list[tuple[str, str, float]]:
    """(objective name, criterion, sign) the strategy maximises, for {criterion: sense}."""
    out = []
    for c, sense in senses.items():
        if sense in ("max", "both"):
            out.append((c, c, 1.0))
        if sense in ("min", "both"):
            out.append((c + MIN, c, -1.0))
    return out


def signed(o: Outcome, objs) -> Outcome:
    """The outcome as the strategy sees it: sign·Φ and sign·dΦ/dx per objective."""
    phi = {name: sign * o.phi.get(c, np.nan) for name, c, sign in objs} if o.phi else {}
    grad = None
    if o.grad is not None:
        grad = {name: None if o.grad.get(c) is None else sign * np.asarray(o.grad[c], float)
                for name, c, sign in objs}
    return Outcome(o.x, phi, o.status, grad, o.nonsmooth)


def in_box(x, lower, upper) -> bool:
    return bool(np.all(x >= lower) and np.all(x <= upper))


def ranges(factory, problem, config, rng, senses: dict[str, str], cuts=None):
    """Drive `factory` (a strategy) for the ends `senses` asks for; return a list of `Extreme`.

    cuts: [(α, lower, upper)] of a fuzzy study (any order; searched from the largest α), or
    None: one search on the problem's box. The batches and outcomes pass through unchanged
    (the runner sees Φ); the strategy is sent the signed outcomes."""
    objs = objectives(senses)
    cfg = Search.of(config)
    levels = [(None, problem.lower, problem.upper)] if cuts is None else sorted(cuts, key=lambda t: -t[0])
    seen: dict[bytes, Outcome] = {o.x.tobytes(): o for o in problem.known}
    spent, extremes, inner = 0, [], None
    for alpha, lower, upper in levels:
        known = tuple(signed(o, objs) for o in seen.values() if in_box(o.x, lower, upper))
        sub = dataclasses.replace(problem, lower=np.asarray(lower, float), upper=np.asarray(upper, float),
                                  criteria=[name for name, _, _ in objs], known=known, inner=inner)
        inner = (sub.lower, sub.upper) if cuts is not None else None
        left = max(cfg.budget - spent, 0)
        gen = factory(sub, cfg if spent == 0 else cfg.model_copy(update={"budget": left}), rng)
        worst, n = yield from _drive(gen, seen, objs)
        spent += n
        starved = "no budget left for this level: the best of the inner levels' evaluations" if left == 0 else ""
        for name, c, sign in objs:
            if worst is not None and name in worst.value:
                note = "; ".join(t for t in (worst.notes.get(name, ""), starved) if t)
                extremes.append(Extreme(c, "max" if sign > 0 else "min", alpha, sign * worst.value[name],
                                        np.asarray(worst.x[name], float), worst.certificate[name], note))
    return extremes


def _drive(gen, seen: dict, objs):
    """Pass the strategy's batches on and its outcomes back (signed); (its Worst, outcomes sent)."""
    sent = 0
    try:
        batch = next(gen)
        while True:
            outcomes = list((yield batch) or [])
            for o in outcomes:
                seen[o.x.tobytes()] = o
            sent += len(outcomes)
            batch = gen.send([signed(o, objs) for o in outcomes])
    except StopIteration as stop:
        return stop.value, sent
