"""The forward model of a scene: pieces assembled once per mesh, then one
thermal solve and one elastic solve per data set.

`Model(scene, smesh)` reads the *structure* of the scene (which regions, loads, supports
exist) and is read-only once built; `Model.solve(c)` takes the `Coefficients` of a data
set (`wcs.model.coefficients.ParameterMap`) and combines the pieces: the data are piecewise
constant on regions and boundary parts, so every operator is an affine combination of
fixed matrices. The mesh gives the dimension: P1 triangles (plane strain or stress) or P1
tetrahedra (3D), dof = d·node + component either way. A solve returns a `Solution` that
owns its fields and the matrices its adjoint needs; the factor objects behind them are
caches that keep their analysis and are refactored whenever a solution asks for a matrix
they no longer hold.

Over 500 lines for one job: `Model` is one class (the structure of a scene, the numbers of a data
set, the solves), whose solve paths share the factor caches it holds; the functions below it are its
own helpers.
"""
from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp

from .. import linalg
from ..choose import SolverFacts, solver_method
from .coefficients import Coefficients, ParameterMap
from ..contact.methods import ContactMethod, method_of
from ..contact.problem import ContactProblem
from ..contact.solver import ContactResult, factor_regularized, pinned_dofs, regularize
from ..contact.units import UnitFactors, stiffness_units
from ..contact.zone import ContactState, build_zone, canonical_split, dependent_rows, held_rows, tied_rows
from ..errors import SolveError, StudyError
from ..fem import forms
from ..geometry import tet
from ..fem.affine import CellAffineOperator, conduction_cells, elastic_cells
from ..fem.constraints import Constraint, Elimination, Reduction, eliminate
from ..fem.gluing import build_glue, glue_elimination, glue_heat, glued_clusters, heat_glue_elimination
from ..fem.rigid import rigid_modes
from ..fem.stress import cell_mean, strain_operator, stresses
from .heat import heat_by_krylov
from .materials import lame
from ..scene.estimate import (CLOSED_START_STEPS, ITERATIVE_STEPS, EvaluationFacts, cost_words, evaluation_cost,
                              evaluation_fault, evaluation_memory, iterative_installed)
from ..scene.meshdata import SceneMesh
from ..geometry.facets import nodal_normals
from ..status import Status
from ..options import Solver


@dataclass(frozen=True)
class Solution:
    """A solved data set: nodal fields, cell-wise stresses, and what its adjoint needs."""
    u: np.ndarray              # (d nnodes,) node-interleaved displacement
    T: np.ndarray | None       # (nnodes,) temperature, None without a thermal step
    stress: np.ndarray         # (4, ncells) xx, yy, zz, xy in 2D; (6, ncells) xx, yy, zz, yz, xz, xy in 3D
    coefficients: Coefficients
    iterations: int = 1
    krylov_steps: tuple | None = ()        # Krylov iterations per outer step (`wcs.contact.methods.Solved`)
    solver: str = "direct"                 # what actually solved it (e.g. "dd", "monolithic after dd stagnated")
    contact: object | None = None
    timings: dict = field(default_factory=dict)
    w: np.ndarray | None = None            # reduced displacement unknowns
    theta: np.ndarray | None = None        # temperature on the heat nodes (direct thermal step)
    raw: ContactResult | None = None       # the contact solver's result (contact)
    # the matrices this solution factored, and the caches that factor them (`factor`, ...)
    stiffness: sp.csr_matrix | None = field(default=None, repr=False)
    conduction: sp.csr_matrix | None = field(default=None, repr=False)
    scale: np.ndarray | float = 1.0        # contact: the data set's reduced stiffness is s_u · stiffness on unit u
    factors: SimpleNamespace | None = field(default=None, repr=False, compare=False)

    def factor(self) -> linalg.Factor:
        """The factorization of this solution's reduced stiffness (no contact)."""
        return self.factors.elastic.of(self.stiffness)

    def heat_factor(self) -> linalg.Factor:
        """The factorization of this solution's reduced conduction matrix."""
        return self.factors.heat.of(self.conduction)

    def contact_factor(self, model):
        """The contact factorization of this solution's reduced stiffness (`.factor.solve`, `.W`)."""
        return model.factored(self.stiffness, self.scale)


def _fresh_cache() -> SimpleNamespace:
    """A model's caches: they change the speed of a solve, never its answer (`Model.solve`)."""
    return SimpleNamespace(
        elastic=linalg.HeldFactor(spd=True),     # Cholesky of the reduced stiffness (no contact)
        heat=linalg.HeldFactor(spd=True),        # Cholesky of the reduced conduction matrix
        contact=None,                            # the contact factorization (`UnitFactors`; method qp: a `ContactFactor`), refactored in place
        anchor=None,                             # contact state at the nominal data: other solves start from it
        anchor_tried=False,
        stiffness=None,                          # (coefficients, K) of the last K(c) `stiffness` assembled
        support=None,                            # (coefficients, K U0) of the last reduced system
        direction=None)                          # (c*, K*, its units' blocks) of the last contact stiffness


