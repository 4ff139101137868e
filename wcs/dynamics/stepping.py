r"""The time levels of a dynamic study: one contact solve per level (`wcs.dynamics.schemes`).

`dynamic_matrices` assembles the data set's reduced mass, damping and stiffness;
`initial_state` gives (w₀, v₀); `step_levels` runs the levels and returns a `History`.

Each level's problem is a `ContactProblem` with the level's operator A (positive definite:
no rigid modes, R = None), the gap shifted by the last level's displacement and the slip limit
of the level (Tresca g as given; Coulomb F·p with the pressure p of the previous level, as the
seed does: "the frictional term is approximated by its value in the previous time level"
[101, §3]), started from the last level's multipliers. The methods that solve a
`ContactProblem` in one call (`wcs.contact.methods.Primal`) solve it: 'iterative' by its own
`solve_problem`; 'monolithic' by the condensed Newton (`solve_condensed`) on a factor of A
held per operator — its registered `solve_problem` factors the model's static stiffness by
units with springs on the pinned DOFs of the floating bodies (exact for K R = 0 only, wrong
for A); 'dd', which assembles each subdomain's matrix itself, by its `solve_level` with A's
per-region coefficients over the cells' stiffness, mass and absorbing pieces
(`level_coefficients`; the layer's and the dashpots' `wcs.dynamics.absorbing.AbsorbingCells`).

A level that fails stops the run with a SolveError naming the level and the time: the levels
before it are never passed off as the answer.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp

from wcs import linalg
from wcs.contact.methods import settings
from wcs.contact.problem import ContactProblem
from wcs.contact.solver import OPEN, ContactResult, solve_condensed
from wcs.errors import SolveError, StudyError
from wcs.model.materials import plane_lame
from wcs.model.model import Solution
from wcs.progress import phase
from wcs.status import Status

from . import energy, schemes
from .mass import mass_cell_matrices, mass_operator, viscous_lame
from .spec import Dynamics, InitialVelocity


def region_dynamics(model, pmap, x=(), others=None) -> tuple[np.ndarray, np.ndarray]:
    """(ρ, (λ₁, μ₁)) per region at data vector x: the density and the viscous Lamé constants
    (`wcs.dynamics.mass.viscous_lame`), read from the data set's numbers by dotted path."""
    s = pmap.slots(x, others)
    c = pmap.coefficients(x, others)
    scene = model.scene
    rho = np.empty(len(model.region_material))
    visc = np.zeros((len(model.region_material), 2))
    for j, name in enumerate(model.region_material):
        material = scene.materials[name]
        rho[j] = s[pmap.index[f"materials.{name}.density"]]
        v = material.viscosity
        if v is None:
            continue
        value = {key: s[pmap.index[f"materials.{name}.viscosity.{key}"]]
                 for key in ("ratio", "E", "nu") if getattr(v, key) is not None}
        visc[j] = (value["ratio"] * c.lam[j], value["ratio"] * c.mu[j]) if "ratio" in value else \
            plane_lame({"E": value["E"], "nu": value["nu"]}, model.plane or "strain")
    return rho, visc


@dataclass(frozen=True)
class Assembled(schemes.Matrices):
    """The reduced matrices with the per-region data they are made of: density ρ, viscous Lamé
    constants (λ₁, μ₁), whether C holds an extra damping matrix (a layer, dashpots) and that
    matrix as cell pieces with their per-region coefficients (`wcs.dynamics.loading.damping_cells`)."""
    rho: np.ndarray | None = None
    visc: np.ndarray | None = None
    damped: bool = False
    absorbing: tuple | None = None


def dynamic_matrices(model, c, rho, visc, damping: sp.spmatrix | None = None, absorbing=None) -> Assembled:
    """The reduced M (density ρ per region), C (viscous a⁽¹⁾ plus `damping`, an extra damping
    matrix on the full DOFs such as an absorbing layer's α or dashpots) and K of data set c;
    `absorbing`: `damping` as (cell pieces, per-region coefficients), for `dd`."""
    M = model.reduce(mass_operator(model)(rho))
    C = model.reduce(model.K(visc)) if np.any(visc) else None
    if damping is not None:
        extra = sp.csr_matrix(model.Tt @ damping @ model.elim.T)
        C = extra if C is None else sp.csr_matrix(C + extra)
    return Assembled(sp.csr_matrix(M), C, sp.csr_matrix(model.reduce(model.stiffness(c))),
                     np.asarray(rho, float), np.asarray(visc, float), damping is not None, absorbing)


