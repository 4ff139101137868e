"""Projected local ascent: a trust-region SQP loop of our own, driven by the runner.

scipy's optimisers call the objective themselves; ours must instead *yield*
the points it wants solved (the runner evaluates them in parallel, from its
store on resume). So the outer loop is written here and only the cheap inner
problems go to scipy. For each run (criterion c, start z) in scaled
coordinates, with f = Φ_c(z), g = dΦ_c/dz and B ≻ 0 approximating −∇²Φ_c:

    step      d = argmax  g·d − ½ dᵀB d   s.t.  z + d ∈ P,  ‖d‖∞ ≤ Δ
              (a small QP on the box + linear constraints A x ≤ b; SLSQP, no solves)
    predicted π = g·d − ½ dᵀB d > 0,   actual α = Φ_c(z + d) − f   (one solve)
    ratio     ρ = α / π: accept when ρ > 0.1; Δ ← 2Δ (≤ 1) when ρ > 0.75 and
              the step reached the trust-region boundary, Δ ← Δ/4 when ρ < 0.25
    curvature damped BFGS (Powell) on s = d, y = g − g_new, keeps B ≻ 0
    stop      KKT: Frank–Wolfe gap(z, g) ≤ tol·scale;  Δ < 1e-9;  max_iter;  budget

This is a projected quasi-Newton ascent: from B = ‖g‖·I the first step is the
projected steepest ascent clipped to the trust region; near a non-degenerate
maximum it becomes an SQP/Newton step. The trust region replaces a line
search (a failed or worse trial shrinks Δ), so a failed evaluation is just a
rejected step. All runs advance in lockstep: one batch holds one trial per run.

Gradients: `Outcome.grad` when present. When missing at the current point
(an evaluation asked without gradients, a failed adjoint, a criterion
without one), the point is asked again with gradients if it never was, and
otherwise dΦ/dz is taken by forward differences in z with step h = 1e-6
(inward at a bound; one solve per parameter, charged to the budget; an FD
point may violate A x ≤ b by at most h — it is always inside the box).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scaling import FD_STEP


@dataclass
class Run:
    c: str
    z: np.ndarray
    f: float
    g: np.ndarray | None
    delta: float = 0.5
    B: np.ndarray | None = None
    done: str = ""
    iterations: int = 0


def ascend(archive, starts, tol: float, max_iter: int = 40, label: str = "local ascent"):
    """Local ascents of criteria from records: starts = [(criterion, Record), …]. Returns the runs
    (and notes, per criterion, why each stopped)."""
    runs = runs_from(starts)
    yield from advance(archive, runs, tol, max_iter)
    note_runs(archive, runs, label)
    return runs


def runs_from(starts) -> list[Run]:
    return [Run(c, r.z.copy(), r.phi[c], r.grad.get(c)) for c, r in starts if r is not None and r.ok[c]]


STOPS = {                 # why a run stopped (Run.done), in words
    "kkt": "the KKT conditions held there (no direction of ascent inside the admissible set)",
    "budget": "the budget was spent",
    "iterations": "its step limit was reached",
    "no gradient": "its point had no gradient",
    "no predicted gain": "its model of the criterion promised no gain",
    "trust region collapsed": "no step improved the criterion (the trust region shrank below 1e-9)",
}


def note_runs(archive, runs, label: str) -> None:
    """One note per criterion for its runs: how many, how far each got and why it stopped,
    runs that stopped alike told once (e.g. "3 restarted ascents: all stopped before a first
    step: the budget was spent"). A KKT stop at a non-smooth point is said to rest on a one-sided
    gradient."""
    for c in archive.criteria:
        mine = [r for r in runs if r.c == c]
        if not mine:
            continue
        why = {}
        for r in mine:
            rec = archive.find(r.z)
            rough = r.done == "kkt" and rec is not None and rec.nonsmooth
            text = ("the adjoint gradient of its active set showed no ascent direction, but the point is not "
                    "smooth (that gradient is one-sided there)" if rough else STOPS.get(r.done, r.done))
            why.setdefault(text, []).append(r.iterations)
        head = label if len(mine) == 1 else f"{len(mine)} {label}s"
        parts = [f"{_who(len(steps), len(mine))} {_steps(steps)}: {text}" for text, steps in why.items()]
        archive.note(f"{head}: " + ", ".join(parts), c)


def _who(n: int, total: int) -> str:
    return "it" if total == 1 else "all" if n == total else str(n)


def _steps(steps: list[int]) -> str:
    lo, hi = min(steps), max(steps)
    if hi == 0:
        return "stopped before a first step"
    span = str(hi) if lo == hi else f"{lo} to {hi}"
    return f"stopped after {span} step{'' if span == '1' else 's'}"


def advance(archive, runs, tol, max_iter, fd: bool = True):
    """Advance the runs not done, in lockstep, until each is done or has made max_iter steps
    in all (done = "iterations": it may be advanced further). Without `fd`, a run whose point
    has no gradient stops there instead of paying n solves for finite differences."""
    space = archive.space
    while True:
        active = [r for r in runs if not r.done]
        yield from _ensure_gradients(archive, active, fd)
        for r in active:
            if r.g is None:
                rec = archive.find(r.z)
                r.g = rec.grad.get(r.c) if rec is not None else None
            if r.g is None:
                r.done = "no gradient"
            elif space.gap(r.z, r.g) <= tol * archive.scale(r.c):
                r.done = "kkt"
            elif r.iterations >= max_iter:
                r.done = "iterations"
        active = [r for r in active if not r.done]
        trials = []
        for r in active:
            if r.B is None:
                r.B = max(np.linalg.norm(r.g), 1e-300) * np.eye(space.n)
            d, pred = _step(space, r.z, r.g, r.B, r.delta)
            if pred <= 1e-14 * archive.scale(r.c):
                r.done = "no predicted gain"
            else:
                trials.append((r, d, pred))
        if not trials or archive.remaining == 0:
            for r, _, _ in trials:
                r.done = "budget"
            return
        recs = yield from archive.ask([r.z + d for r, d, _ in trials], "local", gradients=True)
        for (r, d, pred), rec in zip(trials, recs):
            r.iterations += 1
            if rec is None:
                r.done = "budget"
                continue
            s = rec.z - r.z
            f_new = rec.phi[r.c] if rec.ok[r.c] else -np.inf
            g_new = rec.grad.get(r.c)
            if g_new is not None:
                _bfgs(r.B, s, r.g - g_new)
            rho = (f_new - r.f) / pred
            if rho > 0.1 and f_new > r.f:
                r.z, r.f, r.g = rec.z.copy(), f_new, g_new
            if rho > 0.75 and np.max(np.abs(d)) >= 0.9 * r.delta:
                r.delta = min(2.0 * r.delta, 1.0)
            elif rho < 0.25:
                r.delta = 0.25 * np.max(np.abs(d))
            if r.delta < 1e-9:
                r.done = "trust region collapsed"
        if archive.exhausted:
            for r in runs:
                r.done = r.done or "budget"
            return


def _step(space, z, g, B, delta):
    """The trust-region QP: (d, predicted gain).

    The Newton step B⁻¹g when it is feasible; otherwise SLSQP on the model in
    variables scaled by the step length r = min(Δ, ‖B⁻¹g‖∞) (so the QP is O(1)
    whatever the size of g), started from the clipped Newton step; compared
    with the Cauchy step along the clipped gradient and the better taken."""
    lo, hi = np.maximum(-delta, -z), np.minimum(delta, 1.0 - z)

    def gain(d):
        return float(g @ d - 0.5 * d @ B @ d)

    def finish(d):
        zt = space.repair(z + np.clip(d, lo, hi))    # snaps to bounds, removes round-off violations
        return zt - z

    dn = np.linalg.solve(B, g)
    if np.all(dn >= lo) and np.all(dn <= hi) and space.feasible(z + dn, 0.0):
        d = finish(dn)
        return d, gain(d)
    candidates = []
    p = np.clip(g * delta / max(np.max(np.abs(g)), 1e-300), lo, hi)     # Cauchy step on the box
    if space.feasible(z + p, 0.0) and g @ p > 0:
        t = min(1.0, (g @ p) / max(p @ B @ p, 1e-300))
        candidates.append(finish(t * p))
    r = max(min(delta, np.max(np.abs(dn))), 1e-12)
    gs = max(np.max(np.abs(g)), 1e-300)
    gh, Bh = g / gs, B * (r / gs)
    u0 = np.clip(dn, lo, hi) / r
    if space.A is not None and not space.feasible(z + r * u0):
        u0 = np.zeros_like(z)
    cons = []
    if space.A is not None:
        cons = [{"type": "ineq", "fun": lambda u: space.b - space.A @ (z + r * u),
                 "jac": lambda u: -r * space.A}]
    from scipy.optimize import minimize   # scipy.optimize (0.4 s) loads where a search needs it
    res = minimize(lambda u: -gh @ u + 0.5 * u @ Bh @ u, u0, jac=lambda u: -gh + Bh @ u,
                   method="SLSQP", bounds=list(zip(lo / r, hi / r)), constraints=cons,
                   options={"ftol": 1e-15, "maxiter": 200})
    candidates.append(finish(r * res.x))
    d = max(candidates, key=gain)
    return d, gain(d)


def _bfgs(B, s, y):
    """Damped BFGS update (Powell) of B ≈ −∇²Φ in place; skipped for tiny steps."""
    Bs = B @ s
    sBs = float(s @ Bs)
    if sBs <= 1e-300 or np.linalg.norm(s) < 1e-14:
        return
    sy = float(s @ y)
    if sy < 0.2 * sBs:
        theta = 0.8 * sBs / (sBs - sy)
        y = theta * y + (1 - theta) * Bs
        sy = float(s @ y)
    B += np.outer(y, y) / sy - np.outer(Bs, Bs) / sBs


def _ensure_gradients(archive, runs, fd=True):
    """Give every run a gradient at its point: ask again with gradients, else finite differences."""
    need = [r for r in runs if r.g is None]
    if not need:
        return
    again = [r.z for r in need if not (archive.find(r.z) and archive.find(r.z).asked_gradients)]
    if again:
        yield from archive.ask(again, "gradient", gradients=True)
    pending = []
    for r in need:
        rec = archive.find(r.z)
        if rec is not None and rec.grad.get(r.c) is None and rec.ok[r.c]:
            pending.append(rec)
    if fd:
        yield from finite_differences(archive, pending)


def finite_differences(archive, recs):
    """Forward differences in z at the records (all criteria at once); stored as rec.grad."""
    space, recs = archive.space, _unique(recs)
    h = FD_STEP
    points, plan = [], []
    for rec in recs:
        steps = []
        for i in range(space.n):
            if space.width[i] == 0:
                steps.append(None)
                continue
            e = np.zeros(space.n)
            e[i] = h
            zi = rec.z + e if rec.z[i] + h <= 1.0 and space.feasible(rec.z + e) else rec.z - e
            if zi[i] < 0:
                zi = rec.z + e
            steps.append(zi)
            points.append(zi)
        plan.append(steps)
    if not points:
        return
    if len(points) > archive.remaining:
        return
    space_key = {space.key(p): p for p in points}
    outs = yield from archive.ask(list(space_key.values()), "fd", gradients=False, exact=True)
    got = {space.key(p): o for p, o in zip(space_key.values(), outs)}
    for rec, steps in zip(recs, plan):
        for c in archive.criteria:
            if rec.grad.get(c) is not None or not rec.ok[c]:
                continue
            g = np.zeros(space.n)
            for i, zi in enumerate(steps):
                if zi is None:
                    continue
                o = got.get(space.key(zi))
                if o is None or not o.ok[c]:
                    g = None
                    break
                g[i] = (o.phi[c] - rec.phi[c]) / (o.z[i] - rec.z[i])
            if g is not None:
                rec.grad[c] = g
                rec.fd.add(c)


def _unique(recs):
    seen, out = set(), []
    for r in recs:
        if id(r) not in seen:
            seen.add(id(r))
            out.append(r)
    return out
