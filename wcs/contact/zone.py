"""The contact zone of a scene: every contact's node pairs stacked into one set
of jump operators (the friction data per node are coefficients: `wcs.model.coefficients`).

Rows are the paired slave nodes of all contacts, in scene order. `Bn u ≤ gap`
is non-penetration, `Bt u` the relative tangential slip (see `pairs.py`). In 3D each
row has two tangents and Bt stacks them by component over the whole zone (row j·m + i
is tangent j of row i), as `wcs.contact.solver` reads it; the rows of a contact are
node-to-node where its faces match (`pairs.match_faces`), dual mortar (`mortar3d`) where they
do not (`auto`) or when asked.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import StudyError
from ..scene.meshdata import SceneMesh
from ..scene.selectors import arc_coordinate
from .mortar import directional_rows, mortar_contact, sides_match
from .mortar3d import jump_rows, mortar_sides3d
from .pairs import ContactPairs, jump_rows3d, match_faces, normal_jump_matrix, pair_contact, tangent_jump_matrix

DISCRETIZATIONS = ("auto", "node-to-node", "mortar")


@dataclass
class ContactZone:
    names: list[str]             # contact names
    pairs: list[ContactPairs]    # ContactPairs (node-to-node) or mortar.MortarPairs, per contact
    contact_of_node: np.ndarray  # (m,) index into names
    Bn: sp.csr_matrix            # (m, ndof)
    Bt: sp.csr_matrix            # ((d − 1) m, ndof), stacked by component
    gap: np.ndarray              # (m,) initial gaps
    weight: np.ndarray           # (m,) tributary lengths (2D), areas (3D)
    arc: np.ndarray | None       # (m,) normalised position along its contact's slave side (2D; None in 3D)
    coords: np.ndarray           # (m, d)
    discretization: list[str] | None = None   # per contact: "node-to-node" or "mortar"
    tangents: np.ndarray | None = None        # (m, d − 1, d) the tangent directions of each row

    @property
    def nodes(self) -> np.ndarray:
        return np.concatenate([p.slave for p in self.pairs])


def contact_discretization(smesh: SceneMesh, spec, path: str) -> str:
    """The discretization a contact uses: its `discretization` key, `auto` (the default)
    meaning node-to-node when the two sides match (mortar.sides_match), mortar otherwise."""
    kind = spec.discretization
    if kind not in DISCRETIZATIONS:
        raise StudyError(f"unknown discretization {kind!r} (one of {', '.join(DISCRETIZATIONS)})",
                         path=f"{path}.discretization")
    if kind != "auto":
        return kind
    for side in ("slave", "master"):
        if getattr(spec, side) not in smesh.boundaries:
            raise StudyError(f"unknown boundary {getattr(spec, side)!r}", path=f"{path}.{side}")
    try:
        match = sides_match(smesh.mesh, smesh.boundaries[spec.slave], smesh.boundaries[spec.master], path)
    except StudyError:              # node-to-node pairing impossible: let mortar try (and report)
        match = False
    return "node-to-node" if match else "mortar"


def _rows(pr, nn: int):
    """(Bn, Bt) of one contact's pairs, node-to-node or mortar."""
    if getattr(pr, "discretization", "node-to-node") == "mortar":
        return directional_rows(pr.C, pr.normal, nn), directional_rows(pr.C, pr.tangent, nn)
    return normal_jump_matrix(pr, nn), tangent_jump_matrix(pr, nn)


def build_zone(scene, smesh: SceneMesh) -> ContactZone | None:
    contacts = scene.contacts
    if not contacts:
        return None
    if smesh.mesh.p.shape[0] == 3:
        return _build_zone3d(contacts, smesh)
    mesh = smesh.mesh
    nn = mesh.p.shape[1]
    names, pairs, owner, arcs, kinds = [], [], [], [], []
    for k, (name, spec) in enumerate(contacts.items()):
        path = f"scene.contacts.{name}"
        kind = contact_discretization(smesh, spec, path)
        pr = mortar_contact(smesh, spec, path) if kind == "mortar" else pair_contact(smesh, spec, path)
        names.append(name)
        pairs.append(pr)
        kinds.append(kind)
        owner.append(np.full(len(pr), k))
        arcs.append(arc_coordinate(mesh, smesh.boundaries[spec.slave], pr.slave))
    slaves = np.concatenate([p.slave for p in pairs])
    rows = [_rows(p, nn) for p in pairs]
    return ContactZone(
        names=names, pairs=pairs, contact_of_node=np.concatenate(owner),
        Bn=sp.vstack([r[0] for r in rows]).tocsr(),
        Bt=sp.vstack([r[1] for r in rows]).tocsr(),
        gap=np.concatenate([p.gap for p in pairs]), weight=np.concatenate([p.weight for p in pairs]),
        arc=np.concatenate(arcs), coords=mesh.p[:, slaves].T.copy(), discretization=kinds,
        tangents=np.concatenate([p.tangent for p in pairs])[:, None, :],
    )


