r"""Friction laws: the slip bounds gw of the Tresca problems a contact method solves.

A method solves the Tresca problem for given slip bounds gw_i (|λt,i| ≤ gw_i); the law
drives it. Frictionless: gw = 0. Tresca: gw = g·w, one problem. Coulomb: gw = g·w + F·λn
depends on the answer's normal forces, and the solution is the fixed point over Tresca
problems (the seed's method of successive approximations, [21] §3; g > 0 where contacts of
either law share a zone): from a first bound (all stick, or the warm pressures), until the
pressures p = λn / w settle, ‖Δp‖ ≤ tol ‖p‖, in at most `max_iter` Tresca problems after
the first.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


class TrescaSolve(Protocol):
    """A method's Tresca problems of one contact problem, each started from the last answer."""

    def __call__(self, gw: np.ndarray) -> tuple[np.ndarray | None, bool, int]:
        """Solve with slip bounds gw (m,): (λn, converged, iterations); λn None where none."""


@dataclass(frozen=True)
class Driven:
    """What a law's drive ends with: the last bounds, whether the last Tresca problem and the
    fixed point converged, and the iterations of the Tresca problems and of the fixed point."""
    gw: np.ndarray
    ok: bool
    settled: bool
    iterations: int
    fixed_point_iterations: int = 0


class Law(Protocol):
    """A friction law: the bounds of the first Tresca problem, and the drive over them."""

    coulomb: bool          # the bounds depend on the normal forces

    def start(self, lam_n: np.ndarray | None, stuck: float) -> np.ndarray:
        """The first bounds: from the normal forces λn of a warm start, else `stuck` above g·w."""

    def drive(self, tresca: TrescaSolve, gw: np.ndarray, tol: float, max_iter: int) -> Driven:
        """Solve the law's problem by Tresca problems from the bounds gw."""


@dataclass(frozen=True)
class Tresca:
    """Fixed slip bounds gw = g·w (frictionless: gw = 0): one Tresca problem."""
    gw: np.ndarray
    coulomb = False

    def start(self, lam_n, stuck):
        return self.gw

    def drive(self, tresca, gw, tol, max_iter):
        _, ok, iterations = tresca(gw)
        return Driven(gw, ok, True, iterations)


def frictionless(m: int) -> Tresca:
    """No friction: the bounds are zero."""
    return Tresca(np.zeros(m))


@dataclass(frozen=True)
class Coulomb:
    """Slip bounds gw = g·w + F·λn: the fixed point over Tresca problems (module docstring)."""
    gw: np.ndarray         # g·w, the part that does not depend on λn
    F: np.ndarray          # friction coefficient per node
    w: np.ndarray          # nodal weights: p = λn / w
    coulomb = True

    def start(self, lam_n, stuck):
        return self.gw + (self.F * lam_n if lam_n is not None else stuck)

    def drive(self, tresca, gw, tol, max_iter):
        lam_n, ok, iterations = tresca(gw)
        n, settled = 0, False
        while ok and n < max_iter and not settled:
            p_old = lam_n / self.w
            gw = self.gw + self.F * lam_n
            lam_n, ok, steps = tresca(gw)
            iterations += steps
            n += 1
            settled = ok and bool(np.linalg.norm(lam_n / self.w - p_old)
                                  <= tol * max(np.linalg.norm(lam_n / self.w), 1e-300))
        return Driven(gw, ok, settled, iterations, n)


def law_of(w: np.ndarray, g: np.ndarray | None = None, F: np.ndarray | None = None) -> Tresca | Coulomb:
    """The law of a contact zone with weights w, slip limits g and friction coefficients F
    (None: zero): Coulomb where any F > 0, else Tresca (frictionless where g is None)."""
    m = len(w)
    gw = np.zeros(m) if g is None else np.asarray(g, dtype=float) * w
    if F is not None and np.any(np.asarray(F, dtype=float) > 0):
        return Coulomb(gw, np.asarray(F, dtype=float), w)
    return Tresca(gw)
