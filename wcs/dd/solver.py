r"""The seed's domain decomposition contact solver [21, §4–7].

Interface equation [21, (4.32)] for the trace U of the solution on the
subdomain interfaces Γ (reduced DOFs shared by two or more units):

    S0 U + S_con(U) = F,   S0 = Σ_{s∈T} R_sᵀ S_s R_s,   S_con(U) = Σ_p R_pᵀ S_p(R_p U).

1. Auxiliary problem (4.35)–(4.48): every pair glued (bilateral, no friction),
   S U⁰ = F⁰, S = S0 + Σ_p R_pᵀ S⁰_p R_p, by PCG1 with the balancing
   Neumann–Neumann preconditioner (5.9)–(5.14), injections D_u (5.5)–(5.8), and a
   coarse space of the rigid-motion traces of every unit (the kernels of the floating
   ones among them, [21, (5.11)]).
2. The outer iteration (`step`):
   - interface Newton (`newton`): J_k δ = F − S0 U_k − S_con(U_k) with
     J_k = S0 + Σ_p R_pᵀ S_p^{A_k} R_p, the pairs linearised at the active set A_k of
     the last local contact solves (closed normal, stuck tangential rows; in 3D with the
     stiffness across each slip on the disc, `PairUnit.across_slip`), by PCG with
     J_k's balancing preconditioner and Eisenstat–Walker tolerances; Tresca in 2D is piecewise
     affine, so it ends once A_k settles (the residual of the interface equation is
     checked); in 3D it converges quadratically near the solution. Coulomb: a fixed point
     over Tresca problems (slip bound from the last pressures, first all stick), as the
     monolithic solver.
   - the seed's successive approximations (`seed`) (4.37), (6.1):
     S0 U^k = F − S_con(U^{k−1}), each by PCG2 with the reduced preconditioner (6.7)
     (injections oD_u (6.4)–(6.6): the ρ-weights over linear subdomains only, so 1 next to
     a pair), warm started from U^{k−1}; S_con by one local contact solve per pair.
     They contract only if ρ(S0⁻¹ dS_con) < 1 ([21, Cor. 7.1]: 2β² < 1); `auto` estimates
     ρ from below by power steps at U⁰ (stopping once the bound reaches `seed_rho`) and
     takes them below `seed_rho`, else Newton.
3. Monitoring of the seed's step ([21, §7]): stop when ‖U^k − U^{k−1}‖_{S0} ≤ tol ‖U^k‖_{S0}; the
   contraction estimate q_k = ‖ΔU^k‖/‖ΔU^{k−1}‖ gives the a-posteriori bound
   q/(1−q)‖ΔU^k‖ (Theorem 7.1: contraction 2β² < 1); q_k ≥ 1 for `patience`
   steps is divergence (or stagnation), and a run whose predicted number of
   steps exceeds the budget stops early. Relaxation U^k ← ω U^k + (1−ω) U^{k−1}
   (fixed ω, or Aitken's dynamic ω) is the cheap cure; a failed run returns a
   status and message for the caller to fall back to the monolithic solver.

Entry points: `solve_dd` (elasticity with contact, on the model's reduced
system) and `solve_heat_dd` (the thermal step: the same decomposition, all
subdomains linear). Options: the study's `solver` block (`wcs.study.Solver`, its
`dd` block `wcs.study.DomainDecomposition`: each option with its default there);
`tolerance` and `max_iterations` (the budget of successive approximations) apply.
`relaxation: anderson` (with `anderson`, `mixing`, `anderson_restart`) measured worse
than Aitken on the off-centre pad, converges on the tunnel with β = 0.1 where Aitken
stagnates (results/bench/dd_iterations_nonlinear.csv).

MPI: `solve_dd(..., comm=)` / `solve_heat_dd(..., comm=)` distribute the units over
the communicator's ranks (team.py: deterministic gathers summed in unit order, so
the result is bitwise the serial one).
"""
from __future__ import annotations

import time
import weakref
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from wcs.fem.affine import CellAffineOperator
from wcs.status import DDOutcome, Status
from wcs.options import DomainDecomposition, Solver
from wcs.progress import phase

from .interface import HELD_KEPT, PairUnit, SetupError, Unit, _orth, admissible, rigid_basis, tangent_rows
from .partition import Partition, facet_components, node_unknowns, partition
from .pcg import Coarse, CoarseSingular, pcg
from .team import Team

class DDResult(NamedTuple):
    """What `solve_dd` returns; unpacks as (u, lam_n, lam_t, info, status, message)."""
    u: np.ndarray | None           # (d nnodes,) full displacement (None on failure)
    lam_n: np.ndarray | None       # (m,) normal contact forces, zone row order
    lam_t: np.ndarray | None       # ((d − 1) m,) tangential contact forces, tangent j of node i at j·m + i
    info: dict                     # iteration counts, history, active set, timings, sizes
    status: DDOutcome
    message: str


# ---- structure -------------------------------------------------------------------------------
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


def _local_pieces(t_nodes, cells, ncomp, T, node_dofs, local, group, p, components):
    """Local nodes, DOFs, elimination block, affine operator, per-component admissible modes
    (the kernel's pieces) and the rigid-motion traces of every component in the reduced local
    DOFs (Tᵀ of the motions: a support removes the components it fixes) for the coarse space."""
    nodes = np.unique(t_nodes[:, cells])
    dofs = np.unique(node_dofs[nodes].indices)
    rows = (ncomp * nodes[:, None] + np.arange(ncomp)).ravel()
    Tloc = sp.csr_matrix(T[rows][:, dofs])
    lt = np.searchsorted(nodes, t_nodes[:, cells])
    op = CellAffineOperator(lt, nodes.size, local[:, cells], group[cells])
    modes, traces = [], []
    for comp in components:
        cn = np.unique(t_nodes[:, comp])
        R = rigid_basis(p, cn, ncomp)
        M = np.zeros((rows.size, R.shape[1]))
        pos = (ncomp * np.searchsorted(nodes, cn)[:, None] + np.arange(ncomp)).ravel()
        M[pos] = R
        modes.append(admissible(M, Tloc))
        traces.append(Tloc.T @ M)
    return nodes, dofs, Tloc, op, modes, np.hstack(traces) if traces else np.zeros((dofs.size, 0))


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