def _pairs3d(smesh: SceneMesh, spec, path: str):
    """The rows of one 3D contact: node-to-node where its faces match (`auto` or `node-to-node`)."""
    kind = spec.discretization
    if kind not in DISCRETIZATIONS:
        raise StudyError(f"unknown discretization {kind!r} (one of {', '.join(DISCRETIZATIONS)})",
                         path=f"{path}.discretization")
    for side in ("slave", "master"):
        if getattr(spec, side) not in smesh.boundaries:
            raise StudyError(f"unknown boundary {getattr(spec, side)!r}", path=f"{path}.{side}")
    faces = smesh.boundaries[spec.slave], smesh.boundaries[spec.master]
    pr = None if kind == "mortar" else match_faces(smesh.mesh, *faces, path)
    if pr is not None:
        return pr
    if kind == "node-to-node":
        raise StudyError("node-to-node contact in 3D needs matching faces (a master node at every slave "
                         "node); these do not match: use discretization mortar (or auto)", path=f"{path}.discretization")
    return mortar_sides3d(smesh.mesh, *faces, path)


def _rows3d(pr, nn: int):
    """(Bn (m, 3 nn), Bt (2m, 3 nn) stacked by component) of one 3D contact."""
    return jump_rows(pr) if pr.discretization == "mortar" else jump_rows3d(pr, nn)


def _build_zone3d(contacts, smesh: SceneMesh) -> ContactZone:
    mesh = smesh.mesh
    nn = mesh.p.shape[1]
    pairs = [_pairs3d(smesh, spec, f"scene.contacts.{name}") for name, spec in contacts.items()]
    rows = [_rows3d(p, nn) for p in pairs]
    sizes = [len(p) for p in pairs]
    slaves = np.concatenate([p.slave for p in pairs])
    return ContactZone(
        names=list(contacts), pairs=pairs,
        contact_of_node=np.concatenate([np.full(n, k) for k, n in enumerate(sizes)]),
        Bn=sp.vstack([bn for bn, _ in rows]).tocsr(),
        Bt=sp.vstack([bt[j * n:(j + 1) * n] for j in range(2) for (_, bt), n in zip(rows, sizes)]).tocsr(),
        gap=np.concatenate([p.gap for p in pairs]), weight=np.concatenate([p.weight for p in pairs]),
        arc=None, coords=mesh.p[:, slaves].T.copy(), discretization=[p.discretization for p in pairs],
        tangents=np.concatenate([p.tangent for p in pairs]),
    )


def _row_norms2(B: sp.spmatrix) -> np.ndarray:
    """‖B_i‖² of each row."""
    return np.asarray(B.multiply(B).sum(axis=1)).ravel()


def held_rows(B_r: sp.spmatrix, B: sp.spmatrix) -> np.ndarray:
    """The rows the supports hold: ‖B_r,i‖ ≤ 1e-10 ‖B_i‖, the row on the unknowns (B_r, supports
    eliminated) round-off of the row on all DOFs (B) — the share `solver.null_rows` solves as
    null. A 3D fault node on a support that holds two components of both sides keeps ~3e-15 of
    its unit normal along the free third (area-weighted face normals): the tunnel's right side
    holds u_x, u_z, the fault's normal (−2, 0, 3)/√13 has n_y ~ 3e-15 there. Geometry only."""
    return _row_norms2(B_r) <= 1e-20 * _row_norms2(B)


