"""Node-to-segment contact pairs between a slave and a master boundary side (2D), and
node-to-node pairs on matching faces (3D, `match_faces`).

Sign conventions (used everywhere in wcs.contact)
-------------------------------------------------
* ``normal[i]`` (written ``n_i``) is the unit normal pointing OUT of the slave
  body towards the master body: ``n_i = -nu_master(y_i)``, the opposite of the
  master side's outward normal at the projection ``y_i`` of slave node ``x_i``
  (the master facet's normal, or the master nodal normal -- length-weighted
  facet average -- when ``y_i`` is a master node).  For matching (coincident)
  sides this is exactly the slave side's outward nodal normal.  This is the
  normal ``n = n^k`` of body ``k`` in the contact conditions of [21, §2], with the slave
  as body ``k``.
* ``tangent[i] = R(+90°) n_i = (-n_y, n_x)``.
* ``gap[i] = (y_i - x_i) · n_i`` in the reference configuration: ``>= 0`` open,
  ``< 0`` initial penetration, exactly 0 for coincident nodes.  ``y_i`` is the
  closest point of the master side, so ``|gap|`` is the distance to it.
* Jumps: with ``u`` the displacement vector,
  ``(B_n u)_i = (u(x_i) - sum_k w_ik u(m_ik)) · n_i`` (slave minus master,
  along ``n_i``), ``(B_t u)_i`` the same along ``t_i``.  A slave node moving
  towards the master increases ``B_n u``; the deformed gap is
  ``gap - B_n u``, so non-penetration is ``B_n u <= gap`` ([68, (2.10)]:
  ``u_n^k - u_n^l <= d``, d the initial gap) and ``B_t u`` is the relative tangential slip.
* ``weight[i]`` is the tributary length of the slave node (half the lengths
  of its adjacent slave facets): nodal force = traction × weight.

Which slave nodes are paired
----------------------------
Each slave node is projected (closest point) onto the master side.  It is
DROPPED (listed in ``dropped``) when the projection falls outside the master
side -- the closest point is an end node of the master side and the
orthogonal projection lies beyond it (relative tolerance ``1e-6`` of the end
facet's length) -- or when the sides do not face each other there (the
slave's own outward nodal normal has ``n_slave · n_i <= 0``).  If no kept node
is within ``max(5 × mean facet length, 1% of the master side length)`` of the
master side, the two sides do not face each other: ``StudyError`` at ``path``
(``check_near``, also used by mortar in 2D and 3D).
A kept node whose initial gap is below ``-PENETRATION`` × the mean facet length
lies deep inside the master body: the sides overlap or face away from each other
(e.g. the top of the upper block against the bottom of the lower one, whose
normals also oppose): ``StudyError`` (``check_penetration``, also used by mortar).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import StudyError
from ..geometry import tet
from ..geometry.facets import facet_lengths, facet_normals, nodal_normals
from ..geometry.near import nearest_within

SNAP = 1e-9             # |s| (facet parameter) below this -> the projection is the master node
OUTSIDE = 1e-6          # projection parameter beyond an end of the master side by more -> dropped
COINCIDENT = 1e-9       # distance / mean facet length below this -> coincident nodes, gap 0
PENETRATION = 0.5       # initial gap / mean facet length below -this -> the sides do not face
_CHUNK = 2_000_000      # slave nodes x master facets per vectorised block


@dataclass(frozen=True, eq=False)
class ContactPairs:
    """Node-to-segment pairs; row ``i`` is one kept slave node (sorted ids)."""

    slave: np.ndarray            # (m,) slave node ids, sorted
    master_nodes: np.ndarray     # (m, 2) master node ids (the projection's facet)
    master_weights: np.ndarray   # (m, 2) linear interpolation weights, sum 1; (1, 0) if coincident
    normal: np.ndarray           # (m, 2) n_i: out of the slave, = -master outward normal
    tangent: np.ndarray          # (m, 2) (-n_y, n_x)
    gap: np.ndarray              # (m,) (y_i - x_i)·n_i, >= 0 open
    weight: np.ndarray           # (m,) tributary length of the slave node
    dropped: np.ndarray          # slave node ids not paired (projection outside / not facing)

    def __len__(self) -> int:
        return int(self.slave.size)


def pair_sides(mesh, slave_facets, master_facets, path: str = "contact") -> ContactPairs:
    """Pair every slave node with its closest-point projection on the master side.

    ``mesh`` is a ``skfem.MeshTri`` whose facets ``slave_facets`` and
    ``master_facets`` are boundary facets (so the outward normals are defined by
    their single cell).  See the module docstring for the conventions.
    """
    slave_facets = np.unique(np.asarray(slave_facets, dtype=np.int64))
    master_facets = np.unique(np.asarray(master_facets, dtype=np.int64))
    if slave_facets.size == 0 or master_facets.size == 0:
        raise StudyError("a contact side has no edge", path=path)
    p = mesh.p
    snodes, snormal = nodal_normals(mesh, slave_facets)
    mf = mesh.facets[:, master_facets]                     # (2, M)
    if np.intersect1d(snodes, mf).size:
        raise StudyError("the slave and master sides share nodes (same body?); a contact needs "
                         "two sides of different bodies", path=path)

    # tributary lengths of slave nodes
    slen = facet_lengths(mesh, slave_facets)
    sidx = np.searchsorted(snodes, mesh.facets[:, slave_facets])
    weight = 0.5 * (np.bincount(sidx[0], slen, snodes.size) + np.bincount(sidx[1], slen, snodes.size))

    # master geometry
    A = p[:, mf[0]].T
    B = p[:, mf[1]].T
    D = B - A
    L2 = np.einsum("ij,ij->i", D, D)
    mlen = np.sqrt(L2)
    mnormal = facet_normals(mesh, master_facets)           # (M, 2) outward of master
    mnodes, mnn = nodal_normals(mesh, master_facets)
    degree = np.bincount(np.searchsorted(mnodes, mf.ravel()), minlength=mnodes.size)
    h = float(np.concatenate([slen, mlen]).mean())

    # closest point on the master polyline, chunked brute force over facets
    X = p[:, snodes].T
    S = X.shape[0]
    M = A.shape[0]
    best = np.empty(S, dtype=np.int64)
    s_raw = np.empty(S)
    step = max(1, _CHUNK // M)
    for lo in range(0, S, step):
        x = X[lo:lo + step]
        s = np.einsum("cmk,mk->cm", x[:, None, :] - A[None], D) / L2
        sc = np.clip(s, 0.0, 1.0)
        r = x[:, None, :] - (A[None] + sc[..., None] * D[None])
        j = np.argmin(np.einsum("cmk,cmk->cm", r, r), axis=1)
        best[lo:lo + step] = j
        s_raw[lo:lo + step] = s[np.arange(len(x)), j]

    s = np.clip(s_raw, 0.0, 1.0)
    at0 = s * mlen[best] <= SNAP * mlen[best]
    at1 = (1.0 - s) * mlen[best] <= SNAP * mlen[best]
    s = np.where(at0, 0.0, np.where(at1, 1.0, s))
    a_node, b_node = mf[0, best], mf[1, best]
    # outside the master side: clamped to an end node (degree 1) and beyond it
    end_a = degree[np.searchsorted(mnodes, a_node)] == 1
    end_b = degree[np.searchsorted(mnodes, b_node)] == 1
    outside = (end_a & (s_raw < -OUTSIDE)) | (end_b & (s_raw > 1.0 + OUTSIDE))

    # master outward normal at the projection: facet normal, or nodal normal at a node
    nu = mnormal[best].copy()
    vert = at0 | at1
    vnode = np.where(at1, b_node, a_node)
    nu[vert] = mnn[np.searchsorted(mnodes, vnode[vert])]
    n = -nu + 0.0                                          # no negative zeros
    facing = np.einsum("ij,ij->i", snormal, n) > 0.0
    keep = ~outside & facing

    y = A[best] + s[:, None] * D[best]
    gap = np.einsum("ij,ij->i", y - X, n)
    dist = np.hypot(*(y - X).T)
    coincident = dist <= COINCIDENT * h
    gap[coincident] = 0.0

    check_near(dist[keep], h, float(mlen.sum()), path)

    check_penetration(gap[keep], X[keep], h, path)

    # master nodes / weights; (node, 1) first at a master node
    mn = np.where(at1[:, None], np.stack([b_node, a_node], 1), np.stack([a_node, b_node], 1))
    mw = np.where(at1[:, None], np.stack([1.0 - s, s], 1)[:, ::-1], np.stack([1.0 - s, s], 1))
    tangent = np.stack([-n[:, 1], n[:, 0]], axis=1)
    return ContactPairs(
        slave=snodes[keep], master_nodes=mn[keep], master_weights=mw[keep],
        normal=n[keep], tangent=tangent[keep], gap=gap[keep], weight=weight[keep],
        dropped=snodes[~keep])


def check_near(dist: np.ndarray, h: float, extent: float, path: str) -> None:
    """StudyError at ``path`` unless some paired slave node lies within NEAR = max(5 h, 1 % of
    ``extent``, the master side's length or diameter) of the master side (``dist``: each kept
    node's distance to its projection): a contact joins sides that touch or nearly touch, d^{kl}
    a small initial gap ([68, (2.10)]); sides farther apart are another interface."""
    near = max(5.0 * h, 0.01 * extent)
    if not np.any(dist <= near):
        closest = f"; the closest is {dist.min():.3g} away" if dist.size else ""
        raise StudyError(
            f"the slave and master sides do not face each other (no slave node within "
            f"{near:.3g} of the master side with opposing normals{closest}); a contact joins sides that "
            "touch or nearly touch: name those sides, or move the bodies together", path=path)


def side_extent(mesh, facets) -> float:
    """The diameter of a side's bounding box (its nodes' coordinate ranges)."""
    x = mesh.p[:, np.unique(mesh.facets[:, np.asarray(facets, dtype=np.int64)])]
    return float(np.linalg.norm(np.ptp(x, axis=1)))


def check_penetration(gap: np.ndarray, coords: np.ndarray, h: float, path: str) -> None:
    """StudyError at ``path`` when a slave node (row of ``coords``) starts deeper than
    PENETRATION × h inside the master side (gap < 0 is an initial penetration)."""
    deep = np.flatnonzero(gap < -PENETRATION * h)
    if deep.size:
        i = deep[np.argmin(gap[deep])]
        raise StudyError(
            f"the slave and master sides do not face each other: {deep.size} slave node(s) start inside "
            f"the master body, up to {-gap[i]:.3g} deep at ({coords[i, 0]:.4g}, {coords[i, 1]:.4g}) "
            f"(more than {PENETRATION} x the element size {h:.3g}); a contact joins the two sides that "
            f"touch, each with its outward normal towards the other body", path=path)


def pair_contact(sm, spec, path: str) -> ContactPairs:
    """Pairs of a scene `Contact` (slave and master boundary names) on a SceneMesh."""
    for side in ("slave", "master"):
        if getattr(spec, side) not in sm.boundaries:
            raise StudyError(f"unknown boundary {getattr(spec, side)!r}", path=f"{path}.{side}")
    return pair_sides(sm.mesh, sm.boundaries[spec.slave], sm.boundaries[spec.master], path)


# ---------------------------------------------------------------------------
# jump operators


def _interleaved_is_skfem_order() -> bool:
    """ElementVector(ElementTriP1) numbers DOFs node-interleaved (x0, y0, x1, ...)?"""
    import skfem
    m = skfem.MeshTri()
    nd = skfem.Basis(m, skfem.ElementVector(skfem.ElementTriP1())).nodal_dofs
    return bool(np.array_equal(nd, np.arange(2 * m.nvertices).reshape(-1, 2).T))


_SKFEM_INTERLEAVED: bool | None = None


def default_nodal_dofs(nnodes: int) -> np.ndarray:
    """(2, nnodes) DOF numbers of a P1 vector field in skfem's order (checked once
    against ``skfem.Basis(..., ElementVector(ElementTriP1())).nodal_dofs``)."""
    global _SKFEM_INTERLEAVED
    if _SKFEM_INTERLEAVED is None:
        _SKFEM_INTERLEAVED = _interleaved_is_skfem_order()
    if not _SKFEM_INTERLEAVED:          # pragma: no cover - guards a change in skfem
        raise RuntimeError("skfem's vector P1 DOF order changed; pass nodal_dofs=basis.nodal_dofs")
    return np.arange(2 * nnodes).reshape(-1, 2).T


def _jump_matrix(pairs: ContactPairs, direction: np.ndarray, nnodes: int, nodal_dofs) -> sp.csr_matrix:
    nd = default_nodal_dofs(nnodes) if nodal_dofs is None else np.asarray(nodal_dofs)
    m = len(pairs)
    rows = np.repeat(np.arange(m), 6)
    nodes = np.concatenate([pairs.slave[:, None], pairs.master_nodes], axis=1)      # (m, 3)
    coef = np.concatenate([np.ones((m, 1)), -pairs.master_weights], axis=1)         # (m, 3)
    cols = np.stack([nd[0, nodes], nd[1, nodes]], axis=2).reshape(m, 6)           # x, y per node
    vals = (coef[:, :, None] * direction[:, None, :]).reshape(m, 6)
    ndofs = max(2 * nnodes, int(nd.max()) + 1)
    B = sp.csr_matrix((vals.ravel(), (rows, cols.ravel())), shape=(m, ndofs))
    B.eliminate_zeros()
    return B


def normal_jump_matrix(pairs: ContactPairs, nnodes: int, nodal_dofs=None) -> sp.csr_matrix:
    """(m, ndofs) ``B_n`` with ``(B_n u)_i = (u_slave - sum_k w_ik u_master_k) · n_i``.

    Non-penetration reads ``B_n u <= pairs.gap``.  ``u`` in skfem's vector-P1
    DOF order (node-interleaved; pass ``nodal_dofs=basis.nodal_dofs`` to use a
    basis' own numbering).  Shape ``(m, 2 * nnodes)``.
    """
    return _jump_matrix(pairs, pairs.normal, nnodes, nodal_dofs)


def tangent_jump_matrix(pairs: ContactPairs, nnodes: int, nodal_dofs=None) -> sp.csr_matrix:
    """(m, ndofs) ``B_t`` with ``(B_t u)_i = (u_slave - sum_k w_ik u_master_k) · t_i``:
    the relative tangential displacement (slip) of the slave node."""
    return _jump_matrix(pairs, pairs.tangent, nnodes, nodal_dofs)


# ---------------------------------------------------------------------------
# 3D: node-to-node pairs on matching faces


@dataclass(frozen=True, eq=False)
class FacePairs:
    """Node-to-node pairs of a 3D contact whose faces match (coincident nodes, the bodies' own
    copies); row ``i`` is one kept slave node (sorted ids). The fields a 3D contact's rows have
    (`jump_rows3d`), node-to-node or mortar."""

    slave: np.ndarray            # (m,) slave node ids, sorted
    master: np.ndarray           # (m,) the coincident master node
    normal: np.ndarray           # (m, 3) out of the slave: its area-weighted nodal normal
    tangent: np.ndarray          # (m, 2, 3) t¹, t² with (t¹, t², n) right-handed orthonormal
    gap: np.ndarray              # (m,) 0: the nodes coincide
    weight: np.ndarray           # (m,) tributary area: one third of each adjacent slave triangle on the master face
    dropped: np.ndarray          # slave node ids with no master node there
    discretization: str = "node-to-node"

    def __len__(self) -> int:
        return int(self.slave.size)


def tangents(normal: np.ndarray) -> np.ndarray:
    """(m, 2, 3) unit tangents t¹, t² with (t¹, t², n) right-handed orthonormal: t¹ is the
    coordinate axis least aligned with n (the first on ties) made orthogonal to n, t² = n × t¹."""
    axis = np.eye(3)[np.argmin(np.abs(normal), axis=1)]
    t1 = axis - np.einsum("ij,ij->i", axis, normal)[:, None] * normal
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return np.stack([t1, np.cross(normal, t1)], axis=1)


def match_faces(mesh, slave_facets, master_facets, path: str = "contact") -> FacePairs | None:
    """Pair each slave node of a ``MeshTet`` with the nearest master node within COINCIDENT × the
    mean slave edge (the same point; of master nodes at one distance, the first); None when the
    faces do not match: a match needs the slave triangles whose three nodes pair onto a master
    triangle to cover the smaller of the two faces (to 1e-9 of its area). Those triangles are the
    contact surface: a slave node is kept when it is a corner of one, with one third of the area
    of each as its tributary area; the others (off a smaller master face) are dropped. A kept node
    whose slave and master normals do not oppose is a StudyError."""
    slave_facets = np.unique(np.asarray(slave_facets, dtype=np.int64))
    master_facets = np.unique(np.asarray(master_facets, dtype=np.int64))
    if slave_facets.size == 0 or master_facets.size == 0:
        raise StudyError("a contact side has no face", path=path)
    p = mesh.p
    snodes, snormal = tet.nodal_normals(mesh, slave_facets)
    mnodes, mnormal = tet.nodal_normals(mesh, master_facets)
    if np.intersect1d(snodes, mnodes).size:
        raise StudyError("the slave and master sides share nodes (same body?); a contact needs "
                         "two sides of different bodies", path=path)
    sf, mf = mesh.facets[:, slave_facets], mesh.facets[:, master_facets]
    edges = np.concatenate([np.linalg.norm(p[:, sf[a]] - p[:, sf[(a + 1) % 3]], axis=0) for a in range(3)])
    h = float(edges.mean())
    _, j = nearest_within(p[:, mnodes].T, p[:, snodes].T, COINCIDENT * h)
    paired = j >= 0
    partner = np.full(p.shape[1], -1)
    partner[snodes[paired]] = mnodes[j[paired]]
    _, sarea = tet.face_normals(mesh, slave_facets)
    _, marea = tet.face_normals(mesh, master_facets)
    image = partner[sf]                                        # (3, S) master nodes of each slave triangle
    whole = (image >= 0).all(axis=0)
    master_keys = {tuple(k) for k in np.sort(mf, axis=0).T.tolist()}
    onto = np.array([tuple(k) in master_keys for k in np.sort(image, axis=0).T.tolist()]) & whole
    if sarea[onto].sum() < (1 - 1e-9) * min(sarea.sum(), marea.sum()):
        return None
    idx = np.searchsorted(snodes, sf)
    weight = sum(np.bincount(idx[a, onto], sarea[onto], snodes.size) for a in range(3)) / 3.0
    keep = weight > 0.0
    n = snormal[keep]
    opposed = np.einsum("ij,ij->i", n, mnormal[j[keep]]) < 0.0
    if not opposed.all():
        x = p[:, snodes[keep][~opposed][0]]
        raise StudyError(f"the slave and master sides do not face each other at ({x[0]:.4g}, {x[1]:.4g}, "
                         f"{x[2]:.4g}): their outward normals do not oppose; a contact joins the two sides "
                         "that touch, each with its outward normal towards the other body", path=path)
    return FacePairs(slave=snodes[keep], master=partner[snodes[keep]], normal=n, tangent=tangents(n),
                     gap=np.zeros(int(keep.sum())), weight=weight[keep], dropped=snodes[~keep])


def jump_rows3d(pr: FacePairs, nnodes: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """(Bn, Bt) of node-to-node pairs on node-interleaved DOFs (3 per node): (Bn u)_i =
    (u_slave − u_master)·n_i, (m, 3 nnodes); Bt (2m, 3 nnodes) stacked by component (row
    k·m + i is tangent k of node i), as `wcs.contact.solver` reads them."""
    m = len(pr)

    def rows(direction):
        cols = np.concatenate([3 * pr.slave[:, None] + np.arange(3), 3 * pr.master[:, None] + np.arange(3)], axis=1)
        vals = np.concatenate([direction, -direction], axis=1)
        B = sp.csr_matrix((vals.ravel(), (np.repeat(np.arange(m), 6), cols.ravel())), shape=(m, 3 * nnodes))
        B.eliminate_zeros()
        return B
    return rows(pr.normal), sp.vstack([rows(pr.tangent[:, k]) for k in range(2)]).tocsr()
