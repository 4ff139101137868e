"""The study file's options blocks (`search`, `solver`) and the strict base of every schema
model: frozen pydantic models, each field documented with its one default; an unknown key
is an error naming the closest known one."""
from __future__ import annotations

import difflib
from typing import Annotated, Literal, Optional

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator
from pydantic_core import PydanticCustomError

# defer_build: a model's validator is built when it first validates, with the models it holds
# inside its own, not when its class is defined: a study validates with its top level and one
# scene (2D or 3D), and the other models' validators were never used (forward references
# resolve then, from the module's names)
CONFIG = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, defer_build=True)


def did_you_mean(word: str, choices) -> str:
    choices = sorted(str(c) for c in choices)
    close = difflib.get_close_matches(str(word), choices, n=1)
    if close:
        return f" (did you mean '{close[0]}'?)"
    return f" (expected one of: {', '.join(choices)})" if choices else ""


class Strict(BaseModel):
    """A mapping with a fixed set of keys; an unknown key is an error with a hint."""

    model_config = CONFIG

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data):
        if isinstance(data, dict):
            allowed = [f.alias or name for name, f in cls.model_fields.items()]
            for key in data:
                if key not in allowed:
                    raise PydanticCustomError(
                        "unknown_key", "unknown key '{key}'{hint}",
                        {"key": str(key), "hint": did_you_mean(key, allowed)})
        return data


# Counts of the search and the solver: a million solves is weeks of work at the sizes wcs
# runs; every count fits the results file's int64 (a budget of 1e30 did not).
MAX_SOLVES = 1_000_000


# The smallest relative tolerance of a solve: about 50 machine epsilons (2.2e-16). A relative
# residual below it is rounding noise no iteration can reduce (the demo's semismooth Newton reaches
# 1e-15 and ran its 200 steps at 1e-16).
MIN_TOLERANCE = 1e-14


def _resolvable(tolerance: float) -> float:
    if tolerance < MIN_TOLERANCE:
        raise ValueError(f"a relative tolerance below {MIN_TOLERANCE:g} (about 50 times the machine epsilon "
                         f"2.2e-16) is below the rounding of the solve, no iteration reaches it")
    return tolerance


Tolerance = Annotated[float, AfterValidator(_resolvable)]


class Options(Strict):
    """Options of the search or the solver: frozen; every field documented with its one default."""

    model_config = ConfigDict(**CONFIG, frozen=True)

    @classmethod
    def of(cls, options):
        """These options as the model: `options` itself, or a mapping (None: {}) validated by it."""
        return options if isinstance(options, cls) else cls.model_validate(options or {})


class SampleDesign(Options):
    design: Literal["lhs", "sobol", "vertices", "grid"] = Field(
        "lhs", description="space-filling design of the sample")
    n: int = Field(32, ge=1, le=MAX_SOLVES, description="points of the sample (local: of its "
                   "starting sample; auto: the most of its first sample)")
    seed: int = Field(0, ge=0, le=2**32 - 1, description="seed of every random draw of the search")


class LocalSearch(Options):
    starts: int = Field(3, ge=1, le=1000, description="best sample points per criterion the local ascent starts from")


class Search(Options):
    method: Literal["auto", "sample", "local", "global"] = Field("auto", description="search strategy")
    sample: SampleDesign = Field(default_factory=SampleDesign, description="the sample design")
    budget: int = Field(200, ge=1, le=MAX_SOLVES, description="most forward solves of the search")
    local: LocalSearch = Field(default_factory=LocalSearch, description="the local ascent")
    kkt_tol: float = Field(1e-6, gt=0, lt=1, description="relative Frank–Wolfe gap below which a point is "
                           "certified (corner-kkt, local-kkt)")
    safeguard: Optional[int] = Field(None, ge=0, le=MAX_SOLVES, description="points of auto's first sample "
                                     "besides the centre; null: min(2n + 1, sample.n), n the parameters")


