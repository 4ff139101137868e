"""The outer iterations of the decomposition on the interface equation S0 U + S_con(U) = F
[21, (4.32)]: interface Newton (with the Coulomb fixed point over Tresca problems), the
seed's successive approximations [21, (4.37), (6.1)] with their monitoring [21, §7], and the
estimate of ρ(S0⁻¹ dS_con) that chooses between them."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from wcs.contact.laws import Coulomb, Tresca
from wcs.status import DDOutcome, Status

from .decomposition import Decomposition
from .operator import InterfaceOperator, pairs_apply
from .pair import HELD_KEPT
from .pcg import Coarse, CoarseSingular, pcg
from .team import Team
from .unit import SetupError

LOCAL_MAX_ITERATIONS = 200     # semismooth Newton steps of a pair's local contact solve


@dataclass
class Iteration:
    """What the outer iteration of one solve works with and owns: the decomposition, the
    interface operators of the linear subdomains (S0) and of the glued problem (S), the load F
    of the interface equation S0 U + S_con(U) = F [21, (4.32)], the zone rows' gaps d = gap − Bn u0,
    weights w, slip limits g and friction coefficients, the norm of the reduced load (`load`,
    a scale of Newton's residual), the DD's working options `o`, the `info` it reports into,
    the ranks' `team`, its `cache`: the last contact residual and linearisation
    (`_contact_residual`, `_linearised`), and `reference`: the size of the displacement the
    solve's is an increment of (a time level's, the local solves' certificate scale)."""
    dec: Decomposition
    S0: InterfaceOperator
    S: InterfaceOperator
    F: np.ndarray
    d: np.ndarray
    weight: np.ndarray
    slip: np.ndarray
    friction: np.ndarray
    load: float
    o: dict
    info: dict
    team: Team
    cache: dict = field(default_factory=dict)
    reference: float = 0.0

    @property
    def slip_bounds(self) -> np.ndarray:
        """The Tresca slip bounds g·w of the zone rows."""
        return self.slip * self.weight

    @property
    def first_bounds(self) -> np.ndarray | None:
        """The slip bounds of the first Tresca problem: g·w, or for Coulomb None (all stick, its
        fixed point's start)."""
        return None if self.friction.any() else self.slip_bounds

    def contact(self, p, V: np.ndarray):
        """Pair p's local contact solve with interface values V (`PairUnit.contact`) on its rows'
        gaps, weights, slip limits and friction coefficients."""
        rows = p.rows
        return p.contact(V, self.d[rows], self.weight[rows], self.slip[rows], _coulomb(self.friction, rows),
                         self.o["contact_tolerance"], LOCAL_MAX_ITERATIONS, self.reference)

    def tresca(self, p, V: np.ndarray, bound: np.ndarray | None):
        """Pair p's local Tresca solve with interface values V (`PairUnit.tresca`) on its rows'
        gaps and slip bounds `bound` (None: all stick)."""
        return p.tresca(V, self.d[p.rows], None if bound is None else bound[p.rows], self.o["contact_tolerance"],
                        LOCAL_MAX_ITERATIONS, self.reference)


def _local_solves(it: Iteration, U: np.ndarray, solve) -> tuple[np.ndarray | None, str]:
    """S_con(U) = Σ_p R_pᵀ S_p(R_p U) by the own pairs' independent local contact solves
    `solve(p, R_p U)` → (S_p(R_p U), ContactResult), summed over the ranks; on a failed local
    solve (None, the first failure's message on every rank)."""
    team, pairs = it.team, it.dec.pairs
    pieces, error = {}, None
    t = time.perf_counter()
    for p in team.local(pairs):
        tp = time.perf_counter()
        r, res = solve(p, U[p.gamma])
        team.charge(p, "contact", tp)
        if res.status != Status.SOLVED:
            error = error or f"contact solve of pair {p.index}: {res.message}"
            r = np.zeros(p.gamma.size)
        pieces[p.index] = r
    team.timings["contact"] += time.perf_counter() - t
    if team.comm is not None:
        error = team.first_error(error)
    if error:
        return None, error
    return team.sum(pairs, pieces, it.dec.nif), ""


def successive(it: Iteration, U0: np.ndarray):
    """S0 U^k = F − S_con(U^{k−1}) with monitoring (step `glued`: S U^k = F − S_con(U^{k−1}) + L U^{k−1},
    L the glued pairs' part of S); returns (status, message, U).

    The map T(U) = S0⁻¹(F − S_con(U)) is evaluated by PCG2 warm started from U (inexact:
    see `_inner_tolerance`); the fixed-point residual f = T(U) − U. Update: plain/fixed
    relaxation U ← U + ω f, Aitken's dynamic ω, or Anderson acceleration ("anderson",
    history `anderson` steps, least squares in the S0 energy inner product; the history
    is cleared when the residual grows)."""
    dec, o, info, team, F = it.dec, it.o, it.info, it.team, it.F
    S0 = it.S if o["step"] == "glued" else it.S0          # the operator each step inverts
    pairs = dec.pairs
    tol, budget, patience = o["tolerance"], o["max_iterations"], o["patience"]
    relax = o["relaxation"]
    mode = relax.lower() if isinstance(relax, str) else "fixed"
    aitken, anderson = mode == "aitken", mode == "anderson"
    omega = 1.0 if isinstance(relax, str) else float(relax)

    U, SU = U0.copy(), S0.apply(U0)
    hist = {"dU": [], "U": [], "q": [], "omega": [], "pcg2": [], "estimate": []}
    info["history"] = hist
    info["successive"] = 0
    info["pcg2"] = 0
    prev_step = None          # unrelaxed update r_{k−1} (Aitken)
    first = None
    Fnorm = np.linalg.norm(F)
    acc = []                  # Anderson: (f, Sf, g, Sg) of previous steps
    beta = o["mixing"]
    for k in range(1, budget + 1):
        rc, msg = _local_solves(it, U, it.contact)
        if rc is None:
            if hist["q"] and hist["q"][-1] > 1 and hist["dU"][-1] > hist["dU"][0]:     # the iterates were growing
                return DDOutcome.DIVERGED, (f"successive approximations diverged: contraction estimate q = "
                                            f"{hist['q'][-1]:.3g} ≥ 1 at step {k - 1} (they converge only "
                                            f"when they contract, q = 2β² < 1; seed [21, Cor. 7.1]), then at "
                                            f"step {k} the {msg}"), U
            return DDOutcome.LOCAL_FAILED, msg, U
        b = F - rc
        if o["step"] == "glued":     # S U^k = F − S_con(U) + L U, L = Σ_p R_pᵀ S⁰_p R_p
            b = b + team.sum(pairs, team.each("iterate", pairs, lambda p: p.apply_S(U[p.gamma])), dec.nif)
        eta = _inner_tolerance(o, hist)
        r2 = pcg(S0.apply, S0.precondition, b, U, tol=eta, max_iter=o["pcg_max_iterations"],
                 coarse=S0.coarse, reference=max(Fnorm, np.linalg.norm(b)))
        info["successive"] = k
        info["pcg2"] += r2.iterations
        hist["pcg2"].append(r2.iterations)
        step, Sstep = r2.x - U, r2.Sx - SU
        if anderson:
            n_step = float(np.sqrt(abs(step @ Sstep)))
            if acc and o["anderson_restart"] and n_step > o["anderson_restart"] * hist["dU"][-1]:
                acc = []                                    # residual grew a lot: restart the history
            gk, Sgk = U + beta * step, SU + beta * Sstep     # mixing β: damped map U + β(T(U) − U)
            if acc:
                # g = U + βf: the Anderson update U − ΔU γ + β(f − ΔF γ), ΔG = ΔU + βΔF
                dF = np.stack([step - a[0] for a in acc], axis=1)
                SdF = np.stack([Sstep - a[1] for a in acc], axis=1)
                dG = np.stack([gk - a[2] for a in acc], axis=1)
                SdG = np.stack([Sgk - a[3] for a in acc], axis=1)
                G = 0.5 * (dF.T @ SdF + SdF.T @ dF)
                G += 1e-12 * max(np.trace(G), 1e-300) * np.eye(G.shape[0])
                gamma = np.linalg.lstsq(G, SdF.T @ step, rcond=1e-12)[0]
                Unew, SUnew = gk - dG @ gamma, Sgk - SdG @ gamma
            else:
                Unew, SUnew = gk.copy(), Sgk.copy()
            acc.append((step, Sstep, gk, Sgk))
            acc = acc[-o["anderson"]:]
            hist["omega"].append(float("nan"))
            dU, SdU = Unew - U, SUnew - SU
            U, SU = Unew, SUnew
            n_dU = n_step                                   # the fixed-point residual ‖T(U) − U‖_S0
            n_U = float(np.sqrt(abs(r2.x @ r2.Sx)))
        else:
            if aitken and prev_step is not None:
                dr = step - prev_step
                den = float(dr @ dr)
                if den > 0:
                    omega = float(np.clip(-omega * (prev_step @ dr) / den, 0.02, 2.0))
            prev_step = step
            hist["omega"].append(omega)
            dU, SdU = omega * step, omega * Sstep
            U, SU = U + dU, SU + SdU
            n_dU = float(np.sqrt(abs(dU @ SdU)))
            n_U = float(np.sqrt(abs(U @ SU)))
        hist["dU"].append(n_dU)
        hist["U"].append(n_U)
        if not np.isfinite(n_dU) or not np.isfinite(n_U):
            return DDOutcome.DIVERGED, f"successive approximations diverged (non-finite iterate at step {k})", U
        q = n_dU / hist["dU"][-2] if len(hist["dU"]) > 1 and hist["dU"][-2] > 0 else np.nan
        hist["q"].append(q)
        est = q / (1 - q) * n_dU / max(n_U, 1e-300) if np.isfinite(q) and q < 1 else np.inf
        hist["estimate"].append(est)
        if n_dU <= tol * n_U:
            if anderson:                  # T(U) − U is within tolerance at the evaluated U: keep T(U)
                U, SU = r2.x, r2.Sx
            info["contraction"] = _mean_q(hist["q"])
            return DDOutcome.CONVERGED, f"converged in {k} successive approximations ({info['pcg2']} PCG2 iterations, " \
                                        f"{info['pcg1']} PCG1)", U
        if not r2.converged:
            return DDOutcome.BUDGET, f"PCG2 did not converge in {r2.iterations} iterations at step {k}", U
        first = n_dU if first is None else first
        qbar = _mean_q(hist["q"][-patience:])
        info["contraction"] = qbar
        if k > patience and n_dU >= hist["dU"][-1 - patience]:     # no net decrease in `patience` steps
            kind = DDOutcome.DIVERGED if n_dU > first else DDOutcome.STAGNATED
            return kind, (f"successive approximations {kind.value} at step {k}: contraction estimate "
                          f"q = {qbar:.3g} ≥ 1 over the last {patience} steps (‖ΔU‖/‖U‖ = {n_dU / max(n_U, 1e-300):.3g}); "
                          f"they converge only when they contract, q = 2β² < 1 (seed [21, Cor. 7.1]): try "
                          f"relaxation or larger pairs"), U
        rate = (n_dU / hist["dU"][0]) ** (1.0 / (k - 1)) if k > 1 and hist["dU"][0] > 0 else np.nan
        if np.isfinite(rate) and rate < 1 and k >= 10:       # overall rate: Aitken's q_k fluctuate
            need = np.log(tol * n_U / n_dU) / np.log(rate)
            if k + need > budget:
                return DDOutcome.STAGNATED, (f"successive approximations stagnating at step {k}: mean contraction "
                                             f"{rate:.4f} needs ~{need:.0f} more steps to reach {tol:g}, "
                                             f"beyond the budget of {budget}"), U
    return DDOutcome.BUDGET, (f"successive approximations did not reach {tol:g} in {budget} steps "
                              f"(‖ΔU‖/‖U‖ = {hist['dU'][-1] / max(hist['U'][-1], 1e-300):.3g})"), U


def _inner_tolerance(o, hist) -> float:
    """PCG2 tolerance (relative to max(‖F‖, ‖b‖)) of the next step: at least `inner_tolerance`,
    and `forcing` × the last relative increment (inexact inner solves: no point solving
    S0 U = b far below the error of the current U)."""
    eta = o["inner_tolerance"]
    if hist["dU"]:
        eta = max(eta, o["forcing"] * hist["dU"][-1] / max(hist["U"][-1], 1e-300))
    return eta


def _mean_q(qs) -> float:
    qs = [q for q in qs if np.isfinite(q) and q > 0]
    return float(np.exp(np.mean(np.log(qs)))) if qs else float("nan")


# ---- interface Newton ---------------------------------------------------------------------------
def _contact_residual(it: Iteration, U: np.ndarray, bound: np.ndarray | None):
    """S_con(U) = Σ_p R_pᵀ S_p(R_p U) of the Tresca problems with slip bounds `bound` (None:
    all stick), and the active sets {pair index: (free, across_slip)} of every pair (gathered:
    the free rows and, in 3D, the slipping nodes' disc springs); on a failed local solve
    (None, None, message). The last evaluation is kept in `cache` ("residual"): the ρ
    estimate's at U⁰ is Newton's first, and the pairs' last local solutions (`PairUnit.result`)
    are those of the last evaluation."""
    key = (U.tobytes(), None if bound is None else np.asarray(bound).tobytes())
    if it.cache.get("residual", (None,))[0] == key:
        return it.cache["residual"][1]
    team = it.team
    rc, error = _local_solves(it, U, lambda p, V: it.tresca(p, V, bound))
    if rc is None:
        out = (None, None, error)
    else:
        free = {p.index: (p.result.free, p.across_slip()) for p in team.local(it.dec.pairs)}
        out = (rc, {i: f for part in team.allgather(free) for i, f in part.items()}, "")
    it.cache["residual"] = (key, out)
    return out


def _linearised(it: Iteration, free: dict) -> list:
    """The pairs linearised at the active sets `free` ({pair index: (free, across_slip)}); the
    last set's are kept in `cache` (with the operator J built on them, "J"), so a step whose
    active set (and, in 3D, slip springs) did not change refactors nothing."""
    dec, team, cache = it.dec, it.team, it.cache
    key = b"".join(a.tobytes() for p in dec.pairs for a in (free[p.index][0], *(free[p.index][1] or ())))
    if cache.get("key") != key:
        cache.pop("J", None)
        pairs = []
        for p in dec.pairs:
            rows, springs = free[p.index]
            t = time.perf_counter()
            pairs.append(p.linearised(rows, team.mine(p), springs))
            if team.mine(p):
                team.charge(p, "contact", t)
        cache.update(key=key, pairs=pairs)
    return cache["pairs"]


def rho_estimate(it: Iteration, U0: np.ndarray) -> tuple[float, int] | None:
    """A lower bound of ρ(S0⁻¹ dS_con) at U⁰ (dS_con: the pairs linearised at the active set of
    the local contact solves there), and the power steps it took: the Rayleigh quotient
    xᵀLx / xᵀS0x (S0⁻¹L is S0-self-adjoint, L ⪰ 0: every x gives a lower bound, power steps
    x ← S0⁻¹ L x (PCG2 to 1e-2) raise it towards ρ), from a fixed start on the pairs'
    interface DOFs (L applied to a fixed random vector: where L acts and S0 is soft; measured
    from the random vector itself, one power step on Hertz and the tunnel, 0 from there), after each of at most
    `rho_steps` steps; it stops as soon as the bound reaches `seed_rho` (the seed's step is
    then ruled out whatever more steps would give). The seed's step
    U^k = S0⁻¹(F − S_con(U^{k−1})) [21, (4.37)] contracts near the solution only if ρ < 1
    ([21, Cor. 7.1]: 2β² < 1). The contacts are the first Tresca problem's (`first_bounds`:
    interface Newton's first residual). None: a local contact solve failed."""
    dec, S0, o, team = it.dec, it.S0, it.o, it.team
    _, free, _ = _contact_residual(it, U0, it.first_bounds)
    if free is None:
        return None
    L = _linearised(it, free)
    x = pairs_apply(team, L, dec.nif, np.random.default_rng(0).standard_normal(dec.nif))   # fixed: the same ρ
    x /= max(np.linalg.norm(x), 1e-300)
    for k in range(o["rho_steps"] + 1):
        Lx = pairs_apply(team, L, dec.nif, x)
        q = float(x @ Lx) / max(float(x @ S0.apply(x)), 1e-300)
        if q >= o["seed_rho"] or k == o["rho_steps"]:
            return q, k
        r = pcg(S0.apply, S0.precondition, Lx, np.zeros(dec.nif), tol=1e-2,
                max_iter=o["pcg_max_iterations"], coarse=S0.coarse)
        x = r.x / max(np.linalg.norm(r.x), 1e-300)


def coulomb_newton(it: Iteration, U: np.ndarray):
    """Interface Newton for Tresca (slip bounds g·w); for Coulomb the fixed point over
    Tresca problems that every contact method shares (`wcs.contact.laws.Coulomb`): first all
    stick, then bounds g·w + F λn from the last pressures, until ‖Δp‖ ≤ tol ‖p‖ (p = λn / w;
    at most max_fixed_point_iterations Tresca solves, the first included). Returns (status,
    message, U); the pairs' `result` is the last Tresca problem's solve at U."""
    dec, o, info, team, weight = it.dec, it.o, it.info, it.team, it.weight
    coulomb = bool(it.friction.any())
    law = Coulomb(it.slip_bounds, it.friction, weight) if coulomb else Tresca(it.slip_bounds)
    info["newton"] = info["pcg2"] = info["successive"] = 0
    info["history"] = {"residual": [], "pcg2": [], "eta": [], "step": []}
    last = {"U": U, "solves": 0}

    def tresca(gw):       # one interface Newton, from the last U; all-infinite bounds: all stick
        status, message, last["U"] = _newton(it, last["U"], None if np.isinf(gw).all() else gw)
        last.update(status=status, message=message, solves=last["solves"] + 1)
        if status != DDOutcome.CONVERGED or not coulomb:
            return None, status == DDOutcome.CONVERGED, 0
        info["fixed_point"] = last["solves"]
        lam = {p.index: p.result.lam_n for p in team.local(dec.pairs)}
        lam_n = np.zeros(weight.size)
        for part in team.allgather(lam):
            for i, ln in part.items():
                lam_n[dec.units[i].rows] = ln
        return lam_n, True, 0

    # DD counts the first Tresca problem in max_fixed_point_iterations; the law counts those after it
    driven = law.drive(tresca, law.start(None, np.inf), o["tolerance"], o["max_fixed_point_iterations"] - 1)
    status, message, U = last["status"], last["message"], last["U"]
    if not driven.ok or not coulomb:
        return status, message, U
    if driven.settled:
        return status, f"{message}; Coulomb fixed point: {last['solves']} Tresca problems", U
    return (DDOutcome.BUDGET, f"Coulomb fixed point did not converge in {o['max_fixed_point_iterations']} "
            f"Tresca problems", U)


def _newton(it: Iteration, U: np.ndarray, bound: np.ndarray | None):
    """Newton on the interface equation S0 U + S_con(U) = F [21, (4.32)] (Tresca, bounds
    `bound`; None: all stick): J_k δ = r_k = F − S0 U_k − S_con(U_k) with
    J_k = S0 + Σ_p R_pᵀ S_p^{A_k} R_p, the pairs linearised at the active sets A_k of the
    local contact solves at U_k, by PCG with J_k's balancing Neumann–Neumann preconditioner,
    from δ = 0 to a tolerance relative to the right-hand side (Eisenstat–Walker:
    η_k = min(forcing, 0.9 (‖r_k‖/‖r_{k−1}‖)²), never below what the outer tolerance needs).
    S_con is piecewise affine (Tresca 2D): once A_k is the solution's set one step solves; in
    3D it is smooth along a slip on the disc and J_k its derivative there (`across_slip`).
    A full step can jump over the solution's piece (a node slipping one way, then the other):
    the step is halved until ‖r‖ decreases by (1 − 1e-4 t (1 − η)) (inexact Newton
    backtracking; δ is a descent direction of ‖r‖², J_k being S_con's derivative).
    Converged when ‖r_k‖ ≤ tol · max(‖F‖, ‖S0 U_k‖, ‖S_con(U_k)‖, `load`) — r_k is the global
    equilibrium residual on Γ (the units' interiors are solved exactly), `load` the norm of the
    reduced load: a scale that does not vanish where the interface does not move (an open
    contact over an unloaded body). `cache`: see `_linearised`."""
    dec, S0, S, F, o, info, team, cache = it.dec, it.S0, it.S, it.F, it.o, it.info, it.team, it.cache
    hist, tol, lin, load = info["history"], o["tolerance"], dec.linear, it.load

    def residual(U):
        rc, free, error = _contact_residual(it, U, bound)
        if rc is None:
            return None, None, None, error
        SU = S0.apply(U)
        ref = max(np.linalg.norm(F), np.linalg.norm(SU), np.linalg.norm(rc), load, 1e-300)
        return F - SU - rc, ref, free, ""

    r, ref, free, error = residual(U)
    nr_prev, eta = None, o["forcing"]
    for k in range(o["max_iterations"] + 1):
        if r is None:
            return DDOutcome.LOCAL_FAILED, error, U
        nr = float(np.linalg.norm(r))
        hist["residual"].append(nr / ref)
        if nr <= tol * ref:
            return DDOutcome.CONVERGED, (f"interface Newton converged in {info['newton']} steps ({info['pcg2']} PCG "
                                         f"iterations, {info['pcg1']} PCG1)"), U
        if k == o["max_iterations"]:
            break
        if nr_prev is not None:
            eta = min(o["forcing"], 0.9 * (nr / nr_prev) ** 2)
        eta = min(max(eta, 0.5 * tol * ref / nr), 0.5)
        nr_prev = nr
        try:
            lp = _linearised(it, free)
            if "J" not in cache:
                kept_J = dec.kept.setdefault("J", {})      # J_k's coarse projections of the data set by active set
                if cache["key"] not in kept_J:
                    Z = S.coarse.Z                 # J Z = S Z + Σ_p R_pᵀ (S_p^A − S⁰_p) R_p Z: products of the pairs
                    if "pairs_SZ" not in dec.kept:     # Σ_p R_pᵀ S⁰_p R_p Z: the glued pairs', one per data set
                        dec.kept["pairs_SZ"] = pairs_apply(team, dec.pairs, dec.nif, Z)
                    JZ = S.coarse.SZ + pairs_apply(team, lp, dec.nif, Z) - dec.kept["pairs_SZ"]
                    tc = time.perf_counter()
                    if len(kept_J) >= HELD_KEPT:
                        del kept_J[next(iter(kept_J))]      # the oldest
                    kept_J[cache["key"]] = Coarse(Z, None, SZ=JZ)
                    team.timings["coarse"] += time.perf_counter() - tc
                cache["J"] = InterfaceOperator(lp + lin, dec.nif, S.weights, dec.traces, team,
                                               coarse=kept_J[cache["key"]])
            J = cache["J"]
        except (SetupError, CoarseSingular) as exc:
            return DDOutcome.LOCAL_FAILED, f"interface Newton step {k + 1}: the linearised problem is singular: {exc}", U
        step = pcg(J.apply, J.precondition, r, np.zeros(dec.nif), tol=eta, max_iter=o["pcg_max_iterations"],
                   coarse=J.coarse)
        info["newton"] = info["successive"] = info["newton"] + 1
        info["pcg2"] += step.iterations
        hist["pcg2"].append(step.iterations)
        hist["eta"].append(eta)
        if not step.converged:
            return DDOutcome.BUDGET, f"PCG of interface Newton step {k + 1} did not converge in {step.iterations} iterations", U
        t = 1.0
        while True:
            r, ref, free, error = residual(U + t * step.x)
            if r is None or np.linalg.norm(r) <= (1 - 1e-4 * t * (1 - eta)) * nr:
                break
            t /= 2
            if t < 2.0 ** -30:
                return DDOutcome.STAGNATED, (f"interface Newton stagnated at step {k + 1}: no step along the Newton "
                                             f"direction decreases the residual {nr / ref:.3g}"), U
        hist["step"].append(t)
        U = U + t * step.x
    return DDOutcome.BUDGET, (f"interface Newton did not reach {tol:g} in {o['max_iterations']} steps "
                              f"(residual {hist['residual'][-1]:.3g})"), U


def _coulomb(F: np.ndarray, rows: np.ndarray) -> np.ndarray | None:
    """The friction coefficients of the zone rows `rows` for a local contact solve: None where
    none is positive (Tresca)."""
    Fr = F[rows]
    return Fr if Fr.any() else None
