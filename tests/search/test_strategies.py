"""Search strategies on analytic problems (tests/support/search_problems.py) with exact gradients.

Each strategy is driven by a plain serial runner that counts solves; the
acceptance figures for `auto`: monotone worst case to 1e-4 within
40 solves on 6 parameters (< 2^6 vertices), interior maxima to 1e-3 against a
dense grid, a flat region to 1e-4 within 40 solves, Lipschitz profiles to the
LP optimum, bitwise determinism, a hard budget, failures skipped.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from scipy.optimize import minimize

from tests.support.search_problems import (PROBLEMS, X_STAR, AnalyticProblem, drive, flat, interior, interior_dense_grid,
                             lipschitz, monotone, relative_error, two_bumps)
from wcs.search import Outcome, Problem, STRATEGIES
from wcs.search.compare import compare_with_lhs
from wcs.search.designs import design
from wcs.search.ranges import ranges
from wcs.search.scaling import Space

METHODS = ["auto", "local", "global", "sample"]


def cfg(method, budget=40, **kw):
    return {"method": method, "budget": budget, "sample": {"design": "lhs", "n": 32, "seed": 0}, **kw}


def test_registry():
    assert set(STRATEGIES) == {"sample", "local", "global", "auto"}


# ------------------------------------------------------------------ designs
@pytest.mark.parametrize("name", ["lhs", "sobol", "vertices", "grid"])
def test_designs_in_box_seeded(name):
    space = Space(monotone().problem)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        Z1, _ = design(name, space, 20, np.random.default_rng(3))
        Z2, _ = design(name, space, 20, np.random.default_rng(3))
    assert Z1.shape[1] == 6 and len(Z1) >= 1
    assert np.all((Z1 >= 0) & (Z1 <= 1))
    assert np.array_equal(Z1, Z2)


def test_design_sizes():
    space = Space(Problem(["a", "b", "c"], np.zeros(3), np.ones(3), ["f"]))
    rng = np.random.default_rng(0)
    Z, _ = design("lhs", space, 10, rng)
    assert len(Z) == 10                                   # one point per stratum in every parameter
    assert all(sorted(np.floor(Z[:, i] * 10)) == list(range(10)) for i in range(3))
    Z, note = design("sobol", space, 10, rng)
    assert len(Z) == 16 and "16" in note
    Z, _ = design("vertices", space, 100, rng)
    assert len(Z) == 8 and set(np.unique(Z)) == {0.0, 1.0}
    Z, note = design("vertices", space, 5, rng)
    assert len(Z) == 5 and "5 of 2^3" in note
    Z, _ = design("grid", space, 27, rng)
    assert len(Z) == 27 and sorted(np.unique(Z)) == [0.0, 0.5, 1.0]


def test_constrained_designs_satisfy_lipschitz():
    tp = lipschitz()
    space = Space(tp.problem)
    for name in ["lhs", "sobol", "vertices", "grid"]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            Z, _ = design(name, space, 16, np.random.default_rng(1))
        X = np.array([space.to_x(z) for z in Z])
        assert np.all(X @ tp.problem.A_ub.T <= tp.problem.b_ub * (1 + 1e-12)), name
    Z, _ = design("vertices", space, 16, np.random.default_rng(1))
    assert all(space.is_vertex(z) for z in Z)


# ------------------------------------------------------------ (a) monotone
def test_auto_monotone_corner_within_40_solves():
    tp = monotone()
    run = drive("auto", tp, cfg("auto"))
    assert run.solves <= 40 < 2 ** 6
    for c in tp.problem.criteria:
        assert relative_error(tp, run.worst, c) <= 1e-4
        assert run.worst.certificate[c] == "corner-kkt"                  # (h)
    assert run.batches[0].gradients


def test_auto_without_safeguard_is_a_few_solves():
    tp = monotone()
    run = drive("auto", tp, cfg("auto", safeguard=0))
    assert run.solves <= 1 + len(tp.problem.criteria)                     # centre + one corner each
    assert all(relative_error(tp, run.worst, c) <= 1e-12 for c in tp.problem.criteria)
    assert set(run.worst.certificate.values()) == {"corner-kkt"}


@pytest.mark.parametrize("method", ["local", "global"])
def test_local_and_global_monotone(method):
    tp = monotone()
    run = drive(method, tp, cfg(method, budget=200))
    assert run.solves <= 200
    assert all(relative_error(tp, run.worst, c) <= 1e-4 for c in tp.problem.criteria)


def test_lhs_needs_many_more_solves_than_auto():
    tp = monotone()
    auto = drive("auto", tp, cfg("auto"))
    c = "disp"
    res = compare_with_lhs(tp.problem, tp.phi, 1e-4, tp.optimum[c], criterion=c, n_max=4096, repeats=3)
    assert res["n"] is None or res["n"] >= 20 * auto.solves
    assert res["ladder"][-1][1] > 1e-4 if res["n"] is None else True


# ------------------------------------------------------------ (b) interior
@pytest.mark.parametrize("method,budget", [("auto", 40), ("local", 120), ("global", 200)])
def test_interior_maximum_against_dense_grid(method, budget):
    tp = interior()
    grid = interior_dense_grid()
    run = drive(method, tp, cfg(method, budget=budget))
    assert run.solves <= budget
    for c in tp.problem.criteria:
        assert run.worst.value[c] >= grid[c] - 1e-3 * abs(grid[c])       # at least the dense grid's max
        assert relative_error(tp, run.worst, c) <= 1e-3
        assert run.worst.value[c] <= tp.optimum[c] + 1e-12
    if method == "auto":
        assert set(run.worst.certificate.values()) == {"local-kkt"}       # (h)


# ------------------------------------------------------- (e) two local maxima
def slsqp(tp, c, z0):
    """SLSQP on Φ_c with its exact gradient over the box, from z0: (value, point)."""
    res = minimize(lambda x: -tp.phi(x)[c], z0, jac=lambda x: -tp.grad(x)[c], method="SLSQP",
                   bounds=list(zip(tp.problem.lower, tp.problem.upper)), options={"ftol": 1e-15})
    return -res.fun, res.x


@pytest.mark.parametrize("seed", range(3))
def test_auto_restarts_reach_what_an_attack_from_one_flip_neighbours_finds(seed):
    """The ascent from the gradient corner stops on a local maximum (the broad
    bump); SLSQP from a one-flip neighbour of that point finds a higher one. The restarts
    from the best vertices' one-flip neighbours must reach at least the attack's value."""
    tp = two_bumps()
    c = "bumps"
    local, x_local = slsqp(tp, c, np.full(3, 0.9))                        # the broad bump's maximum
    attack = max(slsqp(tp, c, np.where(np.arange(3) == i, 1.0 - np.round(x_local), x_local))[0]
                 for i in range(3))
    assert attack > 1.2 * local                                           # the trap is real
    run = drive("auto", tp, cfg("auto", budget=80), seed=seed)
    assert run.solves <= 80
    assert run.worst.value[c] >= attack * (1 - 1e-9)
    assert run.worst.value[c] <= tp.optimum[c] * (1 + 1e-12)
    assert run.worst.certificate[c] == "local-kkt"
    assert any(b.stage == "restart" for b in run.batches)


# ------------------------------------------------- fuzzy levels (ranges.py)
def drive_levels(tp, cuts, budget=300):
    """Play `ranges` with `auto` over the α-cuts [(α, lower, upper)]: ({(criterion, α): Extreme}, solves)."""
    gen = ranges(STRATEGIES["auto"], tp.problem, cfg("auto", budget=budget), np.random.default_rng(0),
                 {c: "max" for c in tp.problem.criteria}, cuts)
    solves = 0
    try:
        batch = next(gen)
        while True:
            outs = [tp.outcome(x, batch.gradients) for x in batch.points]
            solves += len(outs)
            batch = gen.send(outs)
    except StopIteration as stop:
        return {(e.criterion, e.level): e for e in stop.value}, solves


def interior_cuts(core_q):
    """The α-cuts at 0, 0.25, …, 1 of trapezoids from the `interior` box to the core
    θ ∈ [0.45, 0.65], r ∈ [0.7, 0.9], q ∈ core_q."""
    tp = interior()
    lo, hi = tp.problem.lower, tp.problem.upper
    c, d = np.array([0.45, 0.7, core_q[0]]), np.array([0.65, 0.9, core_q[1]])
    return tp, [(a, lo + a * (c - lo), hi - a * (hi - d)) for a in (0.0, 0.25, 0.5, 0.75, 1.0)]


def assert_interior_maxima(tp, cuts, ext):
    """trade = r (cos θ + 0.6 sin θ) − 0.3 q² is largest at θ = atan 0.6, r at its upper bound and
    q nearest 0; quad at X_STAR, inside every cut. Points to 1e-5 (the KKT tolerance 1e-6 of a
    gap linear in the distance), values to 1e-12 (their error is quadratic in it)."""
    for a, lower, upper in cuts:
        q = min(max(0.0, lower[2]), upper[2])
        trade, quad = ext["trade", a], ext["quad", a]
        np.testing.assert_allclose(trade.x, [np.arctan(0.6), upper[1], q], atol=1e-5)
        assert trade.value == pytest.approx(upper[1] * np.sqrt(1.36) - 0.3 * q * q, rel=1e-12), a
        np.testing.assert_allclose(quad.x, X_STAR, atol=1e-5)
        assert quad.value == pytest.approx(1.0, rel=1e-12), a
        assert trade.certificate == quad.certificate == "local-kkt", a


def test_fuzzy_levels_carry_an_interior_maximum_out_for_two_solves_a_level():
    """Trade's maximum sits at r's upper bound and inside in θ, q at every level:
    each level outside the core tries the corner its gradient's signs point to (worse), then the
    inner maximum carried out to the cut's bound, which is the cut's maximum (KKT there, no ascent,
    no restarts); quad's lies inside every cut and keeps its certificate without a solve."""
    tp, cuts = interior_cuts((-0.1, 0.4))
    ext, solves = drive_levels(tp, cuts)
    assert_interior_maxima(tp, cuts, ext)
    _, core = drive_levels(tp, cuts[-1:])
    assert solves == core + 2 * 4                         # before: 147 (restarted ascents at every level)
    for a, _, _ in cuts[:-1]:
        assert "carried out" in ext["trade", a].note and "restart" not in ext["trade", a].note, a


