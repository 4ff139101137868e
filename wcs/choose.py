"""Defaults chosen from the benchmarks (`make bench`, results/bench/; README: "Choosing methods").

Pure functions of facts about a study; each returns (choice, reason) where the reason names the
chart that justifies the rule, so a caller can put it in the results file or a log line.

    solver_method(SolverFacts(...))  -> ("monolithic" | "dd" | "iterative", reason)
    preconditioner(PreconditionerFacts(...)) -> ("amg" | "bddc", reason)
    search_method(SearchFacts(...))  -> ("auto" | "local" | "global" | "sample", reason)
    mesh_size(MeshFacts(...))        -> (size [m], reason)

Nothing here reads files or runs solves; the thresholds are the numbers read off the charts of
one `make bench` run on the reference machine (2 cores) and are kept as named constants.
"""
from __future__ import annotations

from dataclasses import dataclass

# ---- solver (forward_hertz.png, forward_tunnel.png, forward_tresca.png, scaling.png,
#      dd_stability.png, stability_materials.png)
DD_MIN_UNKNOWNS = 1_000_000     # the DD was slower than the monolithic solver at every size measured
#                                 (Hertz 3.6e3-1.2e5 unknowns, tunnel 4e3-6e4: forward_*.png); with interface
#                                 Newton, one factor per unit and packed products, on new data 2.1-2.3x
#                                 (Hertz 1.06e5) and 1.1-1.2x (tunnel 1.04e5, dd_cost.csv, quiet machine);
#                                 the ratio falls with size (tunnel 1.48 -> 1.25 -> 1.13 at 1.0e5, 1.9e5,
#                                 3.7e5; Hertz 2.77 -> 2.34 -> 2.09 at 1.1e5, 2.1e5, 4.3e5), crossing near
#                                 1e6 on the tunnel by extrapolation: the DD is picked from there on, and
#                                 only where it is known to converge
DD_MAX_CONTRAST = 10.0          # dd_stability.png: with E_pad/E_base <= 0.1 the seed's iteration diverges
#                                 and Aitken converges in only some cases
DD_MAX_NU = 0.45                # stability_materials.png: the DD fails (status 5) from nu = 0.49
NU_LOCKING = 0.45               # stability_materials.png: P1 Hertz peak-pressure error 2% at 0.45, 8% at 0.49,
#                                 27% at 0.499, 135% at 0.4999 (0.2% at 0.3): say so in the reason
ITERATIVE_MARGIN = 2.0          # 3D: auto takes the iterative method for speed where its estimated time is under half
#                                 the monolithic one's: its Newton steps are not known before solving (2 on the
#                                 block patch, 19 on Hertz, >200 on the tunnel with Tresca, not converged there yet:
#                                 wcs/scene/estimate.py ITERATIVE_STEPS); the shipped tunnel split once for the mesh
#                                 check (1.1e5 unknowns, 5856 contact rows: 150 s against 89 s) stays monolithic


@dataclass(frozen=True)
class SolverFacts:
    unknowns: int                       # displacement unknowns (2 x nodes), estimated or from the mesh
    contact: bool = True                # any contact pair
    friction: str = "none"              # "none" | "tresca" | "coulomb"
    gradients: bool = True              # the search asks adjoint gradients (auto, local, global polish)
    stiffness_contrast: float = 1.0     # max E / min E over bodies in contact (>= 1)
    max_nu: float = 0.3                 # largest Poisson ratio of any material
    dd_converges: bool | None = None    # the DD converged on this scene family (a dd_stability point or a trial)
    dimension: int = 2                  # 2 or 3
    costs: dict | None = None           # method -> (peak bytes, seconds) of one evaluation (wcs.scene.estimate)
    memory: float = float("inf")        # bytes one evaluation may take (USABLE_SHARE of `machine_memory`)
    iterative_installed: bool = True    # PETSc (petsc4py and the wheel dolfinx-solver-real) importable
    floating: bool = False              # a body held by contact alone (its Newton steps are taken in the complement of its rigid modes)
    dynamic: bool = False               # a dynamic study: the method solves each time level (no adjoint through time)


