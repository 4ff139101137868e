"""`sample`: evaluate one space-filling design and keep the best point per criterion.

One batch (no gradients) of `sample.n` points of `sample.design` (designs.py),
capped by the budget. Nothing is checked, so every certificate is "heuristic"
— this is what users do without wcs, and the baseline the other strategies
are measured against.
"""
from __future__ import annotations

import warnings

from ..options import Search
from .archive import Archive
from .designs import design


def sample(problem, config, rng):
    cfg = Search.of(config)
    archive = Archive(problem, cfg.budget)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        Z, note = design(cfg.sample.design, archive.space, cfg.sample.n, rng, cap=archive.remaining)
    archive.note(note)
    yield from archive.ask(list(Z), "sample", gradients=False)
    return archive.worst(cfg.kkt_tol)
