"""Mortar contact rows of two nonmatching triangulated surfaces (3D): the integrals of
`wcs.geometry.mortar3d` (whose docstring states the rows) turned into the contact rows the
solver reads, as `wcs.contact.mortar` does in 2D."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import StudyError
from ..geometry.mortar3d import side_integrals3d
from .pairs import check_near, check_penetration, side_extent, tangents


@dataclass(frozen=True, eq=False)
class MortarPairs3D:
    """Mortar contact rows of one 3D contact (row j = kept slave node): the fields of
    `mortar.MortarPairs` with 3-vectors, two tangents per node and the integrals D, M."""

    slave: np.ndarray          # (m,)
    normal: np.ndarray         # (m, 3)
    tangent: np.ndarray        # (m, 2, 3)
    gap: np.ndarray            # (m,) weighted gap g̃_j = −(C x)_j · n_j, ≥ 0 open
    weight: np.ndarray         # (m,) D_jj
    dropped: np.ndarray
    C: sp.csr_matrix           # (m, nnodes)
    M: sp.csr_matrix           # (m, nnodes)
    master: np.ndarray
    discretization: str = "mortar"

    def __len__(self) -> int:
        return int(self.slave.size)


def mortar_sides3d(mesh, slave_facets, master_facets, path: str = "contact") -> MortarPairs3D:
    """Mortar contact rows between a slave and a master side of a ``MeshTet`` (boundary
    facet indices; see the module doc)."""
    x = mesh.p.T
    mi = side_integrals3d(mesh, slave_facets, master_facets, path=path)
    if mi.slave.size == 0:
        raise StudyError("the slave and master sides do not face each other (no slave triangle "
                         "projects onto the master side along its normal)", path=path)
    n = mi.normal
    CX = mi.C @ x                                               # (m, 3): x_j − Σ (D⁻¹M)_jl x_l
    gap = -np.einsum("ij,ij->i", CX, n)
    h = float(np.sqrt(np.mean(mi.D)))
    gap[np.abs(gap) <= 1e-12 * h] = 0.0
    check_penetration(gap, x[mi.slave], h, path)
    check_near(np.linalg.norm(CX, axis=1), h, side_extent(mesh, master_facets), path)
    return MortarPairs3D(slave=mi.slave, normal=n, tangent=tangents(n), gap=gap, weight=mi.D.copy(),
                         dropped=mi.dropped, C=mi.C, M=mi.M, master=mi.master)


def mortar_contact3d(sm, spec, path: str) -> MortarPairs3D:
    """`mortar_sides3d` of a scene contact (slave and master boundary names)."""
    for side in ("slave", "master"):
        if getattr(spec, side) not in sm.boundaries:
            raise StudyError(f"unknown boundary {getattr(spec, side)!r}", path=f"{path}.{side}")
    return mortar_sides3d(sm.mesh, sm.boundaries[spec.slave], sm.boundaries[spec.master], path)


def directional_rows3d(C: sp.csr_matrix, direction: np.ndarray) -> sp.csr_matrix:
    """(m, 3 nnodes) rows ``(C u)_j · d_j`` on node-interleaved DOFs (3i, 3i+1, 3i+2)."""
    C = C.tocoo()
    rows = np.tile(C.row, 3)
    cols = np.concatenate([3 * C.col + k for k in range(3)])
    vals = np.concatenate([C.data * direction[C.row, k] for k in range(3)])
    B = sp.csr_matrix((vals, (rows, cols)), shape=(C.shape[0], 3 * C.shape[1]))
    B.eliminate_zeros()
    return B


def jump_rows(pr: MortarPairs3D) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """(Bn, Bt) of one contact: Bn (m, 3 nnodes), Bt (2m, 3 nnodes) stacked by component
    (row k·m + j is tangent k of slave node j), as `wcs.contact.solver` reads them."""
    Bt = sp.vstack([directional_rows3d(pr.C, pr.tangent[:, k]) for k in range(2)]).tocsr()
    return directional_rows3d(pr.C, pr.normal), Bt