class DomainDecomposition(Options):
    subdomains: int = Field(8, ge=1, le=4096, description="subdomains of the partition")
    pair_size: float = Field(1.0, gt=0, le=100, description="unknowns of the band around a contact "
                             "side, in mean subdomain shares n/subdomains")
    relaxation: Literal["aitken", "anderson"] | Annotated[float, Field(gt=0, le=2)] = Field(
        "aitken", description="update of the successive approximations: Aitken's dynamic ω, "
        "Anderson acceleration, or a fixed ω (1 = the seed)")
    patience: int = Field(8, ge=1, le=10_000, description="steps with contraction q ≥ 1 before \"stagnated\"")
    step: Literal["auto", "newton", "seed", "glued"] = Field(
        "auto", description="outer iteration: interface Newton (S0 + the pairs linearised at the current "
        "active set), the seed's successive steps with S0, or with S0 + the glued pairs; auto: the seed's "
        "where the power estimate of ρ(S0⁻¹ dS_con) at the start is below seed_rho, else Newton")
    seed_rho: float = Field(0.5, gt=0, le=1, description="step auto takes the seed's step below this "
                            "estimate of its contraction ρ(S0⁻¹ dS_con) (margin below 1: the estimate is a "
                            "lower bound, and is taken at the start, not at the solution)")
    rho_steps: int = Field(5, ge=1, le=100, description="power steps of the ρ estimate (each one PCG2 "
                           "solve to 1e-2)")
    pcg_tolerance: Optional[Tolerance] = Field(None, gt=0, lt=1, description="relative tolerance of PCG1 "
                                           "(the glued start U⁰); null: `forcing` for interface Newton "
                                           "(step newton, auto), max(solver.tolerance, 1e-8) for the seed's "
                                           "step and the thermal step")
    pcg_max_iterations: int = Field(500, ge=1, le=100_000, description="iteration budget of each PCG solve")
    inner_tolerance: Optional[Tolerance] = Field(None, gt=0, lt=1, description="floor of PCG2's relative "
                                             "tolerance; null: solver.tolerance / 10")
    forcing: float = Field(0.1, ge=0, le=1, description="PCG2 stops at forcing × the last relative "
                           "increment (inexact inner solves); Newton: the largest Eisenstat–Walker tolerance")
    contact_tolerance: Tolerance = Field(1e-10, gt=0, lt=1, description="tolerance of the local contact solves")
    anderson: int = Field(5, ge=1, le=100, description="history of Anderson acceleration, in steps")
    anderson_restart: float = Field(0.0, ge=0, le=1e6, description="clear Anderson's history when the "
                                    "residual grows by this factor; 0: never")
    mixing: float = Field(1.0, gt=0, le=2, description="Anderson's mixing β: the damped map U + β(T(U) − U)")

    @field_validator("relaxation", mode="wrap")
    @classmethod
    def _one_message(cls, value, handler):
        try:
            return handler(value)
        except ValidationError:
            raise ValueError("must be 'aitken', 'anderson' or a fixed ω in (0, 2]") from None


class Iterative(Options):
    preconditioner: Literal["auto", "amg", "bddc"] = Field(
        "auto", description="preconditioner of the contact steps' Krylov solves and their adjoint (auto: by the "
                "measured cost, `wcs check` says which and why; bddc: not in a dynamic study)")
    tolerance: Tolerance = Field(1e-8, gt=0, le=1e-2, description="relative residual each Krylov solve is driven to")


# why each method that is not distributed solves an evaluation on one rank (solver.ranks_per_evaluation)
SERIAL = {"auto": "auto may choose a method that solves on one rank",
          "monolithic": "monolithic factors K and the dense Delassus operator on one rank",
          "qp": "qp is the cvxpy reference, solved on one rank",
          "dd": "dd solves each evaluation's subdomains on one rank under a run"}


class Solver(Options):
    method: Literal["auto", "monolithic", "dd", "qp", "iterative"] = Field(
        "auto", description="contact solver (qp: the cvxpy reference; iterative: active set with CG + "
        "algebraic multigrid on PETSc, no dense condensation)")
    tolerance: Tolerance = Field(1e-8, gt=0, le=1e-2, description="relative tolerance of the contact solve "
                             "(above 1e-2 a \"solved\" state is not a solution)")
    max_iterations: int = Field(200, ge=1, le=100_000, description="iteration budget of the contact solve "
                                "(dd: of the outer iteration — successive approximations, or Newton steps of each Tresca problem)")
    max_fixed_point_iterations: int = Field(100, ge=1, le=100_000, description="most solves of the "
                                            "Coulomb fixed point (slip bound from the last pressures)")
    dd: DomainDecomposition = Field(default_factory=DomainDecomposition, description="the domain decomposition")
    fallback: bool = Field(True, description="a failed dd solve falls back to the monolithic solver (visibly)")
    iterative: Iterative = Field(default_factory=Iterative, description="the iterative method's Krylov solves")
    ranks_per_evaluation: int = Field(1, ge=1, le=4096, description="MPI ranks each evaluation's solve spans "
                                      "under mpiexec -n N (N/k groups evaluate different data sets; iterative only)")

    @field_validator("ranks_per_evaluation")
    @classmethod
    def _distributed(cls, k, info):
        method = info.data.get("method")
        if k > 1 and method in SERIAL:
            raise ValueError(f"{k} ranks per evaluation need a distributed method, solver.method iterative "
                             f"(the only one): {SERIAL[method]}")
        return k
