"""The grid search of `wcs.geometry.near` against brute force (every query against every point,
the squared distance summed over the axes in the same order): the same pairs and the same d2 to
the bit, and the same nearest point (the smallest index among equal distances), on random,
graded, duplicated and tied point sets, empty ones, one point, queries far away, and in batches
of a few pairs (the batches' seams must not lose or repeat a pair)."""
import numpy as np
import pytest

from wcs.geometry import near


def brute_pairs(points, queries, radius):
    """{(q, p): d2} of every pair within radius, by all pairs."""
    if len(points) == 0 or len(queries) == 0:
        return {}
    e = queries[:, None, :] - points[None, :, :]
    d2 = e[..., 0] * e[..., 0]
    for j in range(1, points.shape[1]):
        d2 = d2 + e[..., j] * e[..., j]
    radius = np.broadcast_to(radius, (len(queries),))
    q, p = np.nonzero((d2 <= radius[:, None] ** 2) & (radius[:, None] >= 0))
    return dict(zip(zip(q.tolist(), p.tolist()), d2[q, p].tolist()))


def grid_pairs(points, queries, radius):
    out = {}
    for q, p, d2 in near.within(points, queries, radius):
        for key, value in zip(zip(q.tolist(), p.tolist()), d2.tolist()):
            assert key not in out, f"pair {key} given twice"
            out[key] = value
    return out


def brute_nearest(points, queries, radius):
    """(dist, index): the first index of the smallest d2 within radius, else (inf, -1)."""
    best, index = np.full(len(queries), np.inf), np.full(len(queries), -1)
    for (q, p), d2 in sorted(brute_pairs(points, queries, radius).items()):    # by query, then point
        if d2 < best[q]:
            best[q], index[q] = d2, p
    return np.sqrt(best), index


def graded(rng, side, levels=6):
    """Points whose spacing doubles from one shell to the next, 2^(levels-1) times over (a
    graded mesh's nodes): level k a jittered lattice of spacing 2^k / 100 filling the cube of
    half-width side × that spacing around the origin, less the cube of level k - 1; and each
    point's spacing."""
    x, spacing = [], []
    for k in range(levels):
        a = 2.0 ** k / 100
        g = np.arange(-side, side + 1) * a
        lattice = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
        lattice = lattice[np.abs(lattice).max(axis=1) > (side * a / 2 if k else -1.0)]
        x.append(lattice + rng.normal(size=lattice.shape) * 0.1 * a)
        spacing.append(np.full(len(lattice), a))
    return np.concatenate(x), np.concatenate(spacing)


@pytest.fixture(params=[near.PAIRS, 7])
def batch(request, monkeypatch):
    """The default batches, and batches of ~7 pairs and 3 queries (every seam exercised)."""
    if request.param != near.PAIRS:
        monkeypatch.setattr(near, "PAIRS", request.param)
        monkeypatch.setattr(near, "QUERIES", 3)
    return request.param


@pytest.mark.parametrize("seed", range(6))
def test_within_gives_every_pair_of_brute_force_on_random_and_graded_sets(seed, batch):
    rng = np.random.default_rng(seed)
    if seed % 2:
        points, spacing = graded(rng, 3)
        pick = rng.choice(len(points), 200)
        queries = points[pick] + rng.normal(size=(200, 3)) * spacing[pick, None]
        radius = 3.0 * spacing[pick] * rng.random(200)
    else:
        points = rng.random((500, 3)) * 10.0 ** rng.integers(-3, 4)
        queries = rng.random((300, 3)) * points.max() * 1.2 - 0.1 * points.max()
        radius = rng.random(300) ** 3 * 0.3 * points.max()
    points[:20] = points[20:40]                                   # duplicated points
    queries[:10] = points[50:60]                                  # queries on points
    radius[:5] = 0.0                                              # a zero radius: the coincident points
    expected = brute_pairs(points, queries, radius)
    assert len(expected) > 300
    assert grid_pairs(points, queries, radius) == expected


