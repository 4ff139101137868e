"""Contact methods by name (`solver.method`): how `Model.solve` solves a data set's contact.

A method is a `ContactMethod` registered in `METHODS` under the name a study gives; the
model looks its method up once (`method_of`) and then asks it, never its name. Most methods
solve the model's `ContactProblem` in one call (`Primal`, with a function of the model and
the problem returning a `ContactResult`); the domain decomposition solves the model itself
(`wcs.dd.method`). A new method is one module, its registration line here and its tests; a
method whose module loads a heavy library (cvxpy, PETSc) is registered by the module's
name and loaded when a study names it.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from wcs import linalg
from wcs.contact.problem import ContactProblem
from wcs.contact.solver import ContactResult, solve_condensed
from wcs.errors import SolveError
from wcs.status import Status


@dataclass(frozen=True)
class Solved:
    """A data set's contact solution as a method reports it (what `Model.solve` puts in its
    `Solution`): the displacement, the contact state, the iterations and what solved it; from
    a solve of the `ContactProblem`, its reduced unknowns w, the raw result and the stiffness
    K with the scales of its units. krylov_steps: the Krylov iterations of each outer step
    (() where no Krylov method solved it, None where the method does not count them)."""
    u: np.ndarray
    contact: object
    iterations: int
    solver: str
    w: np.ndarray | None = None
    raw: ContactResult | None = None
    stiffness: object = None
    scale: np.ndarray | float = 1.0
    krylov_steps: tuple | None = ()


def krylov_counts(steps) -> tuple[int, int]:
    """(all, most in one step) of the Krylov iterations per outer step `steps`: (0, 0) for a
    solve without a Krylov method (steps ()), (-1, -1) where they were not counted (None)."""
    if steps is None:
        return -1, -1
    return int(sum(steps)), int(max(steps, default=0))


class ContactMethod(Protocol):
    """A way to solve a model's contact, one data set at a time."""

    anchored: bool     # every solve starts from the nominal data's contact state (`Model.solve`)
    units: bool        # K is factored by its units (`wcs.contact.units`)
    assembles: bool    # needs the data set's reduced K(c) (else, with units, the load alone)

    def check(self, model) -> None:
        """Refuse (StudyError) a study the method cannot solve, when the model is built."""

    def heat(self, model, c) -> np.ndarray | None:
        """The temperature by the method's own thermal solve; None: by the direct one."""

    def solve(self, model, c, Kr, rhs, u0, nominal: bool, adjoint: bool) -> Solved:
        """Solve data set c (reduced stiffness Kr, load rhs, support displacement u0); with
        `adjoint`, a solution whose factorization and active set the adjoint can use."""

    def release(self, model) -> None:
        """Free what the method keeps of the model's solves for later ones (`Model.release`)."""


def settings(options) -> dict:
    """The study's tolerances as the keywords of `wcs.contact.solver.solve_contact`."""
    return dict(tol=options.tolerance, max_iter=options.max_iterations, tol_fp=options.tolerance,
                max_fp_iter=options.max_fixed_point_iterations)


def newton(model, problem: ContactProblem) -> ContactResult:
    """The condensed semismooth Newton (`solve_condensed`) on the model's contact factorization."""
    try:
        factored = model.factored(problem.K, problem.scale)
    except linalg.FactorizationError as exc:
        raise SolveError(f"factorization failed: {exc}", status=Status.SINGULAR) from exc
    return solve_condensed(problem, factored=factored, **settings(model.options))


@dataclass(frozen=True)
class Primal:
    """A method that solves the model's `ContactProblem` in one call, `solve_problem(model,
    problem)`. polish: the adjoint needs the monolithic factorization and active set, so for
    it the answer is polished by 'monolithic' (Newton from its multipliers and active set)."""
    name: str
    solve_problem: Callable[[object, ContactProblem], ContactResult]
    anchored: bool = False
    units: bool = False
    assembles: bool = True
    polish: bool = False

    def check(self, model) -> None:
        return None

    def heat(self, model, c) -> None:
        return None

    def release(self, model) -> None:
        return None

    def solve(self, model, c, Kr, rhs, u0, nominal, adjoint, warm=None, used=None) -> Solved:
        """As `ContactMethod.solve`; warm: a result whose multipliers start the solve, and
        `used` what solved it then (a polish, a fallback)."""
        Ks, scale = model._contact_stiffness(c, Kr)
        if self.polish and adjoint:
            res = model._solve_contact(c, Ks, rhs, u0, nominal, None, scale, self)[3]
            warm = ContactResult(None, res.lam_n, res.lam_t, Status.SOLVED, "", active=res.active)
            return method_of("monolithic").solve(model, c, Kr, rhs, u0, nominal, adjoint, warm,
                                               f"{self.name}, polished by monolithic for the adjoint")
        u, contact, iterations, res = model._solve_contact(c, Ks, rhs, u0, nominal, warm, scale, self)
        return Solved(u, contact, iterations, used or self.name, res.u, res, Ks, scale, res.krylov_steps)


METHODS: dict[str, ContactMethod | str] = {}


def register(name: str, method: ContactMethod | str) -> None:
    """Make `method` the one a study names `name` (`solver.method`); a string
    "module:attribute" names a method loaded when it is first asked for (`method_of`)."""
    METHODS[name] = method


def method_of(name: str) -> ContactMethod:
    """The method registered as `name`, loaded on first use."""
    method = METHODS[name]
    if isinstance(method, str):
        module, attribute = method.split(":")
        method = METHODS[name] = getattr(importlib.import_module(module), attribute)
    return method


register("monolithic", Primal("monolithic", newton, anchored=True, units=True, assembles=False))
register("qp", "wcs.contact.qp:QP")           # cvxpy: loaded only for the reference solver
register("dd", "wcs.dd.method:METHOD")            # the seed's domain decomposition, wcs/dd/
register("iterative", "wcs.contact.iterative:METHOD")   # PETSc: loaded only for the iterative method