def build_decomposition(model, dd) -> Decomposition:
    """Partition the model's mesh and build the units of the elastic problem (`dd`: the
    `DomainDecomposition` options, or a mapping of them)."""
    dd = DomainDecomposition.of(dd)
    t0 = time.perf_counter()
    smesh, mesh = model.smesh, model.smesh.mesh
    dim = mesh.p.shape[0]
    part = model_partition(model, dd)
    T = model.elim.T
    node_of_dof, node_dofs = dofs_of_nodes(T, dim)
    Bn, Bt = model.Bn_r, model.Bt_r
    contact_of_row = model.zone.contact_of_node
    units, traces = [], []
    for q, (subs, contacts) in enumerate(zip(part.pairs, part.pair_contacts)):
        cells = np.flatnonzero(np.isin(part.subdomain, subs))
        comps = [c for s in subs for c in facet_components(part.cells(s), mesh.f2t)]
        nodes, dofs, Tloc, op, modes, trace = _local_pieces(mesh.t, cells, dim, T, node_dofs, model.K.local,
                                                            smesh.cell_region, mesh.p, comps)
        rows = np.flatnonzero(np.isin(contact_of_row, contacts))
        outside = np.setdiff1d(np.unique(Bn[rows].indices), dofs)
        if outside.size:
            raise SetupError("contact rows reach outside their pair (partition bug)")
        units.append(PairUnit(len(units), subs, dofs, op, Tloc, modes, None, rows,
                              Bn[rows][:, dofs], Bt[tangent_rows(rows, Bn.shape[0], dim - 1)][:, dofs]))
        traces.append(trace)
    for s in part.linear:
        cells = part.cells(s)
        comps = facet_components(cells, mesh.f2t)
        nodes, dofs, Tloc, op, modes, trace = _local_pieces(mesh.t, cells, dim, T, node_dofs, model.K.local,
                                                            smesh.cell_region, mesh.p, comps)
        Z = _orth(np.hstack(modes)) if modes else np.zeros((dofs.size, 0))
        units.append(Unit(len(units), (s,), dofs, op, Tloc, Z, None))
        traces.append(trace)
    nif = _interface(units, T.shape[1])
    _interface_regions(units, part, mesh.t, node_of_dof, smesh.cell_region)
    return Decomposition(part, units, nif, T.shape[1], traces, {"setup": time.perf_counter() - t0})


# ---- weights, loads and global operators ---------------------------------------------------------
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


class InterfaceOperator:
    """S = Σ_u R_uᵀ S_u R_u over `units` (linear uses of each unit) with the balancing
    Neumann–Neumann preconditioner M⁻¹ = (I − P) Σ_u R_uᵀ D_u S_u† D_u R_u ([21, (5.14)]).

    Coarse space V_H = span{R_uᵀ D_u Y_u}: `traces[i]` the rigid-motion traces Y_u of every
    unit (local DOFs × modes), not only the kernels Z_u ⊂ span Y_u of the floating ones
    ([21, (5.11)] needs those; a subdomain held by a roller or a sliver of a support has a
    small Neumann eigenvalue on the others and needs them too).
    `team`: the distribution of the units over MPI ranks (`Team(None, units)`: serial);
    each rank solves its own units' local problems, the pieces are summed in unit order.
    `coarse`: the coarse projection when known (kept for the data set: S and S0; interface
    Newton's J_k, on the glued operator's basis — the same units, weights and traces — with
    J_k Z from the glued S Z and the pairs' changes)."""

    def __init__(self, units, nif: int, weights: list[np.ndarray], traces: list[np.ndarray],
                 team: Team | None = None, coarse: Coarse | None = None):
        self.units, self.nif, self.weights = units, nif, weights
        self.team = team if team is not None else Team(None, units)
        self.weight = {u.index: w for u, w in zip(units, weights)}
        self.applications = 0
        if coarse is not None:
            self.coarse = coarse
            return
        tm = self.team.timings
        t, inner = time.perf_counter(), tm["dirichlet"] + tm["comm"]
        self.coarse = Coarse(self._basis(units, nif, weights, traces), self.apply)   # ZᵀSZ: k applications at once
        tm["coarse"] += time.perf_counter() - t - (tm["dirichlet"] + tm["comm"] - inner)

    @staticmethod
    def _basis(units, nif, weights, traces) -> np.ndarray:
        """An orthonormal basis of V_H = span{R_uᵀ D_u Y_u}."""
        Zs = [(u.gamma, w[:, None] * y[u.B]) for u, w, y in zip(units, weights, traces) if y.shape[1] and u.B.size]
        k = sum(z.shape[1] for _, z in Zs)
        Z = np.zeros((nif, k))
        j = 0
        for g, z in Zs:
            Z[g, j:j + z.shape[1]] = z
            j += z.shape[1]
        return _orth(Z)

    def apply(self, U: np.ndarray) -> np.ndarray:
        self.applications += 1
        tm = self.team.timings
        t = time.perf_counter()
        pieces = self.team.each(_product_phase(U), self.units, lambda u: u.apply_S(U[u.gamma]))   # local Dirichlet solves
        tm["dirichlet"] += time.perf_counter() - t
        return self.team.sum(self.units, pieces, self.nif, U.shape[1:])

    def precondition(self, H: np.ndarray) -> np.ndarray:
        tm = self.team.timings
        t = time.perf_counter()
        w = self.weight
        pieces = self.team.each("iterate", self.units,
                                lambda u: w[u.index] * u.neumann(w[u.index] * H[u.gamma]))   # local Neumann solves
        tm["neumann"] += time.perf_counter() - t
        out = self.team.sum(self.units, pieces, self.nif, H.shape[1:])
        t = time.perf_counter()
        out = self.coarse.project_out(out)
        tm["coarse"] += time.perf_counter() - t
        return out

    def load(self) -> np.ndarray:
        t = time.perf_counter()
        pieces = self.team.each("assemble", self.units, lambda u: u.condensed_load())
        self.team.timings["dirichlet"] += time.perf_counter() - t
        return self.team.sum(self.units, pieces, self.nif)


# ---- the elastic contact solve ------------------------------------------------------------------
_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _dd_options(options) -> dict:
    """The DD's working values of the `solver` options (a `Solver`, or a mapping of them):
    the typed values, with the two tolerances the schema derives from `tolerance`."""
    solver = Solver.of(options)
    dd, tol = solver.dd, solver.tolerance
    return {
        **dd.model_dump(exclude={"pcg_tolerance", "inner_tolerance"}),
        "tolerance": tol,
        "max_iterations": solver.max_iterations,
        "max_fixed_point_iterations": solver.max_fixed_point_iterations,
        "pcg_tolerance": max(tol, 1e-8) if dd.pcg_tolerance is None else dd.pcg_tolerance,
        "inner_tolerance": tol / 10 if dd.inner_tolerance is None else dd.inner_tolerance,
    }