class LevelCells:
    """The cells' matrices of a level operator as affine pieces (`wcs.fem.affine.CellMatrices`'
    protocol): the stiffness's (λ, μ), the consistent mass of unit density and, with absorbing
    boundaries, their pieces (`wcs.dynamics.absorbing.AbsorbingCells`), per cell. `key`: what of
    the pieces depends on the data set beyond the coefficients (the layer's cells)."""

    def __init__(self, model, absorbing=None):
        self.stiffness, self.p, self.t = model.K.local, model.smesh.mesh.p, model.smesh.mesh.t
        self.absorbing = absorbing
        self.npieces = self.stiffness.npieces + 1 + (absorbing.npieces if absorbing is not None else 0)
        self.block = self.stiffness.block
        self.key = absorbing.key if absorbing is not None else b""

    def of(self, cells) -> np.ndarray:
        extra = [self.absorbing.of(cells)] if self.absorbing is not None else []
        return np.concatenate([self.stiffness.of(cells), mass_cell_matrices(self.p, self.t[:, cells])] + extra)


def level_coefficients(model, c, mats: Assembled, dyn: Dynamics, key: str) -> np.ndarray:
    """Per region, the coefficients of `LevelCells` whose sum is the level operator A of
    `wcs.dynamics.schemes`: seed A = M/τ² + C/τ + K, stabilized A = 2M/τ² + C/τ + K/2 (C the
    viscous a⁽¹⁾, the stiffness at (λ₁, μ₁), plus the absorbing boundaries' damping), the
    stabilized predictor's A = M."""
    tau, kc = dyn.time_step, model.stiffness_coefficients(c)
    rho = mats.rho[:, None]
    absorbing = [] if mats.absorbing is None else [mats.absorbing[1] * (key != "predictor") / tau]
    if key == "predictor":
        return np.hstack([np.zeros_like(kc), rho] + absorbing)
    if dyn.scheme == "stabilized":
        return np.hstack([kc / 2 + mats.visc / tau, 2 * rho / tau**2] + absorbing)
    return np.hstack([kc + mats.visc / tau, rho / tau**2] + absorbing)


def rigid_velocity(model, initial: InitialVelocity) -> np.ndarray:
    """v₀ on the reduced unknowns: each named body moves with its given velocity, the others rest;
    StudyError where a support of the body holds it in that direction (the velocity cannot be)."""
    d = model.dim
    v = np.zeros(d * model.nnodes)
    bodies = model.smesh.bodies
    for body, vel in initial.velocity.items():
        nodes = np.flatnonzero(model.smesh.node_body == bodies.index(body))
        for i in range(d):
            v[d * nodes + i] = vel[i]
    T = model.elim.T
    vw = sp.linalg.spsolve(sp.csc_matrix(T.T @ T), T.T @ v)
    miss = np.abs(T @ vw - v).max(initial=0.0)
    if miss > 1e-9 * np.abs(v).max(initial=1.0):
        raise StudyError("a support holds a body given this velocity in its direction (its supported nodes "
                         "cannot move so); give a velocity along what its supports leave free",
                         path="dynamics.initial.velocity")
    return vw


def initial_state(model, c, dyn: Dynamics) -> tuple[np.ndarray, np.ndarray, ContactResult | None]:
    """(w₀, v₀, the contact at t = 0): the static solution of the scene (`static`, [101] §2:
    "the initial data satisfy the static contact problem"), or the undeformed rest with the
    given rigid velocities."""
    n = model.elim.T.shape[1]
    if dyn.initial == "static":
        try:
            sol = model.solve(c)
        except SolveError as e:
            raise SolveError(f"the static initial state (dynamics.initial: static) cannot be solved: {e}; "
                             "start from `rest` or given velocities", status=e.status) from None
        return np.asarray(sol.w, float), np.zeros(n), sol.raw
    v = rigid_velocity(model, dyn.initial) if isinstance(dyn.initial, InitialVelocity) else np.zeros(n)
    return np.zeros(n), v, None


class LevelSolver:
    """One contact problem per call through the model's contact method (see the module
    docstring), with a factor held per operator name ('step', 'predictor')."""

    def __init__(self, model, level=None):
        self.model = model
        self.factors = {}
        self.elastic = {}
        self.level = level          # key -> (LevelCells, coefficients, c): the decomposition's A
        method = model.method
        if not hasattr(method, "solve_problem") and not (hasattr(method, "solve_level") and level is not None):
            raise StudyError(f"'{model.solver_method}' does not step in time yet; use monolithic or iterative",
                             path="solver.method")

    def __call__(self, key: str, problem: ContactProblem) -> ContactResult:
        if self.level is not None:
            return self.model.method.solve_level(self.model, key, problem, *self.level(key))
        if self.model.solver_method == "monolithic":
            res = solve_condensed(problem, factor=self.factors.get(key), **settings(self.model.options))
            if res.factor is not None:
                self.factors[key] = res.factor
            return res
        return self.model.method.solve_problem(self.model, problem)

    def linear(self, key: str, A, rhs) -> np.ndarray:
        """A Δ = rhs without contact (a scene without contacts)."""
        held = self.elastic.setdefault(key, linalg.HeldFactor(spd=True))
        return held.of(A).solve(rhs)


