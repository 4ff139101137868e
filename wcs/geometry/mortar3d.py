r"""Segment-based dual mortar contact of two nonmatching triangulated surfaces (3D).

The 3D form of `wcs.geometry.mortar` (seed [101, (16)–(26)]; the segment-based
integration of Puso & Laursen, CMAME 193 (2004), with the dual basis of Popp,
Gitterle, Gee & Wall, IJNME 83 (2010)): rows of the same form, so the solver, the
criteria and the adjoint gradients see only ``Bn, Bt, gap, weight``.

The integrals
-------------
Slave side Γ_s and master side Γ_m are P1 surface triangles (boundary facets of
a tetrahedral mesh, each oriented with its outward normal). Each flat slave
triangle T is its own projection plane: the master triangles that face it
(ν_m · n_T < −0.001) are projected onto the plane of T along n_T and clipped
against T (Sutherland–Hodgman, both convex); each clipped polygon is cut into
triangles from its vertex centroid and integrated with the 3-point rule, exact
for the degree-2 products below. Along n_T the projection is affine, so the
master shape functions φ^m_l at a point of the polygon are its barycentric
coordinates in the projected master triangle, and

    D_jj = ∫ ψ_j φ_j ds,     M_jl = ∫ ψ_j φ^m_l ds

are exact on the slave triangles. The dual basis ψ_j, biorthogonal to φ_j
(∫ψ_i φ_j = δ_ij ∫φ_j, [101, (16)]), is built per slave triangle on its
*covered* part: ψ = A φ with A = D_T M_T⁻¹, M_T the covered 3 × 3 mass matrix,
D_T = diag(M_T 1); on a fully covered triangle that is ψ_a = 3φ_a − 1. A
triangle covered on less than 1e-6 of its area contributes nothing; a slave node
whose D_jj is below 1e-6 of its tributary area (a third of its triangles) has no
row (``dropped``). Slave nodes on the boundary of the slave side or held by a
support are treated as in the 2D contact mortar: no crosspoint modification (a
support only removes the constrained DOFs from the rows; a node at the edge of
the covered zone gets its row from its covered triangles). Excluded slave nodes
(``exclude``: gluing, a slave node carrying a support) are the 2D glue's
crosspoint modification: on each slave triangle the dual function of an excluded
vertex is shared equally by the triangle's kept vertices (ψ̃_i = ψ_i + ψ_a / k, k
kept vertices; a triangle with no kept vertex contributes nothing), the excluded
node has no row and a kept row gets ``+S_ia / D_ii`` on it (``S_ia = ∫ψ̃_i φ_a``).
Σ_i ψ̃_i = Σ_i ψ_i, so the rows still see no jump in a rigid motion. Master triangles
that overlap in projection (two layers of the master side over one slave
triangle) are a `StudyError`: the covered area would exceed the triangle's.

Rows
----
As in 2D, ``(C u)_j = u_j − Σ_l (D⁻¹M)_jl u_l`` (the basis transformation of
[101, (24)–(25)]); Σ_l M_jl = D_jj, so a rigid motion has no jump. The row
normal is ``n_j = −∫φ_j ν_m ds / |·|`` (the master's outward normal averaged
over the support of φ_j, reversed: out of the slave; on a flat master exactly
the master normal, on matching sides the area-weighted slave nodal normal), the
tangents ``t_j¹, t_j²`` complete it to a right-handed orthonormal frame
(`pairs.tangents`), the weighted gap is ``g̃_j = −(C x)_j · n_j`` and the weight is
``w_j = D_jj`` (the covered tributary area): λn_j = w_j p_j carries the pressure
p_j. ``Bn`` has one row per kept slave node, ``Bt`` two, stacked by component
(row k·m + j is tangent k of node j), on node-interleaved DOFs (3i, 3i+1, 3i+2).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import StudyError
from . import tet

FACING = 1e-3               # a master triangle faces a slave one when ν_m · n_T < −FACING
MIN_COVER = 1e-6            # a covered fraction of a slave triangle / tributary area below this is ignored
OVERLAP = 1e-9              # covered area above (1 + OVERLAP) × the triangle's: the master overlaps itself
# 3-point rule on the reference triangle, exact for degree 2 (barycentric points, weights sum 1)
_QB = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
_QW = np.full(3, 1 / 3)


def oriented_facets(mesh, facets) -> np.ndarray:
    """(k, 3) node ids of boundary facets of a ``MeshTet``, ordered so that
    (x1 − x0) × (x2 − x0) points along the outward normal (`tet.face_normals`)."""
    facets = np.asarray(facets, dtype=np.int64)
    tri = mesh.facets[:, facets].T.copy()
    outward, _ = tet.face_normals(mesh, facets)
    ordered, _ = triangle_normals(mesh.p.T, tri)
    flip = np.einsum("ij,ij->i", ordered, outward) < 0.0
    tri[flip, 1], tri[flip, 2] = tri[flip, 2], tri[flip, 1].copy()
    return tri


def triangle_normals(x: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (k, 3) and areas (k,) of the triangles ``tri`` (k, 3) of points ``x`` (n, 3)."""
    c = np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])
    a = np.linalg.norm(c, axis=1)
    return c / a[:, None], 0.5 * a