def _start_tolerance(options, o: dict) -> float:
    """PCG1's tolerance (the glued start U⁰ of the outer iteration): `pcg_tolerance` if given,
    else for interface Newton (step newton or auto) its first step's forcing — U⁰ starts
    Newton at an interface residual of the contacts' linearisation error, not of PCG1's
    (measured: Hertz at 1e5 unknowns PCG1 29 → 10 iterations, Newton's 49 unchanged; the
    tunnel 32 → 8, Newton 38 → 39) — and for the seed's step max(`tolerance`, 1e-8)."""
    if Solver.of(options).dd.pcg_tolerance is None and o["step"] in ("newton", "auto"):
        return max(o["pcg_tolerance"], o["forcing"])
    return o["pcg_tolerance"]


def decomposition(model, options) -> Decomposition:
    """The model's decomposition for these `solver` options (built once, cached on the model)."""
    dd = Solver.of(options).dd
    key = (dd.subdomains, dd.pair_size)
    per_model = _CACHE.setdefault(model, {})
    if key not in per_model:
        with phase("DD set-up"):
            per_model[key] = build_decomposition(model, dd)
    return per_model[key]


def _fail(info, status, message):
    info["status_name"] = status.value
    return DDResult(None, None, None, info, status, message)


def _distribute_load(dec, rho, rhs: np.ndarray, team) -> list:
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


def solve_dd(model, scene, Kr, rhs: np.ndarray, u0: np.ndarray, options=None,
             *, coefficients=None, comm=None) -> DDResult:
    """Solve the model's reduced contact problem (Kr, rhs, u = T w + u0) by the DD method.

    Same inputs as `Model._solve_contact`: Kr = Tᵀ K T, rhs = Tᵀ (f − K u0), u0 the lifted
    support values. The local matrices are assembled per unit from the scene's
    coefficients (`coefficients`: a `Coefficients` already computed, else from `scene`);
    Kr itself is only used to size and check. `options`: the study's `Solver` (a mapping is
    validated by it; None: the defaults). Returns a `DDResult`
    (u_full, lam_n, lam_t, info, status, message); lam_n, lam_t in the zone's row order
    (ContactState(zone, lam_n, lam_t, gap − Bn u, Bt u, info["active"])).

    comm: an MPI communicator (mpi4py) whose ranks share this one solve — every rank calls
    `solve_dd` with the same arguments; the units are distributed over the ranks (`Team`),
    every rank returns the same result, bitwise equal to the serial one (comm=None).
    info["ranks"]: per-rank timings (assemble, dirichlet, neumann, coarse, contact, comm).
    """
    o = _dd_options(options)
    t0 = time.perf_counter()
    info: dict = {"method": "dd", "options": o}
    try:
        dec = decomposition(model, options)
    except (SetupError, CoarseSingular) as exc:
        return _fail(info, DDOutcome.SETUP_FAILED, f"domain decomposition set-up failed: {exc}")
    c = coefficients if coefficients is not None else model.coefficients(scene)
    kc = model.stiffness_coefficients(c)
    team = Team(comm, dec.units, model.smesh.mesh.p.shape[0], dec.measured,
                refactor=not np.array_equal(dec.kept.get("data"), kc))
    tm = team.timings
    info["nranks"] = team.size
    z = model.zone
    g, F = c.slip, c.coulomb
    d = z.gap - z.Bn @ u0
    rho_region = stiffness_measure(c.lam, c.mu)
    info.update(_sizes(dec))
    t = time.perf_counter()
    error = None
    try:
        team.each("assemble", dec.units, lambda u: u.assemble(kc))      # a rank factors its own units only
    except Exception as exc:  # noqa: BLE001 - a local factorization failed: report, let the caller fall back
        error = f"a local factorization failed: {exc}"
    tm["assemble"] += time.perf_counter() - t
    error = team.first_error(error)
    if error:
        return _fail(info, DDOutcome.SETUP_FAILED, error)
    for u in dec.units:            # each solve starts afresh: the answer must not depend on history
        if hasattr(u, "warm"):
            u.warm, u.qp_restarts = None, 0
    rho = [_unit_rho(u, rho_region) for u in dec.units]
    D = _distribute_load(dec, rho, rhs, team)
    lin = dec.linear
    oD = injections(lin, dec.nif, [r for u, r in zip(dec.units, rho) if u.kind == "linear"])
    kept = dec.kept_for(kc)
    try:
        S = InterfaceOperator(dec.units, dec.nif, D, dec.traces, team, coarse=kept.get("S"))
    except CoarseSingular as exc:
        return _fail(info, DDOutcome.SETUP_FAILED, f"the glued interface operator is singular: {exc}")
    kept["S"] = S.coarse
    Y0 = [dec.traces[u.index] for u in lin]
    try:
        S0, singular = InterfaceOperator(lin, dec.nif, oD, Y0, team, coarse=kept.get("S0")), ""
        kept["S0"] = S0.coarse
    except CoarseSingular as exc:        # Newton needs only S0's products; the seed's step its inverse
        S0 = InterfaceOperator(lin, dec.nif, oD, [y[:, :0] for y in Y0], team)
        singular = f"the interface operator of the linear subdomains is singular (a group of them floats " \
                   f"between pairs): {exc}"
    info["coarse"] = {"pcg1": S.coarse.size, "pcg2": S0.coarse.size}
    info["timings"] = {"setup": dec.timings["setup"], "assemble": time.perf_counter() - t}

    # 1. auxiliary problem: PCG1 (its answer kept with the data's coarse spaces while its load F⁰
    #    stays: a study that samples gaps or friction only solves it once; the same U⁰ to the bit)
    t = time.perf_counter()
    F0 = S.load()
    key1 = (_start_tolerance(options, o), o["pcg_max_iterations"])
    last = kept.get("pcg1")
    info["pcg1_kept"] = last is not None and last[0] == key1 and np.array_equal(last[1], F0)
    if info["pcg1_kept"]:
        r1 = last[2]
    else:
        r1 = pcg(S.apply, S.precondition, F0, np.zeros(dec.nif), tol=key1[0], max_iter=key1[1], coarse=S.coarse)
        kept["pcg1"] = (key1, F0, r1)
    info["pcg1"] = r1.iterations
    info["pcg1_residuals"] = r1.residuals
    info["timings"]["pcg1"] = time.perf_counter() - t
    info["pcg1_converged"] = r1.converged      # U⁰ is only the start of the outer iteration

    # 2. the outer iteration: interface Newton, or the seed's successive approximations
    t = time.perf_counter()
    Fl = S0.load()
    gw = g * z.weight
    step, prefix, cache = o["step"], "", {}
    if singular and step == "seed":
        return _fail(info, DDOutcome.SETUP_FAILED, singular)
    if singular and step == "auto":
        step, prefix = "newton", f"{singular}: newton; "
    if step == "auto":
        estimate = _rho_estimate(dec, S0, r1.x, d, None if F.any() else gw, o, team, cache)
        if estimate is None:
            info["ranks"] = team.report()
            return _fail(info, DDOutcome.LOCAL_FAILED, "a contact solve of the ρ estimate failed")
        rho, info["rho_steps"] = estimate
        step = "seed" if rho < o["seed_rho"] else "newton"
        info["rho"] = rho
        prefix = (f"ρ(S0⁻¹ dS_con) ≥ {rho:.3g} at U⁰ ({estimate[1]} power steps; "
                  f"{'<' if step == 'seed' else '≥'} {o['seed_rho']:g}): {step}; ")
    info["step"] = step
    if step == "newton":
        status, message, U = _coulomb_newton(dec, S0, S, Fl, r1.x, d, gw, F, z.weight, o, info, team, cache,
                                             float(np.linalg.norm(rhs)))
    else:
        status, message, U = _successive(dec, S if step == "glued" else S0, Fl, r1.x, d, g, F, z.weight, o,
                                          info, team)
    info["qp_restarts"] = sum(team.allgather(sum(p.qp_restarts for p in team.local(dec.pairs))))
    if info["qp_restarts"]:
        message += (f"; {info['qp_restarts']} local contact solves restarted from the dual QP (their semismooth "
                    f"Newton cycled)")
    message = prefix + message
    info["timings"]["successive"] = time.perf_counter() - t
    if status != DDOutcome.CONVERGED:
        info["ranks"] = team.report()
        return _fail(info, status, message)

    # 3. the solution: interior values of every unit from U (own units, then gathered)
    t = time.perf_counter()
    mine, error = [], None
    for u in team.local(dec.units):
        if u.kind == "pair":
            tc = time.perf_counter()
            if step == "newton":         # the last Tresca problem's solve at U: Newton's last residual
                res = u.result
            else:
                _, res = u.contact(U[u.gamma], d[u.rows], z.weight[u.rows], g[u.rows], _coulomb(F, u.rows),
                                   o["contact_tolerance"], 200)
            tm["contact"] += time.perf_counter() - tc
            team.charge(u, "contact", tc)
            if res.status != Status.SOLVED:
                error = error or f"final contact solve of pair {u.index}: {res.message}"
                continue
            tc = time.perf_counter()
            mine.append((u.index, u.solution(U[u.gamma]), res.lam_n, res.lam_t, res.active))
        else:
            tc = time.perf_counter()
            mine.append((u.index, u.interior(U[u.gamma]), None, None, None))
        team.charge(u, "assemble", tc)          # the interior solves: sparse, as the load's condensation
    parts = team.allgather((error, mine))
    error = next((e for e, _ in parts if e), None)
    gathered = {i: rest for _, piece in parts for i, *rest in piece}
    if error:
        info["ranks"] = team.report()
        return _fail(info, DDOutcome.LOCAL_FAILED, error)
    w = np.zeros(dec.ndof)
    m = z.gap.size
    k = model.smesh.mesh.p.shape[0] - 1          # tangents per node
    lam_n, lam_t, active = np.zeros(m), np.zeros(k * m), np.zeros(m, dtype=np.int64)
    for u in dec.units:                          # unit order, as the serial loop
        loc, ln, lt, act = gathered[u.index]
        if u.kind == "pair":
            lam_n[u.rows], active[u.rows] = ln, act
            lam_t[tangent_rows(u.rows, m, k)] = lt
        w[u.dofs] = loc
    info["timings"]["solution"] = time.perf_counter() - t
    info["active"] = active
    info["w"] = w
    info["timings"]["total"] = time.perf_counter() - t0
    info["status_name"] = DDOutcome.CONVERGED.value
    info["ranks"] = team.report()
    if team.size > 1 and team.size not in dec.measured:      # the costs the next evaluations are assigned by
        dec.measured[team.size] = team.measured()
    u_full = model.elim.T @ w + u0
    return DDResult(u_full, lam_n, lam_t, info, DDOutcome.CONVERGED, message)