@dataclass
class History:
    """What the levels kept: at every level n (time t_n) the contact forces, the closed contact
    nodes, the energies and the criteria; the fields at the output levels."""
    scheme: str
    time: list = field(default_factory=list)
    force_n: list = field(default_factory=list)        # (m,) nodal normal forces λn (stabilized: the step's mean)
    force_t: list = field(default_factory=list)        # ((d−1) m,) tangential forces λt
    closed: list = field(default_factory=list)         # contact nodes closed (stick or slip)
    iterations: list = field(default_factory=list)
    kinetic: list = field(default_factory=list)
    elastic: list = field(default_factory=list)
    work: list = field(default_factory=list)           # work of the loads since t = 0
    viscous: list = field(default_factory=list)        # viscous dissipation since t = 0
    friction: list = field(default_factory=list)       # friction dissipation since t = 0
    phi: dict = field(default_factory=dict)            # criterion -> values per level
    output_levels: list = field(default_factory=list)
    displacement: list = field(default_factory=list)   # (d nnodes,) at the output levels
    velocity: list = field(default_factory=list)

    @property
    def total_force(self) -> np.ndarray:
        """Σ λn per level: the resultant normal contact force [N/m in 2D, N in 3D]."""
        return np.array([f.sum() for f in self.force_n])

    @property
    def numerical(self) -> np.ndarray:
        """Numerical dissipation since t = 0: initial + work − viscous − friction − (kinetic + elastic)."""
        e = np.array(self.kinetic) + np.array(self.elastic)
        return e[0] + np.array(self.work) - np.array(self.viscous) - np.array(self.friction) - e


def level_solution(model, c, u, res: ContactResult | None, T=None) -> Solution:
    """A level as a `Solution` (what the criteria read); T the temperature (thermal scenes)."""
    contact = None
    if model.zone is not None:
        m = model.zone.gap.size
        lam_n = res.lam_n if res is not None else np.zeros(m)
        lam_t = res.lam_t if res is not None else np.zeros(model.Bt_r.shape[0])
        contact = model.contact_state(lam_n, lam_t, u, res.active if res is not None else None)
    return Solution(u=u, T=T, stress=model.cell_stress(u, T, c), coefficients=c, contact=contact)


