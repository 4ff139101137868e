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
from .facets import _clip

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


def _area2(poly: np.ndarray) -> float:
    """Signed area of a 2D polygon (counter-clockwise positive)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _barycentric(tri: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(3, g) barycentric coordinates of points y (g, 2) in the 2D triangle tri (3, 2)."""
    T = np.stack([tri[1] - tri[0], tri[2] - tri[0]], axis=1)          # (2, 2)
    l12 = np.linalg.solve(T, (y - tri[0]).T)                          # (2, g)
    return np.vstack([1.0 - l12.sum(axis=0), l12])


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
    ``exclude`` get no row (their dual functions merged into their neighbours')."""
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
    mc = x[master_tri].mean(axis=1)
    mrad = np.linalg.norm(x[master_tri] - mc[:, None, :], axis=2).max(axis=1)

    ns = snodes.size
    Drow = np.zeros(ns)
    Nrow = np.zeros((ns, 3))                     # ∫ φ_j ν_master ds
    covered = np.zeros(slave_tri.shape[0])
    rows, cols, vals = [], [], []                # slave-local row, master node, M value
    merged = []                                  # (slave-local rows, excluded nodes, S values)
    for e, tri in enumerate(slave_tri):
        xs, n0 = x[tri], sn[e]
        e1 = (xs[1] - xs[0]) / np.linalg.norm(xs[1] - xs[0])
        E = np.stack([e1, np.cross(n0, e1)])                        # (2, 3) in-plane axes
        ys = (xs - xs[0]) @ E.T                                     # counter-clockwise
        sc = xs.mean(axis=0)
        srad = float(np.linalg.norm(xs - sc, axis=1).max())
        d = mc - sc
        lateral = np.linalg.norm(d - (d @ n0)[:, None] * n0, axis=1)
        cand = np.flatnonzero((mnu @ n0 < -FACING) & (lateral <= srad + mrad))
        Y = np.einsum("kvd,ed->kve", x[master_tri[cand]][:, [0, 2, 1]] - xs[0], E)   # reversed: ccw
        lo, hi = ys.min(axis=0), ys.max(axis=0)
        overlap = (Y.min(axis=1) < hi).all(axis=1) & (Y.max(axis=1) > lo).all(axis=1)
        pts, wts, phim, mcols, nus = [], [], [], [], []
        for f, ym in zip(cand[overlap], Y[overlap]):
            if _area2(ym) <= 0.0:
                continue
            poly = _clip(ym, ys)
            if len(poly) < 3:
                continue
            c = poly.mean(axis=0)
            a, b = poly - c, np.roll(poly, -1, axis=0) - c
            sub = 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])        # fan from the centroid
            good = sub > 0.0
            if not good.any():
                continue
            covered[e] += sub[good].sum()
            yg = (_QB[None, :, 0, None] * c + _QB[None, :, 1, None] * (a[good, None] + c)
                  + _QB[None, :, 2, None] * (b[good, None] + c)).reshape(-1, 2)   # Gauss points
            pts.append(yg)
            wts.append(np.repeat(sub[good], 3) * np.tile(_QW, good.sum()))
            phim.append(_barycentric(ym, yg))                       # in the order [0, 2, 1]
            mcols.append(np.broadcast_to(master_tri[f][[0, 2, 1]], (yg.shape[0], 3)))
            nus.append(np.broadcast_to(mnu[f], (yg.shape[0], 3)))
        if covered[e] > (1.0 + OVERLAP) * sarea[e]:
            raise StudyError(f"the master side overlaps itself seen from a slave triangle (covered area "
                             f"{covered[e]:.6g} > the triangle's {sarea[e]:.6g}): two layers of the master "
                             "side face the slave side", path=path)
        if covered[e] < MIN_COVER * sarea[e]:
            continue
        y = np.concatenate(pts)                                     # (G, 2)
        w = np.concatenate(wts)                                     # (G,)
        Nm = np.concatenate(phim, axis=1)                           # (3, G)
        Mc = np.concatenate(mcols)                                  # (G, 3) master node ids
        Ns = _barycentric(ys, y)                                    # (3, G)
        Me = (Ns * w) @ Ns.T
        De = Me.sum(axis=1)
        psi = (De[:, None] * np.linalg.inv(Me)) @ Ns                # ψ = D_T M_T⁻¹ φ
        loc = sloc[e]
        ex = excluded[loc]
        if ex.all():
            continue
        Drow[loc] += De
        Nrow[loc] += Ns @ (w[:, None] * np.concatenate(nus))
        if ex.any():                                                # ψ̃ = Q ψ: the excluded ψ shared
            Q = np.diag((~ex).astype(float))
            Q[np.ix_(~ex, ex)] = 1.0 / np.count_nonzero(~ex)
            psi = Q @ psi
            S = Q[:, ex] * De[ex]                                   # S_ia = ∫ψ̃_i φ_a, a excluded
            merged.append((np.repeat(loc, ex.sum()), np.tile(snodes[loc[ex]], 3), S.ravel()))
        Mval = np.einsum("ig,g,kg->igk", psi, w, Nm)                # (3 slave, G, 3 master)
        rows.append(np.broadcast_to(loc[:, None, None], Mval.shape).ravel())
        cols.append(np.broadcast_to(Mc[None, :, :], Mval.shape).ravel())
        vals.append(Mval.ravel())

    trib = np.bincount(sloc.ravel(), np.repeat(sarea / 3.0, 3), ns)
    keep = (Drow > MIN_COVER * trib) & ~excluded
    m = int(keep.sum())
    newrow = np.full(ns, -1)
    newrow[keep] = np.arange(m)
    nn = x.shape[0]
    if rows:
        r, c, v = (np.concatenate(a) for a in (rows, cols, vals))
        sel = keep[r]
        M = sp.csr_matrix((v[sel], (newrow[r[sel]], c[sel])), shape=(m, nn))
    else:
        M = sp.csr_matrix((m, nn))
    M.sum_duplicates()
    Dk = Drow[keep]
    C = sp.csr_matrix((np.ones(m), (np.arange(m), snodes[keep])), shape=(m, nn)) - sp.diags(1.0 / Dk) @ M
    if merged:
        r, c, v = (np.concatenate(a) for a in zip(*merged))
        sel = keep[r]
        C = C + sp.diags(1.0 / Dk) @ sp.csr_matrix((v[sel], (newrow[r[sel]], c[sel])), shape=(m, nn))
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
