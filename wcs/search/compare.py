"""What users do without wcs: plain Latin hypercube sampling, taking the maximum.

`compare_with_lhs` counts the solves such a user needs to reach the same
accuracy as a wcs search: on the ladder N = 1, 2, 4, …, n_max it draws
`repeats` independent N-point Latin hypercubes of U_ad (seeded) and reports
the first N whose median relative error

    (target − max_{k ≤ N} Φ(x_k)) / |target|

is at most `tol` (None when even n_max does not), with the whole ladder.
A point outside A x ≤ b is projected onto it, as the designs do.
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy.stats import qmc

from .scaling import Space


def compare_with_lhs(problem, f, tol: float, target: float, criterion: str | None = None,
                     n_max: int = 1 << 14, repeats: int = 5, seed: int = 0) -> dict:
    """f(x) -> float, or a mapping criterion -> float (then name `criterion`)."""
    space = Space(problem)
    rng = np.random.default_rng(seed)
    scale = max(abs(target), 1e-300)

    def value(z):
        v = f(space.to_x(space.project(z) if space.constrained else z))
        v = v[criterion] if criterion is not None else v
        return float(v) if np.isfinite(v) else -np.inf

    ladder, found, N = [], None, 1
    while N <= n_max:
        errs = []
        for _ in range(repeats):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                Z = qmc.LatinHypercube(space.n, rng=rng).random(N)
            errs.append((target - max(value(z) for z in Z)) / scale)
        err = float(np.median(errs))
        ladder.append((N, err))
        if err <= tol:
            found = N
            break
        N *= 2
    return {"n": found, "ladder": ladder, "tol": tol, "n_max": n_max}