def _coulomb(F, rows):
    Fr = F[rows]
    return Fr if Fr.any() else None


def _sizes(dec: Decomposition) -> dict:
    return {"subdomains": dec.part.nsub, "pairs": len(dec.part.pairs), "units": len(dec.units),
            "linear_subdomains": len(dec.part.linear), "interface_dofs": dec.nif,
            "floating_units": int(sum(1 for u in dec.units if u.kind == "linear" and u.Z.shape[1])),
            "glue": [u.glue for u in dec.pairs]}


def _unit_rho(u, rho_region) -> np.ndarray:
    """The stiffness measure of unit `u` at each of its interface DOFs: the largest of its
    cells around the DOF's node ([21, (5.5)–(5.7)] with ρ_u taken where the DOF is, so a
    unit holding several materials weighs each interface node by its own: measured on the
    knee, 13 / 20 subdomains, PCG1 at 1e-4 51 / 64 with the unit's area-weighted mean)."""
    b, regions = u.interface_regions
    rho = np.zeros(u.B.size)
    np.maximum.at(rho, b, np.asarray(rho_region, float)[regions])
    return rho


def _interface_regions(units, part, t_nodes, node_of_dof, cell_region) -> None:
    """For every unit, the (interface DOF position, region) pairs of its cells around each
    interface DOF's node: `u.interface_regions`, for `_unit_rho`."""
    for u in units:
        cells = np.flatnonzero(np.isin(part.subdomain, u.subdomains))
        node_cell = sp.csr_matrix((np.ones(t_nodes.shape[0] * cells.size),
                                   (t_nodes[:, cells].ravel(), np.tile(np.arange(cells.size), t_nodes.shape[0]))),
                                  shape=(int(t_nodes.max()) + 1, cells.size))
        hit = node_cell[node_of_dof[u.dofs[u.B]]].tocoo()
        u.interface_regions = (hit.row, cell_region[cells][hit.col])