def test_fuzzy_level_whose_maximum_leaves_a_bound_restarts():
    """At the core q ≥ 0.1 holds trade's maximum at q's lower bound; from α = 0.75 on q = 0 is inside
    the cut: the active set changes there, and that level restarts its ascents; the next ones keep it."""
    tp, cuts = interior_cuts((0.1, 0.4))
    ext, _ = drive_levels(tp, cuts)
    assert_interior_maxima(tp, cuts, ext)
    assert "restarted ascent" in ext["trade", 0.75].note
    assert all("restart" not in ext["trade", a].note for a in (0.0, 0.25, 0.5))


# ---------------------------------------------------------------- (c) flat
@pytest.mark.parametrize("seed", range(10))
def test_flat_region_escaped_within_40_solves(seed):
    tp = flat()
    x0 = np.full(2, 0.5)
    assert all(v == 0 for v in tp.phi(x0).values()) and not any(np.any(g) for g in tp.grad(x0).values())
    run = drive("auto", tp, cfg("auto"), seed=seed)
    assert run.solves <= 40
    for c in tp.problem.criteria:
        assert relative_error(tp, run.worst, c) <= 1e-4
    assert run.worst.certificate == {"p_corner": "corner-kkt", "p_edge": "local-kkt"}


def test_flat_region_is_not_certified_when_nothing_varies():
    tp = flat()
    run = drive("auto", tp, cfg("auto", safeguard=0, budget=1))          # centre only: the trap
    assert run.worst.value["p_corner"] == 0.0
    assert run.worst.certificate["p_corner"] == "heuristic"
    assert "flat" in run.worst.notes["p_corner"]
    # with budget left, the restarts from the centre's one-flip neighbours leave the flat region
    run = drive("auto", tp, cfg("auto", safeguard=0))
    assert relative_error(tp, run.worst, "p_corner") <= 1e-4
    assert run.worst.certificate["p_corner"] == "corner-kkt"


