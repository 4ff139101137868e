"""The domain decomposition as a contact method (`solver.method: dd`), registered by this
module's name in `wcs.contact.methods` and loaded when a study names it."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..contact.methods import Solved, method_of
from ..contact.solver import ContactResult
from ..errors import SolveError, StudyError
from ..status import DDOutcome, Status
from .partition import subdomains_fault
from .solver import Level, solve_decomposed, solve_heat_dd


@dataclass(frozen=True)
class Decomposition:
    """The seed's domain decomposition (`wcs.dd.solver.solve_dd`). Where
    it does not converge the solve falls back to 'monolithic' if the study allows; for the
    adjoint its answer is polished by 'monolithic' (its factorization and active set)."""
    anchored = False
    units = True
    assembles = True

    def check(self, model) -> None:
        fault = subdomains_fault(model.options.dd.subdomains, model.smesh.mesh.t.shape[1])
        if fault is not None:
            raise StudyError(fault, path="solver.dd.subdomains")

    def heat(self, model, c) -> np.ndarray | None:
        T, _, status, _ = solve_heat_dd(model, c, model.options, comm=model.comm)
        return T if status is DDOutcome.CONVERGED else None

    def solve(self, model, c, Kr, rhs, u0, nominal, adjoint) -> Solved:
        dd = model._solve_dd(c, Kr, rhs, u0)
        if dd.status is DDOutcome.CONVERGED and not adjoint:
            contact = model.contact_state(dd.lam_n, dd.lam_t, dd.u, dd.info.get("active"))
            iterations, message = int(dd.info.get("successive", 0)), f"dd: {dd.message}"
            raw = ContactResult(dd.info["w"], dd.lam_n, dd.lam_t, Status.SOLVED, message, iterations=iterations,
                                active=dd.info.get("active"))     # what a dynamic study starts its levels from
            return Solved(dd.u, contact, iterations, message, w=dd.info["w"], raw=raw, krylov_steps=None)
        warm = None
        if dd.status is DDOutcome.CONVERGED:    # the adjoint needs the monolithic factorization: start from dd
            warm = ContactResult(None, dd.lam_n, dd.lam_t, Status.SOLVED, "", active=dd.info.get("active"))
            used = "dd, polished by monolithic for the adjoint"
        elif model.options.fallback:
            used = f"monolithic after dd {dd.message}"
        else:
            raise SolveError(f"domain decomposition: {dd.message}", status=Status.DD_FAILED)
        out = method_of("monolithic").solve(model, c, Kr, rhs, u0, nominal, adjoint, warm, used)
        return dataclasses.replace(out, krylov_steps=None)     # the dd's PCG iterations are not counted here

    def solve_level(self, model, name: str, problem, local, coefficients: np.ndarray, c) -> ContactResult:
        """A time level's contact problem (`wcs.dynamics.stepping`: operator `name`'s A, load, gaps
        and slip bounds of `problem`) by the decomposition, its units' matrices the cells' pieces
        `local` (mass and stiffness) at `coefficients` per region (`Level`); c the data set's
        coefficients (the interface weights). Each level is solved from the glued start, as a
        static solve (the decomposition keeps no answer between solves); a failure is the
        level's (status DD_FAILED): no fallback inside a simulation."""
        m = problem.m
        level = Level(name, local, coefficients, problem.d, problem.g if problem.g is not None else np.zeros(m),
                      problem.reference)
        dd = solve_decomposed(model, c, problem.f, np.zeros(model.elim.T.shape[0]), model.options, model.comm, level)
        if dd.status is not DDOutcome.CONVERGED:
            return ContactResult(None, None, None, Status.DD_FAILED, f"domain decomposition: {dd.message}")
        return ContactResult(dd.info["w"], dd.lam_n, dd.lam_t, Status.SOLVED, f"dd: {dd.message}",
                             iterations=int(dd.info.get("successive", 0)), active=dd.info.get("active"))


METHOD = Decomposition()