def _successive(dec, S0, F, U0, d, g, Fc, weight, o, info, team=None):
    """S0 U^k = F − S_con(U^{k−1}) with monitoring; returns (status, message, U).

    The map T(U) = S0⁻¹(F − S_con(U)) is evaluated by PCG2 warm started from U (inexact:
    see `_inner_tolerance`); the fixed-point residual f = T(U) − U. Update: plain/fixed
    relaxation U ← U + ω f, Aitken's dynamic ω, or Anderson acceleration ("anderson",
    history `anderson` steps, least squares in the S0 energy inner product; the history
    is cleared when the residual grows)."""
    team = team if team is not None else Team(None, dec.units)
    pairs = dec.pairs
    tol, budget, patience = o["tolerance"], o["max_iterations"], o["patience"]
    relax = o["relaxation"]
    mode = relax.lower() if isinstance(relax, str) else "fixed"
    aitken, anderson = mode == "aitken", mode == "anderson"
    omega = 1.0 if isinstance(relax, str) else float(relax)
    tm = team.timings

    def s_con(U):
        t = time.perf_counter()
        pieces, error = {}, None
        for p in team.local(pairs):                  # independent local contact solves
            tp = time.perf_counter()
            r, res = p.contact(U[p.gamma], d[p.rows], weight[p.rows], g[p.rows], _coulomb(Fc, p.rows),
                               o["contact_tolerance"], 200)
            team.charge(p, "contact", tp)
            if res.status != Status.SOLVED:
                error = error or f"contact solve of pair {p.index}: {res.message}"
                r = np.zeros(p.gamma.size)
            pieces[p.index] = r
        tm["contact"] += time.perf_counter() - t
        if team.comm is not None:
            error = team.first_error(error)
        if error:
            return None, error
        return team.sum(pairs, pieces, dec.nif), ""

    U, SU = U0.copy(), S0.apply(U0)
    hist = {"dU": [], "U": [], "q": [], "omega": [], "pcg2": [], "estimate": []}
    info["history"] = hist
    info["successive"] = 0
    info["pcg2"] = 0
    prev_step = None          # unrelaxed update r_{k−1} (Aitken)
    first = None
    Fnorm = np.linalg.norm(F)
    acc = []                  # Anderson: (f, Sf, g, Sg) of previous steps
    beta = o["mixing"]
    for k in range(1, budget + 1):
        rc, msg = s_con(U)
        if rc is None:
            if hist["q"] and hist["q"][-1] > 1 and hist["dU"][-1] > hist["dU"][0]:     # the iterates were growing
                return DDOutcome.DIVERGED, (f"successive approximations diverged: contraction estimate q = "
                                            f"{hist['q'][-1]:.3g} ≥ 1 at step {k - 1} (they converge only "
                                            f"when they contract, q = 2β² < 1; seed [21, Cor. 7.1]), then at "
                                            f"step {k} the {msg}"), U
            return DDOutcome.LOCAL_FAILED, msg, U
        b = F - rc
        if o["step"] == "glued":     # S U^k = F − S_con(U) + L U, L = Σ_p R_pᵀ S⁰_p R_p
            b = b + team.sum(pairs, team.each("iterate", pairs, lambda p: p.apply_S(U[p.gamma])), dec.nif)
        eta = _inner_tolerance(o, hist)
        r2 = pcg(S0.apply, S0.precondition, b, U, tol=eta, max_iter=o["pcg_max_iterations"],
                 coarse=S0.coarse, reference=max(Fnorm, np.linalg.norm(b)))
        info["successive"] = k
        info["pcg2"] += r2.iterations
        hist["pcg2"].append(r2.iterations)
        step, Sstep = r2.x - U, r2.Sx - SU
        if anderson:
            n_step = float(np.sqrt(abs(step @ Sstep)))
            if acc and o["anderson_restart"] and n_step > o["anderson_restart"] * hist["dU"][-1]:
                acc = []                                    # residual grew a lot: restart the history
            gk, Sgk = U + beta * step, SU + beta * Sstep     # mixing β: damped map U + β(T(U) − U)
            if acc:
                # g = U + βf: the Anderson update U − ΔU γ + β(f − ΔF γ), ΔG = ΔU + βΔF
                dF = np.stack([step - a[0] for a in acc], axis=1)
                SdF = np.stack([Sstep - a[1] for a in acc], axis=1)
                dG = np.stack([gk - a[2] for a in acc], axis=1)
                SdG = np.stack([Sgk - a[3] for a in acc], axis=1)
                G = 0.5 * (dF.T @ SdF + SdF.T @ dF)
                G += 1e-12 * max(np.trace(G), 1e-300) * np.eye(G.shape[0])
                gamma = np.linalg.lstsq(G, SdF.T @ step, rcond=1e-12)[0]
                Unew, SUnew = gk - dG @ gamma, Sgk - SdG @ gamma
            else:
                Unew, SUnew = gk.copy(), Sgk.copy()
            acc.append((step, Sstep, gk, Sgk))
            acc = acc[-o["anderson"]:]
            hist["omega"].append(float("nan"))
            dU, SdU = Unew - U, SUnew - SU
            U, SU = Unew, SUnew
            n_dU = n_step                                   # the fixed-point residual ‖T(U) − U‖_S0
            n_U = float(np.sqrt(abs(r2.x @ r2.Sx)))
        else:
            if aitken and prev_step is not None:
                dr = step - prev_step
                den = float(dr @ dr)
                if den > 0:
                    omega = float(np.clip(-omega * (prev_step @ dr) / den, 0.02, 2.0))
            prev_step = step
            hist["omega"].append(omega)
            dU, SdU = omega * step, omega * Sstep
            U, SU = U + dU, SU + SdU
            n_dU = float(np.sqrt(abs(dU @ SdU)))
            n_U = float(np.sqrt(abs(U @ SU)))
        hist["dU"].append(n_dU)
        hist["U"].append(n_U)
        if not np.isfinite(n_dU) or not np.isfinite(n_U):
            return DDOutcome.DIVERGED, f"successive approximations diverged (non-finite iterate at step {k})", U
        q = n_dU / hist["dU"][-2] if len(hist["dU"]) > 1 and hist["dU"][-2] > 0 else np.nan
        hist["q"].append(q)
        est = q / (1 - q) * n_dU / max(n_U, 1e-300) if np.isfinite(q) and q < 1 else np.inf
        hist["estimate"].append(est)
        if n_dU <= tol * n_U:
            if anderson:                  # T(U) − U is within tolerance at the evaluated U: keep T(U)
                U, SU = r2.x, r2.Sx
            info["contraction"] = _mean_q(hist["q"])
            return DDOutcome.CONVERGED, f"converged in {k} successive approximations ({info['pcg2']} PCG2 iterations, " \
                                        f"{info['pcg1']} PCG1)", U
        if not r2.converged:
            return DDOutcome.BUDGET, f"PCG2 did not converge in {r2.iterations} iterations at step {k}", U
        first = n_dU if first is None else first
        qbar = _mean_q(hist["q"][-patience:])
        info["contraction"] = qbar
        if k > patience and n_dU >= hist["dU"][-1 - patience]:     # no net decrease in `patience` steps
            kind = DDOutcome.DIVERGED if n_dU > first else DDOutcome.STAGNATED
            return kind, (f"successive approximations {kind.value} at step {k}: contraction estimate "
                          f"q = {qbar:.3g} ≥ 1 over the last {patience} steps (‖ΔU‖/‖U‖ = {n_dU / max(n_U, 1e-300):.3g}); "
                          f"they converge only when they contract, q = 2β² < 1 (seed [21, Cor. 7.1]): try "
                          f"relaxation or larger pairs"), U
        rate = (n_dU / hist["dU"][0]) ** (1.0 / (k - 1)) if k > 1 and hist["dU"][0] > 0 else np.nan
        if np.isfinite(rate) and rate < 1 and k >= 10:       # overall rate: Aitken's q_k fluctuate
            need = np.log(tol * n_U / n_dU) / np.log(rate)
            if k + need > budget:
                return DDOutcome.STAGNATED, (f"successive approximations stagnating at step {k}: mean contraction "
                                             f"{rate:.4f} needs ~{need:.0f} more steps to reach {tol:g}, "
                                             f"beyond the budget of {budget}"), U
    return DDOutcome.BUDGET, (f"successive approximations did not reach {tol:g} in {budget} steps "
                              f"(‖ΔU‖/‖U‖ = {hist['dU'][-1] / max(hist['U'][-1], 1e-300):.3g})"), U