# ----------------------------------------------------------- (d) Lipschitz
@pytest.mark.parametrize("method,budget", [("auto", 40), ("local", 120), ("global", 200)])
def test_lipschitz_profile_matches_lp(method, budget):
    tp = lipschitz()
    A, b = tp.problem.A_ub, tp.problem.b_ub
    run = drive(method, tp, cfg(method, budget=budget))
    for batch in run.batches:
        assert np.all(batch.points @ A.T <= b + 1e-9 * b), "a point breaks the slope bound"
    assert relative_error(tp, run.worst, "lin") <= 1e-8
    assert abs(run.worst.value["fit"] - tp.optimum["fit"]) <= 1e-6 * abs(tp.optimum["fit"])
    if method == "auto":
        assert run.worst.certificate == {"lin": "corner-kkt", "fit": "local-kkt"}


# --------------------------------------------------------- (e) determinism
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("problem", ["monotone", "lipschitz"])
def test_same_seed_same_batches(method, problem):
    tp = PROBLEMS[problem]()
    r1 = drive(method, tp, cfg(method, budget=60), seed=5)
    r2 = drive(method, tp, cfg(method, budget=60), seed=5)
    assert len(r1.batches) == len(r2.batches)
    for a, b in zip(r1.batches, r2.batches):
        assert a.points.tobytes() == b.points.tobytes() and a.stage == b.stage
    for c in tp.problem.criteria:
        assert r1.worst.x[c].tobytes() == r2.worst.x[c].tobytes()
        assert r1.worst.value[c] == r2.worst.value[c]
    if method in ("sample", "auto"):
        r3 = drive(method, tp, cfg(method, budget=60), seed=6)
        assert r3.batches[0].points.tobytes() != r1.batches[0].points.tobytes()