def step_levels(model, c, mats: schemes.Matrices, dyn: Dynamics,
                load: Callable[[float], np.ndarray] | None = None, criteria=(),
                start: tuple | None = None, states: list | None = None, predictors: list | None = None) -> History:
    """Run the levels of `dyn` on data set c. load(t): the load vector f(t) on the full DOFs at
    time t (time functions, point sources; None: the data set's own loads, constant in time);
    criteria: `wcs.criteria.Criterion`s measured at every level; start: (w₀, v₀, contact at
    t = 0), else `initial_state`; states: a list that receives each level's (Δ, contact result)
    (what the adjoint through time sweeps back over, `wcs.dynamics.adjoint`); predictors: one
    that receives each stabilized level's predictor (δ̃, its projection's contact result or None)."""
    tau, N = dyn.time_step, dyn.levels
    T, zone = model.elim.T, model.zone
    u0 = model.elim.U0 @ c.support_values
    K_full = model.stiffness(c)
    heat = model.solve_heat(c) if model.thermal else None     # a steady temperature: its load is constant
    k0 = model.Tt @ (K_full @ u0)                   # the supports' share of the elastic force
    if load is None:
        constant = model.mechanical_load(c, heat)
        load = lambda t: constant                   # noqa: E731 - the data set's load, at every time

    def f(t: float) -> np.ndarray:
        """Tᵀ f(t): the load on the reduced unknowns."""
        return model.Tt @ load(t)

    w, v, res = start if start is not None else initial_state(model, c, dyn)
    solver = LevelSolver(model, _decomposed(model, c, mats, dyn))
    hist = History(dyn.scheme)
    g = c.slip if zone is not None else None
    F = c.coulomb if zone is not None and c.coulomb.any() else None
    stabilized = dyn.scheme == "stabilized"
    A = (schemes.stabilized_operator if stabilized else schemes.seed_operator)(mats, tau)
    sums = dict(work=0.0, viscous=0.0, friction=0.0)

    def keep(n, t, w, v, res):
        u = T @ w + u0
        hist.time.append(t)
        if zone is not None:
            m = zone.gap.size
            hist.force_n.append(np.array(res.lam_n) if res is not None else np.zeros(m))
            hist.force_t.append(np.array(res.lam_t) if res is not None else np.zeros(model.Bt_r.shape[0]))
            hist.closed.append(int(np.sum(res.active != OPEN)) if res is not None and res.active is not None else 0)
        hist.iterations.append(res.iterations if res is not None else 0)
        hist.kinetic.append(energy.kinetic(mats.M, v))
        hist.elastic.append(energy.elastic(K_full, u))
        for key, value in sums.items():
            getattr(hist, key).append(value)
        if criteria:
            state = level_solution(model, c, u, res, heat)
            for crit in criteria:
                hist.phi.setdefault(crit.name, []).append(crit.value(model, state))
        if n % dyn.output_every == 0 or n == N:
            hist.output_levels.append(n)
            hist.displacement.append(u)
            hist.velocity.append(T @ v)

    keep(0, 0.0, w, v, res)
    with phase("time levels", total=N) as progress:
        for n in range(1, N + 1):
            t_now, t_next = (n - 1) * tau, n * tau
            f_now, f_next = f(t_now) - k0, f(t_next) - k0
            predicted = None
            if stabilized:
                rhs_p = schemes.predictor_load(mats, tau, v)
                projection = (_contact(solver, "predictor", mats.M, rhs_p, model, w, u0, None, None, res, n, t_next)
                              if zone is not None else None)
                predicted = projection.u if projection is not None else tau * v
                if predictors is not None:
                    predictors.append((predicted, projection))
                rhs = schemes.stabilized_load(mats, tau, w, predicted, f_now, f_next)
            else:
                rhs = schemes.seed_load(mats, tau, w, v, f_next)
            if zone is not None:
                slip = g + F * res.lam_n / zone.weight if F is not None and res is not None else g
                res = _contact(solver, "step", A, rhs, model, w, u0, slip, None, res, n, t_next)
                step = res.u
            else:
                step = solver.linear("step", A, rhs)
            v_new = (schemes.stabilized_velocity(tau, v, step, predicted) if stabilized
                     else schemes.seed_velocity(tau, v, step))
            f_mean = (f(t_now) + f(t_next)) / 2 if stabilized else f(t_next)
            sums["work"] += float(f_mean @ step)
            sums["viscous"] += energy.viscous(mats.C, tau, step / tau)
            if zone is not None:
                sums["friction"] += energy.friction(res.lam_t, model.Bt_r @ step)
            w, v = w + step, v_new
            if states is not None:
                states.append((step, res if zone is not None else None))
            keep(n, t_next, w, v, res)
            progress.step()
    return hist


def _contact(solver: LevelSolver, key, A, rhs, model, w, u0, slip, F, warm, n, t) -> ContactResult:
    """The level's contact problem in the increment Δ (gap shifted by the last level's
    displacement), solved; SolveError naming the level where it fails."""
    z = model.zone
    d = z.gap - z.Bn @ u0 - model.Bn_r @ w
    start = None if key != "step" or warm is None else dataclasses.replace(warm, alpha=None)   # no rigid modes here
    problem = ContactProblem(A, rhs, model.Bn_r, model.Bt_r, d, z.weight, slip, F, None, start,
                             reference=float(np.abs(w).max(initial=0.0)))
    res = solver(key, problem)
    if res.status != Status.SOLVED:
        raise SolveError(f"time level {n} (t = {t:.6g} s), {key}: {res.message}", status=res.status)
    return res


def _decomposed(model, c, mats, dyn: Dynamics):
    """For a model that assembles each subdomain itself (`dd`): key -> (LevelCells, A's
    coefficients, c), else None."""
    if not hasattr(model.method, "solve_level"):
        return None
    if not isinstance(mats, Assembled) or (mats.damped and mats.absorbing is None):
        raise StudyError(f"'{model.solver_method}' takes absorbing boundaries as cell pieces only (given a "
                         "damping matrix alone); use monolithic or iterative", path="solver.method")
    cells = LevelCells(model, None if mats.absorbing is None else mats.absorbing[0])
    return lambda key: (cells, level_coefficients(model, c, mats, dyn, key), c)