def _inner_tolerance(o, hist) -> float:
    """PCG2 tolerance (relative to max(‖F‖, ‖b‖)) of the next step: at least `inner_tolerance`,
    and `forcing` × the last relative increment (inexact inner solves: no point solving
    S0 U = b far below the error of the current U)."""
    eta = o["inner_tolerance"]
    if hist["dU"]:
        eta = max(eta, o["forcing"] * hist["dU"][-1] / max(hist["U"][-1], 1e-300))
    return eta


def _mean_q(qs) -> float:
    qs = [q for q in qs if np.isfinite(q) and q > 0]
    return float(np.exp(np.mean(np.log(qs)))) if qs else float("nan")


# ---- interface Newton ---------------------------------------------------------------------------
def _contact_residual(dec, U, d, bound, o, team, cache):
    """S_con(U) = Σ_p R_pᵀ S_p(R_p U) of the Tresca problems with slip bounds `bound` (None:
    all stick), and the active sets {pair index: (free, across_slip)} of every pair (gathered:
    the free rows and, in 3D, the slipping nodes' disc springs); on a failed local solve
    (None, None, message). The last evaluation is kept in `cache` ("residual"): the ρ
    estimate's at U⁰ is Newton's first, and the pairs' last local solutions (`PairUnit.result`)
    are those of the last evaluation."""
    key = (U.tobytes(), None if bound is None else np.asarray(bound).tobytes())
    if cache.get("residual", (None,))[0] == key:
        return cache["residual"][1]
    pieces, free, error = {}, {}, None
    t = time.perf_counter()
    for p in team.local(dec.pairs):                  # independent local contact solves
        tp = time.perf_counter()
        r, res = p.tresca(U[p.gamma], d[p.rows], None if bound is None else bound[p.rows],
                           o["contact_tolerance"], 200)
        team.charge(p, "contact", tp)
        if res.status != Status.SOLVED:
            error = error or f"contact solve of pair {p.index}: {res.message}"
            r = np.zeros(p.gamma.size)
        pieces[p.index], free[p.index] = r, (res.free, p.across_slip())
    team.timings["contact"] += time.perf_counter() - t
    error = team.first_error(error) if team.comm is not None else error
    out = (None, None, error) if error else \
        (team.sum(dec.pairs, pieces, dec.nif), {i: f for part in team.allgather(free) for i, f in part.items()}, "")
    cache["residual"] = (key, out)
    return out


def _linearised(dec, free, team, cache: dict) -> list:
    """The pairs linearised at the active sets `free` ({pair index: (free, across_slip)}); the
    last set's are kept in `cache` (with the operator J built on them, "J"), so a step whose
    active set (and, in 3D, slip springs) did not change refactors nothing."""
    key = b"".join(a.tobytes() for p in dec.pairs for a in (free[p.index][0], *(free[p.index][1] or ())))
    if cache.get("key") != key:
        cache.pop("J", None)
        pairs = []
        for p in dec.pairs:
            rows, springs = free[p.index]
            t = time.perf_counter()
            pairs.append(p.linearised(rows, team.mine(p), springs))
            if team.mine(p):
                team.charge(p, "contact", t)
        cache.update(key=key, pairs=pairs)
    return cache["pairs"]


def _pairs_apply(team, lin_pairs, nif, x):
    """Σ_p R_pᵀ S_p^A R_p x over the linearised pairs (own ones solved, pieces summed; x may
    have columns)."""
    pieces = team.each(_product_phase(x), lin_pairs, lambda p: p.apply_S(x[p.gamma]))
    return team.sum(lin_pairs, pieces, nif, x.shape[1:])


def _product_phase(x: np.ndarray) -> str:
    """The `Team` phase the units' products with x are charged to: `iterate` for a vector (PCG's
    products, every evaluation), `assemble` for columns (the coarse basis: Zᵀ S Z and J_k Z, a
    data set's set-up, kept while its stiffness data stay — as the factorizations, which an
    evaluation on the same data does not count either). Charged to `iterate`, the first
    evaluation's coarse products made the tunnel's pairs (×0.33) weigh 30–31 ms there against
    16–17 ms without them (its linear units 5–12 → 4–11 ms), and on the same data the pairs'
    ranks took too few linear units (their products 32 against 54 ms a solve)."""
    return "iterate" if x.ndim == 1 else "assemble"


