r"""Deterministic partition of the bodies into subdomains for the DD contact solver.

Rule ([21, §4]: subdomain interfaces Γ do not cut the contact boundary, ``Γ ∩ Γ_c = ∅``),
in unknowns, not in area (a band of fixed thickness swallows the mesh refinement along a
contact: one pair held 70–97 % of the unknowns of the tunnel, the knee and Hertz):

1. **Contact bands.** For every contact side (the slave nodes and the master
   nodes of a contact), the cells touching a side node form its seed (every
   cell around a contact node lies in its band: contact nodes are interior to
   one subdomain, interfaces never cut a contact side). The band then takes
   the cells of its body in order of their centroid's distance to the side
   (ties by cell index) until it holds ``pair_size · n / N`` unknowns (n the
   unknowns of the model, N = ``subdomains``): a pair of two sides holds about
   two mean subdomain shares at ``pair_size = 1``, however fine the mesh
   along the contact. A cell claimed by two bands of one body goes to the
   nearer side (ties to the lower band index).
2. **Pairs.** Bands of one body that share a node are merged (otherwise their
   common nodes would be interface DOFs seen by no linear subdomain, and
   ``S0`` of [21, (4.33)] would be singular there). Bands joined through a
   contact form a *cluster* (a pair in [21]; several contacts may chain
   several bands); within a cluster the bands of one body form ONE
   subdomain. A body with free rigid modes (held only by contact) is not
   split: all of it joins its cluster (its linear part would float in
   ``S0`` and the successive approximations [21, (4.37)] would be
   ill-posed). One pair per contact unless bands touch: a contact side is
   not cut along its length, since two neighbouring contact nodes share a
   cell, so any cut across a connected side puts a contact node on Γ and its
   row would couple two pairs' local contact problems.
3. **Linear subdomains.** The remaining cells of every body are split by
   recursive coordinate bisection of the cell centroids (longest extent
   first, stable ties by cell index) at the median of their unknowns, into a
   number of pieces proportional to their unknowns, so that the total is
   ``subdomains``. Pieces are split into facet-connected components;
   components smaller than a quarter of the mean linear subdomain merge into
   the facet neighbour sharing the most facets (a sliver attached by a vertex
   would make the local Dirichlet problem singular).
4. **No subdomain anchored by a sliver of a support.** A linear subdomain whose
   supported nodes (nodes with fewer unknowns than components) span less than
   a quarter of its own extent (the cut passed next to the end of a support)
   gives the cells at those nodes to the linear subdomain of its body that
   shares them and has the most supported nodes, if that one has more: it then
   floats exactly, and its rigid modes enter the coarse space ([21, (5.11)]),
   instead of being nearly singular and left out of it.

Nothing assumes a dimension: cells are simplices of any size, distances and
bisections act on coordinates of any length.

Same mesh, contacts and options → same partition (no randomness, stable sorts).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree


# Cells a subdomain needs on average: fewer leave most subdomains without interior unknowns (1024
# subdomains of the two-blocks demo's 11152 cells: 724 of 1041 thermal units had none), and every
# unit's local factorization holds PARDISO's own memory (0.6 MB measured for a 10-row matrix):
# 4096 subdomains of that mesh grew past 5 GB before the first solve.
MIN_CELLS_PER_SUBDOMAIN = 16


def subdomains_fault(subdomains: int, ncells: int) -> str | None:
    """Why a mesh of `ncells` cells cannot be split into `subdomains` (None: it can)."""
    most = ncells // MIN_CELLS_PER_SUBDOMAIN
    if subdomains <= max(most, 1):
        return None
    return (f"{subdomains} subdomains of a mesh of {ncells} cells leave fewer than {MIN_CELLS_PER_SUBDOMAIN} "
            f"cells to a subdomain: give at most {max(most, 1)}")


@dataclass(frozen=True)
class Partition:
    """Subdomains of the cells; clusters (pairs) of subdomains across contacts."""

    subdomain: np.ndarray            # (ncells,) subdomain of every cell
    body: np.ndarray                 # (nsub,) body index of every subdomain
    pairs: list[tuple[int, ...]]     # subdomains of every cluster (pair), one per body side
    pair_contacts: list[list[int]]   # contact indices (zone order) of every cluster

    @property
    def nsub(self) -> int:
        return int(self.body.size)

    @property
    def linear(self) -> list[int]:
        """Subdomains in no pair, ascending."""
        inpair = {s for p in self.pairs for s in p}
        return [s for s in range(self.nsub) if s not in inpair]

    def cells(self, s: int) -> np.ndarray:
        return np.flatnonzero(self.subdomain == s)


class _UnionFind:
    def __init__(self, n):
        self.parent = list(range(n))

    def find(self, a):
        while self.parent[a] != a:
            self.parent[a] = self.parent[self.parent[a]]
            a = self.parent[a]
        return a

    def union(self, a, b):
        a, b = self.find(a), self.find(b)
        if a != b:
            self.parent[max(a, b)] = min(a, b)


def node_cell_incidence(t: np.ndarray, nnodes: int) -> sp.csr_matrix:
    """(nnodes, ncells) 0/1 matrix: node in cell."""
    k, nc = t.shape
    return sp.csr_matrix((np.ones(k * nc), (t.T.ravel(), np.repeat(np.arange(nc), k))), shape=(nnodes, nc))


def node_unknowns(T: sp.spmatrix, ncomp: int) -> np.ndarray:
    """(nnodes,) unknowns of every node: the columns of the elimination u = T w + u0 that move
    it (ncomp where it is free; fewer on a support; shared columns count at every glued node)."""
    T = sp.csr_matrix(T)
    nn = T.shape[0] // ncomp
    rows = sp.csr_matrix((np.ones(T.shape[0]), (np.arange(T.shape[0]) // ncomp, np.arange(T.shape[0]))),
                         shape=(nn, T.shape[0]))
    moved = rows @ abs(T)
    moved.eliminate_zeros()
    return np.diff(moved.indptr)


def rcb(xy: np.ndarray, n: int, weight: np.ndarray | None = None) -> np.ndarray:
    """Recursive coordinate bisection of points (k, dim) into n parts; labels 0..n-1.

    Cuts across the longest extent; part weights (default: one per point) proportional
    to the part counts (n1 = ⌊n/2⌋ of n). Ties sorted by point index: deterministic.
    """
    labels = np.zeros(len(xy), dtype=np.int64)
    weight = np.ones(len(xy)) if weight is None else np.asarray(weight, float)

    def split(idx, n, first):
        if n <= 1 or idx.size == 0:
            labels[idx] = first
            return
        pts = xy[idx]
        axis = int(np.argmax(np.ptp(pts, axis=0))) if idx.size > 1 else 0
        order = idx[np.lexsort((idx, pts[:, axis]))]
        n1 = n // 2
        cum = np.cumsum(weight[order])
        k = int(np.argmin(np.abs(np.r_[0.0, cum] - cum[-1] * n1 / n)))
        split(order[:k], n1, first)
        split(order[k:], n - n1, first + n1)

    split(np.arange(len(xy)), n, 0)
    return labels


def facet_components(cells: np.ndarray, f2t: np.ndarray) -> list[np.ndarray]:
    """Facet-connected components of a cell set, each sorted, ordered by first cell."""
    cells = np.sort(cells)
    if cells.size == 0:
        return []
    pos = -np.ones(f2t.max() + 2, dtype=np.int64)
    pos[cells] = np.arange(cells.size)
    a, b = f2t
    inner = (b >= 0) & (pos[a] >= 0) & (pos[np.where(b >= 0, b, a)] >= 0)
    ia, ib = pos[a[inner]], pos[b[inner]]
    g = sp.csr_matrix((np.ones(ia.size), (ia, ib)), shape=(cells.size, cells.size))
    ncomp, lab = sp.csgraph.connected_components(g, directed=False)
    comps = [cells[lab == k] for k in range(ncomp)]
    return sorted(comps, key=lambda c: int(c[0]))


def partition(mesh, cell_body: np.ndarray, sides: list[tuple[int, int, np.ndarray]], floating: set[int],
              subdomains: int, pair_size: float, unknowns: np.ndarray) -> Partition:
    """Partition the cells; see the module docstring.

    mesh:      skfem mesh (p, t, f2t)
    cell_body: (ncells,) body index of every cell
    sides:     (contact index, body index, side nodes) for both sides of every contact
    floating:  bodies with free rigid modes (kept whole in their cluster)
    subdomains: total number of subdomains aimed at (pairs' halves included)
    pair_size: unknowns of a contact side's band, in mean subdomain shares n / subdomains
    unknowns:  (nnodes,) unknowns of every node (components not fixed by a support)
    """
    t, p = mesh.t, mesh.p
    nc, nn = t.shape[1], p.shape[1]
    unknowns = np.asarray(unknowns, dtype=np.int64)
    inc = node_cell_incidence(t, nn)
    centroid = p[:, t].mean(axis=1).T
    target = pair_size * unknowns.sum() / max(subdomains, 1)

    # 1. a band per contact side, grown by distance until it holds `target` unknowns;
    #    a floating body's band is the whole body
    nb = len(sides)
    band_body = [b for _, b, _ in sides]
    owner = -np.ones(nc, dtype=np.int64)
    best = np.full(nc, np.inf)
    seeds = []
    for k, (_, b, nodes) in enumerate(sides):
        seed = np.zeros(nc, dtype=bool)
        seed[np.unique(inc[np.asarray(nodes)].indices)] = True
        seeds.append(seed)
        if b in floating:
            owner[(cell_body == b) & (owner < 0)] = k
            continue
        cells = np.flatnonzero(cell_body == b)
        dist, _ = cKDTree(p[:, nodes].T).query(centroid[cells])
        dist[seed[cells]] = -1.0                            # the seed first
        order = cells[np.lexsort((cells, dist))]
        band = order[: _prefix_holding(t[:, order], unknowns, target, int(seed.sum()))]
        d = np.full(nc, np.inf)
        d[cells] = dist
        take = np.zeros(nc, dtype=bool)
        take[band] = True
        take &= d < best
        owner[take], best[take] = k, d[take]
    for k in range(nb):                               # the cells at a side node are never given away
        mine = [j for j in range(nb) if band_body[j] == band_body[k]]
        owner[seeds[k] & ~np.isin(owner, mine)] = k

    # 2. merge bands of one body sharing a node; clusters through contacts
    uf = _UnionFind(nb)
    node_sets = [np.union1d(t[:, owner == k], sides[k][2]) for k in range(nb)]   # a side's nodes count
    for i in range(nb):
        for j in range(i + 1, nb):
            if band_body[i] == band_body[j] and np.intersect1d(node_sets[i], node_sets[j]).size:
                uf.union(i, j)
    by_contact: dict[int, list[int]] = {}
    for k, (c, _, _) in enumerate(sides):
        by_contact.setdefault(c, []).append(k)
    for ks in by_contact.values():
        for k in ks[1:]:
            uf.union(ks[0], k)
    roots = sorted({uf.find(k) for k in range(nb)})

    subdomain = -np.ones(nc, dtype=np.int64)
    body, pairs, pair_contacts = [], [], []
    for r in roots:
        members = [k for k in range(nb) if uf.find(k) == r]
        subs = []
        for b in sorted({band_body[k] for k in members}):
            cells = np.isin(owner, [k for k in members if band_body[k] == b])
            subdomain[cells] = len(body)
            subs.append(len(body))
            body.append(b)
        pairs.append(tuple(subs))
        pair_contacts.append(sorted({sides[k][0] for k in members}))

    # 3. linear subdomains: RCB of the rest of every body, by unknowns
    rest = subdomain < 0
    weight = cell_unknowns(t, unknowns, inc)
    nbodies = int(cell_body.max()) + 1
    load = np.bincount(cell_body[rest], weights=weight[rest], minlength=nbodies)
    load[(load == 0) & (np.bincount(cell_body[rest], minlength=nbodies) > 0)] = 1e-300
    left = max(subdomains - len(body), int(np.count_nonzero(load)))
    share = _apportion(load, left)
    for b in range(nbodies):
        cells = np.flatnonzero(rest & (cell_body == b))
        if cells.size == 0:
            continue
        lab = rcb(centroid[cells], int(share[b]), weight[cells])
        for k in range(int(share[b])):
            for comp in facet_components(cells[lab == k], mesh.f2t):
                subdomain[comp] = len(body)
                body.append(b)
    body = np.asarray(body, dtype=np.int64)
    pair_subs = {s for q in pairs for s in q}
    subdomain, body = _merge_slivers(subdomain, body, pair_subs, mesh.f2t)
    subdomain = _release_support_slivers(subdomain, body, pair_subs, t, p, unknowns < p.shape[0], inc)
    subdomain, body = _merge_slivers(subdomain, body, pair_subs, mesh.f2t)
    return Partition(subdomain=subdomain, body=body, pairs=pairs, pair_contacts=pair_contacts)


def _prefix_holding(t_ordered: np.ndarray, unknowns: np.ndarray, target: float, least: int) -> int:
    """Smallest number k ≥ least of leading cells whose nodes hold ≥ target unknowns (all if never)."""
    ncell = t_ordered.shape[1]
    first = np.full(unknowns.size, ncell)                 # first cell (in order) holding each node
    np.minimum.at(first, t_ordered.ravel(), np.tile(np.arange(ncell), t_ordered.shape[0]))
    held = first < ncell
    order = np.argsort(first[held], kind="stable")
    ranks, held_unknowns = first[held][order], np.cumsum(unknowns[held][order])
    j = int(np.searchsorted(held_unknowns, target))       # nodes needed
    k = ncell if j >= ranks.size else int(ranks[j]) + 1
    return max(k, least)


def cell_unknowns(t: np.ndarray, unknowns: np.ndarray, inc: sp.csr_matrix) -> np.ndarray:
    """Each node's unknowns spread evenly over its cells: the cells' weights sum to the unknowns."""
    valence = np.maximum(np.diff(inc.indptr), 1)
    return (unknowns / valence)[t].sum(axis=0)


def _release_support_slivers(subdomain, body, pair_subs, t, p, supported, inc, fraction=0.25):
    """Rule 4 of the module docstring: where a linear subdomain's supported nodes span less than
    `fraction` of its extent (largest coordinate range), its cells at those nodes go to the
    linear subdomain of its body sharing them with the most supported nodes, if it has more."""
    subdomain = subdomain.copy()
    for s in range(body.size):
        if s in pair_subs:
            continue
        cells = np.flatnonzero(subdomain == s)
        nodes = np.unique(t[:, cells])
        held = nodes[supported[nodes]]
        if held.size == 0:
            continue
        extent = np.ptp(p[:, nodes], axis=1).max()
        if np.ptp(p[:, held], axis=1).max() >= fraction * extent:
            continue
        at = np.unique(inc[held].indices)                    # every cell at a supported node
        near = at[(subdomain[at] != s)]
        near = near[(body[subdomain[near]] == body[s]) & ~np.isin(subdomain[near], list(pair_subs))]
        if near.size == 0:
            continue
        # of the linear subdomains sharing those nodes, the one with the most supported nodes
        counts = {}
        for r in np.unique(subdomain[near]):
            rn = np.unique(t[:, subdomain == r])
            counts[int(r)] = int(np.count_nonzero(supported[rn]))
        r = min(counts, key=lambda r: (-counts[r], r))
        if counts[r] <= held.size:
            continue
        give = at[subdomain[at] == s]
        subdomain[give] = r
    return subdomain


def _apportion(counts: np.ndarray, n: int) -> np.ndarray:
    """n parts over groups proportional to counts (largest remainders), ≥ 1 where counts > 0."""
    out = np.zeros(counts.size, dtype=np.int64)
    live = counts > 0
    if not live.any():
        return out
    out[live] = 1
    extra = n - live.sum()
    if extra > 0:
        ideal = counts / counts.sum() * n
        add = np.floor(np.maximum(ideal - 1, 0)).astype(np.int64)
        while add.sum() > extra:
            add[np.argmax(add)] -= 1
        out += add
        rem = ideal - out
        for k in np.lexsort((np.arange(counts.size), -rem))[: n - out.sum()]:
            if live[k]:
                out[k] += 1
    return out


def _merge_slivers(subdomain, body, pair_subs, f2t, fraction=0.25):
    """Merge small linear components into the facet neighbour sharing the most facets; renumber."""
    a, b = f2t
    inner = b >= 0
    while True:
        sizes = np.bincount(subdomain, minlength=body.size)
        linear = np.array([s for s in range(body.size) if s not in pair_subs and sizes[s] > 0])
        if linear.size == 0:
            break
        small = [s for s in linear if sizes[s] < fraction * sizes[linear].mean()]
        merged = False
        for s in sorted(small, key=lambda s: (sizes[s], s)):
            sa, sb = subdomain[a[inner]], subdomain[b[inner]]
            nbr = np.r_[sb[sa == s], sa[sb == s]]
            nbr = nbr[(nbr != s) & (body[nbr] == body[s])]
            if nbr.size == 0:
                continue
            cnt = np.bincount(nbr, minlength=body.size)
            subdomain[subdomain == s] = int(np.argmax(cnt))
            merged = True
            break
        if not merged:
            break
    used = np.unique(subdomain)
    new = -np.ones(body.size, dtype=np.int64)
    new[used] = np.arange(used.size)
    return new[subdomain], body[used]
