r"""Mortar coupling of two nonmatching boundary sides with dual (biorthogonal) multipliers.

Used for contact (`contacts.<c>.discretization: mortar`, whose rows `wcs.contact.mortar`
builds from these integrals) and for glued interfaces (`glue:`, `wcs.fem.gluing`). Seed
[101, (16)–(26)].

The integrals
-------------
The slave side Γ_s (P1 trace, shape functions φ_j, slave nodes j) is mapped
onto the master side by projecting along the slave normal field
``n(ξ) = (1−ξ) n_a + ξ n_b`` (nodal normals interpolated on each slave
segment, the usual 2D mortar map). Breakpoints are the slave nodes and the
master nodes projected onto the slave segments; on each resulting piece
(segment-to-segment integration on the "supermesh" of the two traces) the
master segment hit at the piece's midpoint (nearest along the normal when
several are) supplies the master shape functions φ^m_l, and Gauss quadrature
(4 points: exact for straight sides, accurate for curved ones) gives

    D_jj = ∫ ψ_j φ_j ds,     M_jl = ∫ ψ_j φ^m_l ds,

with the dual basis ψ_j, biorthogonal to φ_j (∫ψ_i φ_j = δ_ij ∫φ_j, [101, (16)]).
ψ is built per slave segment on its *covered* part (where the projection
lands on the master side): ψ = A φ with A = D_e M_e⁻¹, M_e the covered
mass matrix and D_e = diag(M_e 1); on a fully covered segment that is the
classical ψ_a = 2φ_a − φ_b. A segment covered on less than 1e-6 of its
length contributes nothing; slave nodes left with D_jj = 0 are dropped.

Rows
----
The weak coupling of slave node j, ``∫ ψ_j [u] ds``, divided by D_jj, reads

    (C u)_j = u_j − Σ_l (D⁻¹M)_jl u_l  (+ merged slave terms, see below),

coefficient 1 on the slave node, −(D⁻¹M)_jl on master nodes: the basis
transformation of [101, (24)–(25)] (M̂ = D⁻¹M) — in the transformed basis
the condition involves the slave node only. Since Σ_l M_jl = D_jj (dual basis
and master shape functions both partitions of unity on the covered part),
every row reproduces affine fields: a rigid motion has no jump.

* Contact: the row along the normal ``n_j = −∫φ_j ν_m ds / |·|`` (the master's
  outward normal ν_m averaged over the support of φ_j, reversed: out of the
  slave towards the master, as in pairs.py; on matching sides it is the slave
  nodal normal, on a flat master exactly the master normal) is the weak
  non-penetration ``(C u)_j · n_j ≤ g̃_j``
  with the weighted gap ``g̃_j = −(C x)_j · n_j`` (``x`` the reference
  coordinates): exactly the form of a node-to-segment row (pairs.py), with
  nodal weight ``w_j = D_jj`` (the covered ∫φ_j, the tributary length) so
  that the solver's λn_j = w_j p_j carries the dual multiplier coefficient
  p_j (the pressure) and the Tresca bound |λt_j| ≤ g w_j. The solver
  (PDAS / semismooth Newton, `wcs.contact.solver`), the criteria and the
  adjoint gradients see only ``Bn, Bt, gap, weight``.
* Gluing: ``C u = 0`` componentwise eliminates the slave DOFs,
  ``u_j = Σ_l (D⁻¹M)_jl u_l`` (the linear case of [33]).
* Excluded slave nodes (gluing: a slave node carrying a support): their dual
  function is merged into the neighbour's on the same segment (ψ̃_b = ψ_b +
  ψ_a, the crosspoint modification of the multiplier space); their row is
  dropped and the neighbour's row gets ``+S_ba / D_bb`` on the excluded node
  (``S_ba = ∫ ψ̃_b φ_a``), which stays a kept unknown.

On matching sides ``D⁻¹M`` is the identity on the coincident nodes and the
rows equal node-to-node rows (same normals, weights, zero gaps).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import StudyError
from .facets import facet_normals, nodal_normals

NGAUSS = 4
MIN_COVER = 1e-6            # a covered fraction of a slave segment below this is ignored
PARAM_TOL = 1e-9            # tolerance on the master segment parameter η ∈ [0, 1]
_GX, _GW = np.polynomial.legendre.leggauss(NGAUSS)
_GX, _GW = 0.5 * (_GX + 1.0), 0.5 * _GW             # on [0, 1]


def _cross(u, v):
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


@dataclass(frozen=True)
class MortarIntegrals:
    """The dual mortar operator of one slave / master pair of sides."""

    slave: np.ndarray          # (m,) kept slave node ids (sorted)
    D: np.ndarray              # (m,) D_jj
    C: sp.csr_matrix           # (m, nnodes) coupling rows (1 on the slave, −D⁻¹M on masters, merged terms)
    normal: np.ndarray         # (m, 2) −∫φ_j ν_master / |·|: out of the slave, towards the master
    dropped: np.ndarray        # slave node ids without a row (uncovered or excluded)
    master: np.ndarray         # master node ids with a nonzero coefficient


def _project_onto_segment(xa, xb, na, nb, xm):
    """ξ of points xm (k, 2) projected onto the segment (xa, xb) along n(ξ); NaN if none."""
    E, F = xb - xa, nb - na
    A = xa[None, :] - xm
    c = _cross(A, na[None, :])
    b = _cross(A, F[None, :]) + _cross(E, na)
    a = _cross(E, F)
    scale = np.abs(b) + np.abs(c) + 1e-300
    if abs(a) <= 1e-12 * scale.max():
        with np.errstate(divide="ignore", invalid="ignore"):
            xi = -c / b
        return np.where(np.abs(b) > 1e-300, xi, np.nan)
    disc = b * b - 4 * a * c
    sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
    # numerically stable roots
    q = -0.5 * (b + np.copysign(sq, b))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1, r2 = q / a, c / q
    pick = np.abs(r1 - 0.5) <= np.abs(r2 - 0.5)
    return np.where(pick, r1, r2)


def mortar_integrals(mesh, slave_facets, master_facets, exclude=(), path: str = "mortar") -> MortarIntegrals:
    """Segment-to-segment dual mortar integrals of a slave and a master side (see module doc)."""
    slave_facets = np.unique(np.asarray(slave_facets, dtype=np.int64))
    master_facets = np.unique(np.asarray(master_facets, dtype=np.int64))
    if slave_facets.size == 0 or master_facets.size == 0:
        raise StudyError("a side has no edge", path=path)
    p = mesh.p.T
    snodes, snormal = nodal_normals(mesh, slave_facets)
    sf = np.searchsorted(snodes, mesh.facets[:, slave_facets]).T          # (S, 2) local ids
    sfn = facet_normals(mesh, slave_facets)
    mf = mesh.facets[:, master_facets].T                                  # (M, 2) node ids
    if np.intersect1d(snodes, mf).size:
        raise StudyError("the slave and master sides share nodes (same body?); the two sides "
                         "must belong to different bodies", path=path)
    mnu = facet_normals(mesh, master_facets)
    Cm, Dm = p[mf[:, 0]], p[mf[:, 1]]
    DCm = Dm - Cm
    excluded = np.isin(snodes, np.asarray(exclude, dtype=np.int64))

    S = len(slave_facets)
    nn = mesh.p.shape[1]
    Drow = np.zeros(snodes.size)
    Nrow = np.zeros((snodes.size, 2))            # ∫ φ_j ν_master ds (the contact normal, see the doc)
    rows, cols, vals = [], [], []                # slave-local row, global node, value (−M or +S)
    for e in range(S):
        ia, ib = sf[e]
        xa, xb = p[snodes[ia]], p[snodes[ib]]
        na, nb = snormal[ia], snormal[ib]
        L = float(np.hypot(*(xb - xa)))
        # candidate master segments: facing the slave segment
        facing = mnu @ sfn[e] < -1e-3
        cand = np.flatnonzero(facing)
        if cand.size == 0:
            continue
        xc = _project_onto_segment(xa, xb, na, nb, Cm[cand])
        xd = _project_onto_segment(xa, xb, na, nb, Dm[cand])
        lo, hi = np.fmin(xc, xd), np.fmax(xc, xd)
        ok = np.isfinite(lo) & np.isfinite(hi) & (hi > 0.0) & (lo < 1.0)
        cand, lo, hi = cand[ok], lo[ok], hi[ok]
        if cand.size == 0:
            continue
        br = np.unique(np.clip(np.concatenate([[0.0, 1.0], lo, hi]), 0.0, 1.0))
        pieces = []                                   # (ξ0, ξ1, master segment)
        for k in range(br.size - 1):
            x0, x1 = br[k], br[k + 1]
            if x1 - x0 <= 1e-12:
                continue
            xm = 0.5 * (x0 + x1)
            inside = cand[(lo <= xm) & (hi >= xm)]
            if inside.size == 0:
                continue
            xg = xa + xm * (xb - xa)
            ng = na + xm * (nb - na)
            den = _cross(DCm[inside], ng[None, :])
            with np.errstate(divide="ignore", invalid="ignore"):
                eta = _cross(xg[None, :] - Cm[inside], ng[None, :]) / den
                t = np.einsum("ij,j->i", Cm[inside] + eta[:, None] * DCm[inside] - xg, ng)
            good = np.isfinite(eta) & (eta >= -PARAM_TOL) & (eta <= 1 + PARAM_TOL)
            if not good.any():
                continue
            f = inside[good][np.argmin(np.abs(t[good]))]
            if pieces and pieces[-1][2] == f and abs(pieces[-1][1] - x0) < 1e-14:
                pieces[-1] = (pieces[-1][0], x1, f)
            else:
                pieces.append((x0, x1, f))
        covered = sum(x1 - x0 for x0, x1, _ in pieces)
        if covered < MIN_COVER:
            continue
        # covered mass matrix and dual coefficients A = D_e M_e⁻¹
        Me = np.zeros((2, 2))
        gauss = []
        for x0, x1, f in pieces:
            xi = x0 + (x1 - x0) * _GX
            w = (x1 - x0) * _GW * L
            phi = np.stack([1 - xi, xi])                       # (2, g)
            Me += (phi * w) @ phi.T
            Nrow[[ia, ib]] += (phi @ w)[:, None] * mnu[f][None, :]
            xg = xa[None, :] + xi[:, None] * (xb - xa)[None, :]
            ng = na[None, :] + xi[:, None] * (nb - na)[None, :]
            eta = _cross(xg - Cm[f], ng) / _cross(DCm[f][None, :], ng)
            eta = np.clip(eta, 0.0, 1.0)
            gauss.append((phi, w, np.stack([1 - eta, eta]), f))
        De = Me.sum(axis=1)
        A = De[:, None] * np.linalg.inv(Me)                    # ψ_i = Σ_k A_ik φ_k
        ex = excluded[[ia, ib]]
        if ex.all():
            continue
        Sloc = np.diag(De)                                     # S_ik = ∫ψ_i φ_k
        if ex.any():                                           # merge ψ of the excluded node into the other
            keep, gone = (1, 0) if ex[0] else (0, 1)
            A[keep] += A[gone]
            A[gone] = 0.0
            Sloc[keep] += Sloc[gone]
            Sloc[gone] = 0.0
        loc = (ia, ib)
        for i in range(2):
            if ex[i]:
                continue
            Drow[loc[i]] += Sloc[i, i]
            other = 1 - i
            if Sloc[i, other] != 0.0:
                rows.append(loc[i]); cols.append(snodes[loc[other]]); vals.append(Sloc[i, other])
        for phi, w, phim, f in gauss:
            psi = A @ phi                                      # (2, g)
            Mloc = (psi * w) @ phim.T                          # (2 slave, 2 master)
            for i in range(2):
                if ex[i]:
                    continue
                for k in range(2):
                    rows.append(loc[i]); cols.append(mf[f, k]); vals.append(-Mloc[i, k])

    keep = (Drow > 0.0) & ~excluded
    # drop nodes whose covered ∫φ is negligible against their full tributary length
    lens = np.hypot(*(p[snodes[sf[:, 1]]] - p[snodes[sf[:, 0]]]).T)
    trib = 0.5 * (np.bincount(sf[:, 0], lens, snodes.size) + np.bincount(sf[:, 1], lens, snodes.size))
    keep &= Drow > MIN_COVER * trib
    newrow = np.full(snodes.size, -1)
    newrow[keep] = np.arange(int(keep.sum()))
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    vals = np.asarray(vals, dtype=float)
    sel = keep[rows] if rows.size else np.zeros(0, bool)
    m = int(keep.sum())
    r = newrow[rows[sel]]
    Dk = Drow[keep]
    Cmat = sp.csr_matrix((np.concatenate([np.ones(m), vals[sel] / Dk[r]]),
                          (np.concatenate([np.arange(m), r]), np.concatenate([snodes[keep], cols[sel]]))),
                         shape=(m, nn))
    Cmat.sum_duplicates()
    Cmat.data[np.abs(Cmat.data) < 1e-14] = 0.0
    Cmat.eliminate_zeros()
    master = np.intersect1d(np.unique(Cmat.indices), np.unique(mf))
    Nk = -Nrow[keep]
    Nk /= np.maximum(np.hypot(Nk[:, 0], Nk[:, 1]), 1e-300)[:, None]
    return MortarIntegrals(slave=snodes[keep], D=Dk, C=Cmat, normal=Nk,
                           dropped=snodes[~keep], master=master)