def _rho_estimate(dec, S0, U0, d, bound, o, team, cache) -> tuple[float, int] | None:
    """A lower bound of ρ(S0⁻¹ dS_con) at U⁰ (dS_con: the pairs linearised at the active set of
    the local contact solves there), and the power steps it took: the Rayleigh quotient
    xᵀLx / xᵀS0x (S0⁻¹L is S0-self-adjoint, L ⪰ 0: every x gives a lower bound, power steps
    x ← S0⁻¹ L x (PCG2 to 1e-2) raise it towards ρ), from a fixed start on the pairs'
    interface DOFs (L applied to a fixed random vector: where L acts and S0 is soft; measured
    from the random vector itself, one power step on Hertz and the tunnel, 0 from there), after each of at most
    `rho_steps` steps; it stops as soon as the bound reaches `seed_rho` (the seed's step is
    then ruled out whatever more steps would give). The seed's step
    U^k = S0⁻¹(F − S_con(U^{k−1})) [21, (4.37)] contracts near the solution only if ρ < 1
    ([21, Cor. 7.1]: 2β² < 1). None: a local contact solve failed."""
    _, free, _ = _contact_residual(dec, U0, d, bound, o, team, cache)
    if free is None:
        return None
    L = _linearised(dec, free, team, cache)
    x = _pairs_apply(team, L, dec.nif, np.random.default_rng(0).standard_normal(dec.nif))   # fixed: the same ρ
    x /= max(np.linalg.norm(x), 1e-300)
    for k in range(o["rho_steps"] + 1):
        Lx = _pairs_apply(team, L, dec.nif, x)
        q = float(x @ Lx) / max(float(x @ S0.apply(x)), 1e-300)
        if q >= o["seed_rho"] or k == o["rho_steps"]:
            return q, k
        r = pcg(S0.apply, S0.precondition, Lx, np.zeros(dec.nif), tol=1e-2,
                max_iter=o["pcg_max_iterations"], coarse=S0.coarse)
        x = r.x / max(np.linalg.norm(r.x), 1e-300)


def _coulomb_newton(dec, S0, S, F, U, d, gw, Fc, weight, o, info, team, cache, load):
    """Interface Newton for Tresca (slip bounds gw = g·w); for Coulomb the fixed point over
    Tresca problems of the monolithic path: first all stick, then bounds g·w + F λn from the
    last pressures, until ‖Δp‖ ≤ tol ‖p‖ (p = λn / w; at most max_fixed_point_iterations
    Tresca solves). Returns (status, message, U); the pairs' `result` is the last Tresca
    problem's solve at U."""
    coulomb = bool(Fc.any())
    bound, p_old = (None if coulomb else gw), None
    info["newton"] = info["pcg2"] = info["successive"] = 0
    info["history"] = {"residual": [], "pcg2": [], "eta": [], "step": []}
    for j in range(1, (o["max_fixed_point_iterations"] if coulomb else 1) + 1):
        status, message, U = _newton(dec, S0, S, F, U, d, bound, o, info, team, cache, load)
        if status != DDOutcome.CONVERGED or not coulomb:
            return status, message, U
        lam = {i: p.result.lam_n for i, p in ((p.index, p) for p in team.local(dec.pairs))}
        lam_n = np.zeros(weight.size)
        for part in team.allgather(lam):
            for i, ln in part.items():
                lam_n[dec.units[i].rows] = ln
        p = lam_n / weight
        info["fixed_point"] = j
        if p_old is not None and np.linalg.norm(p - p_old) <= o["tolerance"] * max(np.linalg.norm(p), 1e-300):
            return status, f"{message}; Coulomb fixed point: {j} Tresca problems", U
        p_old, bound = p, gw + Fc * lam_n
    return (DDOutcome.BUDGET, f"Coulomb fixed point did not converge in {o['max_fixed_point_iterations']} "
            f"Tresca problems", U)


def _newton(dec, S0, S, F, U, d, bound, o, info, team, cache, load: float):
    """Newton on the interface equation S0 U + S_con(U) = F [21, (4.32)] (Tresca, bounds
    `bound`; None: all stick): J_k δ = r_k = F − S0 U_k − S_con(U_k) with
    J_k = S0 + Σ_p R_pᵀ S_p^{A_k} R_p, the pairs linearised at the active sets A_k of the
    local contact solves at U_k, by PCG with J_k's balancing Neumann–Neumann preconditioner,
    from δ = 0 to a tolerance relative to the right-hand side (Eisenstat–Walker:
    η_k = min(forcing, 0.9 (‖r_k‖/‖r_{k−1}‖)²), never below what the outer tolerance needs).
    S_con is piecewise affine (Tresca 2D): once A_k is the solution's set one step solves; in
    3D it is smooth along a slip on the disc and J_k its derivative there (`across_slip`).
    A full step can jump over the solution's piece (a node slipping one way, then the other):
    the step is halved until ‖r‖ decreases by (1 − 1e-4 t (1 − η)) (inexact Newton
    backtracking; δ is a descent direction of ‖r‖², J_k being S_con's derivative).
    Converged when ‖r_k‖ ≤ tol · max(‖F‖, ‖S0 U_k‖, ‖S_con(U_k)‖, `load`) — r_k is the global
    equilibrium residual on Γ (the units' interiors are solved exactly), `load` the norm of the
    reduced load: a scale that does not vanish where the interface does not move (an open
    contact over an unloaded body). `cache`: see `_linearised`."""
    hist, tol, lin = info["history"], o["tolerance"], dec.linear

    def residual(U):
        rc, free, error = _contact_residual(dec, U, d, bound, o, team, cache)
        if rc is None:
            return None, None, None, error
        SU = S0.apply(U)
        ref = max(np.linalg.norm(F), np.linalg.norm(SU), np.linalg.norm(rc), load, 1e-300)
        return F - SU - rc, ref, free, ""

    r, ref, free, error = residual(U)
    nr_prev, eta = None, o["forcing"]
    for k in range(o["max_iterations"] + 1):
        if r is None:
            return DDOutcome.LOCAL_FAILED, error, U
        nr = float(np.linalg.norm(r))
        hist["residual"].append(nr / ref)
        if nr <= tol * ref:
            return DDOutcome.CONVERGED, (f"interface Newton converged in {info['newton']} steps ({info['pcg2']} PCG "
                                         f"iterations, {info['pcg1']} PCG1)"), U
        if k == o["max_iterations"]:
            break
        if nr_prev is not None:
            eta = min(o["forcing"], 0.9 * (nr / nr_prev) ** 2)
        eta = min(max(eta, 0.5 * tol * ref / nr), 0.5)
        nr_prev = nr
        try:
            lp = _linearised(dec, free, team, cache)
            if "J" not in cache:
                kept_J = dec.kept.setdefault("J", {})      # J_k's coarse projections of the data set by active set
                if cache["key"] not in kept_J:
                    Z = S.coarse.Z                 # J Z = S Z + Σ_p R_pᵀ (S_p^A − S⁰_p) R_p Z: products of the pairs
                    if "pairs_SZ" not in dec.kept:     # Σ_p R_pᵀ S⁰_p R_p Z: the glued pairs', one per data set
                        dec.kept["pairs_SZ"] = _pairs_apply(team, dec.pairs, dec.nif, Z)
                    JZ = S.coarse.SZ + _pairs_apply(team, lp, dec.nif, Z) - dec.kept["pairs_SZ"]
                    tc = time.perf_counter()
                    if len(kept_J) >= HELD_KEPT:
                        del kept_J[next(iter(kept_J))]      # the oldest
                    kept_J[cache["key"]] = Coarse(Z, None, SZ=JZ)
                    team.timings["coarse"] += time.perf_counter() - tc
                cache["J"] = InterfaceOperator(lp + lin, dec.nif, S.weights, dec.traces, team,
                                               coarse=kept_J[cache["key"]])
            J = cache["J"]
        except (SetupError, CoarseSingular) as exc:
            return DDOutcome.LOCAL_FAILED, f"interface Newton step {k + 1}: the linearised problem is singular: {exc}", U
        step = pcg(J.apply, J.precondition, r, np.zeros(dec.nif), tol=eta, max_iter=o["pcg_max_iterations"],
                   coarse=J.coarse)
        info["newton"] = info["successive"] = info["newton"] + 1
        info["pcg2"] += step.iterations
        hist["pcg2"].append(step.iterations)
        hist["eta"].append(eta)
        if not step.converged:
            return DDOutcome.BUDGET, f"PCG of interface Newton step {k + 1} did not converge in {step.iterations} iterations", U
        t = 1.0
        while True:
            r, ref, free, error = residual(U + t * step.x)
            if r is None or np.linalg.norm(r) <= (1 - 1e-4 * t * (1 - eta)) * nr:
                break
            t /= 2
            if t < 2.0 ** -30:
                return DDOutcome.STAGNATED, (f"interface Newton stagnated at step {k + 1}: no step along the Newton "
                                             f"direction decreases the residual {nr / ref:.3g}"), U
        hist["step"].append(t)
        U = U + t * step.x
    return DDOutcome.BUDGET, (f"interface Newton did not reach {tol:g} in {o['max_iterations']} steps "
                              f"(residual {hist['residual'][-1]:.3g})"), U