class Model:
    """The assembled model of a scene (read-only once built: setting an attribute raises).

    options: the study's `solver` options (a mapping is validated); comm: the MPI
    communicator whose ranks share each DD solve (None: serial)."""

    def __init__(self, scene, smesh: SceneMesh, options=None, comm=None, dynamic: bool = False):
        self.options = Solver.of(options)             # the study's `solver` options (a mapping is validated)
        self.dynamic = dynamic                        # a dynamic study's: `auto` chooses each time level's method
        self.scene = scene
        self.smesh = smesh
        mesh = smesh.mesh
        self.dim = d = mesh.p.shape[0]                # 2: triangles, 3: tetrahedra
        self.plane = scene.plane if d == 2 else None  # 3D: the full Hooke law
        self.nnodes = mesh.p.shape[1]
        self.region_cells = [np.flatnonzero(smesh.cell_region == j) for j in range(len(smesh.regions))]
        self.region_material = self._region_materials(scene)
        self.targets = self._name_targets()

        # elasticity: K(c) = Σ_j λ_j Kλ_j + μ_j Kμ_j over regions j
        self.K = CellAffineOperator(mesh.t, self.nnodes, elastic_cells(mesh.p, mesh.t), smesh.cell_region)
        self.support_keys, constraints = self._support_constraints(scene)
        # glued interfaces (mortar): slave DOFs eliminated on top of the nodal constraints
        supported = np.unique(np.concatenate([c.nodes for c in constraints])) if constraints else ()
        self.glue = build_glue(scene, smesh, supported)
        self.elim: Elimination = glue_elimination(
            eliminate(self.nnodes, d, constraints, len(self.support_keys)), self.glue, self.nnodes, d)
        self.Tt = self.elim.T.T.tocsr()
        self.reduce = Reduction(self.K.pattern(), self.elim.T)
        self.free_modes = self._free_rigid_modes(constraints)

        self.pressure_vectors = {}
        self.traction_vectors = {}
        for name, load in scene.loads.items():
            facets = smesh.boundaries[name]
            if load.pressure is not None:
                self.pressure_vectors[name] = forms.pressure_vector(mesh, facets)
            else:
                self.traction_vectors[name] = forms.traction_vectors(mesh, facets)

        self.thermal = scene.thermal is not None
        if self.thermal:
            self._init_thermal(scene)

        self.zone = build_zone(scene, smesh)
        if self.zone is not None:
            T = self.elim.T
            self.Bn_r, self.Bt_r = (self.zone.Bn @ T).tocsr(), (self.zone.Bt @ T).tocsr()
            self.floating = [(b, m) for b, m in self.free_modes.items() if m.shape[1]]
            self.R_r = (T.T @ np.hstack([m for _, m in self.floating])) if self.floating else None
        self.comm = comm               # MPI communicator the DD solver spreads its subdomains over
        self.solver_method, self.solver_reason = self._choose_solver(scene)
        self.method: ContactMethod = method_of(self.solver_method)   # `wcs.contact.methods`
        self.method.check(self)
        self._anchored = self.zone is not None and self.method.anchored
        # contact: the units of the reduced stiffness, each factored on its own (`wcs.contact.units`)
        self.units = (stiffness_units(self.reduce.pattern, self._region_dofs(), self.region_material)
                      if self.zone is not None and self.method.units else None)
        self.pinned = (pinned_dofs(self.R_r) if self.zone is not None and self.R_r is not None
                       else np.zeros(0, dtype=int))

        # 3D: the strain operator applied from the gradients K holds (its matrix was 0.78 GB at 1e6 unknowns)
        self.G = tet.StrainOperator(mesh.t, self.K.local.g, self.nnodes) if d == 3 else strain_operator(mesh.p, mesh.t)
        self.cell_area = self.K.local.measure        # areas or volumes (elasticity's own: not made again)
        self.nominal = self.coefficients(scene)      # the coefficients of the scene's own data
        forms.release_mapping(mesh)                  # the load and coupling forms are assembled
        self._cache = _fresh_cache()
        for name, value in vars(self).items():
            if name != "_cache":
                _read_only(value)
        self._frozen = True

    def release(self) -> None:
        """Free what the solves keep for later ones (the caches: factorizations, the last K, the
        anchor and the method's own, `ContactMethod.release`): the next solve starts cold, to
        the same answer (a results file is written after this: its arrays and libraries do not
        stack on the solve's)."""
        vars(self._cache).update(vars(_fresh_cache()))
        self.method.release(self)

    def __setattr__(self, name, value):
        if getattr(self, "_frozen", False):
            raise AttributeError(f"the model is read-only once built (tried to set '{name}')")
        object.__setattr__(self, name, value)

    @functools.cached_property
    def body_force_vectors(self) -> np.ndarray:
        """(nregions, d, ndof): ∫_region e_i · v dx, built on first use (a load with body forces)."""
        out = np.array([forms.body_force_vectors(self.smesh.mesh, c) for c in self.region_cells])
        forms.release_mapping(self.smesh.mesh)
        return out

    def _choose_solver(self, scene) -> tuple[str, str]:
        """The study's `solver.method`, `auto` resolved by the benchmark-derived rule
        (wcs/choose.py), with the estimated peak memory and time of one evaluation in the reason;
        StudyError (exit 2) where that estimate exceeds the machine's memory."""
        rows = self.Bn_r.shape[0] + self.Bt_r.shape[0] if self.zone is not None else 0
        units = min(len(set(self.region_material)), len(self.smesh.bodies))   # units share no material, hold whole bodies
        p = self.smesh.mesh.p
        closed = (self.zone is not None and not self.dynamic and _friction(scene) == "none"
                  and bool(np.all(self.zone.gap <= 1e-12 * np.linalg.norm(p.max(axis=1) - p.min(axis=1)))))
        facts = EvaluationFacts(dimension=self.dim, unknowns=self.elim.T.shape[1], stiffness_nnz=self.reduce.nnz,
                                contact_rows=rows, units=units, thermal=self.thermal,
                                newton_steps=CLOSED_START_STEPS if closed else ITERATIVE_STEPS)
        memory = evaluation_memory()
        method = self.options.method
        installed = iterative_installed()                     # the iterative method's PETSc
        if method == "auto":
            method, why = solver_method(self._solver_facts(scene, facts, memory, installed))
        else:
            why = "chosen in the study"
        need, seconds = evaluation_cost(facts, method)
        if need > memory:
            direct = method != "iterative" and rows > 0
            out = ("use solver.method: iterative (it never forms the dense W), or a coarser mesh (`mesh.size`, `refine`)"
                   if direct and self.options.method != "auto" else
                   "install PETSc (the wheel dolfinx-solver-real) for the iterative method, or a coarser mesh "
                   "(`mesh.size`, `refine`)" if direct and not installed else "a coarser mesh (`mesh.size`, `refine`)")
            raise StudyError(f"{evaluation_fault(facts, method)}; {out}", path="solver.method")
        why += f"; {'one time level' if self.dynamic else 'one evaluation'} estimated at {cost_words(need, seconds)}"
        if closed and (self.options.method == "auto" or method == "iterative"):
            why += (f"; the iterative method's estimate assumes {CLOSED_START_STEPS} Newton steps (frictionless, every "
                    "contact node starts closed)")
        return method, why

    def _solver_facts(self, scene, facts: EvaluationFacts, memory: float, installed: bool) -> SolverFacts:
        mats = [scene.materials[m] for m in set(self.region_material)]
        pairs = [lame({"lambda": m.lam, "mu": m.mu} if m.lam is not None else {"E": m.E, "nu": m.nu})
                 for m in mats]
        moduli = [mu for _, mu in pairs]
        nus = [lam / (2 * (lam + mu)) for lam, mu in pairs]
        contacts = scene.contacts
        costs = {m: evaluation_cost(facts, m) for m in ("monolithic", "iterative")}
        return SolverFacts(unknowns=self.dim * self.nnodes, contact=bool(contacts), friction=_friction(scene),
                           stiffness_contrast=max(moduli) / min(moduli), max_nu=max(nus),
                           dimension=self.dim, costs=costs, memory=memory, iterative_installed=installed,
                           floating=self.zone is not None and self.R_r is not None, dynamic=self.dynamic)

    # ---- structure -----------------------------------------------------------------
    def _region_dofs(self) -> list[np.ndarray]:
        """The reduced DOFs each region's cells act on."""
        T = self.elim.T.tocsr()
        d = self.dim
        out = []
        for cells in self.region_cells:
            nodes = np.unique(self.smesh.mesh.t[:, cells])
            out.append(np.unique(T[(d * nodes[:, None] + np.arange(d)).ravel()].indices))
        return out

    def _region_materials(self, scene) -> list[str]:
        """The material of each mesh region (the loader names every region)."""
        material = {(body, r.name): r.material for body, spec in scene.bodies.items() for r in spec.regions}
        return [material[key] for key in self.smesh.regions]

    def _name_targets(self) -> dict[str, list[int]]:
        """Body or region name -> region indices (for body forces and heat sources)."""
        targets: dict[str, list[int]] = {}
        for j, (body, region) in enumerate(self.smesh.regions):
            targets.setdefault(body, []).append(j)
            if region != body:
                targets.setdefault(region, []).append(j)
        return targets

    def _support_constraints(self, scene) -> tuple[list[tuple[str, str]], list[Constraint]]:
        keys, constraints = [], []
        mesh = self.smesh.mesh
        for name, sup in scene.supports.items():
            facets = self.smesh.boundaries[name]
            if sup.u is not None:
                nodes = np.unique(mesh.facets[:, facets])
                for comp, value in enumerate(sup.u):
                    if value is None:
                        continue
                    a = np.zeros((nodes.size, self.dim))
                    a[:, comp] = 1.0
                    constraints.append(Constraint(nodes, a, len(keys)))
                    keys.append((name, f"u.{comp}"))
            else:
                nodes, normals = (tet.nodal_normals if self.dim == 3 else nodal_normals)(mesh, facets)
                constraints.append(Constraint(nodes, normals, len(keys)))
                keys.append((name, "normal"))
        return keys, constraints

    def _free_rigid_modes(self, constraints: list[Constraint]) -> dict[str, np.ndarray]:
        """Per body: the rigid motions no support stops, as (d nnodes, k) columns (k = 0 when held)."""
        node_body = self.smesh.node_body
        rows = {n: [] for n in range(len(self.smesh.bodies))}
        for c in constraints:
            for node, a in zip(c.nodes, c.directions):
                rows[node_body[node]].append((node, a))
        p = self.smesh.mesh.p
        d = self.dim
        free = {}
        for cluster in glued_clusters(len(self.smesh.bodies), self.glue):   # glued bodies move together
            name = self.smesh.bodies[cluster[0]]
            nodes = np.flatnonzero(np.isin(node_body, cluster))
            R = rigid_modes(p, nodes, self.nnodes)
            held = [r for bb in cluster for r in rows[bb]]
            if held:
                A = np.array([[a @ R[d * n:d * n + d, k] for k in range(R.shape[1])] for n, a in held])
                _, s, vt = np.linalg.svd(A)
                rank = int(np.sum(s > 1e-10 * max(s[0], 1e-300)))
                z = vt[rank:].T
            else:
                z = np.eye(R.shape[1])
            free[name] = R @ z
            for other in cluster[1:]:          # a glued cluster's modes are listed once, under its first body
                free[self.smesh.bodies[other]] = np.zeros((d * self.nnodes, 0))
        return free

    def _init_thermal(self, scene):
        mesh = self.smesh.mesh
        # contacts conduct perfectly: coincident nodes of different bodies share one temperature
        _, first, heat_of_node = np.unique(np.round(mesh.p.T, 12), axis=0, return_index=True, return_inverse=True)
        heat_of_node = heat_of_node.ravel()
        nheat = first.size
        self.P = sp.csr_matrix((np.ones(self.nnodes), (np.arange(self.nnodes), heat_of_node)),
                               shape=(self.nnodes, nheat))
        Pt = self.P.T.tocsr()
        t_heat = heat_of_node[mesh.t]
        self.H = CellAffineOperator(t_heat, nheat, conduction_cells(mesh.p, mesh.t), self.smesh.cell_region)
        self.temperature_keys = list(scene.thermal.temperature)
        constraints = []
        for k, name in enumerate(self.temperature_keys):
            nodes = np.unique(heat_of_node[mesh.facets[:, self.smesh.boundaries[name]]])
            constraints.append(Constraint(nodes, np.ones((nodes.size, 1)), k))
        self.heat_elim = eliminate(nheat, 1, constraints, len(self.temperature_keys))
        if self.glue:                   # glued interfaces conduct: the temperature is glued too
            fixed = np.unique(np.concatenate([c.nodes for c in constraints])) if constraints else ()
            self.heat_elim = heat_glue_elimination(
                self.heat_elim, glue_heat(self.glue, heat_of_node, nheat), nheat, fixed)
        self.heat_Tt = self.heat_elim.T.T.tocsr()
        self.reduce_heat = Reduction(self.H(np.ones(len(self.region_cells))), self.heat_elim.T)
        self.source_vectors = np.array([Pt @ forms.source_vector(mesh, c) for c in self.region_cells])
        self.coupling = [forms.coupling_piece(mesh, c) for c in self.region_cells]

    # ---- numbers of a data set -------------------------------------------------------
    def coefficients(self, scene) -> Coefficients:
        """The coefficients of a scene's own numbers (a study's data go through its `ParameterMap`)."""
        return ParameterMap(self, scene).coefficients()

    def stiffness_coefficients(self, c: Coefficients) -> np.ndarray:
        return np.column_stack([c.lam, c.mu])

    def stiffness(self, c: Coefficients) -> sp.csr_matrix:
        """K(c), the last one kept for its callers (0.4 s at 1e5 unknowns in 3D); a solve and its
        adjoint assemble it once without holding it (`reduced_system`)."""
        key = self.stiffness_coefficients(c).tobytes()
        held = self._cache.stiffness
        if held is None or held[0] != key:
            K = self.K(self.stiffness_coefficients(c))
            _read_only(K)                        # shared by the callers of this data set
            held = self._cache.stiffness = (key, K)
        return held[1]

    def mechanical_load(self, c: Coefficients, T: np.ndarray | None) -> np.ndarray:
        f = (np.einsum("ji,jid->d", c.body_force, self.body_force_vectors) if np.any(c.body_force)
             else np.zeros(self.dim * self.nnodes))
        for b, v in self.pressure_vectors.items():
            f += c.pressure[b] * v
        for b, v in self.traction_vectors.items():
            f += c.traction[b] @ v
        if T is not None:
            dT = T - c.reference
            for j, B in enumerate(self.coupling):
                if c.beta[j] != 0.0:
                    f += c.beta[j] * (B @ dT)
        return f

    # ---- solves ------------------------------------------------------------------------
    def solve_heat(self, c: Coefficients) -> np.ndarray:
        """The nodal temperature of data set c."""
        return self.P @ self._heat_theta(c)[0]

    def heat_system(self, c: Coefficients) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
        """The reduced conduction system of data set c: (Kr, rhs, Th0), θ = T_elim Kr⁻¹ rhs + Th0."""
        Kh = self.H(c.kappa)
        Kr = self.reduce_heat(Kh)
        Th0 = self.heat_elim.U0 @ c.temperature_values
        q = self.source_vectors.T @ c.source
        return Kr, self.heat_Tt @ (q - Kh @ Th0), Th0

    def _heat_theta(self, c: Coefficients) -> tuple[np.ndarray, sp.csr_matrix]:
        """The temperature on the heat nodes (θ of `wcs.model.sensitivity`) by the direct solve, and
        the reduced conduction matrix it factored."""
        Kr, rhs, Th0 = self.heat_system(c)
        return self.heat_elim.T @ _factor(self._cache.heat, Kr).solve(rhs) + Th0, Kr

    def solve(self, c: Coefficients, adjoint: bool = False) -> Solution:
        """Solve the data set with coefficients c. A monolithic contact solve starts from the
        contact state at the nominal data (the anchor, solved once on first use from the cold
        start), never from the previous data set; the nominal data themselves are always solved
        from the cold start, so the anchor solve doubles as their evaluation. The answer for a
        data set is then the same whatever was solved before it — in another order, after a
        failed solve or an exception, after a resume, on another MPI rank — to the last bit:
        the caches (the anchor, the factors with their analysis) change the cost of a solve
        only. With `adjoint`, the solution is one whose factorizations the adjoint can use
        (a converged DD solve is polished by the monolithic solver)."""
        cache = self._cache
        nominal = _same_data(c, self.nominal)
        if self._anchored and not cache.anchor_tried and not nominal:
            try:
                self.solve(self.nominal)
            except SolveError:
                cache.anchor_tried = True   # no anchor: every solve starts cold (still deterministic)
        T, theta, Kh = self._heat(c, adjoint) if self.thermal else (None, None, None)
        floating = {b: m for b, m in self.free_modes.items() if m.shape[1]}
        if floating and self.zone is None:
            body, modes = next(iter(floating.items()))
            raise StudyError(f"body '{body}' is not held: {_describe_modes(modes, self.dim)} are free "
                             "(add a support, or a contact that holds it)", path=f"scene.bodies.{body}")
        if self.units is not None and not self.method.assembles:   # K(c) itself unused
            Kr, rhs, u0 = None, *self._reduced_load(c, T)
        else:
            Kr, rhs, u0 = self.reduced_system(c, T)[1:]     # K(c) not held through the solve
        own = dict(coefficients=c, theta=theta, conduction=Kh, factors=cache)
        if self.zone is None:
            w = _factor(cache.elastic, Kr).solve(rhs)
            u = self.elim.T @ w + u0
            return Solution(u=u, T=T, stress=self.cell_stress(u, T, c), w=w, stiffness=Kr, **own)
        out = self.method.solve(self, c, Kr, rhs, u0, nominal, adjoint)
        return Solution(u=out.u, T=T, stress=self.cell_stress(out.u, T, c), solver=out.solver,
                        iterations=out.iterations, krylov_steps=out.krylov_steps, contact=out.contact, w=out.w, raw=out.raw,
                        stiffness=out.stiffness, scale=out.scale, **own)

    def _contact_stiffness(self, c: Coefficients, Kr) -> tuple[sp.csr_matrix, np.ndarray | float]:
        """(K*, s): the reduced stiffness the contact solver factors, and the scales s_u with
        which the data set's stiffness is s_u K* on each unit u (`wcs.contact.units`). K
        is homogeneous of degree one in the moduli, so data sets that differ by one factor on
        every λ and μ of a unit (its Young's modulus) share its K*_u and its contact
        factorization with the Delassus block W*_u (the cost of a 3D evaluation: 8 of 13 s on
        the tunnel at 1.1e5 unknowns): K* is K(c*) with c* on each unit the moduli divided by
        the unit's first region's μ, rounded to 12 significant digits (so that round-off in
        λ/μ does not tell apart what is one direction), times the nominal data's μ of that
        region; s_u = μ / μ_nominal there. The data set is then solved with its moduli rounded
        at the 12th digit, a relative change of at most 5e-13, and its answer depends on its
        data alone (K* on the directions, s on the data). In 2D too (the Tresca pad at 9.6e3
        unknowns: a warm evaluation with a new rubber E 21 → 10 ms, no refactor); the dual QP
        reference keeps K itself."""
        if self.units is None:
            return Kr, 1.0
        coef = self.stiffness_coefficients(c)
        nominal = self.stiffness_coefficients(self.nominal)
        star = nominal.copy()                   # a region acting on no DOF keeps its nominal moduli
        scales = np.empty(len(self.units.regions))
        for u, regions in enumerate(self.units.regions):
            first = coef[regions[0], 1]
            ratio = np.array([float(f"{v:.11e}") for v in (coef[regions] / first).ravel()])
            star[regions] = ratio.reshape(len(regions), -1) * nominal[regions[0], 1]
            scales[u] = first / nominal[regions[0], 1]
        key = star.tobytes()
        held = self._cache.direction
        if held is None or held[0] != key:
            Ks = self.reduce(self.K(star))
            _read_only(Ks)
            held = self._cache.direction = (key, Ks, self._unit_blocks(Ks))
        return held[1], scales

    def _unit_blocks(self, Ks: sp.csr_matrix) -> list[sp.csr_matrix]:
        """The units' diagonal blocks of Ks regularized on the pinned DOFs (`regularize`)."""
        Kreg = regularize(Ks, self.pinned)
        dofs = self.units.dofs
        if len(dofs) == 1:
            return [Kreg]
        blocks = []
        for d in dofs:
            B = Kreg[d][:, d].tocsr()
            B.sort_indices()
            blocks.append(B)
        return blocks

    def factored(self, K: sp.csr_matrix, scale):
        """What solves with the contact stiffness (s_u · K on unit u) and holds its W
        (`.factor.solve`, `.W`): the units' factors (`contact_operator`), else one factor of K."""
        if self.units is not None:
            return self.contact_operator(K, scale)
        return self.contact_factor(K)

    def contact_operator(self, Ks: sp.csr_matrix, scales):
        """The solves with K = blockdiag(s_u K*_u) and its W (`UnitFactors.of`), Ks = K*."""
        held = self._cache.direction
        blocks = held[2] if held is not None and held[1] is Ks else self._unit_blocks(Ks)
        if self._cache.contact is None:
            self._cache.contact = UnitFactors(self.units.dofs, self.contact_rows, self.pinned, self.dim == 3)
        return self._cache.contact.of(blocks, scales)

    def reduced_system(self, c: Coefficients, T: np.ndarray | None):
        """(K, Kr, rhs, u0): the stiffness, Kr = Tᵀ K T on its fixed pattern, the reduced load
        rhs = Tᵀ(f − K u0) and the displacement u0 the supports impose (u = T w + u0). K is the
        one `stiffness` holds for these data, else assembled and not held: a solve needs Kr only
        (K held beside it took 0.5 GB at 1e6 unknowns); what the adjoint takes from K, K U0, is
        kept instead (`support_stiffness`)."""
        key = self.stiffness_coefficients(c).tobytes()
        held = self._cache.stiffness
        K = held[1] if held is not None and held[0] == key else self.K(self.stiffness_coefficients(c))
        _read_only(K)
        self._cache.support = (key, (K @ self.elim.U0.tocsc()).tocsc())
        u0 = self.elim.U0 @ c.support_values
        return K, self.reduce(K), self.Tt @ (self.mechanical_load(c, T) - K @ u0), u0

    def support_stiffness(self, c: Coefficients) -> sp.csc_matrix:
        """K(c) U0 (the elastic forces of the supports' unit displacements, for the adjoint): the
        one the data set's `reduced_system` kept, else from `stiffness`."""
        held = self._cache.support
        if held is not None and held[0] == self.stiffness_coefficients(c).tobytes():
            return held[1]
        return (self.stiffness(c) @ self.elim.U0.tocsc()).tocsc()

    def _reduced_load(self, c: Coefficients, T: np.ndarray | None):
        """(rhs, u0) of `reduced_system` with K(c) u0 summed over the cells the supports move
        (`CellAffineOperator.apply`), K(c) not assembled: a contact solve factors K* of its
        units' directions (`_contact_stiffness`), not K(c) (0.2 s at 1e5 unknowns)."""
        u0 = self.elim.U0 @ c.support_values
        Ku0 = self.K.apply(self.stiffness_coefficients(c), u0)
        return self.Tt @ (self.mechanical_load(c, T) - Ku0), u0

    def _solve_dd(self, c, Kr, rhs, u0):
        from ..dd.solver import solve_dd     # the DD modules (and scipy.spatial) load only for method dd
        return solve_dd(self, self.scene, Kr, rhs, u0, self.options, coefficients=c, comm=self.comm)

    def _heat(self, c: Coefficients, adjoint: bool):
        """The thermal step (T, θ, reduced conduction matrix): by the method's own solve where it
        has one (the decomposition; the iterative method: CG + GAMG, `wcs.model.heat`; θ and the
        matrix None: the adjoint needs the direct factorization), else directly."""
        T = None if adjoint else (heat_by_krylov(self, c) if self.solver_method == "iterative"
                                  else self.method.heat(self, c))
        if T is not None:
            return T, None, None
        theta, Kh = self._heat_theta(c)
        return self.P @ theta, theta, Kh

    def _solve_contact(self, c: Coefficients, Kr, rhs, u0, nominal: bool, warm, scale, method):
        """The contact problem of stiffness s_u · Kr on each unit u (`_contact_stiffness`) by
        `method.solve_problem` (`wcs.contact.methods.Primal`), started from `warm`, else (a
        method `anchored` on the model) from the anchor."""
        z = self.zone
        cache = self._cache
        F = c.coulomb
        problem = ContactProblem(Kr, rhs, self.Bn_r, self.Bt_r, z.gap - z.Bn @ u0, z.weight, c.slip,
                                 F if F.any() else None, self.R_r,
                                 warm if warm is not None or nominal or not self._anchored else cache.anchor, scale,
                                 coefficients=self.stiffness_coefficients(c) if self.units is None else None)
        res = method.solve_problem(self, problem)
        anchor = nominal and self._anchored and warm is None
        cache.anchor_tried |= anchor            # a failure too: then every solve starts cold
        if res.status == Status.UNSOLVABLE:
            raise SolveError(self._unbalanced_message(res, rhs), status=Status.UNSOLVABLE)
        if res.status == Status.NOT_UNIQUE:
            raise SolveError(self._free_motion_message(res.alpha), status=Status.NOT_UNIQUE)
        if res.status != Status.SOLVED:
            raise SolveError(res.message, status=res.status)
        if anchor and cache.anchor is None:
            cache.anchor = dataclasses.replace(res, factor=None)   # the factor moves on with later data
        res = dataclasses.replace(res, factor=None)   # a solution reaches its factor by `contact_factor`
        u = self.elim.T @ res.u + u0
        return u, self.contact_state(res.lam_n, res.lam_t, u, res.active), res.iterations, res

    @functools.cached_property
    def near_nullspace(self) -> np.ndarray:
        """The rigid motions of the whole mesh on the reduced unknowns (least squares through
        u = T w): the near-nullspace of the algebraic multigrid. One set for all bodies: per body
        (12 columns for two bodies) the coarse grids grew and a CG solve on 3D Hertz took 3×."""
        from ..contact.iterative import reduced_modes
        return reduced_modes(self.elim.T, rigid_modes(self.smesh.mesh.p, np.arange(self.nnodes), self.nnodes))

    def contact_factor(self, Kr: sp.csr_matrix):
        """The contact factorization of Kr (`factor_contact`) on the model's pinned DOFs and
        contact rows, made once (not per solve), in the factor object the cache holds (one
        factor object, refactored in place from the first one on)."""
        cf = factor_regularized(regularize(Kr, self.pinned), self.contact_rows, self.pinned,
                                self._cache.contact, self.dim == 3)
        if self._cache.contact is None:
            self._cache.contact = cf
        return cf

    @functools.cached_property
    def contact_rows(self) -> sp.csr_matrix:
        """C = [Bn; Bt] on the reduced unknowns: every contact row, normals first."""
        return sp.vstack([self.Bn_r, self.Bt_r]).tocsr()

    @functools.cached_property
    def held(self) -> np.ndarray:
        """Flags of the contact rows [Bn; Bt] the supports hold (`wcs.contact.zone.held_rows`)."""
        z = self.zone
        return np.r_[held_rows(self.Bn_r, z.Bn), held_rows(self.Bt_r, z.Bt)]

    @functools.cached_property
    def tied(self) -> tuple[np.ndarray, np.ndarray]:
        """(tied, κ) of the contact rows (`wcs.contact.zone.tied_rows`): geometry, once."""
        return tied_rows(self.Bn_r, self.Bt_r, self.held)

    @functools.cached_property
    def dependent(self) -> tuple[np.ndarray, np.ndarray]:
        """(nodes, v) of the contact rows dependent without being tied (`dependent_rows`)."""
        return dependent_rows(self.Bn_r, self.Bt_r, self.held, self.tied[0])

    def contact_state(self, lam_n, lam_t, u, active) -> ContactState:
        """The tractions a solver found for the displacement u, with the closed nodes of tied
        or dependent rows at their canonical split and nothing on held rows (`canonical_split`):
        what every solver reports alike."""
        z = self.zone
        gap = z.gap - z.Bn @ u
        force_n, force_t, moved, jacobian = canonical_split(lam_n, lam_t, gap, *self.tied,
                                                            max(np.abs(u).max(initial=0.0), 1e-300),
                                                            self.held, self.dependent)
        return ContactState(z, force_n, force_t, gap, z.Bt @ u, active, moved, jacobian)

    def _unbalanced_message(self, res, rhs) -> str:
        """Name the floating body whose rigid motion the load can drive, and the load."""
        if res.alpha is None:                     # the QP reference reports unboundedness only
            names = ", ".join(f"'{b}'" for b, _ in self.floating)
            return (f"the load on the floating bodies {names} is not balanced by contact and friction "
                    f"({res.message}): the load must be balanced on the rigid motions of a floating body, "
                    f"its work at most the friction's for every admissible rigid motion w (solvability "
                    f"L(w) <= j(w); seed [21, Remark 2.1])")
        alpha = np.asarray(res.alpha, float)
        k, moved = 0, []                          # (load work, share of the motion, body) of each body it moves
        for body, modes in self.floating:
            a = alpha[k:k + modes.shape[1]]
            moved.append((float(rhs @ (self.elim.T.T @ (modes @ a))), float(np.abs(a).sum()), body))
            k += modes.shape[1]
        work = sum(w for w, _, _ in moved)
        _, top, best = max(moved)                 # the body whose load does the most work
        along = [b for _, sh, b in moved if b != best and sh > 1e-9 * max(top, 1e-300)]
        nodes = np.flatnonzero(self.smesh.node_body == self.smesh.bodies.index(best))
        load = self.elim.T @ rhs                                   # the reduced load, back on the dofs
        d = self.dim
        force = np.array([load[d * nodes + i].sum() for i in range(d)])
        net = ", ".join(f"{f:.4g}" for f in force)
        return (f"body '{best}' is held only by contact and its load is not balanced: "
                f"net load ({net}) {'N' if d == 3 else 'N/m'} drives a rigid motion"
                + "".join(f" (with body '{b}')" for b in along)
                + f" that friction and contact do not resist (load work {work:.3g} > friction work): the load "
                f"must be balanced on the rigid motions of a floating body (solvability L(w) <= j(w); "
                f"seed [21, Remark 2.1])")

    def _free_motion_message(self, beta: np.ndarray) -> str:
        """Name the floating body whose rigid motion the active contact leaves free, and the motion."""
        k, parts, d = 0, [], self.dim
        for body, modes in self.floating:
            v = modes @ beta[k:k + modes.shape[1]]
            k += modes.shape[1]
            nodes = np.flatnonzero(self.smesh.node_body == self.smesh.bodies.index(body))
            dofs = np.concatenate([d * nodes + i for i in range(d)])
            R = rigid_modes(self.smesh.mesh.p, nodes, self.nnodes)[dofs]
            a = np.linalg.lstsq(R, v[dofs], rcond=None)[0]
            parts.append((np.abs(a).max(), body, a, self.smesh.mesh.p[:, nodes].mean(axis=1)))
        _, body, a, c = max(parts, key=lambda t: t[0])
        a = a / np.abs(a).max()
        a = np.where(np.abs(a) > 1e-9, a, 0.0) + 0.0
        if d == 3:
            motion = (f"translation ({a[0]:.3g}, {a[1]:.3g}, {a[2]:.3g}) m with rotation ({a[3]:.3g}, {a[4]:.3g}, "
                      f"{a[5]:.3g}) rad about the axes through ({c[0]:.4g}, {c[1]:.4g}, {c[2]:.4g})")
        else:
            motion = (f"translation ({a[0]:.3g}, {a[1]:.3g}) m with rotation {a[2]:.3g} rad about "
                      f"({c[0]:.4g}, {c[1]:.4g})")
        return (f"body '{body}' is not held: its position is not determined — the rigid motion "
                f"{motion} moves no closed or stuck contact node, so the solution is not "
                f"unique (add a support, friction, or a contact that holds it)")

    def cell_stress(self, u: np.ndarray, T: np.ndarray | None, c: Coefficients) -> np.ndarray:
        """(4, ncells) in 2D (`wcs.fem.stress`), (6, ncells) in 3D (`wcs.geometry.tet`)."""
        reg = self.smesh.cell_region
        dT = cell_mean(self.smesh.mesh.t, T) - c.reference if T is not None else np.zeros(reg.size)
        if self.dim == 3:
            return tet.stresses((self.G @ u).reshape(6, -1), c.lam[reg], c.mu[reg], c.beta[reg], dT)
        strain = (self.G @ u).reshape(3, -1)
        return stresses(strain, c.lam[reg], c.mu[reg], c.beta[reg], dT, self.plane)


