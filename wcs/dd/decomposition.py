"""The structure of the decomposition of a model (its partition into linear subdomains and
contact pairs, the units built on them, the interface DOFs they share) and the stiffness
weights of the units on the interface: the injections D_u of [21, (5.5)–(5.8)]."""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from wcs.fem.affine import CellAffineOperator, CellMatrices
from wcs.options import DomainDecomposition

from .kernels import _orth, admissible, rigid_basis
from .pair import PairUnit, tangent_rows
from .partition import Partition, facet_components, node_unknowns, partition
from .unit import SetupError, Unit


def dofs_of_nodes(T: sp.spmatrix, ncomp: int):
    """(node_of_dof, csr node -> dofs) for an elimination whose columns live on one node each."""
    Tc = sp.csc_matrix(T)
    Tc.sort_indices()
    node_of_dof = Tc.indices[Tc.indptr[:-1]] // ncomp
    nn = T.shape[0] // ncomp
    M = sp.csr_matrix((np.ones(node_of_dof.size), (node_of_dof, np.arange(node_of_dof.size))),
                      shape=(nn, node_of_dof.size))
    M.sort_indices()
    return node_of_dof, M


class Field(NamedTuple):
    """The field the units discretize (displacements, or temperatures): the nodes of its
    unknowns cell by cell `t_nodes` (a column a cell), its components per node `ncomp`, the
    elimination T (its columns on one node each; `node_of_dof`, `node_dofs`: `dofs_of_nodes`),
    the cells' matrices as affine pieces `local` (`CellAffineOperator`), the cells' regions
    and the mesh's points."""
    t_nodes: np.ndarray
    ncomp: int
    T: sp.spmatrix
    node_of_dof: np.ndarray
    node_dofs: sp.csr_matrix
    local: CellMatrices
    region: np.ndarray
    p: np.ndarray


def _field(t_nodes, ncomp: int, T, local, region, p) -> Field:
    return Field(t_nodes, ncomp, T, *dofs_of_nodes(T, ncomp), local, region, p)


def _local_pieces(f: Field, cells: np.ndarray, components: list):
    """Local DOFs, elimination block, affine operator, per-component admissible modes (the
    kernel's pieces) and the rigid-motion traces of every component in the reduced local DOFs
    (Tᵀ of the motions: a support removes the components it fixes) for the coarse space."""
    ncomp = f.ncomp
    nodes = np.unique(f.t_nodes[:, cells])
    dofs = np.unique(f.node_dofs[nodes].indices)
    rows = (ncomp * nodes[:, None] + np.arange(ncomp)).ravel()
    Tloc = sp.csr_matrix(f.T[rows][:, dofs])
    lt = np.searchsorted(nodes, f.t_nodes[:, cells])
    op = CellAffineOperator(lt, nodes.size, f.local.of(cells), f.region[cells])
    modes, traces = [], []
    for comp in components:
        cn = np.unique(f.t_nodes[:, comp])
        R = rigid_basis(f.p, cn, ncomp)
        M = np.zeros((rows.size, R.shape[1]))
        pos = (ncomp * np.searchsorted(nodes, cn)[:, None] + np.arange(ncomp)).ravel()
        M[pos] = R
        modes.append(admissible(M, Tloc))
        traces.append(Tloc.T @ M)
    return dofs, Tloc, op, modes, np.hstack(traces) if traces else np.zeros((dofs.size, 0))


def _linear_unit(f: Field, index: int, part: Partition, s: int, f2t: np.ndarray,
                 kernels: bool = True) -> tuple[Unit, np.ndarray]:
    """The linear unit of subdomain s, its kernel the admissible rigid motions of its
    facet-connected components (none where `kernels` is False: a matrix with mass), and their
    traces."""
    cells = part.cells(s)
    dofs, Tloc, op, modes, trace = _local_pieces(f, cells, facet_components(cells, f2t))
    modes = modes if kernels else []
    Z = _orth(np.hstack(modes)) if modes else np.zeros((dofs.size, 0))
    return Unit(index, (s,), dofs, op, Tloc, Z), trace


def _joined(f: Field, part: Partition, units: list, traces: list, timings: dict) -> Decomposition:
    """The decomposition of the units joined on their interface: its DOFs and regions set."""
    nif = _interface(units, f.T.shape[1])
    _interface_regions(units, part, f)
    return Decomposition(part, units, nif, f.T.shape[1], traces, timings)


