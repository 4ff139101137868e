"""Every evaluation a strategy has seen, the best per criterion, and the budget.

`Archive.ask` is the only place a strategy yields: it drops points already
evaluated (same physical bits), never yields more than the budget has left,
records the outcomes and updates every criterion's best from every outcome
(criteria share evaluations). Strategies call it with `yield from`.

Certificates (`certify`) are a property of the reported point, not of the
strategy that found it. With g = dΦ/dz there and the Frank–Wolfe gap
G = max_{z'∈P} g·(z' − z) (see scaling.py):
- "corner-kkt": z is a vertex of U_ad and G ≤ tol·scale (the KKT sign pattern);
- "local-kkt":  G ≤ tol·scale at a non-vertex point;
- a box of one point (every width 0, e.g. the core of triangular fuzzy numbers) is its own
  maximum: "corner-kkt";
- at a non-smooth point (the active set changes within reach, so g is one-sided) that is a
  corner of the box (no row of A x ≤ b active), the KKT sign test on the one-sided derivatives
  instead: with the inward differences q_i = (Φ(z + s_i h e_i) − Φ(z))/h (s_i = +1 at z_i = 0,
  −1 at z_i = 1; `auto.one_sided`), "corner-kkt" when Σ max(q_i, 0) ≤ tol·scale — Φ does not
  grow along any edge of the box leaving the corner;
- "heuristic":  otherwise — no gradient, a non-smooth point without that test, or a gradient
  that is zero while no evaluation has shown a different value (a flat region, where KKT says
  nothing).
scale = max(|Φ(z)|, spread of the valid values of Φ seen) makes tol relative.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import Batch, Worst
from .scaling import FD_STEP, Space


@dataclass
class Record:
    z: np.ndarray
    x: np.ndarray
    phi: dict[str, float]
    ok: dict[str, bool]
    status: int
    nonsmooth: bool
    stage: str
    asked_gradients: bool
    grad: dict[str, np.ndarray | None] = field(default_factory=dict)   # dΦ/dz
    fd: set[str] = field(default_factory=set)                          # criteria whose grad is a finite difference
    inward: dict[str, np.ndarray] = field(default_factory=dict)        # one-sided differences into the box (a corner)


class Archive:
    def __init__(self, problem, budget: int):
        self.problem = problem
        self.space = Space(problem)
        self.criteria = list(problem.criteria)
        self.budget = int(budget)
        self.spent = 0
        self.exhausted = False          # the budget is spent or the runner cut a batch short
        self.records: list[Record] = []
        self.index: dict[bytes, int] = {}
        self.best: dict[str, int | None] = {c: None for c in self.criteria}
        self.notes: list[tuple[str, str]] = []   # (criterion, or "" for all; text), in the order noted
        for o in problem.known:             # made before (an inner α-level): the strategy's own, free
            z = self.space.to_z(o.x)
            self._record(z, np.asarray(o.x, float), o, "known", o.grad is not None)
            self.index.setdefault(self.space.key(z), self.index[o.x.tobytes()])

    @property
    def remaining(self) -> int:
        return 0 if self.exhausted else max(0, self.budget - self.spent)

    def find(self, z) -> Record | None:
        i = self.index.get(self.space.key(z))
        return None if i is None else self.records[i]

    def ask(self, zs, stage: str, gradients: bool = True, exact: bool = False):
        """Evaluate the points zs (scaled); return their records (None where unaffordable).

        Points are made feasible first (`Space.repair`) unless `exact` (finite-difference
        points: only clipped to the box). A point already evaluated is not asked again,
        unless gradients are wanted now and were not asked for then (that costs one solve)."""
        zs = [np.clip(np.asarray(z, float), 0.0, 1.0) if exact else self.space.repair(z) for z in zs]
        new, keys = [], set()
        for z in zs:
            k = self.space.key(z)
            rec = self.find(z)
            if k in keys or (rec is not None and (rec.asked_gradients or not gradients)):
                continue
            keys.add(k)
            new.append(z)
        take = min(len(new), self.remaining)
        if take < len(new):
            self.exhausted = True
        if take:
            pts = np.array([self.space.to_x(z) for z in new[:take]])
            outcomes = yield Batch(points=pts, stage=stage, gradients=gradients)
            outcomes = list(outcomes or [])
            self.spent += take
            if len(outcomes) < take:
                self.exhausted = True
            for z, x, o in zip(new, pts, outcomes):
                self._record(z, x, o, stage, gradients)
        return [self.find(z) for z in zs]

    def _record(self, z, x, o, stage, gradients):
        phi = {c: float(o.phi.get(c, np.nan)) if o.phi else np.nan for c in self.criteria}
        ok = {c: o.status == 0 and np.isfinite(phi[c]) for c in self.criteria}
        grad = {}
        for c in self.criteria:
            g = None if (o.grad is None or not ok[c]) else o.grad.get(c)
            if g is not None:
                g = np.asarray(g, dtype=float).ravel()
                g = self.space.grad_z(g) if g.size == self.space.n and np.all(np.isfinite(g)) else None
            grad[c] = g
        rec = Record(np.asarray(z, float), x, phi, ok, int(o.status), bool(o.nonsmooth), stage,
                     gradients, grad)
        k = x.tobytes()
        if k in self.index:                     # re-asked for gradients: replace
            i = self.index[k]
            self.records[i] = rec
        else:
            i = len(self.records)
            self.index[k] = i
            self.records.append(rec)
        for c in self.criteria:
            b = self.best[c]
            if ok[c] and (b is None or phi[c] > self.records[b].phi[c]):
                self.best[c] = i

    # ------------------------------------------------------------ queries
    def note(self, text: str, c: str = "") -> None:
        self.notes.append((c, text))

    def notes_of(self, c: str) -> list[str]:
        """The notes of criterion c and those for all, in the order they were made."""
        return [t for who, t in self.notes if who in (c, "") and t]

    def best_record(self, c) -> Record | None:
        return None if self.best[c] is None else self.records[self.best[c]]

    def values(self, c) -> np.ndarray:
        return np.array([r.phi[c] for r in self.records if r.ok[c]])

    def scale(self, c) -> float:
        v = self.values(c)
        if not v.size:
            return 1e-300
        return max(float(np.max(np.abs(v))), float(np.ptp(v)), 1e-300)

    def flat(self, c) -> bool:
        """No evaluation has shown Φ_c to vary: all valid values equal, all gradients zero or absent."""
        v = self.values(c)
        if v.size and np.ptp(v) > 0:
            return False
        return all(r.grad.get(c) is None or not np.any(r.grad[c]) for r in self.records if r.ok[c])

    def certify(self, c, rec: Record | None = None, *, tol: float) -> tuple[str, str]:
        rec = self.best_record(c) if rec is None else rec
        if rec is None:
            return "heuristic", "no successful evaluation"
        if not np.any(self.space.width):
            return "corner-kkt", "the admissible set is this one data set (e.g. the core of triangular fuzzy numbers)"
        g = rec.grad.get(c)
        if rec.nonsmooth:
            return self._certify_rough(c, rec, tol)
        if g is None:
            return "heuristic", "no gradient at the worst point"
        if not np.any(g) and self.flat(c):
            return "heuristic", "zero gradient and no variation seen: a flat region"
        gap = self.space.gap(rec.z, g)
        rel = gap / self.scale(c)
        how = " (finite-difference gradient)" if c in rec.fd else ""
        if rel <= tol:
            kind = "corner-kkt" if self.space.is_vertex(rec.z) else "local-kkt"
            where = ("a vertex of the admissible set where no admissible direction raises the criterion to first "
                     "order" if kind == "corner-kkt" else "no admissible direction raises the criterion to first order")
            return kind, f"{where} (KKT gap {rel:.1e} of scale{how})"
        return "heuristic", (f"the gradient still points into the admissible set: KKT gap {rel:.1e} of scale "
                             f"> {tol:.0e}{how}")

    def _certify_rough(self, c, rec: Record, tol: float) -> tuple[str, str]:
        """A non-smooth point: the KKT sign test on its one-sided differences into the box, when the
        point is a corner of the box and they were taken (`auto.one_sided`)."""
        why = ("the criterion is not differentiable here (the contact's active set, or the criterion's "
               "maximising region or contact node, changes within reach of this data set)")
        q = rec.inward.get(c)
        if q is None and not self.space.is_box_corner(rec.z):
            return "heuristic", (f"{why}, and the point is not a corner of the box (where one-sided differences into "
                                 "the box would test the KKT signs): KKT not checked")
        if q is None:
            return "heuristic", f"{why}, and the budget left no solves for one-sided differences: KKT not checked"
        gain = np.maximum(q, 0.0)
        rel = float(gain.sum()) / self.scale(c)
        if rel <= tol:
            return "corner-kkt", (f"{why}; one-sided differences (step {FD_STEP:.0e} of each interval, into the "
                                  f"box): the criterion does not grow moving any one parameter inward from this "
                                  f"corner, the KKT sign conditions of its one-sided derivatives (gap {rel:.1e} of "
                                  f"scale): a maximum along every edge of the box leaving the corner")
        up = [self.problem.names[i] for i in np.argsort(-gain)[:3] if gain[i] > 0]
        return "heuristic", (f"{why}; one-sided differences (step {FD_STEP:.0e} of each interval, into the box) "
                             f"grow moving {', '.join(up)} inward (gap {rel:.1e} of scale > {tol:.0e}): "
                             f"not a corner maximum")

    def certified(self, c, tol: float) -> bool:
        return self.certify(c, tol=tol)[0] != "heuristic"

    def worst(self, tol: float) -> Worst:
        xs, vals, certs, notes = {}, {}, {}, {}
        centre = self.space.to_x(self.space.centre())
        for c in self.criteria:
            rec = self.best_record(c)
            cert, note = self.certify(c, tol=tol)
            xs[c] = centre.copy() if rec is None else rec.x.copy()
            vals[c] = float("nan") if rec is None else rec.phi[c]
            certs[c] = cert
            notes[c] = "; ".join([note] + self.notes_of(c))
        return Worst(xs, vals, certs, notes)