def solver_method(f: SolverFacts) -> tuple[str, str]:
    """`solver.method: auto` -> "monolithic", "dd" or "iterative" (never "qp": the cvxpy reference,
    28-87x slower than the monolithic Newton for the same answer, forward_hertz.png). The reason
    carries a P1-locking warning when some material has nu > NU_LOCKING. A dynamic study: the
    rules decide the method of each time level's contact solve (its operator A with the mass:
    no rigid modes), without the adjoint-gradient rule (the adjoint through time solves its levels
    with their own factors, whatever the method) and with no fallback."""
    method, why = _size_rule(f) or _solver_rule(f)
    if f.dynamic:
        why = ("each time level is one contact solve (the adjoint through time, where the search asks for "
               f"gradients, solves the levels with their own factors whatever the method): {why}")
    if f.contact and f.costs is not None and method != "iterative":
        why += (f"; the iterative method{'' if f.iterative_installed else ' (not installed: PETSc, the wheel dolfinx-solver-real)'}"
                f" estimated at {_cost(*f.costs['iterative'])}")
    if f.max_nu > NU_LOCKING:
        why += (f"; warning: nu = {f.max_nu:g} > {NU_LOCKING:g}: P1 elements lock (Hertz peak pressure "
                "8% off at 0.49, 27% at 0.499, stability_materials.png)")
    return method, why


def _size_rule(f: SolverFacts) -> tuple[str, str] | None:
    """"iterative" where the estimated direct condensation would not fit in memory, or (3D) would
    be ITERATIVE_MARGIN times slower than the iterative method by the estimate; None: the rules
    below decide (2D keeps its measured rules: the contact zones are small there)."""
    if not f.contact or f.costs is None or not f.iterative_installed:
        return None
    direct, iterative = f.costs["monolithic"], f.costs["iterative"]
    words = (f"{'one time level' if f.dynamic else 'one evaluation'} estimated at {_cost(*direct)} by the monolithic method, "
             f"{_cost(*iterative)} by the iterative one")
    if direct[0] > f.memory and iterative[0] <= f.memory:
        return "iterative", f"{words}: the monolithic method would not fit in the {f.memory / 1e9:.3g} GB this machine gives one evaluation"
    # for speed only where the iterative method is shown to be faster on every case the scene can
    # give: frictionless, a body held by contact alone has its rigid modes projected and the normal
    # active set settles (the 3D block patch of tests/bench/test_bench_kratos.py: 2 Newton steps at
    # every face); with friction on such a body it agrees with the monolithic answer but its CG takes
    # ~380 iterations a Newton step (the 3D knee's floating femur under Coulomb friction, 1.3e4
    # unknowns: 5691 in 15 steps, 195 s of CPU against the monolithic 7.6 s; the 2D knee: 6235 in
    # 23 steps, 129 s against 0.46 s), beyond what its cost estimate assumes
    if f.dimension == 3 and ITERATIVE_MARGIN * iterative[1] < direct[1] and iterative[0] <= f.memory:
        slower = f"{words}: the monolithic method would be more than {ITERATIVE_MARGIN:g}x slower"
        if f.floating and f.friction != "none":
            return "monolithic", (f"{slower} by its estimate, but a body is held by contact alone with {f.friction} "
                                  "friction, where the iterative method's Krylov solves take far more iterations "
                                  "than the estimate assumes")
        return "iterative", slower + ("; a body held by contact alone, frictionless" if f.floating else "")
    return None


def _cost(memory: float, seconds: float) -> str:
    return f"{memory / 1e9:.3g} GB and {seconds:.2g} s"