def _interface(units, ndof):
    count = np.zeros(ndof, dtype=np.int64)
    for u in units:
        count[u.dofs] += 1
    is_if = count >= 2
    position = np.cumsum(is_if) - 1
    for u in units:
        u.set_interface(is_if, position)
    return int(is_if.sum())


@dataclass
class Decomposition:
    """Structure of a decomposition: partition and units (built once per model)."""
    part: Partition
    units: list                 # Unit / PairUnit, pairs first
    nif: int                    # interface size
    ndof: int
    traces: list                # per unit: rigid-motion traces of its components (local DOFs × modes)
    timings: dict = field(default_factory=dict)
    kept: dict = field(default_factory=dict)      # coarse spaces of the last data set (`kept_for`)
    measured: dict = field(default_factory=dict)  # {ranks: {unit index: seconds per phase}} of a first evaluation

    def kept_for(self, data: np.ndarray) -> dict:
        """The coarse projections of S and S0 kept for the data set `data` (the stiffness
        coefficients: S, S0, their weights and coarse spaces depend on nothing else), the glued
        pairs' part of S Z and the last `HELD_KEPT` projections of interface Newton's J_k by
        active set (`_newton`), PCG1's
        last answer by its load F⁰ (`solve_dd`), emptied
        when the data change — as a monolithic factor is kept while its matrix is unchanged (a
        study that samples loads, gaps or friction only)."""
        if not np.array_equal(self.kept.get("data"), data):
            self.kept = {"data": np.array(data, dtype=float)}
        return self.kept

    @property
    def pairs(self):
        return [u for u in self.units if u.kind == "pair"]

    @property
    def linear(self):
        return [u for u in self.units if u.kind == "linear"]


