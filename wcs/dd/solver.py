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
subdomains linear). Options: the study's `solver` block (`wcs.options.Solver`, its
`dd` block `wcs.options.DomainDecomposition`: each option with its default there);
`tolerance` and `max_iterations` (the budget of successive approximations) apply.
`relaxation: anderson` (with `anderson`, `mixing`, `anderson_restart`) measured worse
than Aitken on the off-centre pad, converges on the tunnel with β = 0.1 where Aitken
stagnates (results/bench/dd_iterations_nonlinear.csv).

MPI: `solve_dd(..., comm=)` / `solve_heat_dd(..., comm=)` distribute the units over
the communicator's ranks (team.py: deterministic gathers summed in unit order, so
the result is bitwise the serial one).

This module holds the entry points and the per-model cache of decompositions; the parts:
partition.py (subdomains and pairs), decomposition.py (the units on them, the interface,
the stiffness weights and loads), unit.py and pair.py (a linear subdomain's and a contact
pair's local solves; kernels.py their kernel bases), operator.py (the interface operators
S, S0, J_k with their preconditioner and coarse space; pcg.py the PCG), iterations.py (the
outer iteration: its state `Iteration`, interface Newton, the Coulomb fixed point, the
seed's step, the ρ estimate), team.py (the ranks).
"""
from __future__ import annotations

import time
import weakref
from typing import NamedTuple

import numpy as np

from wcs.status import DDOutcome, Status
from wcs.options import Solver
from wcs.progress import phase

from .decomposition import (Decomposition, build_decomposition, build_heat_decomposition, distribute_load,
                            injections, sizes, stiffness_measure, unit_rho)
from .iterations import Iteration, coulomb_newton, rho_estimate, successive
from .operator import InterfaceOperator
from .pair import tangent_rows
from .pcg import CoarseSingular, pcg
from .team import Team
from .unit import SetupError


class DDResult(NamedTuple):
    """What `solve_dd` returns; unpacks as (u, lam_n, lam_t, info, status, message)."""
    u: np.ndarray | None           # (d nnodes,) full displacement (None on failure)
    lam_n: np.ndarray | None       # (m,) normal contact forces, zone row order
    lam_t: np.ndarray | None       # ((d − 1) m,) tangential contact forces, tangent j of node i at j·m + i
    info: dict                     # iteration counts, history, active set, timings, sizes
    status: DDOutcome
    message: str


class Level(NamedTuple):
    """A time level's contact problem for `solve_decomposed` (`wcs.dynamics.stepping`): the units'
    matrices made of the cells' pieces `local` (mass and stiffness: positive definite, no
    kernel) at `coefficients` (per region, one row a region), the level's gaps `d` (zone rows)
    and slip bounds `slip` (Tresca; Coulomb's taken from the last level's pressures); `name`: the
    operator's (a scheme's 'step' and 'predictor' keep a decomposition each, factored once);
    `reference`: the size of the displacement the level's answer is an increment of."""
    name: str
    local: object
    coefficients: np.ndarray
    d: np.ndarray
    slip: np.ndarray
    reference: float = 0.0


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


def decomposition(model, options, heat: bool = False, level: Level | None = None) -> Decomposition:
    """The model's decomposition for these `solver` options, of the elastic problem, of a time
    level's operator (`Level`: the cells' pieces, one decomposition by operator name and the
    pieces' `key`, e.g. an absorbing layer's cells) or
    (`heat`) of the thermal step (built once, cached on the model)."""
    dd = Solver.of(options).dd
    held = () if level is None else ("level", level.name, getattr(level.local, "key", b""))   # the pieces' own key
    key = ("heat",) * heat + held + (dd.subdomains, dd.pair_size)
    per_model = _CACHE.setdefault(model, {})
    if key not in per_model:
        with phase("DD set-up (heat)" if heat else "DD set-up"):
            per_model[key] = (build_heat_decomposition(model, dd) if heat else
                              build_decomposition(model, dd, None if level is None else level.local))
    return per_model[key]


def _fail(info, status, message):
    info["status_name"] = status.value
    return DDResult(None, None, None, info, status, message)


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
    c = coefficients if coefficients is not None else model.coefficients(scene)
    return solve_decomposed(model, c, rhs, u0, options, comm)


def solve_decomposed(model, c, rhs: np.ndarray, u0: np.ndarray, options=None, comm=None,
                     level: Level | None = None) -> DDResult:
    """`solve_dd` at the data set's coefficients c; level: a time level's problem (`Level`) in
    place of the static one — its units' matrices, gaps and slip bounds, rhs the level's load
    and u0 zero (the answer is the increment, info["w"])."""
    o = _dd_options(options)
    t0 = time.perf_counter()
    info: dict = {"method": "dd", "options": o}
    try:
        dec = decomposition(model, options, level=level)
    except (SetupError, CoarseSingular) as exc:
        return _fail(info, DDOutcome.SETUP_FAILED, f"domain decomposition set-up failed: {exc}")
    kc = model.stiffness_coefficients(c) if level is None else level.coefficients
    team = Team(comm, dec.units, model.smesh.mesh.p.shape[0], dec.measured,
                refactor=not np.array_equal(dec.kept.get("data"), kc))
    tm = team.timings
    info["nranks"] = team.size
    z = model.zone
    g, F = (c.slip, c.coulomb) if level is None else (level.slip, np.zeros_like(c.coulomb))
    d = z.gap - z.Bn @ u0 if level is None else level.d
    rho_region = stiffness_measure(c.lam, c.mu)
    info.update(sizes(dec))
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
    rho = [unit_rho(u, rho_region) for u in dec.units]
    D = distribute_load(dec, rho, rhs, team)
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
    it = Iteration(dec, S0, S, S0.load(), d, z.weight, g, F, float(np.linalg.norm(rhs)), o, info, team,
                   reference=0.0 if level is None else level.reference)
    step, prefix = o["step"], ""
    if singular and step == "seed":
        return _fail(info, DDOutcome.SETUP_FAILED, singular)
    if singular and step == "auto":
        step, prefix = "newton", f"{singular}: newton; "
    if step == "auto":
        estimate = rho_estimate(it, r1.x)
        if estimate is None:
            info["ranks"] = team.report()
            return _fail(info, DDOutcome.LOCAL_FAILED, "a contact solve of the ρ estimate failed")
        rho, info["rho_steps"] = estimate
        step = "seed" if rho < o["seed_rho"] else "newton"
        info["rho"] = rho
        prefix = (f"ρ(S0⁻¹ dS_con) ≥ {rho:.3g} at U⁰ ({estimate[1]} power steps; "
                  f"{'<' if step == 'seed' else '≥'} {o['seed_rho']:g}): {step}; ")
    info["step"] = step
    status, message, U = (coulomb_newton if step == "newton" else successive)(it, r1.x)
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
                _, res = it.contact(u, U[u.gamma])
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


def solve_heat_dd(model, c, options=None, *, comm=None):
    """The thermal step by the same decomposition (the linear case: PCG1 only).

    c: the model's `Coefficients`. Returns (T nodal (nnodes,), info, status, message),
    the same temperature as `Model.solve_heat(c)`. comm: as in `solve_dd`.
    """
    o = _dd_options(options)
    dec = decomposition(model, options, heat=True)
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
    rho = [unit_rho(u, kreg) for u in dec.units]
    D = distribute_load(dec, rho, rhs, team)
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