# -------------------------------------------------------------- (f) budget
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("budget", [1, 2, 5, 13, 37])
def test_budget_is_a_hard_cap(method, budget):
    for problem in PROBLEMS:
        tp = PROBLEMS[problem]()
        spent = 0
        run = drive(method, tp, cfg(method, budget=budget))
        for batch in run.batches:
            assert len(batch.points) <= budget - spent
            spent += len(batch.points)
        assert run.solves == spent <= budget
        assert all(np.isfinite(v) for v in run.worst.value.values())


@pytest.mark.parametrize("method", METHODS)
def test_runner_truncation_ends_the_search(method):
    tp = interior()
    for cap in (1, 4, 9, 12):
        run = drive(method, tp, cfg(method, budget=100), cap=cap)
        assert run.solves <= cap
        sent = sum(len(b.points) for b in run.batches)
        # every batch before the last was answered in full; the one cut short is the last
        assert sent - len(run.batches[-1].points) <= cap
        for c in tp.problem.criteria:
            assert run.worst.x[c].shape == (3,)


# ------------------------------------------------------------ (g) failures
def failing(tp: AnalyticProblem, lo_frac=0.55, hi_frac=0.75):
    """Status 4 and NaN where z_0 ∈ (lo, hi); status 0 but NaN phi where z_1 ∈ (0.3, 0.45)."""
    p = tp.problem

    def evaluate(x, gradients=True):
        z = (x - p.lower) / (p.upper - p.lower)
        if lo_frac < z[0] < hi_frac:
            return Outcome(x, {c: float("nan") for c in p.criteria}, 4, None)
        if 0.3 < z[1] < 0.45:
            return Outcome(x, {c: float("nan") for c in p.criteria}, 0, None)
        return tp.outcome(x, gradients)
    return evaluate


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("problem", ["monotone", "interior", "lipschitz"])
def test_failures_are_skipped(method, problem):
    tp = PROBLEMS[problem]()
    ev = failing(tp)
    run = drive(method, tp, cfg(method, budget=80), evaluate=ev)
    for c in tp.problem.criteria:
        x = run.worst.x[c]
        o = ev(x)
        assert o.status == 0 and o.phi[c] == run.worst.value[c]
    if method == "auto" and problem != "lipschitz":        # the maximisers are outside the failing bands
        assert all(relative_error(tp, run.worst, c) <= 1e-4 for c in tp.problem.criteria)


@pytest.mark.parametrize("method", METHODS)
def test_everything_fails(method):
    tp = interior()

    def dead(x, gradients=True):
        return Outcome(x, {c: float("nan") for c in tp.problem.criteria}, 6, None)
    run = drive(method, tp, cfg(method, budget=20), evaluate=dead)
    assert run.solves <= 20
    for c in tp.problem.criteria:
        assert np.isnan(run.worst.value[c]) and run.worst.certificate[c] == "heuristic"


