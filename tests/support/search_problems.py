"""Analytic test problems for the search strategies, with exact values and gradients.

Each mimics a situation of the physics:
- `monotone`: Φ monotone in every datum on a 6-D box (uniform heating, stacked
  layers): the worst case is the gradient-sign corner;
- `interior`: a trade between two load components (r·(cos θ + 0.6 sin θ)) and a
  concave quadratic: maxima inside the box;
- `flat`: contact pressure with a gap open at the centre of the box,
  Φ = max(0, x1 + x2 − 1.2)·(…): zero value and zero gradient at the centre;
- `lipschitz`: a slip-limit profile g0..g5 on a grid of step Δs with
  0 ≤ g ≤ ḡ and |g_{i+1} − g_i| ≤ C·Δs; a linear functional (LP optimum) and a
  least-squares fit to an infeasible target (optimum on a face, not a vertex);
- `two_bumps`: two local maxima (a broad bump in the middle of the box and a
  narrow higher one near the vertex (0, 1, 1)): the ascent from the gradient
  corner ends on the broad one, a one-flip neighbour lies in the other's basin.

`drive` is a plain serial runner: it plays the generator protocol, counts the
solves and enforces an optional hard cap of its own (truncating batches).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import linprog, minimize

from wcs.search import Outcome, Problem
from wcs.search.registry import STRATEGIES


@dataclass
class AnalyticProblem:
    problem: Problem
    phi: Callable[[np.ndarray], dict]      # x (n,) -> {criterion: value}
    grad: Callable[[np.ndarray], dict]     # x (n,) -> {criterion: dΦ/dx}
    optimum: dict                          # criterion -> max value
    argmax: dict = field(default_factory=dict)
    interior: set = field(default_factory=set)   # criteria whose maximiser is not a vertex

    def outcome(self, x, gradients=True) -> Outcome:
        x = np.array(x, dtype=float)
        return Outcome(x, self.phi(x), 0, self.grad(x) if gradients else None)


# ------------------------------------------------------------------- (a)
def monotone() -> AnalyticProblem:
    lo = np.array([1.0, 0.5, 2.0, 1e6, 0.1, 10.0])
    hi = np.array([2.0, 1.5, 4.0, 3e6, 0.4, 30.0])

    def phi(x):
        return {"disp": x[0] * x[1] / x[2] + 1e-6 * x[3] + np.exp(x[4]) - 0.01 * x[5],
                "temp": 1e-6 * x[3] * x[4] - x[0] + 0.5 * x[5] / x[1],
                "shear": (x[0] + 1e-6 * x[3]) ** 2 / x[2] + x[4] * x[5]}

    def grad(x):
        a = x[0] + 1e-6 * x[3]
        return {"disp": np.array([x[1] / x[2], x[0] / x[2], -x[0] * x[1] / x[2] ** 2, 1e-6, np.exp(x[4]), -0.01]),
                "temp": np.array([-1.0, -0.5 * x[5] / x[1] ** 2, 0.0, 1e-6 * x[4], 1e-6 * x[3], 0.5 / x[1]]),
                "shear": np.array([2 * a / x[2], 0.0, -a ** 2 / x[2] ** 2, 2e-6 * a / x[2], x[5], x[4]])}

    arg = {"disp": np.where([1, 1, 0, 1, 1, 0], hi, lo),
           "temp": np.where([0, 0, 0, 1, 1, 1], hi, lo),      # x2 does not matter
           "shear": np.where([1, 1, 0, 1, 1, 1], hi, lo)}      # x1 does not matter
    names = ["materials.a.E", "materials.a.nu", "materials.b.E", "loads.top.pressure",
             "thermal.reference", "loads.side.pressure"]
    return AnalyticProblem(Problem(names, lo, hi, ["disp", "temp", "shear"]), phi, grad,
                       {c: phi(v)[c] for c, v in arg.items()}, arg)


# ------------------------------------------------------------------- (b)
X_STAR = np.array([0.5, 0.8, 0.3])
H = np.array([[2.0, 1.0, -0.5], [1.0, 4.0, 0.0], [-0.5, 0.0, 2.0]])


def interior() -> AnalyticProblem:
    lo = np.array([0.0, 0.5, -1.0])
    hi = np.array([np.pi / 2, 1.0, 1.0])

    def phi(x):
        d = x - X_STAR
        return {"trade": x[1] * (np.cos(x[0]) + 0.6 * np.sin(x[0])) - 0.3 * x[2] ** 2,
                "quad": 1.0 - 0.5 * d @ H @ d}

    def grad(x):
        return {"trade": np.array([x[1] * (-np.sin(x[0]) + 0.6 * np.cos(x[0])),
                                   np.cos(x[0]) + 0.6 * np.sin(x[0]), -0.6 * x[2]]),
                "quad": -H @ (x - X_STAR)}

    arg = {"trade": np.array([np.arctan(0.6), 1.0, 0.0]), "quad": X_STAR.copy()}
    return AnalyticProblem(Problem(["theta", "r", "q"], lo, hi, ["trade", "quad"]), phi, grad,
                       {"trade": np.sqrt(1.36), "quad": 1.0}, arg, {"trade", "quad"})


def interior_dense_grid(m: int = 101) -> dict:
    """max over an m^3 grid of the `interior` box (vectorised), to check against."""
    t = np.linspace(0, np.pi / 2, m)[:, None, None]
    r = np.linspace(0.5, 1.0, m)[None, :, None]
    q = np.linspace(-1, 1, m)[None, None, :]
    trade = r * (np.cos(t) + 0.6 * np.sin(t)) - 0.3 * q ** 2
    d = [t - X_STAR[0], r - X_STAR[1], q - X_STAR[2]]
    quad = 1.0 - 0.5 * sum(H[i, j] * d[i] * d[j] for i in range(3) for j in range(3))
    return {"trade": float(trade.max()), "quad": float(quad.max())}


# ------------------------------------------------------------------- (c)
def flat() -> AnalyticProblem:
    lo, hi = np.zeros(2), np.ones(2)

    def phi(x):
        s = max(0.0, x[0] + x[1] - 1.2)
        return {"p_corner": s * (1 + x[0] - 0.5 * x[1]), "p_edge": s * (1.5 - x[1])}

    def grad(x):
        s = x[0] + x[1] - 1.2
        if s <= 0:
            return {"p_corner": np.zeros(2), "p_edge": np.zeros(2)}
        return {"p_corner": np.array([(1 + x[0] - 0.5 * x[1]) + s, (1 + x[0] - 0.5 * x[1]) - 0.5 * s]),
                "p_edge": np.array([1.5 - x[1], (1.5 - x[1]) - s])}

    return AnalyticProblem(Problem(["contacts.c.gap", "loads.top.pressure"], lo, hi, ["p_corner", "p_edge"]),
                       phi, grad, {"p_corner": 1.2, "p_edge": 0.65 ** 2},
                       {"p_corner": np.ones(2), "p_edge": np.array([1.0, 0.85])}, {"p_edge"})


# ------------------------------------------------------------------- (d)
def lipschitz() -> AnalyticProblem:
    n, gbar, C, ds = 6, 1e6, 2e6, 0.2
    lo, hi = np.zeros(n), np.full(n, gbar)
    D = np.zeros((n - 1, n))
    D[np.arange(n - 1), np.arange(n - 1)] = -1.0
    D[np.arange(n - 1), np.arange(1, n)] = 1.0
    A, b = np.vstack([D, -D]), np.full(2 * (n - 1), C * ds)
    c = np.array([1.0, -2.0, 0.5, 3.0, -1.0, 0.2]) * 1e-6
    t = np.array([1.0, 0.0, 1.0, 0.0, 1.0, 0.5]) * gbar

    def phi(x):
        return {"lin": float(c @ x), "fit": -float(np.sum(((x - t) / gbar) ** 2))}

    def grad(x):
        return {"lin": c.copy(), "fit": -2.0 * (x - t) / gbar ** 2}

    lp = linprog(-c, A_ub=A, b_ub=b, bounds=list(zip(lo, hi)), method="highs")
    y = minimize(lambda y: np.sum((y - t / gbar) ** 2), np.full(n, 0.5), jac=lambda y: 2 * (y - t / gbar),
                 method="SLSQP", bounds=[(0, 1)] * n,
                 constraints=[{"type": "ineq", "fun": lambda y: b / gbar - A @ y, "jac": lambda y: -A}],
                 options={"ftol": 1e-15, "maxiter": 500}).x
    names = [f"contacts.fault.friction.slip_limit.{i}" for i in range(n)]
    return AnalyticProblem(Problem(names, lo, hi, ["lin", "fit"], A, b), phi, grad,
                       {"lin": float(c @ lp.x), "fit": -float(np.sum((y - t / gbar) ** 2))},
                       {"lin": lp.x, "fit": y * gbar}, {"fit"})


# ------------------------------------------------------------------- (e)
BUMPS = [(np.array([0.75, 0.75, 0.75]), 0.35, 1.0), (np.array([0.05, 0.8, 0.8]), 0.15, 1.1)]   # centre, width, height


def two_bumps() -> AnalyticProblem:
    def phi(x):
        return {"bumps": float(sum(a * np.exp(-np.sum((x - p) ** 2) / (2 * s ** 2)) for p, s, a in BUMPS))}

    def grad(x):
        return {"bumps": -sum(a * np.exp(-np.sum((x - p) ** 2) / (2 * s ** 2)) * (x - p) / s ** 2
                              for p, s, a in BUMPS)}

    res = minimize(lambda x: -phi(x)["bumps"], BUMPS[1][0], jac=lambda x: -grad(x)["bumps"], method="SLSQP",
                   bounds=[(0, 1)] * 3, options={"ftol": 1e-15})
    return AnalyticProblem(Problem(["a", "b", "c"], np.zeros(3), np.ones(3), ["bumps"]), phi, grad,
                           {"bumps": -res.fun}, {"bumps": res.x}, {"bumps"})


PROBLEMS = {"monotone": monotone, "interior": interior, "flat": flat, "lipschitz": lipschitz}


# ------------------------------------------------------------------- runner
@dataclass
class Run:
    worst: object
    batches: list
    solves: int


def drive(method: str, tp: AnalyticProblem, config: dict, seed: int = 0, cap: int | None = None,
          evaluate: Callable | None = None) -> Run:
    """Play the generator: evaluate every batch serially, count solves, enforce `cap`."""
    evaluate = evaluate or tp.outcome
    gen = STRATEGIES[method](tp.problem, config, np.random.default_rng(seed))
    batches, solves = [], 0
    budget = config.get("budget", 200) if cap is None else min(cap, config.get("budget", 200))
    try:
        batch = next(gen)
        while True:
            pts = np.asarray(batch.points)
            assert pts.ndim == 2 and pts.shape[1] == tp.problem.dimension
            assert np.all(pts >= tp.problem.lower) and np.all(pts <= tp.problem.upper), "outside the box"
            batches.append(batch)
            take = min(len(pts), budget - solves)
            outs = [evaluate(x, batch.gradients) for x in pts[:take]]
            solves += take
            batch = gen.send(outs)
    except StopIteration as stop:
        return Run(stop.value, batches, solves)


def relative_error(tp: AnalyticProblem, worst, c: str) -> float:
    return (tp.optimum[c] - worst.value[c]) / max(abs(tp.optimum[c]), 1e-300)


def vertex_ranges(study, lower, upper) -> dict:
    """criterion -> (min, max) of a study's criteria over every vertex of the box [lower, upper]
    (the exhaustive reference of a search on a monotone study)."""
    out = {}
    for corner in itertools.product(*zip(lower, upper)):
        ev = study.evaluate(np.array(corner))
        assert ev.status == 0, ev.message
        for c, v in ev.phi.items():
            lo, hi = out.get(c, (np.inf, -np.inf))
            out[c] = (min(lo, v), max(hi, v))
    return out