def _solver_rule(f: SolverFacts) -> tuple[str, str]:
    if not f.contact:
        return "monolithic", "no contact: one sparse factorization and solve, nothing to iterate"
    if f.dimension == 3:
        return "monolithic", "3D: the monolithic solver (the domain decomposition is 4-12x slower on tetrahedra)"
    if f.gradients and not f.dynamic:
        return "monolithic", ("the search asks adjoint gradients, which need the monolithic factorization "
                              "(a DD answer is polished by the monolithic solver anyway, wcs/model/model.py)")
    if f.friction != "none":
        return "monolithic", ("friction: the DD's successive approximations stagnate or a local solve fails "
                              "in 31 of 32 Tresca cases (dd_stability.png b); its interface Newton converges "
                              "on the tunnel (Tresca) and the knee (Coulomb, dd_iterations.csv) but 1.1-2x "
                              "slower at 1e5 unknowns on new data (dd_cost.csv), while the monolithic Newton converged in <= 11 "
                              "iterations (Tresca) and the Coulomb fixed point for every F it can hold, up "
                              "to 1.5 (stability_friction.png)")
    if f.max_nu > DD_MAX_NU:
        return "monolithic", f"nu = {f.max_nu:g} > {DD_MAX_NU:g}: the DD fails there (status 5, stability_materials.png)"
    if f.stiffness_contrast > DD_MAX_CONTRAST:
        return "monolithic", (f"stiffness contrast {f.stiffness_contrast:.0e} > {DD_MAX_CONTRAST:g}: the DD's "
                              "successive approximations diverge or stagnate there (dd_stability.png a)")
    if f.unknowns < DD_MIN_UNKNOWNS:
        return "monolithic", (f"{f.unknowns} unknowns < {DD_MIN_UNKNOWNS}: the monolithic Newton was faster at "
                              "every measured size (forward_hertz.png, forward_tunnel.png)")
    if f.dd_converges is not True:
        return "monolithic", "the DD has not been shown to converge on this scene family (run one dd solve first)"
    return "dd", (f"{f.unknowns} unknowns >= {DD_MIN_UNKNOWNS}, frictionless, no gradients, contrast <= "
                  f"{DD_MAX_CONTRAST:g}, nu <= {DD_MAX_NU:g} and known to converge: the decomposition "
                  + ("(a level it does not solve fails the evaluation)" if f.dynamic
                     else "(fallback to monolithic on failure)"))


# ---- preconditioner of the iterative method (bench_bddc_*.csv: the 3D patch's glued Newton step, CG to 1e-8,
#      on 1 and 2 ranks, CPU seconds summed over the ranks; tests/bench/test_bench_bddc.py)
BDDC_SETUP_RATIO = 14.0         # one process: BDDC's set-up (subdomain matrices, factorizations, coarse space) over
#                                 GAMG's, the least of the sizes measured: 14x, 17x, 36x at 1.1e4, 2.6e4, 8.0e4 unknowns
#                                 (again 14x, 41x at 1.1e4, 8.0e4: 68.8 s against 1.66 s); CG iterations 11/14/21
#                                 against 17/18/18, each solve 4-7x GAMG's CPU time, and +1.6-4.4 GB against 0.06 at
#                                 8.0e4; ill-conditioned at 1.1e4 (the block's E 1e7 times softer, or its nu 0.499)
#                                 GAMG's iterations grow more (29, 127 against BDDC's 18, 62) but its whole solve still
#                                 took 5-10x less CPU time
BDDC_SETUP_RATIO_RANKS = 3.0    # two ranks, each its share of the subdomains (a distributed MATIS): the same, the least
#                                 measured: 3.0x, 4.1x, 6.6x in three runs at 1.1e4 (BDDC 2.36-2.66 s, GAMG 0.36-0.79
#                                 s), 27x at 8.0e4 (68.4 s against 2.52 s); BDDC's CPU time does not fall with the second
#                                 rank (its set-up is the subdomains' factorizations and the coarse space, shared out,
#                                 not reduced), GAMG's grew (0.17 -> 0.65 s median, 1.66 -> 2.52 s: MPI's waits on a
#                                 loaded machine count as CPU time, which flatters BDDC); CG iterations 11/21 against
#                                 16/17; +2.3 GB a rank at 8.0e4 against 0.16


@dataclass(frozen=True)
class PreconditionerFacts:
    unknowns: int                       # reduced displacement unknowns
    ranks: int = 1                      # ranks each evaluation's solve spans (solver.ranks_per_evaluation)