def test_within_and_nearest_at_exact_ties_and_on_the_radius(batch):
    """Coordinates in binary fractions, so distances are exact: a query midway between two
    points, points exactly on the radius, duplicates (the first index is the nearest)."""
    g = np.stack(np.meshgrid(*[np.arange(8) * 0.25] * 3, indexing="ij"), -1).reshape(-1, 3)
    points = np.concatenate([g, g[::7]])                          # every 7th node twice
    queries = np.concatenate([g[:40] + [0.125, 0.0, 0.0], g[::7], g[::5] + 0.125])
    radius = np.full(len(queries), 0.25)
    expected = brute_pairs(points, queries, radius)
    assert grid_pairs(points, queries, radius) == expected
    assert sum(d2 == 0.0625 for d2 in expected.values()) > 100          # on the radius: kept
    dist, index = near.nearest_within(points, queries, radius)
    b_dist, b_index = brute_nearest(points, queries, radius)
    assert np.array_equal(index, b_index) and np.array_equal(dist, b_dist)
    assert np.all(index[:40] == np.arange(40))                  # midway (0.125 both sides): the first
    assert np.all(index[40:40 + len(g[::7])] == np.arange(0, len(g), 7))   # duplicates: the first


@pytest.mark.parametrize("seed", range(4))
def test_nearest_within_is_the_brute_force_nearest(seed, batch):
    rng = np.random.default_rng(10 + seed)
    points, spacing = graded(rng, 3) if seed % 2 else (rng.random((400, 3)), np.full(400, 0.05))
    points[:30] = points[30:60]
    pick = rng.choice(len(points), 300)
    queries = points[pick] + rng.normal(size=(300, 3)) * spacing[pick, None]
    radius = 2.0 * spacing[pick] * rng.random(300)
    dist, index = near.nearest_within(points, queries, radius)
    b_dist, b_index = brute_nearest(points, queries, radius)
    assert np.array_equal(index, b_index) and np.array_equal(dist, b_dist)
    assert 50 < np.sum(index >= 0) < 300


def test_empty_inputs_one_point_far_queries_and_negative_radii():
    rng = np.random.default_rng(5)
    p, q = rng.random((50, 3)), rng.random((20, 3))
    assert grid_pairs(np.zeros((0, 3)), q, 1.0) == {} and grid_pairs(p, np.zeros((0, 3)), 1.0) == {}
    dist, index = near.nearest_within(np.zeros((0, 3)), q, 1.0)
    assert np.all(index == -1) and np.all(dist == np.inf)
    assert near.nearest_within(p, np.zeros((0, 3)), 1.0)[1].size == 0
    one = np.array([[0.3, 0.4, 0.5]])
    assert grid_pairs(one, q, 0.5) == brute_pairs(one, q, 0.5) != {}
    assert np.array_equal(near.nearest_within(one, q, 0.5)[1], brute_nearest(one, q, 0.5)[1])
    far = q + 1e3
    assert grid_pairs(p, far, 10.0) == {}                          # all queries far away
    assert grid_pairs(p, far, 2e3) == brute_pairs(p, far, 2e3)     # ... within a radius that reaches
    radius = np.where(np.arange(20) % 2, -1.0, 0.3)                # a negative radius: no pair
    assert grid_pairs(p, q, radius) == brute_pairs(p, q, radius)
    with pytest.raises(ValueError, match="finite"):
        list(near.within(p, q, np.inf))


def test_within_in_the_plane():
    rng = np.random.default_rng(6)
    p, q = rng.random((300, 2)), rng.random((100, 2))
    assert grid_pairs(p, q, 0.1) == brute_pairs(p, q, 0.1)


def test_a_graded_set_costs_each_query_candidates_of_its_own_size(monkeypatch):
    """Radii 100x apart: each class of radii (within a factor 2) has cells of half its largest
    radius R, so a query of radius r ≥ R/2 reads only cells within r + √3·R/2 ≤ (1 + √3) r of it:
    at most (1 + √3)³ ≈ 20 times its ball's volume, the count of candidates about that times
    the pairs found (with one grid for all radii a fine query would read ~100³ times more)."""
    rng = np.random.default_rng(7)
    points, spacing = graded(rng, 8)
    radius = 2.0 * spacing
    read = []
    pairs = near._pairs
    monkeypatch.setattr(near, "_pairs", lambda *a: read.append(int(a[-1].sum())) or pairs(*a))
    found = sum(q.size for q, _, _ in near.within(points, points, radius))
    assert found > 10 * len(points)
    assert sum(read) < 20 * found
