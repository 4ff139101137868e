r"""Glued interfaces between bodies meshed independently: dual mortar elimination.

A scene's ``glue: {NAME: {slave: BOUNDARY, master: BOUNDARY}}`` ties the two
sides: the weak continuity ``∫ ψ_j [u] ds = 0`` for every dual multiplier ψ_j
of the slave side ([33] with the dual basis of [101]; `wcs.geometry.mortar` on
the edges of a triangle mesh, `wcs.geometry.mortar3d` on the faces of a
tetrahedral one: rows of the same form) reads, after division by D_jj,
``u_j = Σ_l (D⁻¹M)_jl u_l`` per component: the slave DOFs are functions of the
master DOFs and are eliminated.

It composes with the nodal constraint elimination (`wcs.fem.constraints`):
with ``u = P v`` (``P``: identity on the kept DOFs, the mortar rows on the
slave DOFs; glue chains — a slave side that is another glue's master — are
resolved by repeated substitution) and the nodal elimination
``u = T w + U0 c`` built on all nodes (slave nodes carry no support), the
composition is ``u = (P T) w + (P U0) c``, the identity columns of the slave
DOFs dropped. Slave nodes that carry a support keep their support and are
left out of the glue (their dual function merged into the neighbours',
``exclude=`` of `mortar.mortar_integrals` / `mortar3d.side_integrals3d`). On
matching sides ``D⁻¹M`` is the identity on coincident nodes: the glue is
exactly a node-to-node tie.

The same rows glue the temperature (scalar) across the interface
(`glue_heat`), so heat flows through glued interfaces as through a body.

For the DD solver (wcs/dd): with glue, ``model.elim.T`` has rows that couple
the slave DOFs of one body to master DOFs of another (and to the neighbouring
excluded slave nodes); a reduced unknown may therefore live on two bodies. A
partition that keeps each glued interface (slave side + the master nodes its
rows reach: ``Glue.rows.C`` / ``Glue.rows.master``) inside one subdomain, or
that treats the reduced master DOFs as interface DOFs shared by the glued
subdomains, works with T unchanged; ``glued_clusters`` gives the bodies that
move together (their rigid modes are joint). For mortar CONTACT the rows are
generic (``Bn``/``Bt``) but may reach more than two master nodes and with
negative coefficients: find a contact's master nodes with
``pairs.master`` (MortarPairs) or ``master_weights != 0`` — not ``> 0``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import StudyError
from ..geometry.mortar import MortarIntegrals, mortar_integrals
from ..geometry.mortar3d import MortarIntegrals3D, side_integrals3d
from .constraints import Elimination

SIDE_INTEGRALS = {2: mortar_integrals, 3: side_integrals3d}     # the dual mortar rows by dimension
APART = 0.1                 # a glued slave node farther than this x h from its master image: the sides do not touch


@dataclass(frozen=True)
class Glue:
    name: str
    slave_body: int
    master_bodies: tuple          # a master side may run along several bodies
    rows: MortarIntegrals | MortarIntegrals3D


def build_glue(scene, smesh, supported_nodes=()) -> list[Glue]:
    """The mortar rows of every ``glue`` entry of the scene, in scene order.

    Slave nodes with a support are excluded (they keep the support). A slave node
    already glued by an earlier entry (a crosspoint where slave sides of several
    glues meet) is excluded from the later ones: its value comes from the first,
    the later glues see it as a known neighbour (substitution resolves the chain)."""
    out = []
    nb = smesh.node_body
    dim = smesh.mesh.p.shape[0]
    integrals, side_kind = SIDE_INTEGRALS[dim], ("edge", "triangle")[dim - 2]
    taken = set(np.asarray(supported_nodes, dtype=np.int64).tolist())
    for name, spec in scene.glue.items():
        path = f"scene.glue.{name}"
        for side in ("slave", "master"):
            if getattr(spec, side) not in smesh.boundaries:
                raise StudyError(f"unknown boundary {getattr(spec, side)!r}", path=f"{path}.{side}")
        sf, mf = smesh.boundaries[spec.slave], smesh.boundaries[spec.master]
        sb = np.unique(nb[np.unique(smesh.mesh.facets[:, sf])])      # the bodies first: two sides of one
        mb = np.unique(nb[np.unique(smesh.mesh.facets[:, mf])])      # body fail whatever their supports
        if sb.size != 1:
            raise StudyError("the slave side of a glue must lie on one body", path=f"{path}.slave")
        if sb[0] in mb:
            raise StudyError(f"slave and master of a glue belong to the same body ({smesh.bodies[sb[0]]!r}); "
                             "a glue joins two different bodies", path=f"{path}.master")
        mi = integrals(smesh.mesh, sf, mf, exclude=sorted(taken), path=path)
        if mi.slave.size == 0 and taken.issuperset(np.unique(smesh.mesh.facets[:, sf]).tolist()):
            raise StudyError("every node of the slave side carries a support (or is glued by an earlier "
                             "glue): nothing is left to glue", path=f"{path}.slave")
        if mi.slave.size == 0:
            raise StudyError(f"the glued sides do not face each other (no slave {side_kind} projects "
                             "onto the master side)", path=path)
        check_touching(smesh.mesh.p.T, mi, max(edge_size(smesh.mesh, sf), edge_size(smesh.mesh, mf)), path)
        taken.update(mi.slave.tolist())
        out.append(Glue(name, int(sb[0]), tuple(int(b) for b in mb), mi))
    return out


def edge_size(mesh, facets) -> float:
    """The mean edge length of boundary facets (edges in 2D, triangles in 3D)."""
    f = mesh.facets[:, np.asarray(facets, dtype=np.int64)]
    pairs = [(0, 1)] if f.shape[0] == 2 else [(0, 1), (1, 2), (2, 0)]
    return float(np.mean([np.linalg.norm(mesh.p[:, f[a]] - mesh.p[:, f[b]], axis=0) for a, b in pairs]))


def check_touching(x: np.ndarray, mi, h: float, path: str) -> None:
    """StudyError at ``path`` when a glued slave node lies farther than APART × h (h the larger
    element size of the two sides) from the master side along its row's normal, measured to its
    image: the point it is tied to (the row's master coefficients, normalised to sum 1, applied to
    the master nodes; exactly D⁻¹M x on a row without excluded neighbours). Glue ties sides that
    touch (Γ^{kl} = ∂Ω^k ∩ ∂Ω^l, [21, §2]); across a gap it would be a rigid link the study
    does not state. Matching sides are at 0, curved nonmatching ones at most at the coarser side's
    sagitta, h²/(8R) (below 0.04 h with 24 segments per circle)."""
    w = -mi.C[:, mi.master]
    image = (w @ x[mi.master]) / np.asarray(w.sum(axis=1))
    apart = np.abs(np.einsum("ij,ij->i", x[mi.slave] - image, mi.normal))
    j = int(np.argmax(apart))
    if apart[j] > APART * h:
        at = ", ".join(f"{v:.4g}" for v in x[mi.slave[j]])
        raise StudyError(f"the glued sides do not touch: the slave node at ({at}) is {apart[j]:.3g} from the "
                         f"master side along the normal (more than {APART} x the element size {h:.3g}); glue "
                         "joins sides that coincide (move a side, or use a contact for a gap)", path=path)


def substitution(glues: list[Glue], nnodes: int, ncomp: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """(P, slave DOFs): u = P u with P[:, slave DOFs] = 0 (the slave DOFs expressed in kept DOFs)."""
    ndof = ncomp * nnodes
    if not glues:
        return sp.identity(ndof, format="csr"), np.zeros(0, dtype=np.int64)
    slave_nodes = np.concatenate([g.rows.slave for g in glues])
    slave_dofs = (ncomp * slave_nodes[:, None] + np.arange(ncomp)).ravel()
    keep = np.ones(ndof, bool)
    keep[slave_dofs] = False
    r, c, v = [np.flatnonzero(keep)], [np.flatnonzero(keep)], [np.ones(int(keep.sum()))]
    for g in glues:
        C = g.rows.C.tocoo()
        off = C.col != g.rows.slave[C.row]                   # u_j = −Σ_{k≠j} C_jk u_k
        row_node, col_node, val = g.rows.slave[C.row[off]], C.col[off], -C.data[off]
        for k in range(ncomp):
            r.append(ncomp * row_node + k); c.append(ncomp * col_node + k); v.append(val)
    P0 = sp.csr_matrix((np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(ndof, ndof))
    P = P0
    for _ in range(len(glues) + 1):
        if P[:, slave_dofs].nnz == 0:
            return P.tocsr(), np.sort(slave_dofs)
        P = (P0 @ P).tocsr()
        P.eliminate_zeros()
    raise StudyError("the glued interfaces form a cycle (a slave side depends on itself through "
                     "other glues); make one side of the cycle a master", path="scene.glue")


def glue_elimination(elim: Elimination, glues: list[Glue], nnodes: int, ncomp: int) -> Elimination:
    """Compose a nodal-constraint elimination with the glue substitution (see the module doc)."""
    if not glues:
        return elim
    P, slave_dofs = substitution(glues, nnodes, ncomp)
    T = (P @ elim.T).tocsc()
    T.eliminate_zeros()
    used = np.diff(T.indptr) > 0
    T = sp.csr_matrix(T[:, np.flatnonzero(used)])
    U0 = sp.csr_matrix(P @ elim.U0)
    return Elimination(T=T, U0=U0, fixed_dofs=elim.fixed_dofs)


def glue_heat(glues: list[Glue], heat_of_node: np.ndarray, nheat: int) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """Scalar glue rows on the heat nodes (coincident nodes already merged): per slave heat
    node ``(h, heat nodes k, coefficients a)`` meaning ``θ_h = Σ a_k θ_k``. Rows already
    satisfied by the merge (the slave coincides with its master) are left out."""
    out = []
    for g in glues:
        C = g.rows.C.tocsr()
        for j in range(C.shape[0]):
            lo, hi = C.indptr[j], C.indptr[j + 1]
            cols, vals = heat_of_node[C.indices[lo:hi]], C.data[lo:hi]
            h = heat_of_node[g.rows.slave[j]]
            acc = np.zeros(0)
            keys, inv = np.unique(cols, return_inverse=True)
            acc = np.bincount(inv, vals, keys.size)
            self_coef = acc[keys == h].sum()
            others = keys != h
            if abs(self_coef) < 1e-10 or not np.any(np.abs(acc[others]) > 1e-14):
                continue
            out.append((int(h), keys[others], -acc[others] / self_coef))
    return out


def heat_glue_elimination(elim: Elimination, rows, nheat: int, constrained=()) -> Elimination:
    """Compose the heat nodes' elimination with the scalar glue rows of `glue_heat`
    (rows of a slave heat node with a prescribed temperature are left out)."""
    fixed = set(np.asarray(constrained, dtype=np.int64).tolist())
    rows = [r for r in rows if r[0] not in fixed]
    if not rows:
        return elim
    slaves = np.array([h for h, _, _ in rows], dtype=np.int64)
    if np.unique(slaves).size != slaves.size:     # a heat node glued twice: keep the first row
        _, first = np.unique(slaves, return_index=True)
        rows = [rows[i] for i in sorted(first)]
        slaves = slaves[sorted(first)]
    keep = np.ones(nheat, bool)
    keep[slaves] = False
    r, c, v = [np.flatnonzero(keep)], [np.flatnonzero(keep)], [np.ones(int(keep.sum()))]
    for h, ks, a in rows:
        r.append(np.full(ks.size, h)); c.append(ks); v.append(a)
    P0 = sp.csr_matrix((np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(nheat, nheat))
    P = P0
    for _ in range(len(rows) + 1):
        if P[:, slaves].nnz == 0:
            break
        P = (P0 @ P).tocsr()
        P.eliminate_zeros()
    else:
        raise StudyError("the glued interfaces form a cycle", path="scene.glue")
    T = (P @ elim.T).tocsc()
    T.eliminate_zeros()
    used = np.diff(T.indptr) > 0
    return Elimination(T=sp.csr_matrix(T[:, np.flatnonzero(used)]), U0=sp.csr_matrix(P @ elim.U0),
                       fixed_dofs=elim.fixed_dofs)


def glued_clusters(nbodies: int, glues: list[Glue]) -> list[list[int]]:
    """Bodies joined by glue, as sorted groups (each body in exactly one group), ordered
    by their first body."""
    parent = list(range(nbodies))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for g in glues:
        for m in g.master_bodies:
            a, b = find(g.slave_body), find(m)
            if a != b:
                parent[max(a, b)] = min(a, b)
    groups: dict[int, list[int]] = {}
    for i in range(nbodies):
        groups.setdefault(find(i), []).append(i)
    return [groups[k] for k in sorted(groups)]