def _friction(scene) -> str:
    """The scene's friction law: "coulomb" where a contact has a coefficient, else "tresca" where
    one has a slip limit, else "none"."""
    laws = [c.friction for c in scene.contacts.values() if c.friction is not None]
    return ("coulomb" if any(f.coefficient for f in laws) else "tresca" if any(f.slip_limit for f in laws)
            else "none")


def _factor(held: linalg.HeldFactor, A) -> linalg.Factor:
    """`held` holding the SPD matrix A (a held stiffness, a conduction matrix with fixed
    temperatures), by Cholesky: its analysis reads the pattern only; an LU's scaling and
    matching read the values of the first matrix factored, so every later answer depended on
    which data set came first (last bits of a heated plate's shear)."""
    try:
        return held.of(A)
    except linalg.FactorizationError as exc:
        raise SolveError(f"factorization failed: {exc}", status=Status.SINGULAR) from None


def _read_only(value) -> None:
    """Make the arrays of a built model (and of its parts: sparse matrices, dataclasses,
    containers) read-only in place."""
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    elif sp.issparse(value):
        for a in ("data", "indices", "indptr", "row", "col"):
            if hasattr(value, a):
                getattr(value, a).flags.writeable = False
    elif isinstance(value, dict):
        for v in value.values():
            _read_only(v)
    elif isinstance(value, (list, tuple)):
        for v in value:
            _read_only(v)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            _read_only(getattr(value, f.name))


def _same_data(a: Coefficients, b: Coefficients) -> bool:
    """Whether two data sets give bitwise the same numbers to the model."""
    for f in dataclasses.fields(Coefficients):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, dict):
            if x.keys() != y.keys() or not all(np.array_equal(x[k], y[k]) for k in x):
                return False
        elif not np.array_equal(x, y):
            return False
    return True


def _describe_modes(modes: np.ndarray, dim: int = 2) -> str:
    k = modes.shape[1]
    if dim == 3:
        return {1: "one rigid motion", 2: "two rigid motions", 3: "three rigid motions", 4: "four rigid motions",
                5: "five rigid motions",
                6: "all six rigid motions (translations along x, y, z, rotations about them)"}[k]
    return {1: "one rigid motion", 2: "two rigid motions", 3: "all three rigid motions (x, y, rotation)"}[k]
