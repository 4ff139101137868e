r"""Deterministic partition of the bodies into subdomains for the DD contact solver.

Rule ([21, §4]: subdomain interfaces Γ do not cut the contact boundary, ``Γ ∩ Γ_c = ∅``):

1. **Contact bands.** For every contact side (the slave nodes and the master
   nodes of a contact), the cells touching a side node form a band; every
   band is grown to the cells of its body whose centroid lies within
   ``δ = pair_size · H`` of the side (H = (area/subdomains)^½, the mean
   subdomain diameter): a band of even thickness, also on graded meshes. Since every cell around a contact node lies in its band, contact
   nodes are interior to one subdomain: interfaces never cut a contact side.
2. **Pairs.** Bands of one body that share a node are merged (otherwise their
   common nodes would be interface DOFs seen by no linear subdomain, and
   ``S0`` of [21, (4.33)] would be singular there). Bands joined through a
   contact form a *cluster* (a pair in [21]; several contacts may chain
   several bands); within a cluster the bands of one body form ONE
   subdomain. A body with free rigid modes (held only by contact) is not
   split: all of it joins its cluster (its linear part would float in
   ``S0`` and the successive approximations [21, (4.37)] would be
   ill-posed).
3. **Linear subdomains.** The remaining cells of every body are split by
   recursive coordinate bisection of the cell centroids (longest extent
   first, stable ties by cell index) into a number of pieces proportional
   to their cell count, so that the total is ``subdomains``. Pieces are
   split into facet-connected components; components smaller than a
   quarter of the mean linear subdomain merge into the facet neighbour
   sharing the most facets (a sliver attached by a vertex would make the
   local Dirichlet problem singular).

Same mesh, contacts and options → same partition (no randomness, stable sorts).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree


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
    nc = t.shape[1]
    return sp.csr_matrix((np.ones(3 * nc), (t.T.ravel(), np.repeat(np.arange(nc), 3))), shape=(nnodes, nc))


def rcb(xy: np.ndarray, n: int) -> np.ndarray:
    """Recursive coordinate bisection of points (k, 2) into n parts; labels 0..n-1.

    Cuts across the longest extent; part sizes proportional to the part counts
    (n1 = ⌊n/2⌋ of n). Ties sorted by point index: deterministic.
    """
    labels = np.zeros(len(xy), dtype=np.int64)

    def split(idx, n, first):
        if n <= 1 or idx.size == 0:
            labels[idx] = first
            return
        pts = xy[idx]
        axis = int(np.argmax(np.ptp(pts, axis=0))) if idx.size > 1 else 0
        order = idx[np.lexsort((idx, pts[:, axis]))]
        n1 = n // 2
        k = int(round(idx.size * n1 / n))
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
              subdomains: int, pair_size: float) -> Partition:
    """Partition the cells; see the module docstring.

    mesh:      skfem.MeshTri (p, t, f2t)
    cell_body: (ncells,) body index of every cell
    sides:     (contact index, body index, side nodes) for both sides of every contact
    floating:  bodies with free rigid modes (kept whole in their cluster)
    subdomains: total number of subdomains aimed at (pairs' halves included)
    pair_size: band thickness in units of the mean subdomain diameter
    """
    t, p = mesh.t, mesh.p
    nc, nn = t.shape[1], p.shape[1]
    inc = node_cell_incidence(t, nn)

    # 1. a band per contact side; a floating body's band is the whole body
    bands, band_body = [], []
    for _, b, nodes in sides:
        cells = np.unique(inc[np.asarray(nodes)].indices)
        bands.append(np.isin(np.arange(nc), cells) if b not in floating else cell_body == b)
        band_body.append(b)
    nb = len(bands)

    # grow every band to the cells of its body within distance δ of its side (nearest side
    # claims a contested cell; ties to the lower band index): a band of even thickness
    # δ = pair_size · H, H = (area / subdomains)^½ the mean subdomain diameter
    centroid = p[:, t].mean(axis=1).T
    e1, e2 = p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]
    area = 0.5 * np.abs(e1[0] * e2[1] - e1[1] * e2[0])
    delta = pair_size * np.sqrt(area.sum() / max(subdomains, 1))
    owner = -np.ones(nc, dtype=np.int64)
    best = np.full(nc, np.inf)
    for k in range(nb):
        dist, _ = cKDTree(p[:, sides[k][2]].T).query(centroid)
        take = (bands[k] | ((dist <= delta) & (cell_body == band_body[k]))) & (dist < best)
        if band_body[k] in floating:
            take = bands[k] & (owner < 0)
        owner[take], best[take] = k, dist[take]
    for k in range(nb):                               # the cells at a side node are never given away
        owner[bands[k] & ~np.isin(owner, [j for j in range(nb) if band_body[j] == band_body[k]])] = k

    # 2. merge bands of one body sharing a node; clusters through contacts
    uf = _UnionFind(nb)
    node_sets = [np.unique(t[:, owner == k]) for k in range(nb)]
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

    # 3. linear subdomains: RCB of the rest of every body
    rest = subdomain < 0
    nbodies = int(cell_body.max()) + 1
    counts = np.bincount(cell_body[rest], minlength=nbodies)
    left = max(subdomains - len(body), int(np.count_nonzero(counts)))
    share = _apportion(counts, left)
    for b in range(nbodies):
        cells = np.flatnonzero(rest & (cell_body == b))
        if cells.size == 0:
            continue
        lab = rcb(centroid[cells], int(share[b]))
        for k in range(int(share[b])):
            for comp in facet_components(cells[lab == k], mesh.f2t):
                subdomain[comp] = len(body)
                body.append(b)
    body = np.asarray(body, dtype=np.int64)
    subdomain, body = _merge_slivers(subdomain, body, {s for q in pairs for s in q}, mesh.f2t)
    return Partition(subdomain=subdomain, body=body, pairs=pairs, pair_contacts=pair_contacts)


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
