"""Space-filling designs in scaled coordinates z ∈ [0, 1]^n, seeded from `rng`.

- `lhs`: Latin hypercube (scipy.stats.qmc.LatinHypercube): each of the n
  one-dimensional projections has exactly one point in each of N strata.
- `sobol`: scrambled Sobol' points (scipy.stats.qmc.Sobol). Their balance
  holds for N = 2^m, so N is rounded up to a power of two (down when the
  budget does not allow it); the note says so.
- `vertices`: the 2^n corners of the box (fixed parameters excluded), or a
  seeded subset of N distinct corners when 2^n > N.
- `grid`: full factorial with k = ⌈N^(1/d)⌉ levels per free parameter
  (k^d ≥ N points; k is lowered while k^d exceeds the cap).

Linear constraints A x ≤ b: points are projected onto the polytope P
(Euclidean projection in z, `Space.project`); `vertices` instead maps each
sign pattern s ∈ {±1}^n to the vertex of P maximising s·z (an LP), which is
a vertex of U_ad by construction. Duplicates after projection are removed.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

DESIGNS = ("lhs", "sobol", "vertices", "grid")


def design(name: str, space, n: int, rng: np.random.Generator, cap: int | None = None):
    """(points (N, dim) in z, note) for design `name` with about `n` points, at most `cap`."""
    cap = np.iinfo(np.int64).max if cap is None else cap
    n = max(0, min(n, cap))
    if n == 0:
        return np.zeros((0, space.n)), ""
    free = np.flatnonzero(space.width > 0)
    d = free.size
    note = ""
    if name in ("lhs", "sobol"):
        from scipy.stats import qmc     # lazy: scipy.stats costs 0.5 s of start-up that `wcs check` does not need
    if d == 0:
        Z = np.zeros((1, 0))
    elif name == "lhs":
        Z = qmc.LatinHypercube(d, rng=rng).random(n)
    elif name == "sobol":
        m = 1 << max(0, math.ceil(math.log2(n)))
        if m > cap:
            m = 1 << int(math.floor(math.log2(cap)))
        if m != n:
            note = f"sobol: {n} points rounded to {m} = 2^{int(math.log2(m))} (balance of Sobol' sets)"
        Z = qmc.Sobol(d, rng=rng).random_base2(int(math.log2(m)))
    elif name == "vertices":
        Z = _vertices(d, n, rng)
        if len(Z) < 2 ** min(d, 62):
            note = f"vertices: {len(Z)} of 2^{d} corners, chosen at random"
    elif name == "grid":
        k = max(1, math.ceil(n ** (1.0 / d) - 1e-9))
        while k > 1 and k ** d > cap:
            k -= 1
        levels = np.linspace(0.0, 1.0, k) if k > 1 else np.array([0.5])
        Z = np.stack(np.meshgrid(*[levels] * d, indexing="ij"), -1).reshape(-1, d)
        if k ** d != n:
            note = f"grid: {k} levels per parameter, {k ** d} points"
    else:
        raise ValueError(f"unknown design {name!r}; choose from {', '.join(DESIGNS)}")
    full = np.zeros((len(Z), space.n))
    full[:, free] = Z
    if space.constrained:
        if name == "vertices":
            full = np.array([space.lp_vertex(2.0 * z - 1.0, z) for z in full])
        else:
            full = np.array([space.project(z) for z in full])
    return _unique(space, full), note


def _vertices(d: int, n: int, rng: np.random.Generator) -> np.ndarray:
    if d <= 30:
        idx = np.arange(2 ** d) if 2 ** d <= n else np.sort(rng.choice(2 ** d, size=n, replace=False))
        return ((idx[:, None] >> np.arange(d)) & 1).astype(float)
    return _distinct_bits(d, n, rng)


def _distinct_bits(d: int, n: int, rng: np.random.Generator) -> np.ndarray:
    rows, seen = [], set()
    while len(rows) < n:
        r = rng.integers(0, 2, size=d)
        if r.tobytes() not in seen:
            seen.add(r.tobytes())
            rows.append(r.astype(float))
    return np.array(rows)


def _unique(space, Z: np.ndarray) -> np.ndarray:
    seen, keep = set(), []
    for i, z in enumerate(Z):
        k = space.key(z)
        if k not in seen:
            seen.add(k)
            keep.append(i)
    return Z[keep]


def lhs(space, n: int, rng: np.random.Generator) -> np.ndarray:
    """A projected Latin hypercube of n points (no note)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return design("lhs", space, n, rng)[0]
