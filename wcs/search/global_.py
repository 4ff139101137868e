"""`global`: DIRECT box subdivision (Jones et al. 1993), batched, then a local polish.

scipy.optimize.direct calls the objective itself and optimises one function;
here the same algorithm is written as a generator over all criteria at once:

- Hyper-rectangles of the scaled box [0,1]^n, each with its centre c, its
  side lengths 3^(−k_i) and Φ(c) for every criterion; the size is
  σ = ½‖sides‖₂.
- Selection: for each criterion, the potentially optimal rectangles — j such
  that for some K > 0, Φ_j + Kσ_j ≥ Φ_i + Kσ_i for all i and
  Φ_j + Kσ_j ≥ Φ_max + ε|Φ_max| (ε = 1e-4): the upper-right convex hull of
  (σ, Φ). The union over criteria is divided in one batch.
- Division: along the longest sides I, sample c ± δe_i (δ = side/3) for
  i ∈ I, then trisect the sides one after another, the side with the best
  max(Φ(c+δe_i), Φ(c−δe_i)) first (so the best points get the largest
  rectangles), using the criterion that selected the rectangle.
- Failed evaluations count as the worst value seen (so failed rectangles are
  still divided when large, never preferred).
- Linear constraints: a centre outside P is evaluated at its projection onto P
  (a heuristic extension of DIRECT; the rectangle keeps its nominal centre).

DIRECT uses 3/4 of the budget without gradients; the rest polishes the best
point of each criterion with the local ascent (ascent.py), which is where the
KKT certificates come from.
"""
from __future__ import annotations

import numpy as np

from ..options import Search
from .archive import Archive
from .ascent import ascend

EPS = 1e-4
POLISH = 0.25


def global_(problem, config, rng):
    cfg = Search.of(config)
    archive = Archive(problem, cfg.budget)
    space, crit = archive.space, archive.criteria
    polish = int(POLISH * archive.budget) if archive.budget >= 8 else 0
    free = np.flatnonzero(space.width > 0)
    if free.size == 0:
        yield from archive.ask([space.centre()], "global")
        return archive.worst(cfg.kkt_tol)

    levels = [np.zeros(space.n, dtype=int)]       # k_i: side = 3^-k_i
    centres = [np.full(space.n, 0.5)]
    values = [None]                                # Record per rectangle
    recs = yield from archive.ask([space.project(centres[0])], "global", gradients=False)
    values[0] = recs[0]

    while archive.remaining > polish and not archive.exhausted:
        selected = _select(levels, values, crit, free)
        batch, plans = [], []
        for j, c in selected:
            k = levels[j][free]
            longest = free[k == k.min()]
            delta = 3.0 ** -(levels[j][longest[0]] + 1)
            pts = []
            for i in longest:
                e = np.zeros(space.n)
                e[i] = delta
                pts += [centres[j] + e, centres[j] - e]
            if len(batch) + len(pts) > archive.remaining - polish:
                break
            batch += pts
            plans.append((j, c, longest, pts))
        if not plans:
            break
        recs = yield from archive.ask([space.project(p) for p in batch], "global", gradients=False)
        at = dict(zip(range(len(batch)), recs))
        pos = 0
        for j, c, longest, pts in plans:
            got = [at[pos + t] for t in range(len(pts))]
            pos += len(pts)
            score = [max(_value(got[2 * t], c, values), _value(got[2 * t + 1], c, values))
                     for t in range(len(longest))]
            for t in np.argsort(-np.array(score), kind="stable"):
                i = longest[t]
                levels[j][i] += 1
                for p, r in ((pts[2 * t], got[2 * t]), (pts[2 * t + 1], got[2 * t + 1])):
                    levels.append(levels[j].copy())
                    centres.append(p)
                    values.append(r)
        if archive.exhausted:
            break

    if archive.remaining and not archive.exhausted:
        starts = [(c, archive.best_record(c)) for c in crit if not archive.certified(c, cfg.kkt_tol)]
        yield from ascend(archive, [s for s in starts if s[1] is not None], cfg.kkt_tol)
    return archive.worst(cfg.kkt_tol)


def _value(rec, c, values):
    if rec is not None and rec.ok[c]:
        return rec.phi[c]
    ok = [r.phi[c] for r in values if r is not None and r.ok[c]]
    return min(ok) if ok else 0.0


def _select(levels, values, crit, free):
    """(rectangle, criterion) pairs: the potentially optimal rectangles of every criterion."""
    size = np.array([0.5 * np.linalg.norm(3.0 ** -lv[free].astype(float)) for lv in levels])
    chosen, seen = [], set()
    for c in crit:
        ok = [r.phi[c] for r in values if r is not None and r.ok[c]]
        worst = min(ok) if ok else 0.0
        f = np.array([r.phi[c] if r is not None and r.ok[c] else worst for r in values])
        for j in _potentially_optimal(size, f):
            if j not in seen:
                seen.add(j)
                chosen.append((j, c))
    return chosen


def _potentially_optimal(size, f):
    """Indices j on the upper-right hull of (size, f) passing the ε test (maximisation)."""
    fmax = f.max()
    # per distinct size, the best rectangle (first index among ties)
    groups = {}
    for j in range(len(f)):
        key = round(float(size[j]), 12)
        if key not in groups or f[j] > f[groups[key]]:
            groups[key] = j
    cand = sorted(groups.values(), key=lambda j: size[j])
    out = []
    for a, j in enumerate(cand):
        smaller = [i for i in cand[:a]]
        larger = [i for i in cand[a + 1:]]
        k_lo = max([(f[i] - f[j]) / (size[j] - size[i]) for i in smaller], default=0.0)
        k_hi = min([(f[j] - f[i]) / (size[i] - size[j]) for i in larger], default=np.inf)
        if k_lo > k_hi:
            continue
        if np.isfinite(k_hi) and f[j] + k_hi * size[j] < fmax + EPS * abs(fmax):
            continue
        out.append(j)
    return out
