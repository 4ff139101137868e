r"""Adjoint gradients through time: dJ/dx of each criterion's reduced history
J = R(φ₀ … φ_N) by one reverse sweep over the levels' final active sets.

The seed scheme [101, (10)] (`wcs.dynamics.schemes`) solves at level n, on its final active set
(closed normals 𝒜, stuck tangents 𝒮, slipping tangents held at λt = σ gw, σ = ±1 in 2D), the
linear saddle-point system

    [A  Gᵀ] [Δ_n]   [r_n − Bt_slipᵀ σ gw_n]      r_n = f(t_n) − k₀ − K w_{n−1} + M v_{n−1}/τ,
    [G  0 ] [μ_n] = [h_n               ],      h_n = [d₀ − Bn w_{n−1}]_𝒜 ; 0_𝒮,

G = [Bn_𝒜; Bt_𝒮], A = M/τ² + C/τ + K, gw_n = g·w + F λn_{n−1} (Coulomb with the previous level's
pressure, [101, §3]), then w_n = w_{n−1} + Δ_n, v_n = Δ_n/τ. The reduction weighs the levels:
max (min) → the level of the peak (least), final → N, mean → 1/(N+1) each, so J = Σ c_n φ_n.
The adjoint sweep (n = N … 1) carries ŵ = ∂J/∂w_n, v̂ = ∂J/∂v_n, l̂ = ∂J/∂λn_n; at each level
one solve with the (symmetric) saddle-point matrix of its active set,

    [A  Gᵀ; G  0] [a; b] = [ŵ + c_n φ_w + v̂/τ ; c_n φ_λ on 𝒜, 𝒮],

then ŵ ← ŵ + c_{n−1}φ_w − K a − Bn_𝒜ᵀ b_𝒜, v̂ ← M a/τ, l̂ ← F ĝw with
ĝw = σ (c_n φ_λt − Bt a) on the slipping rows, and the data's share

    dJ/dx += aᵀ (∂f(t_n) − ∂k₀ − ∂K w_n + ∂M (v_{n−1}/τ − Δ_n/τ²) − ∂C Δ_n/τ) + b_𝒜ᵀ ∂d₀ + ĝwᵀ ∂gw.

The stabilized scheme (`wcs.dynamics.schemes`, Deuflhard–Krause–Ertel) solves at level n two
systems. The predictor's M-projection, frictionless, on its final closed normals 𝒫 (P = Bn_𝒫):

    [M  Pᵀ] [δ̃_n]   [τ M v_{n−1}           ]
    [P  0 ] [μ̃_n] = [(d₀ − Bn w_{n−1})_𝒫],

then the step, with A = 2M/τ² + C/τ + K/2 and r_n = (f(t_{n−1}) + f(t_n))/2 − k₀ − K w_{n−1} +
2M δ̃_n/τ² in the system above, and w_n = w_{n−1} + Δ_n, v_n = v_{n−1} + 2(Δ_n − δ̃_n)/τ (λ_n the
step's mean contact force). Its sweep solves the step's system with the top [ŵ + c_n φ_w +
2v̂/τ], then the predictor's

    [M  Pᵀ; P  0] [ã; b̃] = [2 M a/τ² − 2 v̂/τ ; 0]

(∂J/∂δ̃_n: through r_n and v_n), and carries ŵ ← ŵ + c_{n−1}φ_w − K a − Bn_𝒜ᵀ b_𝒜 − Pᵀ b̃,
v̂ ← v̂ + τ M ã, l̂ as above; the data's share is

    aᵀ ((∂f(t_{n−1}) + ∂f(t_n))/2 − ∂k₀ − ∂K (w_{n−1} + Δ_n/2) + 2 ∂M (δ̃_n − Δ_n)/τ² − ∂C Δ_n/τ)
    + b_𝒜ᵀ ∂d₀ + ĝwᵀ ∂gw + ãᵀ ∂M (τ v_{n−1} − δ̃_n) + b̃ᵀ ∂d₀_𝒫.

The predictor's active set is checked for switches as the step's (`level_switch`, against the
predictors' own largest multiplier and increment).

The data's derivatives ∂M, ∂C, ∂K, ∂f(t), ∂k₀, ∂d₀, ∂g, ∂F (the matrices with their dashpot
impedances √(ρ(λ+2μ)), the sources' nodal loads and Ricker wavelets, …) are central differences
of the data's assembly at the same solution — not of the simulation — with the step
`DATA_STEP` of the box's width: the data are smooth in x (affine in amplitudes and moduli,
√ and exp elsewhere), so their truncation error is O(DATA_STEP²) ≈ 1e-8 of the data and the
round-off ≈ 3ε E/(2 DATA_STEP) over the width ≈ 1e-12 of it (measured on K: 1.9e-11 at this step,
1.6e-9 at 1e-6). The round-off is what counts: the levels' shares aᵀ∂K w … nearly cancel where a
criterion hardly depends on a datum (the mean contact pressure over an impact is its impulse,
which the modulus does not change), and the sum keeps their absolute error — at 1e-6 the coarse
cylinder impact's mean pressure had 3.4e-4 of its derivative along the modulus wrong (3.5 % of
its change across the box), at 1e-4 it has 3e-7 (3e-5 of that change, 4e-6 of its value).

The start: from rest or given rigid velocities, w₀ = 0 and v₀ do not depend on x. From the static
state (`initial: static`), w₀ and λ₀ are a static contact solution: the sweep's ŵ₀ (and the
level-0 criterion's partials, the Coulomb l̂₀, and the released supports' reactions, a constant
load of every level: ∂J/∂R = T Σ_n a_n) are the partials of one static adjoint solve per
criterion (`wcs.model.sensitivity.coefficient_gradients`).

Not differentiable — the criterion's gradient is None and the search takes finite differences
of the reduced criterion, which its record says (`Evaluation.message`, the certificate's
"finite-difference gradient"): a peak (least) reached at two levels within `REL_TOL` (a
plateau: on the seismic study the fault's slip stops growing and holds to the end; its levels'
gradients agree only to about the adjoint's own accuracy, and one sweep column per tied level
would cost more than the search's differences), a criterion's own kink or region switch at a weighted level, a contact node at a switch at a level
that moves it (a closed node with λn ≈ 0, an open one touching, a stuck one at |λt| ≈ gw, a
slipping one at zero slip increment; within REL_TOL of the level's largest pressure and
increment, `level_switch`; the stabilized predictor's normals likewise), a singular active-set
system, a point source within the data step of a cell face (its P1 shape functions' gradients jump
there), and what the sweep does not cover: a 3D node slipping on its disc.

A thermal scene: the temperature θ is steady (one heat solve per data set, its load constant over
the levels); its share, Σ_n c_n ∂φ_n/∂θ · ∂θ/∂x, takes ∂θ/∂x, like the other data, by central
differences of the heat solve (linear in θ, smooth in x), and the thermal load enters ∂f.

Memory: the sweep keeps each level's increment and contact result (stabilized: and its
predictor's; N vectors of the reduced
size: the seismic study's 240 × 15,456 doubles, 30 MB); a 3D model of 1e6 unknowns over 1000
levels would hold 8 GB, where checkpointing (every √N-th level stored, the rest recomputed)
trades it for a second forward run. Each level's system is solved with the forward's factor of A
and its Delassus operator (the monolithic method's); a method without them (iterative) gets a
sparse LU of the level's saddle-point matrix per active set, for 2D and small 3D models only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from wcs.model.coefficients import flatten
from wcs.model.criteria import REL_TOL, Partials
from wcs.model.sensitivity import coefficient_gradients, contact_nonsmooth, criterion_partials

from . import schemes
from .loading import at_time_zero, damping_matrix, load_function, source_at
from .release import released_dofs, released_names
from .sources import containing_cells
from .stepping import dynamic_matrices, level_solution, region_dynamics

DATA_STEP = 1e-4            # the data's central-difference step, a fraction of the box's width


@dataclass
class TimeGradients:
    """dJ/dx per criterion (None: not differentiable there or not covered) and why ('' where it is
    the adjoint's)."""
    grad: dict
    why: dict


@dataclass
class LevelData:
    """What the levels' equations take from a data set: the coefficients, M, C, K, the load
    f(t) on the full DOFs (without the released supports' reactions), the supports' u₀ and the
    steady temperature θ on the heat nodes (a thermal scene; else None; the nodal one is P θ)."""
    c: object
    mats: object
    load: object
    u0: np.ndarray
    theta: np.ndarray | None = None


def level_data(ev, model, pmap, x, others=None) -> LevelData:
    """The levels' data at x (as `wcs.dynamics.history.simulate` builds them)."""
    scene = ev.study.scene
    c = pmap.coefficients(x, others)
    s = pmap.slots(x, others)
    rho, visc = region_dynamics(model, pmap, x, others)
    theta = model._heat_theta(c)[0] if model.thermal else None         # as `solve_heat`: P θ
    heat = model.P @ theta if theta is not None else None
    load = load_function(model, scene, c, s, pmap.index, heat)
    if load is None:
        constant = model.mechanical_load(c, heat)
        load = lambda t: constant                       # noqa: E731 - constant in time
    mats = dynamic_matrices(model, c, rho, visc, damping_matrix(model, scene, c, rho, s, pmap.index))
    return LevelData(c, mats, load, model.elim.U0 @ c.support_values, theta)


def data_steps(study, x) -> np.ndarray:
    """The central-difference step of each uncertain number: `DATA_STEP` of its box's width."""
    width = np.array([e.upper - e.lower for e in study.uncertain], float)
    return DATA_STEP * np.where(width > 0, width, np.maximum(np.abs(x), 1.0))


def reduction_weights(how, phi) -> tuple[np.ndarray, str]:
    """(c_n, why not differentiable or '') of a history phi reduced by `how`: a peak (least value)
    is tied where another level comes within REL_TOL of the history's largest magnitude."""
    phi = np.asarray(phi, float)
    c = np.zeros(phi.size)
    if how == "mean":
        c[:] = 1.0 / phi.size
        return c, ""
    if how == "final":
        c[-1] = 1.0
        return c, ""
    n = int(np.argmax(phi) if how == "max" else np.argmin(phi))
    close = np.flatnonzero(np.abs(phi - phi[n]) <= REL_TOL * max(np.abs(phi).max(), 1e-300))
    c[n] = 1.0
    if close.size > 1:
        word = "peak" if how == "max" else "least value"
        where = f"levels {close[0]} and {close[1]}" if close.size == 2 else \
            f"{close.size} levels from {close[0]} to {close[-1]}"
        return c, f"its {word} over time is reached at {where} (within {REL_TOL:g})"
    return c, ""


def _active(model, res):
    """(closed normals, stuck tangent rows, slipping tangent rows with gw > 0, σ) of a level."""
    m = res.lam_n.size
    gw = np.where(np.isfinite(res.gw), res.gw, 0.0) if res.gw is not None else np.zeros(m)
    closed, stick = res.free[:m], res.free[m:]
    k = stick.size // m
    slip = ~stick & (np.tile(gw, k) > 0)
    sigma = np.where(slip, np.sign(res.lam_t), 0.0)
    return closed, stick, slip, sigma, gw


def level_switch(model, res, prev, d, step, fs_all, us_all) -> str:
    """'' or where a contact node of a level sits at a switch of its active set, within REL_TOL of
    the level's largest pressure and increment: closed with λn ≈ 0, open with a zero gap, stuck at
    |λt| ≈ gw or slipping by ≈ 0 — each only where the level moved the node (its gap or its force
    changed by more than REL_TOL of the history's largest pressure fs_all and increment us_all;
    prev: the last level's result). A node that keeps its state, at a switch as
    the static state left it (a fault node touching at zero pressure at the tunnel's wall, one at
    rest at its slip limit) before the waves arrive, stays so under any small change of the data
    (the start is an equilibrium of every data set), so the level is smooth there."""
    m = res.lam_n.size
    closed, stick, slip, _, gw = _active(model, res)
    moves = ~model.held[:m]
    k = stick.size // m
    before_n = prev.lam_n if prev is not None else np.zeros(m)
    before_t = prev.lam_t if prev is not None else np.zeros_like(res.lam_t)
    moved = (np.abs(model.Bn_r @ step) > REL_TOL * us_all) | (np.abs(res.lam_n - before_n) > REL_TOL * fs_all) \
        | (np.linalg.norm((res.lam_t - before_t).reshape(k, m), axis=0) > REL_TOL * fs_all)
    fs = max(np.abs(res.lam_n).max(initial=0.0), 1e-300)
    us = max(np.abs(d).max(initial=0.0), np.abs(step).max(initial=0.0), 1e-300)
    lam_t = np.linalg.norm(res.lam_t.reshape(k, m), axis=0)
    ds = np.linalg.norm((model.Bt_r @ step).reshape(k, m), axis=0)
    stuck = stick.reshape(k, m).any(axis=0)
    slipping = slip.reshape(k, m).any(axis=0)
    checks = {"closed with a vanishing pressure": closed & (res.lam_n <= REL_TOL * fs),
              "open and touching": ~closed & (d - model.Bn_r @ step <= REL_TOL * us),
              "stuck at its slip limit": stuck & (gw > 0) & (lam_t >= (1 - REL_TOL) * gw),
              "slipping by nothing": slipping & closed & (ds <= REL_TOL * us)}
    for what, where in checks.items():
        hit = np.flatnonzero(where & moved & moves)
        if hit.size:
            return f"contact node {hit[0]} is {what}"
    return ""


class LevelSystem:
    """Solves [A Gᵀ; G 0] [a; b] = [t; s] on a level's active set. With the forward's factor of A
    and its Delassus operator W = C A⁻¹ Cᵀ (C = [Bn; Bt]; the monolithic method holds both):
    b = W_GG⁻¹ (G A⁻¹ t − s), a = A⁻¹ (t − Gᵀ b) — two solves with A and a small dense one (W_GG's
    LU once per active set); otherwise the sparse LU of the whole matrix, once per active set."""

    def __init__(self, A, model, held=None):
        A = sp.csr_matrix(A)
        self.A, self.model, self.cache = A, model, {}
        self.held = held if held is not None and held.W is not None and not len(held.pinned) \
            and held.K_data is not None and np.array_equal(held.K_data, A.data) else None
        self.C = sp.vstack([model.Bn_r, model.Bt_r]).tocsr() if model.zone is not None else None

    def rows(self, res) -> tuple[np.ndarray, np.ndarray]:
        """The closed normals and stuck tangents of a level (rows of Bn_r, Bt_r) that constrain:
        a row held by supports on both sides is no constraint (res None: none)."""
        if res is None:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        m = res.lam_n.size
        n_rows, t_rows = np.flatnonzero(res.free[:m]), np.flatnonzero(res.free[m:])
        live = abs(self.C[np.r_[n_rows, m + t_rows]]).max(axis=1).toarray().ravel() > 0
        return n_rows[live[:n_rows.size]], t_rows[live[n_rows.size:]]

    def _solve_A(self, rhs):
        return np.column_stack([self.held.factor.solve(col) for col in rhs.T])

    def solve(self, res, top, bottom):
        """(a, b) of the level's system, or None where it is singular."""
        n_rows, t_rows = self.rows(res)
        key = b"" if res is None else res.free.tobytes()
        idx = np.r_[n_rows, (res.lam_n.size if res is not None else 0) + t_rows]
        if self.held is not None:
            if key not in self.cache:
                W = self.held.W[np.ix_(idx, idx)]
                self.cache[key] = sla.lu_factor(W) if idx.size and np.linalg.matrix_rank(W) == idx.size else \
                    (None if idx.size else ())
            lu = self.cache[key]
            if lu is None:
                return None
            y = self._solve_A(top)
            if not idx.size:
                return y, np.zeros((0, top.shape[1]))
            G = self.C[idx]
            b = sla.lu_solve(lu, G @ y - bottom)
            return self._solve_A(top - G.T @ b), b
        if key not in self.cache:
            G = self.C[idx] if self.C is not None else None
            K = sp.bmat([[self.A, G.T], [G, None]]) if idx.size else self.A
            try:
                self.cache[key] = spla.splu(sp.csc_matrix(K))
            except RuntimeError:
                self.cache[key] = None
        if self.cache[key] is None:
            return None
        sol = self.cache[key].solve(np.vstack([top, bottom]))
        return sol[:top.shape[0]], sol[top.shape[0]:]


def _derivatives(ev, model, pmap, x, others, steps):
    """Per uncertain number: (the data at x + h, the data at x − h, h)."""
    out = []
    for i, h in enumerate(steps):
        e = np.zeros_like(x)
        e[i] = h
        out.append((level_data(ev, model, pmap, x + e, others), level_data(ev, model, pmap, x - e, others), h))
    return out


def source_on_face(ev, x, others, steps) -> str:
    """'' or the source whose point lies within the data step of a cell face (its nodal loads are
    not differentiable in the point there)."""
    pmap, sm = ev.map, ev.smesh
    box = {e.path: i for i, e in enumerate(ev.study.uncertain)}
    for name, source in ev.study.scene.sources.items():
        moved = [box[k] for k in (f"sources.{name}.point.{j}" for j in range(len(source.point))) if k in box]
        if not moved:
            continue
        cells = set()
        for sign in (-1.0, 0.0, 1.0):
            xs = np.array(x, float)
            xs[moved] += sign * steps[moved]
            here = source_at(name, source, pmap.slots(xs, others), pmap.index)
            found = containing_cells(sm.mesh.p, sm.mesh.t, np.asarray(here.point, float))[0]
            cells.add(tuple(found))
        if len(cells) > 1 or len(next(iter(cells))) > 1:
            return f"the point of source '{name}' lies on a cell face (its P1 load is not differentiable there)"
    return ""


def gradients(ev, x, others, hist, record) -> TimeGradients:
    """dJ/dx of every criterion of evaluator ev at data vector x, from the simulation `hist`
    (`wcs.dynamics.history.simulate` with `record`)."""
    names = [c.name for c in ev.criteria]
    why = {n: "" for n in names}
    grad = {n: None for n in names}
    model, pmap, states = record["model"], record["map"], record["states"]
    steps = data_steps(ev.study, np.asarray(x, float))
    reason = source_on_face(ev, x, others, steps)
    if model.zone is not None and not reason:
        reason = _switch_or_disc(model, record)
    if reason:
        return TimeGradients(grad, {n: reason for n in names})
    weights = {}
    for spec in ev.study.criteria:
        weights[spec.name], why[spec.name] = reduction_weights(spec.over_time or "max", hist.phi[spec.name])
    dyn = ev.study.dynamics
    data = level_data(ev, model, pmap, x, others)
    deriv = _derivatives(ev, model, pmap, x, others, steps)
    sweep = _Sweep(ev, model, pmap, x, others, dyn.time_step, data, deriv, record, weights, why)
    out = sweep.run()
    for j, n in enumerate(names):
        if not why[n] and out is not None and np.all(np.isfinite(out[:, j])):
            grad[n] = out[:, j]
        elif not why[n]:
            why[n] = sweep.failure or "the adjoint through time failed"
    return TimeGradients(grad, why)


def _switch_or_disc(model, record) -> str:
    """'' or the first level whose active set has a switch within reach or a node slipping on a
    3D disc."""
    w = record["start"][0].copy()
    u0 = model.elim.U0 @ record["c"].support_values
    z = model.zone
    prev = record["start"][2]
    fs = max([np.abs(res.lam_n).max(initial=0.0) for _, res in record["states"]] + [1e-300])
    us = max([np.abs(step).max(initial=0.0) for step, _ in record["states"]] + [1e-300])
    projections = [p for _, p in record.get("predictors") or ()]
    fp = max([np.abs(p.lam_n).max(initial=0.0) for p in projections] + [1e-300])
    up = max([np.abs(p.u).max(initial=0.0) for p in projections] + [1e-300])
    for n, (step, res) in enumerate(record["states"], start=1):
        if res.lam_t.size > res.lam_n.size:
            _, _, slip, _, _ = _active(model, res)
            if slip.any():
                return f"at time level {n} a 3D contact node slips on its disc (not covered by the adjoint through time)"
        d = z.gap - z.Bn @ u0 - model.Bn_r @ w
        if projections:
            where = level_switch(model, projections[n - 1], projections[n - 2] if n >= 2 else None, d,
                                 projections[n - 1].u, fp, up)
            if where:
                return f"at time level {n} the predictor's projection: {where}: the history is not differentiable there"
        where = level_switch(model, res, prev, d, step, fs, us)
        if where:
            return f"at time level {n} {where}: the history is not differentiable there"
        w, prev = w + step, res
    return ""


class _Sweep:
    """The reverse sweep of the module docstring, all criteria at once (columns)."""

    def __init__(self, ev, model, pmap, x, others, tau, data, deriv, record, weights, why):
        self.ev, self.model, self.pmap, self.x, self.others = ev, model, pmap, x, others
        self.tau, self.data, self.deriv, self.record = tau, data, deriv, record
        self.weights, self.why = weights, why
        self.crits = list(ev.criteria)
        self.failure = ""

    def partials(self, n, u, res):
        """(φ_w (reduced), φ_λn, φ_λt, φ_u (full DOFs), the explicit dJ/dx), one column per criterion,
        of the criteria at level n times their reductions' weights c_n."""
        model, c = self.model, self.data.c
        k = len(self.crits)
        m = model.zone.gap.size if model.zone is not None else 0
        pn = np.zeros((m, k))
        pt = np.zeros((model.Bt_r.shape[0] if model.zone is not None else 0, k))
        pu, coef = np.zeros((model.elim.T.shape[0], k)), np.zeros((len(self.x), k))
        state = None
        for j, crit in enumerate(self.crits):
            cn = self.weights[crit.name][n]
            if cn == 0.0:
                continue
            heat = model.P @ self.data.theta if self.data.theta is not None else None
            state = level_solution(model, c, u, res, heat) if state is None else state
            P, kink = criterion_partials(crit, model, state)
            if kink and not self.why[crit.name]:
                self.why[crit.name] = f"at time level {n} the criterion has a kink or its maximising region switches"
            if P.u is not None:
                pu[:, j] = cn * P.u
            if P.lam_n is not None:
                pn[:, j] = cn * P.lam_n
            if P.lam_t is not None:
                pt[:, j] = cn * P.lam_t
            if P.coef:
                flat, sl = flatten(c)
                g = np.zeros_like(flat)
                for name, v in P.coef.items():
                    g[sl[name]] += v
                coef[:, j] = cn * (self.pmap.jacobian(self.x, self.others).T @ g)
            if P.theta is not None:                         # the steady temperature θ(x)
                coef[:, j] += cn * np.array([((hi.theta - lo.theta) / (2 * h)) @ P.theta for hi, lo, h in self.deriv])
        for i, (hi, lo, h) in enumerate(self.deriv):        # u_n = T w_n + u₀: the supports' share
            coef[i] += ((hi.u0 - lo.u0) / (2 * h)) @ pu
        pw = model.Tt @ pu
        return pw, pn, pt, pu, coef

    def run(self) -> np.ndarray | None:
        model, tau, data, rec = self.model, self.tau, self.data, self.record
        T, Tt, z = model.elim.T, model.Tt, model.zone
        M, K = data.mats.M, data.mats.K
        states = rec["states"]
        stabilized = self.ev.study.dynamics.scheme == "stabilized"
        last = states[-1][1] if states else None
        operator = schemes.stabilized_operator if stabilized else schemes.seed_operator
        system = LevelSystem(operator(data.mats, tau), model, last.factor if last is not None else None)
        N, k, P = len(states), len(self.crits), len(self.x)
        w0, v0, res0 = rec["start"]
        ws = np.cumsum([w0] + [s for s, _ in states], axis=0)          # w_0 … w_N
        if stabilized:
            preds = rec["predictors"]
            projected = next((p for _, p in reversed(preds) if p is not None), None)
            projection = LevelSystem(M, model, projected.factor if projected is not None else None)
            vs = [v0]
            for (step, _), (pred, _) in zip(states, preds):
                vs.append(schemes.stabilized_velocity(tau, vs[-1], step, pred))
        else:
            vs = [v0] + [s / tau for s, _ in states]                    # seed: v_n = Δ_n/τ
        dK = [(hi.mats.K - lo.mats.K) / (2 * h) for hi, lo, h in self.deriv]
        dM = [(hi.mats.M - lo.mats.M) / (2 * h) for hi, lo, h in self.deriv]
        dC = [((hi.mats.C - lo.mats.C) / (2 * h)) if hi.mats.C is not None else None for hi, lo, h in self.deriv]
        K_full = [(model.stiffness(hi.c), model.stiffness(lo.c)) for hi, lo, _ in self.deriv]
        dk0 = [Tt @ ((Kh @ hi.u0 - Kl @ lo.u0) / (2 * h)) for (hi, lo, h), (Kh, Kl) in zip(self.deriv, K_full)]
        dd0 = [-(z.Bn @ ((hi.u0 - lo.u0) / (2 * h))) if z is not None else None for hi, lo, h in self.deriv]
        dg = [(hi.c.slip - lo.c.slip) / (2 * h) if z is not None else None for hi, lo, h in self.deriv]
        dF = [(hi.c.coulomb - lo.c.coulomb) / (2 * h) if z is not None else None for hi, lo, h in self.deriv]
        F = np.asarray(data.c.coulomb, float) if z is not None else None
        grad = np.zeros((P, k))
        w_hat, v_hat = np.zeros((T.shape[1], k)), np.zeros((T.shape[1], k))
        l_hat = np.zeros((z.gap.size, k)) if z is not None else None
        a_sum = np.zeros((T.shape[1], k))
        for n in range(N, 0, -1):
            step, res = states[n - 1]
            prev_res = states[n - 2][1] if n >= 2 else res0
            u = T @ ws[n] + data.u0
            pw, pn, pt, _, coef = self.partials(n, u, res)
            grad += coef
            top = w_hat + pw + (2 * v_hat if stabilized else v_hat) / tau
            n_rows, t_rows = system.rows(res)
            bottom = np.vstack([(l_hat + pn)[n_rows], pt[t_rows]]) if z is not None else np.zeros((0, k))
            out = system.solve(res, top, bottom)
            if out is None:
                self.failure = f"at time level {n} the active set's system is singular"
                return None
            a, b_n = out[0], out[1][:n_rows.size]
            if z is not None:
                _, _, slip, sigma, _ = _active(model, res)
                ghat = np.where(slip[:, None], sigma[:, None] * (pt - model.Bt_r @ a), 0.0)   # ∂J/∂gw per tangent row
                m = res.lam_n.size
                ghat_node = ghat.reshape(-1, m, k).sum(axis=0)
                lam_prev = prev_res.lam_n if prev_res is not None else np.zeros(m)
            # the data's share at this level: ∂r − ∂A Δ (module docstring)
            t_n = n * tau
            if stabilized:
                pred, proj = preds[n - 1]
                y_M = 2 * (pred - step) / tau**2
                y_K = ws[n - 1] + step / 2
            else:
                y_M, y_K = vs[n - 1] / tau - step / tau**2, ws[n]
            for i, (hi, lo, h) in enumerate(self.deriv):
                f_i = (hi.load(t_n) - lo.load(t_n)) / (2 * h)
                if stabilized:
                    f_i = (f_i + (hi.load(t_n - tau) - lo.load(t_n - tau)) / (2 * h)) / 2
                r = (Tt @ f_i - dk0[i] - dK[i] @ y_K + dM[i] @ y_M)
                if dC[i] is not None:
                    r = r - dC[i] @ (step / tau)
                grad[i] += r @ a
                if z is not None:
                    grad[i] += dd0[i][n_rows] @ b_n
                    dgw = dg[i] * z.weight + dF[i] * lam_prev
                    grad[i] += dgw @ ghat_node
            a_sum += a
            w_hat = w_hat + pw - K @ a
            if z is not None:
                w_hat -= model.Bn_r[n_rows].T @ b_n
                l_hat = F[:, None] * ghat_node if F is not None and prev_res is not None else np.zeros_like(l_hat)
            if not stabilized:
                v_hat = M @ a / tau
                continue
            # the predictor: [M Pᵀ; P 0] [ã; b̃] = [2 M a/τ² − 2 v̂/τ; 0]
            p_rows, _ = projection.rows(proj)
            out = projection.solve(proj, 2 * (M @ a) / tau**2 - 2 * v_hat / tau, np.zeros((p_rows.size, k)))
            if out is None:
                self.failure = f"at time level {n} the predictor's active-set system is singular"
                return None
            a_p, b_p = out
            for i, (hi, lo, h) in enumerate(self.deriv):
                grad[i] += (dM[i] @ (tau * vs[n - 1] - pred)) @ a_p
                if z is not None:
                    grad[i] += dd0[i][p_rows] @ b_p
            if z is not None:
                w_hat -= model.Bn_r[p_rows].T @ b_p
            v_hat = v_hat + tau * (M @ a_p)
        # level 0 and the start
        u0_state = T @ ws[0] + data.u0
        if self.ev.study.dynamics.initial == "static":
            grad += self.static_share(w_hat, l_hat, a_sum, u0_state, res0)
        else:
            grad += self.partials(0, u0_state, res0)[4]
        return grad

    def static_share(self, w_hat, l_hat, a_sum, u_s, res0) -> np.ndarray:
        """dJ/dx through the static initial state: one static adjoint solve per criterion with the
        partials of J in u_s, λ_s (w₀ = (TᵀT)⁻¹Tᵀ(u_s − u₀), the level-0 criterion, Coulomb's
        l̂₀, the released supports' reactions R = mask (K u_s − f + Bᵀλ))."""
        ev, model, x, others = self.ev, self.model, self.x, self.others
        static, smap = ev.model, ev.map
        T = model.elim.T
        k = len(self.crits)
        c = smap.coefficients(x, others)
        c0 = at_time_zero(c, ev.study.scene, smap.slots(x, others), smap.index)
        sol = static.solve(c0, adjoint=True)
        _, pn0, pt0, pu0, coef = self.partials(0, u_s, res0)
        TtT = sp.csc_matrix(T.T @ T)
        pu = pu0 + T @ spla.spsolve(TtT, w_hat).reshape(-1, k)
        pn = pn0 + (l_hat if l_hat is not None else 0.0)
        pt = pt0
        grad = coef.copy()
        names = released_names(ev.study.scene)
        z = static.zone
        if names:
            H = released_dofs(static, names)[:, None] * (T @ a_sum)            # ∂J/∂R on the held DOFs
            pu = pu + static.stiffness(c0) @ H
            if z is not None:
                pn = pn + z.Bn @ H
                pt = pt + z.Bt @ H
            for i, h in enumerate(data_steps(ev.study, np.asarray(x, float))):
                e = np.zeros(len(x))
                e[i] = h
                R = [static.stiffness(ci) @ u_s - static.mechanical_load(ci, static.solve_heat(ci) if static.thermal
                                                                          else None)
                     for ci in (at_time_zero(smap.coefficients(x + s * e, others), ev.study.scene,
                                             smap.slots(x + s * e, others), smap.index) for s in (1.0, -1.0))]
                grad[i] += ((R[0] - R[1]) / (2 * h)) @ H
        partials = [Partials(u=pu[:, j], lam_n=pn[:, j] if z is not None else None,
                             lam_t=pt[:, j] if z is not None else None) for j in range(k)]
        if sol.raw is not None and contact_nonsmooth(static, sol):
            for crit in self.crits:
                self.why[crit.name] = self.why[crit.name] or "the static initial state has a contact switch within reach"
        J0 = _jacobian_at_time_zero(ev, x, others)
        for j, gc in enumerate(coefficient_gradients(static, sol, partials)):
            if gc is None:
                self.why[self.crits[j].name] = self.why[self.crits[j].name] or "the static initial state's adjoint is singular"
                continue
            grad[:, j] += J0.T @ gc
        return grad


def _jacobian_at_time_zero(ev, x, others) -> np.ndarray:
    """∂c₀/∂x of the coefficients the static initial state takes (`at_time_zero`: timed loads
    at their factor of t = 0): the map's exact Jacobian, scaled where a load is timed."""
    smap = ev.map
    J = smap.jacobian(x, others)
    c = smap.coefficients(x, others)
    c0 = at_time_zero(c, ev.study.scene, smap.slots(x, others), smap.index)
    if c0 is c:
        return J
    f, f0 = flatten(c)[0], flatten(c0)[0]
    scale = np.divide(f0, f, out=np.ones_like(f), where=f != 0)
    return scale[:, None] * J