def test_missing_gradients_fall_back_to_finite_differences():
    tp = interior()
    run = drive("auto", tp, cfg("auto", budget=150), evaluate=lambda x, g=True: tp.outcome(x, False))
    assert run.solves <= 150
    assert any(b.stage == "fd" and not b.gradients for b in run.batches)
    for c in tp.problem.criteria:
        assert relative_error(tp, run.worst, c) <= 1e-3


def rough(tp):
    def evaluate(x, gradients=True):
        o = tp.outcome(x, gradients)
        o.nonsmooth = True
        return o
    return evaluate


def test_a_nonsmooth_corner_is_certified_by_its_one_sided_differences():
    """Every point flagged non-smooth (the adjoint gradient one-sided, as at a contact switch):
    at each criterion's best corner the search takes one difference into the box per parameter
    (step 1e-6 of the interval) and certifies corner-kkt when none grows — here, where the
    quotients taken independently below all fall or vanish (x2 does not move temp, x1 not shear).
    Before: heuristic, "non-smooth point: KKT not checked"."""
    tp = monotone()
    run = drive("auto", tp, cfg("auto"), evaluate=rough(tp))
    width = tp.problem.upper - tp.problem.lower
    steps = [b for b in run.batches if b.stage == "one-sided"]
    assert len(steps) == 1 and not steps[0].gradients
    for c in tp.problem.criteria:
        assert relative_error(tp, run.worst, c) <= 1e-4
        x = run.worst.x[c]
        assert np.all((x == tp.problem.lower) | (x == tp.problem.upper))
        inward = np.where(x == tp.problem.lower, 1.0, -1.0)
        moved = x + inward[:, None] * np.eye(6) * 1e-6 * width
        assert all(np.any(np.all(np.isclose(steps[0].points, y, rtol=1e-13, atol=0), axis=1)) for y in moved)
        q = np.array([tp.phi(y)[c] - tp.phi(x)[c] for y in moved]) / 1e-6
        assert np.all(q <= 1e-9 * abs(tp.phi(x)[c]))                    # nothing grows inward
        assert run.worst.certificate[c] == "corner-kkt"
        assert "one-sided differences" in run.worst.notes[c] and "every edge of the box" in run.worst.notes[c]


def test_a_nonsmooth_point_without_one_sided_differences_is_not_certified():
    """The same with a budget that cannot pay for the differences (6 solves a corner)."""
    tp = monotone()
    run = drive("auto", tp, cfg("auto", budget=18), evaluate=rough(tp))
    assert not any(b.stage == "one-sided" for b in run.batches)
    assert set(run.worst.certificate.values()) == {"heuristic"}
    assert all("not differentiable here" in run.worst.notes[c] and "the budget left no solves for one-sided"
               in run.worst.notes[c] for c in tp.problem.criteria)


# ------------------------------------------------------------------ sample
def test_sample_is_one_batch_and_every_outcome_updates_every_criterion():
    tp = monotone()
    run = drive("sample", tp, cfg("sample", budget=100))
    assert len(run.batches) == 1 and not run.batches[0].gradients and run.solves == 32
    pts = run.batches[0].points
    for c in tp.problem.criteria:
        assert run.worst.value[c] == max(tp.phi(x)[c] for x in pts)
        assert run.worst.certificate[c] == "heuristic"


def test_notes_say_once_and_in_words_why_the_ascents_stopped():
    """A budget spent by the restarts' one-flip neighbours (the 3D tunnel's pattern): the note
    says how many neighbours were paid for and, once for the three restarted ascents, that they
    stopped before a first step because the budget was spent (before: "restarted ascent: budget
    after 0 steps, budget after 0 steps, budget after 0 steps" and "10 neighbours evaluated")."""
    tp = interior()
    run = drive("auto", tp, cfg("auto", budget=30))
    for c in tp.problem.criteria:
        note = run.worst.notes[c]
        assert "local ascent: it stopped after" in note and "the KKT conditions held there" in note
        assert "restarts: 5 of the 10 one-flip neighbours of the best points evaluated before the budget ran out" in note
        assert note.endswith("3 restarted ascents: all stopped before a first step: the budget was spent")
        assert note.count("budget") == 2