def preconditioner(f: PreconditionerFacts) -> tuple[str, str]:
    """`solver.iterative.preconditioner: auto` -> "amg" or "bddc", with the measurement behind it.
    BDDC's cost is its subdomains' factorizations and coarse space, GAMG's set-up a few sparse
    products: BDDC loses at every measured size on one process (`BDDC_SETUP_RATIO`) and on two
    ranks sharing out its subdomains (`BDDC_SETUP_RATIO_RANKS`: its CPU time is shared, not
    reduced). GAMG's iterations grow more with a material contrast or near incompressibility,
    but on one process not to BDDC's cost (measured). So auto takes amg on any number of ranks;
    where BDDC's flat iterations would pay for its set-up (many ranks) was not measured."""
    if f.ranks > 1:
        return "amg", (f"{f.ranks} ranks: on 2 ranks, each its share of the subdomains, BDDC's set-up took "
                       f"{BDDC_SETUP_RATIO_RANKS:g}x GAMG's CPU time and more, growing with the size (summed over the "
                       "ranks), for as many CG iterations on the 3D patch (bench_bddc_*.csv); a second rank "
                       "shares out its factorizations without reducing them")
    return "amg", (f"one process, {f.unknowns} unknowns; BDDC's set-up took {BDDC_SETUP_RATIO:g}x GAMG's CPU time and "
                   "more, growing with the size, for as many CG iterations on the 3D patch at 1.1e4-8e4 unknowns "
                   "(bench_bddc_*.csv); a stiffness contrast of 1e7 or nu = 0.499 grew GAMG's iterations more but "
                   "not to BDDC's cost")


# ---- search (search_convergence.png, search_solves_to_tolerance.csv)
GLOBAL_MIN_BUDGET = 150         # DIRECT (+ polish) reached 1e-3 in 152-162 solves on all three bench studies


@dataclass(frozen=True)
class SearchFacts:
    dimension: int                      # number of parameters
    budget: int = 200                   # forward solves allowed
    gradients: bool = True              # adjoint gradients available for the criteria


def search_method(f: SearchFacts) -> tuple[str, str]:
    """`search.method: auto` resolution (the strategy names of wcs.search.registry)."""
    if f.gradients:
        return "auto", ("gradient-sign corners with KKT checks reached 1e-4 relative in 14, 15 and 36 solves "
                        "(heated plate, stacked layers, tunnel with 22 parameters) where the max of 512-1024 LHS "
                        "samples is still 5-23% short, and local / global needed 36 to >200 / 154-186 "
                        "(search_convergence.png)")
    if f.budget >= GLOBAL_MIN_BUDGET:
        return "global", ("no adjoint gradients: auto's corners cannot be formed; DIRECT needs none and reached "
                          "1e-3 in 152-162 solves on every bench study (search_convergence.png)")
    return "sample", (f"no adjoint gradients and a budget < {GLOBAL_MIN_BUDGET}: too small for DIRECT; a Latin "
                      "hypercube at least spends it evenly (it stays 5-23% short: search_convergence.png)")


# ---- mesh (forward_hertz.png, forward_tunnel.png)
DIAGONAL_FRACTION = 1 / 20      # global size: 1/20 of the bounding-box diagonal (the mesher's default)
CONTACT_POINTS = 6              # Hertz: h = a/6 -> 0.2% (peak) / 0.3% (width); a/3 -> 2.4% / 1.5% (forward_hertz.png)
FEATURE_POINTS = 10             # tunnel: wall size = radius/10 -> criteria within 0.5% of a 4x finer mesh
#                                 (radius/20: 0.4%, forward_tunnel.png)


@dataclass(frozen=True)
class MeshFacts:
    diagonal: float                     # bounding-box diagonal of the scene [m]
    contact_width: float | None = None  # expected contact half-width a (Hertz estimate), or the contact side length [m]
    feature: float | None = None        # smallest curved feature (hole radius) [m]


def mesh_size(f: MeshFacts) -> tuple[float, str]:
    """Default `mesh.size` when the study gives none (about 1% accuracy of the criteria): the smallest
    of diagonal/20, feature/10 and contact half-width/6, with the reason. Callers that can refine
    locally should use the feature and contact sizes there and diagonal/20 elsewhere."""
    h = f.diagonal * DIAGONAL_FRACTION
    why = [f"diagonal/{round(1 / DIAGONAL_FRACTION)}"]
    if f.feature:
        h2 = f.feature / FEATURE_POINTS
        if h2 < h:
            h, why = h2, [f"smallest feature/{FEATURE_POINTS} (forward_tunnel.png)"]
    if f.contact_width:
        h3 = f.contact_width / CONTACT_POINTS
        if h3 < h:
            h, why = h3, [f"contact half-width/{CONTACT_POINTS} (forward_hertz.png)"]
    return h, "mesh size = " + why[0]