def contact_sides(model) -> list[tuple[int, int, np.ndarray]]:
    """(contact, body, side nodes) for the slave and master sides of every contact: the master
    side is every other node its rows of Bn reach (node-to-segment, node-to-node or mortar, in
    any dimension; a dual mortar coefficient may be negative)."""
    nb, z = model.smesh.node_body, model.zone
    sides = []
    for k, pr in enumerate(z.pairs if z is not None else ()):
        rows = z.Bn[np.flatnonzero(z.contact_of_node == k)]
        rows.eliminate_zeros()
        master = np.setdiff1d(rows.indices // model.dim, pr.slave)
        sides.append((k, int(nb[pr.slave[0]]), pr.slave))
        sides.append((k, int(nb[master[0]]), master))
    return sides


def model_partition(model, dd: DomainDecomposition):
    """The partition of the model's mesh into subdomains and contact pairs."""
    smesh = model.smesh
    floating = {smesh.bodies.index(b) for b, m in model.free_modes.items() if m.shape[1]}
    return partition(smesh.mesh, smesh.cell_body, contact_sides(model), floating,
                     dd.subdomains, dd.pair_size, node_unknowns(model.elim.T, smesh.mesh.p.shape[0]))


def build_decomposition(model, dd, local=None) -> Decomposition:
    """Partition the model's mesh and build the units of the elastic problem (`dd`: the
    `DomainDecomposition` options, or a mapping of them). `local`: the cells' matrices as affine
    pieces (`wcs.fem.affine.CellMatrices`' protocol) whose sum is positive definite on every unit
    — a time level's mass with the stiffness (`wcs.dynamics.stepping`) — so the units have no
    kernel; None: the stiffness's, the units' kernels their admissible rigid motions."""
    dd = DomainDecomposition.of(dd)
    t0 = time.perf_counter()
    smesh, mesh = model.smesh, model.smesh.mesh
    dim = mesh.p.shape[0]
    part = model_partition(model, dd)
    kernels = local is None
    f = _field(mesh.t, dim, model.elim.T, model.K.local if kernels else local, smesh.cell_region, mesh.p)
    Bn, Bt = model.Bn_r, model.Bt_r
    contact_of_row = model.zone.contact_of_node
    units, traces = [], []
    for subs, contacts in zip(part.pairs, part.pair_contacts):
        cells = np.flatnonzero(np.isin(part.subdomain, subs))
        comps = [c for s in subs for c in facet_components(part.cells(s), mesh.f2t)]
        dofs, Tloc, op, modes, trace = _local_pieces(f, cells, comps)
        rows = np.flatnonzero(np.isin(contact_of_row, contacts))
        outside = np.setdiff1d(np.unique(Bn[rows].indices), dofs)
        if outside.size:
            raise SetupError("contact rows reach outside their pair (partition bug)")
        units.append(PairUnit(len(units), subs, dofs, op, Tloc, modes if kernels else [], rows,
                              Bn[rows][:, dofs], Bt[tangent_rows(rows, Bn.shape[0], dim - 1)][:, dofs]))
        traces.append(trace)
    for s in part.linear:
        unit, trace = _linear_unit(f, len(units), part, s, mesh.f2t, kernels)
        units.append(unit)
        traces.append(trace)
    return _joined(f, part, units, traces, {"setup": time.perf_counter() - t0})


def build_heat_decomposition(model, dd) -> Decomposition:
    """Units of the heat equation: every subdomain of the elastic partition, all linear
    (contacts conduct perfectly: both sides share the heat nodes, which become interface DOFs;
    `dd` as in `build_decomposition`)."""
    part = model_partition(model, DomainDecomposition.of(dd))    # the elastic partition (no elastic units needed)
    smesh, mesh = model.smesh, model.smesh.mesh
    heat_of_node = model.P.indices                       # P: one entry per row
    f = _field(heat_of_node[mesh.t], 1, model.heat_elim.T, model.H.local, smesh.cell_region, mesh.p)
    units, traces = [], []
    for s in range(part.nsub):
        unit, trace = _linear_unit(f, s, part, s, mesh.f2t)
        units.append(unit)
        traces.append(trace)
    return _joined(f, part, units, traces, {})


def _interface_regions(units, part: Partition, f: Field) -> None:
    """For every unit, the (interface DOF position, region) pairs of its cells around each
    interface DOF's node: `u.interface_regions`, for `unit_rho`."""
    t_nodes, node_of_dof, cell_region = f.t_nodes, f.node_of_dof, f.region
    for u in units:
        cells = np.flatnonzero(np.isin(part.subdomain, u.subdomains))
        node_cell = sp.csr_matrix((np.ones(t_nodes.shape[0] * cells.size),
                                   (t_nodes[:, cells].ravel(), np.tile(np.arange(cells.size), t_nodes.shape[0]))),
                                  shape=(int(t_nodes.max()) + 1, cells.size))
        hit = node_cell[node_of_dof[u.dofs[u.B]]].tocoo()
        u.interface_regions = (hit.row, cell_region[cells][hit.col])


# ---- weights and loads ------------------------------------------------------------------------------
def stiffness_measure(lam: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """Young-modulus-like ρ per region: μ(3λ+2μ)/(λ+μ)."""
    return mu * (3 * lam + 2 * mu) / np.maximum(lam + mu, 1e-300)


def injections(units, nif: int, rho: np.ndarray) -> list[np.ndarray]:
    """D_u on the interface DOFs of each unit: ρ_u / Σ_{t ∋ m} ρ_t ([21, (5.5)–(5.7)]).

    Σ_u R_uᵀ D_u R_u = I ([21, (5.8)]) on the interface DOFs the units cover."""
    total = np.zeros(nif)
    for u, r in zip(units, rho):
        total[u.gamma] += r
    return [r / total[u.gamma] for u, r in zip(units, rho)]


def unit_rho(u, rho_region) -> np.ndarray:
    """The stiffness measure of unit `u` at each of its interface DOFs: the largest of its
    cells around the DOF's node ([21, (5.5)–(5.7)] with ρ_u taken where the DOF is, so a
    unit holding several materials weighs each interface node by its own: measured on the
    knee, 13 / 20 subdomains, PCG1 at 1e-4 51 / 64 with the unit's area-weighted mean)."""
    b, regions = u.interface_regions
    rho = np.zeros(u.B.size)
    np.maximum.at(rho, b, np.asarray(rho_region, float)[regions])
    return rho


def distribute_load(dec, rho, rhs: np.ndarray, team) -> list:
    """The stiffness-weighted injections D_s ([21, (5.5)–(5.7)]) and each own unit's share of
    the reduced load (interface entries weighted by D_s, so the shares sum to the load)."""
    D = injections(dec.units, dec.nif, rho)
    for u, w in zip(dec.units, D):
        if team.mine(u):
            t = time.perf_counter()
            f = rhs[u.dofs].copy()
            f[u.B] *= w
            u.set_load(f)
            team.charge(u, "assemble", t)
    return D


def sizes(dec: Decomposition) -> dict:
    return {"subdomains": dec.part.nsub, "pairs": len(dec.part.pairs), "units": len(dec.units),
            "linear_subdomains": len(dec.part.linear), "interface_dofs": dec.nif,
            "floating_units": int(sum(1 for u in dec.units if u.kind == "linear" and u.Z.shape[1])),
            "glue": [u.glue for u in dec.pairs]}