def _clip_many(poly: np.ndarray, count: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each counter-clockwise polygon ``poly[p, :count[p]]`` (P, K, 2) clipped by its
    counter-clockwise triangle ``tri[p]`` (P, 3, 2): `facets._clip` of all pairs at once, the same
    operations in the same order (Sutherland–Hodgman; an emptied polygon has count 0). Returns the
    clipped polygons (P, K', 2) and their vertex counts (P,)."""
    for i in range(3):
        a, b = tri[:, i], tri[:, (i + 1) % 3]
        e = b - a
        side = (e[:, None, 0] * (poly[:, :, 1] - a[:, None, 1])
                - e[:, None, 1] * (poly[:, :, 0] - a[:, None, 0]))                # >= 0: inside
        j = np.arange(poly.shape[1])
        prev = (j[None, :] - 1) % np.maximum(count, 1)[:, None]                  # p = poly[j − 1]
        p, sp_ = np.take_along_axis(poly, prev[:, :, None], axis=1), np.take_along_axis(side, prev, axis=1)
        real = j[None, :] < count[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            cut = p + (poly - p) * (sp_ / (sp_ - side))[:, :, None]
        out = np.stack([cut, poly], axis=2).reshape(poly.shape[0], -1, 2)       # cut_j, q_j, ...
        keep = (np.stack([(sp_ >= 0) != (side >= 0), side >= 0], axis=2) & real[:, :, None]).reshape(poly.shape[0], -1)
        count = keep.sum(axis=1)
        slot = np.cumsum(keep, axis=1) - 1
        poly = np.zeros((poly.shape[0], max(int(count.max(initial=0)), 1), 2))
        r, c = np.nonzero(keep)
        poly[r, slot[r, c]] = out[r, c]
    return poly, count


def _pairs(x: np.ndarray, slave_tri: np.ndarray, sn: np.ndarray, mnu: np.ndarray, mc: np.ndarray,
           mrad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(slave, master) triangle index pairs, sorted by slave then master: the master faces the
    slave (ν_m · n_T < −FACING) and their bounding circles may overlap laterally (in the slave's
    plane): lateral² = |d|² − (d·n_T)² ≤ (1 + 1e-6)(r_s + r_m)², d the centroids' difference
    (about the points' mean). The margin only adds pairs whose circles are disjoint: their clipped
    polygon is empty, so it changes nothing."""
    o = x.mean(axis=0)
    xs = x[slave_tri] - o
    sc, mc = xs.mean(axis=1), mc - o
    srad = np.linalg.norm(xs - sc[:, None, :], axis=2).max(axis=1)
    s2, m2 = np.einsum("sd,sd->s", sc, sc), np.einsum("md,md->m", mc, mc)
    chunk = max(1, 2 ** 22 // mc.shape[0])                    # (chunk × masters) floats at a time
    es, fs = [], []
    for lo in range(0, slave_tri.shape[0], chunk):
        hi = min(lo + chunk, slave_tri.shape[0])
        n0, c0 = sn[lo:hi], sc[lo:hi]
        dn = n0 @ mc.T - np.einsum("sd,sd->s", n0, c0)[:, None]
        lateral2 = (s2[lo:hi, None] + m2[None, :] - 2.0 * (c0 @ mc.T)) - dn ** 2
        reach = srad[lo:hi, None] + mrad[None, :]
        e, f = np.nonzero((n0 @ mnu.T < -FACING) & (lateral2 <= (1.0 + 1e-6) * reach ** 2))
        es.append(e + lo)
        fs.append(f)
    return np.concatenate(es), np.concatenate(fs)


def _segments(x, slave_tri, master_tri, sn, mnu):
    """The clipped polygons of all facing pairs cut into triangles from their vertex centroid, and
    each triangle's 3-point rule. Returns the in-plane frames ``(E, ys)`` of the slave triangles
    ((S, 2, 3) axes, (S, 3, 2) vertices, counter-clockwise), the covered area of each slave
    triangle, and per Gauss point (in the order: slave, master, fan triangle, point): slave
    triangle, master triangle, projected point (G, 2), weight, and per pair its projected master
    vertices (order [0, 2, 1]: counter-clockwise) and pair index of each point."""
    xs = x[slave_tri]
    d1 = xs[:, 1] - xs[:, 0]
    e1 = d1 / np.sqrt(np.vecdot(d1, d1))[:, None]                       # |d1| as np.linalg.norm of one
    E = np.stack([e1, np.cross(sn, e1)], axis=1)                          # (S, 2, 3) in-plane axes
    ys = np.matmul(xs - xs[:, :1], E.transpose(0, 2, 1))                  # (S, 3, 2) counter-clockwise
    mc = x[master_tri].mean(axis=1)
    mrad = np.linalg.norm(x[master_tri] - mc[:, None, :], axis=2).max(axis=1)
    e, f = _pairs(x, slave_tri, sn, mnu, mc, mrad)
    Y = np.einsum("kvd,ked->kve", x[master_tri[f]][:, [0, 2, 1]] - xs[e, :1], E[e])   # reversed: ccw
    lo, hi = ys[e].min(axis=1), ys[e].max(axis=1)
    area2 = 0.5 * ((Y[:, :, 0] * np.roll(Y[:, :, 1], -1, axis=1)).sum(axis=1)
                   - (np.roll(Y[:, :, 0], -1, axis=1) * Y[:, :, 1]).sum(axis=1))
    use = (Y.min(axis=1) < hi).all(axis=1) & (Y.max(axis=1) > lo).all(axis=1) & (area2 > 0.0)
    e, f, Y = e[use], f[use], Y[use]
    poly, n = _clip_many(Y, np.full(e.size, 3), ys[e])
    j = np.arange(poly.shape[1])
    real = j[None, :] < n[:, None]
    c = np.zeros((e.size, 2))
    for k in range(poly.shape[1]):                                        # the vertex mean, in order
        c = c + np.where(real[:, k, None], poly[:, k], 0.0)
    c = c / np.maximum(n, 1)[:, None]
    a = poly - c[:, None, :]
    b = np.take_along_axis(poly, ((j[None, :] + 1) % np.maximum(n, 1)[:, None])[:, :, None], axis=1) - c[:, None, :]
    sub = 0.5 * (a[:, :, 0] * b[:, :, 1] - a[:, :, 1] * b[:, :, 0])       # fan from the centroid
    good = real & (sub > 0.0) & (n >= 3)[:, None]
    cover = np.zeros(e.size)
    for k in range(poly.shape[1]):
        cover = cover + np.where(good[:, k], sub[:, k], 0.0)
    covered = np.zeros(slave_tri.shape[0])
    np.add.at(covered, e, cover)
    pair, k = np.nonzero(good)
    cc = c[pair][:, None, :]
    yg = (_QB[None, :, 0, None] * cc + _QB[None, :, 1, None] * (a[pair, k][:, None] + cc)
          + _QB[None, :, 2, None] * (b[pair, k][:, None] + cc)).reshape(-1, 2)     # Gauss points
    w = np.repeat(sub[pair, k], 3) * np.tile(_QW, pair.size)
    return E, ys, covered, np.repeat(pair, 3), yg, w, e, f, Y


def _barycentric_many(tri: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(B, 3, g) barycentric coordinates of points y (B, g, 2) in the 2D triangles tri (B, 3, 2):
    `_barycentric` of each (the same LAPACK solve per triangle, g right-hand sides)."""
    T = np.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]], axis=2)          # (B, 2, 2)
    l12 = np.linalg.solve(T, (y - tri[:, :1]).transpose(0, 2, 1))                  # (B, 2, g)
    return np.concatenate([1.0 - l12.sum(axis=1, keepdims=True), l12], axis=1)


def _grouped(key: np.ndarray, index: np.ndarray):
    """(value, index[key == value]) for each distinct value of ``key``."""
    for v in np.unique(key):
        yield int(v), index[key == v]


def _master_shapes(Y: np.ndarray, y: np.ndarray, gpair: np.ndarray) -> np.ndarray:
    """(G, 3) master shape functions φ^m at the points ``y`` (G, 2): barycentric in the
    projected master triangle ``Y[gpair]`` (order [0, 2, 1]), each pair's points solved together."""
    Nm = np.empty((y.shape[0], 3))
    count = np.bincount(gpair, minlength=Y.shape[0])
    start = np.searchsorted(gpair, np.arange(Y.shape[0]))
    for g, pairs in _grouped(count[count > 0], np.flatnonzero(count)):
        at = start[pairs][:, None] + np.arange(g)
        Nm[at] = _barycentric_many(Y[pairs], y[at]).transpose(0, 2, 1)
    return Nm


def _triangle_terms(ys, y, w, Nm, nu, ge, kept, ex):
    """The 3 × 3 algebra of each kept slave triangle T (its points ``ge == T`` contiguous), batched
    by the number of points: D_T = diag(M_T 1) (S, 3), ∫φ_a ν_m (S, 3, 3), the dual basis
    ψ = D_T M_T⁻¹ φ (shared from the excluded vertices ``ex`` (S, 3) as ψ̃ = Q ψ) and the M
    values ψ̃_i w φ^m_k at each point (G, 3, 3), and S_ia = ∫ψ̃_i φ_a of the excluded a (S, 3, 3)."""
    S = ys.shape[0]
    De, Ne, Sx = np.zeros((S, 3)), np.zeros((S, 3, 3)), np.zeros((S, 3, 3))
    Mp = np.zeros((y.shape[0], 3, 3))
    count = np.bincount(ge, minlength=S)
    start = np.searchsorted(ge, np.arange(S))
    for g, tris in _grouped(count[kept], np.flatnonzero(kept)):
        at = start[tris][:, None] + np.arange(g)               # (B, g) point indices
        wg = w[at]
        Ns = _barycentric_many(ys[tris], y[at])                # (B, 3, g)
        Me = np.matmul(Ns * wg[:, None, :], Ns.transpose(0, 2, 1))
        De[tris] = Me.sum(axis=2)
        psi = np.matmul(De[tris][:, :, None] * np.linalg.inv(Me), Ns)
        Ne[tris] = np.matmul(Ns, wg[:, :, None] * nu[at])
        part = ex[tris].any(axis=1)
        if part.any():                                         # ψ̃ = Q ψ: the excluded ψ shared
            k = ex[tris[part]]
            Q = (np.eye(3) * ~k[:, None, :]
                 + (~k[:, :, None] & k[:, None, :]) / np.count_nonzero(~k, axis=1)[:, None, None])
            psi[part] = np.matmul(Q, psi[part])
            Sx[tris[part]] = Q * k[:, None, :] * De[tris[part]][:, None, :]
        Mp[at] = np.einsum("big,bg,bkg->bigk", psi, wg, Nm[at].transpose(0, 2, 1)).transpose(0, 2, 1, 3)
    return De, Ne, Mp, Sx


@dataclass(frozen=True)
class MortarIntegrals3D:
    """The dual mortar operator of one slave / master pair of triangulated sides."""

    slave: np.ndarray          # (m,) kept slave node ids (sorted)
    D: np.ndarray              # (m,) D_jj = ∫ψ_j φ_j = the covered ∫φ_j
    M: sp.csr_matrix           # (m, nnodes) M_jl on the master node columns
    C: sp.csr_matrix           # (m, nnodes) coupling rows: 1 on the slave node, −D⁻¹M on masters
    normal: np.ndarray         # (m, 3) −∫φ_j ν_master / |·|: out of the slave, towards the master
    dropped: np.ndarray        # slave node ids without a row
    master: np.ndarray         # master node ids with a nonzero coefficient
    covered: np.ndarray        # (S,) covered area of each slave triangle (in the order given)


def mortar_integrals3d(x: np.ndarray, slave_tri: np.ndarray, master_tri: np.ndarray,
                       exclude=(), path: str = "mortar") -> MortarIntegrals3D:
    """Segment-based dual mortar integrals (see the module doc) of the slave triangles
    ``slave_tri`` (S, 3) and master triangles ``master_tri`` (M, 3), node ids into the points
    ``x`` (n, 3), each ordered counter-clockwise about its outward normal; the slave nodes
    ``exclude`` get no row (their dual functions merged into their neighbours'). All facing
    pairs are clipped and integrated at once (`_segments`), the 3 × 3 algebra of the slave
    triangles is batched by their number of Gauss points."""
    slave_tri = np.asarray(slave_tri, dtype=np.int64).reshape(-1, 3)
    master_tri = np.asarray(master_tri, dtype=np.int64).reshape(-1, 3)
    if slave_tri.shape[0] == 0 or master_tri.shape[0] == 0:
        raise StudyError("a side has no triangle", path=path)
    snodes, sloc = np.unique(slave_tri, return_inverse=True)
    sloc = sloc.reshape(-1, 3)
    if np.intersect1d(snodes, master_tri).size:
        raise StudyError("the slave and master sides share nodes (same body?); the two sides "
                         "must belong to different bodies", path=path)
    sn, sarea = triangle_normals(x, slave_tri)
    mnu, _ = triangle_normals(x, master_tri)
    excluded = np.isin(snodes, np.asarray(exclude, dtype=np.int64))
    E, ys, covered, gpair, y, w, pe, pf, Y = _segments(x, slave_tri, master_tri, sn, mnu)
    over = np.flatnonzero(covered > (1.0 + OVERLAP) * sarea)
    if over.size:
        e = over[0]
        raise StudyError(f"the master side overlaps itself seen from a slave triangle (covered area "
                         f"{covered[e]:.6g} > the triangle's {sarea[e]:.6g}): two layers of the master "
                         "side face the slave side", path=path)
    Nm = _master_shapes(Y, y, gpair)
    ge = pe[gpair]                                             # slave triangle of each point
    kept = (covered >= MIN_COVER * sarea) & ~excluded[sloc].all(axis=1)
    De, Ne, Mp, Sx = _triangle_terms(ys, y, w, Nm, mnu[pf[gpair]], ge, kept, excluded[sloc])
    ns = snodes.size
    Drow = np.zeros(ns)
    Nrow = np.zeros((ns, 3))                                   # ∫ φ_j ν_master ds
    np.add.at(Drow, sloc[kept], De[kept])
    np.add.at(Nrow, sloc[kept].ravel(), Ne[kept].reshape(-1, 3))
    trib = np.bincount(sloc.ravel(), np.repeat(sarea / 3.0, 3), ns)
    keep = (Drow > MIN_COVER * trib) & ~excluded
    m = int(keep.sum())
    newrow = np.full(ns, -1)
    newrow[keep] = np.arange(m)
    nn = x.shape[0]
    point, i = np.divmod(np.flatnonzero(np.repeat(kept[ge], 3)), 3)   # (point, slave vertex) entries
    o = np.lexsort((point, i, ge[point]))                      # in the order slave triangle, vertex, point
    point, i = point[o], i[o]
    r = np.repeat(sloc[ge[point], i], 3)
    c = master_tri[pf[gpair[point]]][:, [0, 2, 1]].ravel()
    v = Mp[point, i].ravel()
    sel = keep[r]
    M = sp.csr_matrix((v[sel], (newrow[r[sel]], c[sel])), shape=(m, nn))
    M.sum_duplicates()
    Dk = Drow[keep]
    C = sp.csr_matrix((np.ones(m), (np.arange(m), snodes[keep])), shape=(m, nn)) - sp.diags(1.0 / Dk) @ M
    mask = kept[:, None, None] & np.broadcast_to(excluded[sloc][:, None, :], Sx.shape)
    if mask.any():                                             # S_ia of the excluded vertices a
        r = np.broadcast_to(sloc[:, :, None], Sx.shape)[mask]
        c = np.broadcast_to(snodes[sloc][:, None, :], Sx.shape)[mask]
        sel = keep[r]
        C = C + sp.diags(1.0 / Dk) @ sp.csr_matrix((Sx[mask][sel], (newrow[r[sel]], c[sel])), shape=(m, nn))
    C = C.tocsr()
    C.data[np.abs(C.data) < 1e-14] = 0.0
    C.eliminate_zeros()
    master = np.setdiff1d(np.unique(C.indices), snodes)
    Nk = -Nrow[keep]
    Nk /= np.maximum(np.linalg.norm(Nk, axis=1), 1e-300)[:, None]
    return MortarIntegrals3D(slave=snodes[keep], D=Dk, M=M, C=C, normal=Nk,
                             dropped=snodes[~keep], master=master, covered=covered)


def side_integrals3d(mesh, slave_facets, master_facets, exclude=(), path: str = "mortar") -> MortarIntegrals3D:
    """`mortar_integrals3d` of a slave and a master side of a ``MeshTet`` (boundary facet
    indices), as `wcs.geometry.mortar.mortar_integrals` of a triangle mesh's sides."""
    return mortar_integrals3d(mesh.p.T, oriented_facets(mesh, np.unique(slave_facets)),
                              oriented_facets(mesh, np.unique(master_facets)), exclude=exclude, path=path)
