"""Which points lie near which queries: a uniform grid of cells, one grid for each class of query
radii. The points are sorted by their cell, so a run of cells along the last axis is one range of
them; a query reads the runs its ball reaches, each cut to the ball's chord, and keeps the points
within its radius. Queries are classed by radius within a factor 2, each class on a grid of cells
half its largest radius wide over the points in its reach: a query of radius r reads only cells
within (1 + √3) r of it, so a graded mesh (cells of sizes 100x apart) costs each query candidates
of its own size, not the fine points under a coarse radius nor the coarse cells of a fine one.
The candidate pairs are made PAIRS at a time, so no array of (queries x candidates) is held at
once."""
from collections.abc import Iterator

import numpy as np

PAIRS = 1 << 15         # candidate pairs made and measured at once (their arrays: ~2 MB)
QUERIES = 1024          # queries whose runs of cells are listed at once
CELLS = 2               # cells per largest radius of a class
MAX_CELLS = 1 << 20     # cells along an axis at most (the cell keys of up to 3 axes stay within int64)
MARGIN = 2.0 ** -40     # of the coordinates' magnitude: a ball's box widened past rounding


def within(points: np.ndarray, queries: np.ndarray, radius) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Every pair (q, p) with d2 = ‖queries[q] − points[p]‖² ≤ radius[q]², d2 summed over the
    axes in order (as scipy's cKDTree sums it), yielded as index arrays (q, p, d2) of at most
    about PAIRS pairs each; each pair once, in no promised order. points (n, d), queries (k, d),
    radius a scalar or (k,); a negative radius has no pairs."""
    points, queries = np.asarray(points, float), np.asarray(queries, float)
    radius = np.broadcast_to(np.asarray(radius, float), (len(queries),))
    if not (np.isfinite(points).all() and np.isfinite(queries).all() and np.isfinite(radius).all()):
        raise ValueError("points, queries and radii must be finite")
    live = np.flatnonzero(radius >= 0.0)
    if len(points) == 0 or live.size == 0:
        return
    scale = max(np.abs(points).max(), np.abs(queries[live]).max())
    level = np.floor(np.log2(np.maximum(radius[live], 1e-300) / max(radius[live].max(), 1e-300)))
    level = np.maximum(level, -60.0)
    for L in np.unique(level):
        yield from _class_pairs(points, queries, radius, live[level == L], scale)


def nearest_within(points: np.ndarray, queries: np.ndarray, radius) -> tuple[np.ndarray, np.ndarray]:
    """(dist, index) of the nearest point to each query among those within its radius (`within`):
    index −1 and dist inf where there is none; of points at the same distance (equal d2), the
    first (the smallest index)."""
    queries = np.asarray(queries, float)
    best = np.full(len(queries), np.inf)
    index = np.full(len(queries), -1, dtype=np.int64)
    for q, p, d2 in within(points, queries, radius):
        o = np.lexsort((p, d2, q))                      # each query's nearest (then smallest index) first
        q, p, d2 = q[o], p[o], d2[o]
        first = np.ones(q.size, dtype=bool)
        first[1:] = q[1:] != q[:-1]
        q, p, d2 = q[first], p[first], d2[first]
        better = (d2 < best[q]) | ((d2 == best[q]) & (p < index[q]))    # than an earlier batch's
        best[q[better]], index[q[better]] = d2[better], p[better]
    return np.sqrt(best), index


def _class_pairs(points, queries, radius, qs, scale):
    """`within` for the queries qs, whose radii lie within a factor 2 of each other."""
    m = radius[qs] + MARGIN * (radius[qs] + scale)          # past rounding, on every side of a ball
    delta = MARGIN * scale                                  # a point's distance to its cell's sides
    q_lo, q_hi = queries[qs] - m[:, None], queries[qs] + m[:, None]
    ps = np.flatnonzero(((points >= q_lo.min(axis=0)) & (points <= q_hi.max(axis=0))).all(axis=1))
    if ps.size == 0:
        return
    x = points[ps]
    lo = x.min(axis=0)
    extent = np.ptp(x, axis=0)
    h = max(radius[qs].max() / CELLS, extent.max() / MAX_CELLS, 1e-300)
    n = np.floor(extent / h).astype(np.int64) + 1                      # cells along each axis
    key = _keys(np.minimum(np.floor((x - lo) / h).astype(np.int64), n - 1).T, n)
    order = np.argsort(key, kind="stable")
    key, ps, xt = key[order], ps[order], x[order].T.copy()
    near = np.argsort(_keys(np.clip(np.floor((queries[qs] - lo) / h), 0, n - 1).astype(np.int64).T, n),
                      kind="stable")
    qs, m, q_lo, q_hi = qs[near], m[near], q_lo[near], q_hi[near]     # neighbouring queries together
    top = (n - 1).astype(float)
    d = points.shape[1]
    for s in range(0, len(qs), QUERIES):
        qb, mb, y = qs[s:s + QUERIES], m[s:s + QUERIES], queries[qs[s:s + QUERIES]].T.copy()
        a = np.clip(np.floor((q_lo[s:s + QUERIES] - lo) / h), 0.0, top + 1).astype(np.int64).T
        b = np.clip(np.floor((q_hi[s:s + QUERIES] - lo) / h), -1.0, top).astype(np.int64).T
        width = np.maximum(b - a + 1, 0)[:-1]
        runs = np.prod(width, axis=0)                                   # runs of cells along the last axis
        owner = np.repeat(np.arange(len(qb)), runs)
        k = np.arange(owner.size) - np.repeat(np.cumsum(runs) - runs, runs)
        cell = np.zeros((d, owner.size), dtype=np.int64)
        gap2 = np.zeros(owner.size)
        for j in range(d - 2, -1, -1):                                  # k in mixed radix over the axes
            w = width[j].take(owner)
            cell[j] = a[j].take(owner) + k % w
            k //= w
            side = lo[j] + cell[j] * h
            yj = y[j].take(owner)
            g = np.maximum(np.maximum(side - yj, yj - (side + h)) - delta, 0.0)
            gap2 += g * g
        chord2 = mb.take(owner) ** 2 - gap2            # the ball's half chord along the run, squared
        keep = np.flatnonzero(chord2 >= 0.0)
        owner, cell, chord = owner.take(keep), cell.take(keep, axis=1), np.sqrt(chord2.take(keep))
        z = y[-1].take(owner) - lo[-1]
        cell[-1] = np.clip(np.floor((z - chord) / h), 0.0, top[-1] + 1)
        first = np.searchsorted(key, _keys(cell, n), side="left")
        cell[-1] = np.clip(np.floor((z + chord) / h), -1.0, top[-1])
        count = np.maximum(np.searchsorted(key, _keys(cell, n), side="right") - first, 0)
        yield from _pairs(xt, ps, y, radius[qb] ** 2, qb, owner, first, count)


def _pairs(x, ps, y, r2, qb, owner, first, count):
    """The pairs within radius of the runs of sorted points x[:, first:first + count] (ps: their
    indices) of the queries qb[owner] (at y[:, owner], radius squared r2[owner]), about PAIRS
    candidates at a time. Coordinates by axis (d, n): `np.take` along the axis gathers them
    ~3x faster than rows by fancy indexing."""
    end = np.cumsum(count)
    batch = (end - count) // PAIRS
    cuts = np.concatenate([[0], np.flatnonzero(np.diff(batch)) + 1, [len(count)]])
    for c0, c1 in zip(cuts[:-1], cuts[1:]):
        c = count[c0:c1]
        total = int(c.sum())
        if total == 0:
            continue
        idx = np.arange(total) + np.repeat(first[c0:c1] - (np.cumsum(c) - c), c)
        e = np.repeat(y[:, owner[c0:c1]], c, axis=1) - np.take(x, idx, axis=1)
        d2 = e[0] * e[0]
        for j in range(1, len(e)):
            d2 += e[j] * e[j]
        keep = d2 <= np.repeat(r2[owner[c0:c1]], c)
        yield np.repeat(qb[owner[c0:c1]], c)[keep], ps.take(idx[keep]), d2[keep]


def _keys(cell: np.ndarray, n: np.ndarray) -> np.ndarray:
    """The cells (d, k) by their index in the row-major order of the grid of n cells (the last
    axis fastest)."""
    key = cell[0].copy()
    for j in range(1, len(cell)):
        key = key * n[j] + cell[j]
    return key