def tied_rows(Bn: sp.spmatrix, Bt: sp.spmatrix, held: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(tied, κ), one entry per tangent row j·m + i: whether node i's tangent row j is parallel
    to its normal row on the unknowns, Bt_j,i = κ Bn_i (rollers on both sides of the node: both
    rows act on one relative motion, so only λn + κ λt of the pair is determined), to an angle
    below 1e-5 rad (t² − (n·t)²/n² ≤ 1e-10 t²; parallel rows leave ~1e-16 t² of round-off).
    held ((1 + k) m, `held_rows` of [Bn; Bt]): rows of round-off, tied to nothing (a held
    normal of ~3e-15 is parallel to a free tangent, and κ ~ 3e14 put 3.5e19 Pa on the 3D
    tunnel fault's end). Geometry only (the reduced rows), so every solver of a scene finds the
    same rows."""
    m = Bn.shape[0]
    k = Bt.shape[0] // m if m else 1
    n2 = np.tile(_row_norms2(Bn), k)
    Bn_k = sp.vstack([Bn] * k).tocsr()
    nt = np.asarray(Bn_k.multiply(Bt).sum(axis=1)).ravel()
    t2 = _row_norms2(Bt)
    kappa = np.divide(nt, n2, out=np.zeros_like(nt), where=n2 > 0)
    tied = (n2 > 0) & (t2 > 0) & (t2 - kappa * nt <= 1e-10 * t2)
    if held is not None:
        tied &= ~np.tile(held[:m], k) & ~held[m:]
    return tied, np.where(tied, kappa, 0.0)


def dependent_rows(Bn: sp.spmatrix, Bt: sp.spmatrix, held: np.ndarray, tied: np.ndarray):
    """(nodes, v): the nodes whose acting rows (neither held nor tied) are linearly dependent on
    the unknowns — their unit rows' Gram matrix has an eigenvalue ≤ 5e-11 (1 − cos θ at the
    angle 1e-5 rad of `tied_rows`) — and for each the combination v ((1 + k),: over λn, λt,1..k,
    zero on the other rows) with Σ_r v_r B_r = 0, so that only λ modulo v acts there. A 3D node
    on a support holding one component of both sides has three rows in two free directions
    (the oblique tunnel's fault on its left roller); rows so dependent without being tied
    leave one such v per node (two would need all three rows parallel: tied). Geometry only."""
    m = Bn.shape[0]
    k = Bt.shape[0] // m if m else 1
    X = [Bn.tocsr()] + [Bt[j * m:(j + 1) * m].tocsr() for j in range(k)]
    act = ~held.reshape(1 + k, m).T & ~np.c_[np.zeros(m, dtype=bool), tied.reshape(k, m).T]
    G = np.empty((m, 1 + k, 1 + k))
    for a in range(1 + k):
        for b in range(a, 1 + k):
            G[:, a, b] = G[:, b, a] = np.asarray(X[a].multiply(X[b]).sum(axis=1)).ravel() * act[:, a] * act[:, b]
    d = np.sqrt(np.where(act, np.einsum("ijj->ij", G), 1.0))
    G = G / (d[:, :, None] * d[:, None, :]) + np.eye(1 + k) * ~act[:, None, :]
    w, V = np.linalg.eigh(G)
    nodes = np.flatnonzero((w[:, 0] <= 5e-11) & (act.sum(axis=1) >= 2))
    v = V[nodes, :, 0] / d[nodes]
    return nodes, v / np.linalg.norm(v, axis=1)[:, None]


def canonical_split(force_n, force_t, gap, tied, kappa, scale: float, held=None, dependent=None):
    """The multipliers of closed nodes with tied rows (`tied_rows`) at one canonical split:
    only a = λn + Σ_j κ_j λt,j acts there, and any λ with that a, λn ≥ 0 and λt within its
    bound solves the problem (which split a solver returns depends on its path: the
    decomposition and the monolithic Newton differed by 4–8 % in λn at the tunnel fault's
    roller-held end). Reported: where a ≥ 0, the tied tangents carry nothing (the supports
    hold that motion) and the normal all of a; where a < 0 (pulled apart), the normal nothing
    and the tied tangents a at the least norm, λt,j = a κ_j / Σ κ² — no larger than any split
    with λn ≥ 0, so within the friction bound whenever the solver's split is.
    Closed: gap ≤ 1e-7 · scale (the displacement scale; the criteria's "within reach").
    A held row (`held_rows`, flags of [λn; λt]) acts on nothing, so its multiplier is not
    determined at all: it carries nothing (the supports hold that motion).
    Dependent rows (`dependent_rows`: nodes i, combinations v): λ_i + s v acts alike for every
    s; reported, the s of the least |λt| with λn ≥ 0 on a closed node (the same rule: the
    tangents carry the least, within the friction bound whenever the solver's split is; a
    slipping node's λt ∥ slip is that one already); an open node keeps λn = 0.
    Returns (force_n, force_t, moved, (dn, dt)): moved flags the tangent rows whose force went
    to the normal; dn (m,), dt ((d − 1) m,) the derivatives of the reported λn by the solver's
    λn and λt (the adjoint of a pressure differentiates the reported value)."""
    m = force_n.size
    k = force_t.size // m if m else 1
    dn = np.ones(m)
    if held is not None:
        force_n, force_t = np.where(held[:m], 0.0, force_n), np.where(held[m:], 0.0, force_t)
        dn[held[:m]] = 0.0
    closed = gap <= 1e-7 * scale
    T = tied.reshape(k, m) & closed[None, :]
    kt = kappa.reshape(k, m) * T
    a = force_n + (kt * force_t.reshape(k, m)).sum(axis=0)
    pulled = T.any(axis=0) & (a < 0)
    share = a * kt / np.where(pulled, (kt * kt).sum(axis=0), 1.0)
    t = np.where(T & pulled[None, :], share, np.where(T, 0.0, force_t.reshape(k, m)))
    T &= ~pulled[None, :]
    n = np.where(T.any(axis=0), a, np.where(pulled, 0.0, force_n))
    dn[pulled] = 0.0
    dt = np.where(T, kt, 0.0)
    if dependent is not None and dependent[0].size:
        i, v = dependent
        vn, vt = v[:, 0], v[:, 1:].T
        vv = (vt * vt).sum(axis=0)
        s = -(vt * t[:, i]).sum(axis=0) / vv
        floor = np.divide(-n[i], vn, out=np.full(i.size, -np.inf), where=vn > 0)
        ceil = np.divide(-n[i], vn, out=np.full(i.size, np.inf), where=vn < 0)
        fixed = ~closed[i] & (vn != 0)
        clamped = ~fixed & ((s < floor) | (s > ceil))
        s = np.where(fixed, 0.0, np.clip(s, floor, ceil))
        n[i] = np.where(clamped, 0.0, n[i] + vn * s)
        t[:, i] += vt * s
        dn[i] = np.where(clamped, 0.0, dn[i])
        dt[:, i] = np.where(fixed | clamped, 0.0, -vn * vt / vv)
    return n, t.ravel(), T.ravel(), (dn, dt.ravel())


@dataclass
class ContactState:
    """Contact tractions of a solution on the slave nodes (the results file's `contact_*` fields)."""
    zone: ContactZone
    force_n: np.ndarray      # λn ≥ 0, nodal normal force [N/m in 2D, N in 3D]
    force_t: np.ndarray      # λt ((d − 1) m,), stacked by component as Bt
    gap: np.ndarray          # deformed gap ≥ 0 where open
    slip: np.ndarray         # relative tangential displacement, as force_t
    status: np.ndarray | None = None
    moved: np.ndarray | None = None   # tangent rows whose force `canonical_split` put on the normal
    jacobian: tuple | None = None     # (dn, dt): ∂(reported λn)/∂(the solver's λn, λt), `canonical_split`

    @property
    def nodes(self):
        return self.zone.nodes

    @property
    def weight(self):
        return self.zone.weight

    @property
    def pressure(self):
        return self.force_n / self.zone.weight

    def by_node(self, v: np.ndarray) -> np.ndarray:
        """A tangential vector as the rows have it: (m,) in 2D, (m, 2) in 3D (from the stacking by
        component)."""
        m = self.zone.gap.size
        return v if v.size == m else v.reshape(-1, m).T

    @property
    def shear(self):
        """τ_t: (m,) in 2D, (m, 2) along the row's two tangents in 3D."""
        w = self.zone.weight
        return self.by_node(self.force_t) / (w if self.force_t.size == w.size else w[:, None])

    def fields(self) -> dict:
        z = self.zone
        out = {
            "contact_coords": (("contact_node", "dim"), z.coords, {"units": "m"}),
            "contact_pair": (("contact_node",), np.array([z.names[k] for k in z.contact_of_node], dtype=object),
                             {"long_name": "contact name"}),
            "contact_pressure": (("contact_node",), self.pressure, {"units": "Pa", "long_name": "contact pressure -tau_n"}),
            "contact_gap": (("contact_node",), self.gap, {"units": "m", "long_name": "normal gap (>= 0 open)"}),
        }
        if z.coords.shape[1] == 2:
            out["contact_slip"] = (("contact_node",), self.slip, {"units": "m", "long_name": "relative tangential displacement"})
            out["contact_shear"] = (("contact_node",), self.shear, {"units": "Pa", "long_name": "tangential traction tau_t"})
            return out
        tangential = ("contact_node", "tangent")           # 3D: components along the node's two tangents
        out["contact_slip"] = (tangential, self.by_node(self.slip),
                               {"units": "m", "long_name": "relative tangential displacement along contact_tangents"})
        out["contact_shear"] = (tangential, self.shear,
                                {"units": "Pa", "long_name": "tangential traction tau_t along contact_tangents"})
        out["contact_tangents"] = (("contact_node", "tangent", "dim"), z.tangents,
                                   {"long_name": "the two unit tangents of each contact node"})
        return out


def slave_segments(zone: ContactZone, scene, smesh: SceneMesh) -> np.ndarray:
    """(s, 2) the contact rows at the two ends of each slave-side edge whose ends are both rows
    (an edge reaching a dropped node, which has no master opposite, carries no contact)."""
    segments, offset = [], 0
    for name, pr in zip(zone.names, zone.pairs):
        row = np.full(smesh.mesh.p.shape[1], -1)
        row[pr.slave] = offset + np.arange(len(pr))
        ends = row[smesh.mesh.facets[:, smesh.boundaries[scene.contacts[name].slave]]].T
        segments.append(ends[(ends >= 0).all(axis=1)])
        offset += len(pr)
    return np.vstack(segments)