# ---- the thermal step -------------------------------------------------------------------------
def build_heat_decomposition(model, options) -> Decomposition:
    """Units of the heat equation: every subdomain of the elastic partition, all linear
    (contacts conduct perfectly: both sides share the heat nodes, which become interface DOFs)."""
    part = model_partition(model, Solver.of(options).dd)    # the elastic partition (no elastic units needed)
    smesh, mesh = model.smesh, model.smesh.mesh
    heat_of_node = model.P.indices                       # P: one entry per row
    th = heat_of_node[mesh.t]
    T = model.heat_elim.T
    node_of_dof, node_dofs = dofs_of_nodes(T, 1)
    units, traces = [], []
    for s in range(part.nsub):
        cells = part.cells(s)
        comps = facet_components(cells, mesh.f2t)
        _, dofs, Tloc, op, modes, trace = _local_pieces(th, cells, 1, T, node_dofs, model.H.local,
                                                        smesh.cell_region, mesh.p, comps)
        Z = _orth(np.hstack(modes)) if modes else np.zeros((dofs.size, 0))
        units.append(Unit(s, (s,), dofs, op, Tloc, Z, None))
        traces.append(trace)
    nif = _interface(units, T.shape[1])
    _interface_regions(units, part, th, node_of_dof, smesh.cell_region)
    return Decomposition(part, units, nif, T.shape[1], traces)


def solve_heat_dd(model, c, options=None, *, comm=None):
    """The thermal step by the same decomposition (the linear case: PCG1 only).

    c: the model's `Coefficients`. Returns (T nodal (nnodes,), info, status, message),
    the same temperature as `Model.solve_heat(c)`. comm: as in `solve_dd`.
    """
    o = _dd_options(options)
    per_model = _CACHE.setdefault(model, {})
    key = ("heat", o["subdomains"], o["pair_size"])
    if key not in per_model:
        with phase("DD set-up (heat)"):
            per_model[key] = build_heat_decomposition(model, options)
    dec = per_model[key]
    team = Team(comm, dec.units, model.smesh.mesh.p.shape[0])
    Kh = model.H(c.kappa)
    Th0 = model.heat_elim.U0 @ c.temperature_values
    q = model.source_vectors.T @ c.source
    rhs = model.heat_Tt @ (q - Kh @ Th0)
    t = time.perf_counter()
    for u in team.local(dec.units):
        u.assemble(c.kappa)
    team.timings["assemble"] += time.perf_counter() - t
    kreg = np.asarray(c.kappa, float)
    rho = [_unit_rho(u, kreg) for u in dec.units]
    D = _distribute_load(dec, rho, rhs, team)
    info = {"method": "dd", "subdomains": len(dec.units), "interface_dofs": dec.nif, "nranks": team.size}
    try:
        S = InterfaceOperator(dec.units, dec.nif, D, dec.traces, team)
    except CoarseSingular as exc:
        return None, info, DDOutcome.SETUP_FAILED, f"thermal interface operator singular: {exc}"
    info["coarse"] = S.coarse.size
    r = pcg(S.apply, S.precondition, S.load(), np.zeros(dec.nif), tol=o["pcg_tolerance"],
            max_iter=o["pcg_max_iterations"], coarse=S.coarse)
    info["pcg1"] = r.iterations
    if not r.converged:
        return None, info, DDOutcome.BUDGET, f"thermal PCG did not converge in {r.iterations} iterations"
    mine = [(u.index, u.interior(r.x[u.gamma])) for u in team.local(dec.units)]
    loc = {i: x for part in team.allgather(mine) for i, x in part}
    w = np.zeros(dec.ndof)
    for u in dec.units:
        w[u.dofs] = loc[u.index]
    info["ranks"] = team.report()
    theta = model.heat_elim.T @ w + Th0
    return model.P @ theta, info, DDOutcome.CONVERGED, f"converged in {r.iterations} PCG iterations"
