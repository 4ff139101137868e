"""Mortar contact rows of two nonmatching sides of a triangle mesh: the dual mortar integrals
(`wcs.geometry.mortar`, whose docstring states the rows) turned into the contact rows the solver
reads (normals, tangents, weighted gaps, weights), and whether two sides match node for node."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import StudyError
from ..geometry.mortar import mortar_integrals
from ..scene.selectors import arc_coordinate
from .pairs import check_near, check_penetration, default_nodal_dofs, pair_sides, side_extent


@dataclass(frozen=True, eq=False)
class MortarPairs:
    """Mortar contact rows of one contact, the same fields as `pairs.ContactPairs`
    (row i = kept slave node) plus the coupling rows ``C``. ``master_nodes`` /
    ``master_weights`` list, per row, the master nodes and the coefficients
    (D⁻¹M)_jl, padded with weight 0 (dual coefficients may be NEGATIVE: use
    ``master_weights != 0`` to find the master nodes a row reaches, or ``master``)."""

    slave: np.ndarray
    master_nodes: np.ndarray
    master_weights: np.ndarray
    normal: np.ndarray
    tangent: np.ndarray
    gap: np.ndarray
    weight: np.ndarray
    dropped: np.ndarray
    C: sp.csr_matrix
    master: np.ndarray
    discretization: str = "mortar"

    def __len__(self) -> int:
        return int(self.slave.size)


def mortar_sides(mesh, slave_facets, master_facets, path: str = "contact") -> MortarPairs:
    """Mortar contact rows between a slave and a master side (see the module doc)."""
    mi = mortar_integrals(mesh, slave_facets, master_facets, path=path)
    if mi.slave.size == 0:
        raise StudyError("the slave and master sides do not face each other (no slave segment "
                         "projects onto the master side along its normal)", path=path)
    n = mi.normal + 0.0
    X = mesh.p.T
    CX = mi.C @ X                                               # (m, 2): x_j − Σ (D⁻¹M)_jl x_l
    gap = -np.einsum("ij,ij->i", CX, n)
    h = float(np.mean(mi.D))
    gap[np.abs(gap) <= 1e-12 * h] = 0.0
    check_penetration(gap, X[mi.slave], h, path)
    check_near(np.linalg.norm(CX, axis=1), h, side_extent(mesh, master_facets), path)
    # master nodes / coefficients, padded
    Cm = mi.C.tolil()
    masters = set(mi.master.tolist())
    mn, mw = [], []
    for j, (cols, vals) in enumerate(zip(Cm.rows, Cm.data)):
        pairs = [(c, -v) for c, v in zip(cols, vals) if c != mi.slave[j] and c in masters]
        mn.append([c for c, _ in pairs])
        mw.append([v for _, v in pairs])
    k = max(1, max(len(r) for r in mn))
    MN = np.zeros((len(mn), k), dtype=np.int64)
    MW = np.zeros((len(mn), k))
    for j, (a, b) in enumerate(zip(mn, mw)):
        order = np.argsort(-np.abs(b), kind="stable")
        a, b = np.asarray(a)[order], np.asarray(b)[order]
        MN[j, :a.size], MW[j, :b.size] = a, b
        MN[j, a.size:] = a[0] if a.size else 0
    tangent = np.stack([-n[:, 1], n[:, 0]], axis=1)
    return MortarPairs(slave=mi.slave, master_nodes=MN, master_weights=MW, normal=n, tangent=tangent,
                       gap=gap, weight=mi.D.copy(), dropped=mi.dropped, C=mi.C, master=mi.master)


def mortar_contact(sm, spec, path: str) -> MortarPairs:
    for side in ("slave", "master"):
        if getattr(spec, side) not in sm.boundaries:
            raise StudyError(f"unknown boundary {getattr(spec, side)!r}", path=f"{path}.{side}")
    return mortar_sides(sm.mesh, sm.boundaries[spec.slave], sm.boundaries[spec.master], path)


def directional_rows(C: sp.csr_matrix, direction: np.ndarray, nnodes: int) -> sp.csr_matrix:
    """(m, 2 nnodes) rows ``(C u)_j · d_j`` on node-interleaved DOFs (skfem's vector-P1 order)."""
    nd = default_nodal_dofs(nnodes)
    C = C.tocoo()
    rows = np.concatenate([C.row, C.row])
    cols = np.concatenate([nd[0, C.col], nd[1, C.col]])
    vals = np.concatenate([C.data * direction[C.row, 0], C.data * direction[C.row, 1]])
    B = sp.csr_matrix((vals, (rows, cols)), shape=(C.shape[0], 2 * nnodes))
    B.eliminate_zeros()
    return B


def sides_match(mesh, slave_facets, master_facets, path: str = "contact") -> bool:
    """True when node-to-node pairing is exact: every paired slave node projects onto a
    master node (one to one) and no master node between the hit ones is left out."""
    pr = pair_sides(mesh, slave_facets, master_facets, path)
    if len(pr) == 0 or np.any(pr.master_weights[:, 1] != 0.0):
        return False
    hit = pr.master_nodes[:, 0]
    if np.unique(hit).size != hit.size:
        return False
    master_facets = np.unique(np.asarray(master_facets, dtype=np.int64))
    mnodes = np.unique(mesh.facets[:, master_facets])
    s = arc_coordinate(mesh, master_facets, mnodes)
    sh = s[np.searchsorted(mnodes, hit)]
    between = (s >= sh.min() - 1e-12) & (s <= sh.max() + 1e-12)
    return int(between.sum()) == hit.size
