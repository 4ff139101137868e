"""`local`: multistart projected ascent from the best points of a sample.

1. A sample: the centre of U_ad plus a design (`sample.design`) of
   min(sample.n, budget/3) − 1 points, with gradients.
2. Per criterion, the `starts` best points that lie at least 0.05 apart
   (∞-norm in scaled coordinates) start a trust-region SQP ascent
   (ascent.py: projected quasi-Newton on the box, SQP steps under A x ≤ b).
3. All runs advance in lockstep, one batch per iteration, until each meets
   KKT (Frank–Wolfe gap ≤ tol), stalls, or the budget is spent.
Certificate: "local-kkt" (or "corner-kkt" at a vertex) where KKT holds at the
reported point.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..options import Search
from .archive import Archive
from .ascent import ascend
from .designs import design

SEPARATION = 0.05


def local(problem, config, rng):
    cfg = Search.of(config)
    archive = Archive(problem, cfg.budget)
    space = archive.space
    n = max(1, min(cfg.sample.n, archive.remaining // 3))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        Z, note = design(cfg.sample.design, space, n - 1, rng) if n > 1 else (np.zeros((0, space.n)), "")
    archive.note(note)
    yield from archive.ask([space.centre(), *Z], "sample", gradients=True)
    starts = [(c, r) for c in archive.criteria for r in top_points(archive, c, cfg.local.starts)]
    yield from ascend(archive, starts, cfg.kkt_tol)
    return archive.worst(cfg.kkt_tol)


def top_points(archive, c, k, separation=SEPARATION):
    """The k best valid records for criterion c, pairwise at least `separation` apart."""
    recs = sorted((r for r in archive.records if r.ok[c]), key=lambda r: -r.phi[c])
    chosen = []
    for r in recs:
        if len(chosen) == k:
            break
        if all(np.max(np.abs(r.z - q.z)) >= separation for q in chosen):
            chosen.append(r)
    return chosen
