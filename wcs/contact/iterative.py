r"""Contact by a primal–dual active set on the primal unknowns, with Krylov solves on PETSc.

The same discrete problem as `wcs.contact.solver.solve_contact` (read its docstring for the
signs): K u + Bnᵀλn + Btᵀλt = f, Bn u ≤ d ⊥ λn ≥ 0, and λt = Π(λt + c Bt u) on the friction
discs |λt,i| ≤ g_i w_i — but the Delassus operator W = C K⁻¹ Cᵀ is never formed.

Newton step. With z = λ + c ⊙ (C u − [d; 0]) the active-set prediction of the semismooth
Newton method (Hüeber, Stadler, Wohlmuth, SIAM J. Sci. Comput. 30 (2008)) is: a normal row with
z_n > 0 is closed (C_i u = d_i), a tangent with |z_t| ≤ gw sticks (C_i u = 0), others are open
(λn = 0) or slip. In 2D a slipping tangent carries the known force λt = gw sign z; on a disc
(3D) λt = Π(z) = gw ν, ν = z/|z|, is linearised with the Jacobian D = γ(I − ννᵀ), γ = gw/|z|,
of the projection: λt − D(λt + c r_t) = Π(z) gives λt = gw ν + c γ/(1 − γ) ττᵀ r_t (τ ⊥ ν in the
tangent plane, r_t = Bt u), a spring across the slip. D is symmetric, so the Newton matrix
K + Σ Btᵀ (cγ/(1 − γ) ττᵀ) Bt is symmetric positive definite and every step is solved by CG.

Elimination of the closed and stuck rows (the seed's dual basis, [101] (24)–(25)): each row's
slave part touches one slave node only (node-to-node rows: coefficient ±1 on both nodes of the
pair; dual mortar rows: 1 on the slave node in the row's direction, −D⁻¹M on master nodes),
so the unknowns that only the rows of one contact node touch (its *own* unknowns) hold an
invertible block of its active rows. One pivot per active row is chosen among them (QR with
column pivoting), and with P the pivots, O the rest, C_A u = b_A gives
u_P = C_AP⁻¹(b_A − C_AO u_O) with C_AP block diagonal (one block per node): u = Z u_O + u_b,
Z = [−C_AP⁻¹ C_AO; I]. The step solves Zᵀ K Z u_O = Zᵀ(f − K u_b) by CG preconditioned by
GAMG with the rigid-body near-nullspace restricted to O (the rows of C vanish on a rigid
motion common to both sides), or by BDDC of the step's subdomain matrices (`wcs.contact.bddc`,
`solver.iterative.preconditioner`). The multipliers of the active rows are the residual on the
pivots, λ_A = C_AP⁻ᵀ (f − K u)_P. Active rows of one node that are linearly dependent on its
other active rows (a tangent parallel to the normal: rollers on both sides of the node) carry
no multiplier of their own (λ = 0 there, the constraint holds through the others); rows that
act on nothing (supports on both sides) are never active (λ = 0). An active row without an
own unknown that is not such a combination cannot be eliminated here: status OTHER_FAILURE,
never a wrong number.

Floating bodies (rigid modes R, K R = 0). Where the closed and stuck rows and the disc springs
leave rigid motions N = Rβ free (C_A N = 0, `_free_modes`), Zᵀ K Z is singular with the null
space N_O, and the step is taken in its complement: the right-hand side's part along N (the
load on the free motions that the step's slip forces do not balance; zero at an answer, where
`solvability.unbalanced` has found the load balanced) is projected out, the least-squares
step, as the condensed Newton's singular systems are solved; the projected system is solved
with springs A_jj on r unknowns j where N is regular (pivoted QR), an exact generalized
inverse for a consistent right-hand side (the argument of `wcs.contact.solver`'s K⁺: the
springs carry Nᵀb = 0); and the free motions keep the amplitude of the iterate the step
starts from (the step vanishes on those unknowns). An answer whose rows leave a motion free is
not unique (NOT_UNIQUE, `free_rigid_motion`).

Inexact Newton: each step's CG is driven to the Eisenstat–Walker forcing term η_k =
0.9 (φ_k / φ_{k−1})² (choice 2, safeguarded to [rtol, 1e-4]; at 1e-2 a loose step
mispredicted the stick/slip split of a Tresca pad and the active set cycled), φ the complementarity residual
‖λ − Π_B(z)‖; an answer is accepted only from a step solved to the final `rtol`. Such a step
solves for its correction from the iterate, Zᵀ K Z δ = r, r = Zᵀ(f − K u_b) − Zᵀ K Z u_O (u_O
the iterate's own unknowns), to rtol of ‖r‖ (never below `MIN_TOLERANCE` of the whole
right-hand side: rounding noise); solved for u itself its error was rtol·‖u‖ however small the
change, and the Coulomb fixed point over Tresca answers stalled at that noise (‖Δp‖ = 4e-8 to
1e-7 of ‖p‖ on a 3D Coulomb shear patch at the default tolerances 1e-8, never reaching its
own 1e-8). Loose steps, and steps that leave rigid motions free, are solved whole (from the
iterate, the floating Tresca pad started all open took another path and ended at an answer
with no stuck node, NOT_UNIQUE). A step
with nodes slipping on discs, and in 2D every step after a pattern met again at full
accuracy (a cycle of full steps) and every step on a floating body, is shortened until ‖Φ‖²
decreases (Armijo, as the condensed Newton does); the 2D steps so shortened are solved to
`rtol` (a loose step is no descent direction of ‖Φ‖²). On the 2D knee's floating femur,
held sideways by the 2 of its 140 contact nodes that stick, full loose steps slid it sideways
and wandered over ever new patterns (the Coulomb fixed point's second Tresca problem: 100
steps, none repeated); loose steps shortened did not decrease ‖Φ‖².

Over 500 lines for one method: the Krylov active-set solve and its adjoint (`IterativeAdjoint`),
which reuses the method's rows (`_Rows`), its PETSc operator and its CG.
"""
from __future__ import annotations

import dataclasses
import functools
import time
import weakref

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from wcs.choose import BDDC_SETUP_RATIO, PreconditionerFacts
from wcs.choose import preconditioner as choose_preconditioner
from wcs.contact.bddc import REBUILD_ITERATIONS, SetupFailure, model_parts, parts_of
from wcs.contact.distributed import Layout, RowBlocks
from wcs.contact.laws import law_of
from wcs.contact.methods import Primal, Solved, settings
from wcs.contact.solvability import unbalanced
from wcs.contact.solver import (ARMIJO, MIN_STEP, ContactResult, _across_slip, _first_free_set, _states,
                                conditions_violated, disc_scales, free_rigid_motion, pinned_dofs, project)
from wcs.errors import StudyError
from wcs.fem.rigid import rigid_modes
from wcs.group import evaluation_comm, share, together
from wcs import linalg
from wcs.options import MIN_TOLERANCE
from wcs.status import Status

ETA_MAX = 1e-4       # loosest forcing term of the inexact Newton
NULL = 1e-10         # a contact row with ‖C_i‖ ≤ NULL max‖C_j‖ acts on round-off only
BALANCE = 1e-6       # relative residual of a floating body's equilibrium above which an adjoint is refused
DEPENDENT = 1e-8     # relative singular value below which a node's active rows are dependent
COUPLED = 10.0       # GMRES over Coulomb-coupled adjoint rows to this times the CG tolerance: its products are
                     # CG solves, exact to that tolerance only (measured floor 1.5e-12 at CG's 1e-12, a Coulomb pad)


def solve_contact_iterative(K, f, Bn, Bt, d, w, g=None, F=None, R=None, *, tol=1e-10, max_iter=100,
                            warm: ContactResult | None = None, near_nullspace=None, rtol=1e-12,
                            tol_fp=1e-8, max_fp_iter=50, reference=0.0, krylov: "Krylov | None" = None) -> ContactResult:
    """Tresca (g) or Coulomb (F) contact by the primal active set with CG + GAMG (module docstring).

    Arguments and result as `solve_contact` (no factor: `factor` is None). near_nullspace:
    (n, r) rigid-body modes of K's unknowns for GAMG (6 in 3D, 3 in 2D); rtol: relative
    residual of the final Krylov solves. `iterations` counts Newton steps, `krylov_iterations`
    their CG iterations in total and `krylov_steps` those of each step (one per Newton step). Floating bodies (R): the load's balance is checked as in
    `solve_contact` (UNSOLVABLE; Coulomb: where the fixed point fails, at the last pressures);
    a Newton step whose closed and stuck rows leave rigid modes free is taken in their
    complement (module docstring), and an answer that leaves one free is NOT_UNIQUE, as in
    `solve_contact`. An active row with no unknown of its own ends the solve with status
    OTHER_FAILURE (module docstring). krylov: the `Krylov` to solve the steps with (the caller
    frees it; None: one of this solve's own).
    Coulomb: the fixed point over Tresca bounds g w + F λn of `solve_contact`, from the glued
    (all-stick) solution or the warm pressures."""
    t0 = time.perf_counter()
    m = Bn.shape[0]
    k = Bt.shape[0] // m if m else 1
    f, d, w = (np.asarray(a, dtype=float) for a in (f, d, w))
    C = sp.vstack([Bn, Bt]).tocsr()
    K = sp.csr_matrix(K, dtype=float)
    Fc = np.zeros(m) if F is None else np.asarray(F, dtype=float)
    coulomb = bool(np.any(Fc > 0))
    law = law_of(w, g, Fc if coulomb else None)
    gw = law.start(warm.lam_n if warm is not None and warm.lam_n is not None else None, np.inf)
    R = None if R is None or not np.asarray(R).size else np.asarray(R, dtype=float).reshape(len(f), -1)
    timings = {}
    if R is not None and not coulomb:
        found = unbalanced(f, Bn, Bt, gw, R)
        if found is not None:
            value, alpha = found
            return ContactResult(None, None, None, Status.UNSOLVABLE,
                                 f"unbalanced load on a floating body: fᵀv − j(v) = {value:.3e} > 0 "
                                 f"for the admissible rigid motion v = Rα, α = {np.array2string(alpha, precision=4)}",
                                 alpha=alpha)
        timings["solvability"] = time.perf_counter() - t0
    t = time.perf_counter()
    rows = _Rows(C, m, k)
    timings["rows"] = time.perf_counter() - t
    step = _Stepper(K, f, C, np.r_[d, np.zeros(k * m)], rows, near_nullspace, R, krylov)
    c = _scales(K, C, m, k)
    lam = np.zeros((1 + k) * m) if warm is None or warm.lam_n is None else np.r_[warm.lam_n, warm.lam_t]
    # a warm start takes the warm answer's displacement with its multipliers: from u = 0, z = λ + c (C u − b)
    # put every slipping node on the rim of its disc (|z_t| = gw), where the linearised projection's spring
    # across the slip degenerates; CG then failed (2000 iterations) on the first step of the 3D tunnel
    u_start = warm.u if warm is not None and warm.u is not None and len(warm.u) == len(f) else np.zeros(len(f))
    state = {"u": np.array(u_start, dtype=float), "lam": lam, "free0": _first_free_set(warm, gw, k),
             "eta": ETA_MAX if warm is None else rtol}

    def tresca(bounds):     # one Tresca problem from the last answer (the law drives them: `wcs.contact.laws`)
        state["u"], state["lam"], state["free"], n, ok = _newton(
            step, c, state["u"], state["lam"], state["free0"], bounds, m, k, tol, max_iter, rtol, state["eta"])
        state["free0"], state["eta"] = None, ETA_MAX
        return state["lam"][:m], ok, n

    try:
        driven = law.drive(tresca, gw, tol_fp, max_fp_iter)
    finally:                # on every rank of a group alike, failed or not (PETSc's destroy is collective)
        if krylov is None:  # a caller's `Krylov` is the caller's to free
            step.krylov_solver.close()
    u, lam, free, gw = state["u"], state["lam"], state["free"], driven.gw
    iters, fp_iters, ok, fp_ok = driven.iterations, driven.fixed_point_iterations, driven.ok, driven.settled
    status, message = Status.SOLVED, "converged"
    violation = conditions_violated(u, Bn @ u - d, lam[:m], lam[m:], gw, k, tol, reference) if ok else ""
    beta = _left_free(C, R, C @ u - step.b, lam, free, m, k, tol) if ok and R is not None else None
    found = unbalanced(f, Bn, Bt, np.where(np.isfinite(gw), gw, 0.0), R) if not ok and coulomb and R is not None \
        else None
    if found is not None:       # friction F p may be too weak to hold a floating body (as `solve_contact`)
        status, message = Status.UNSOLVABLE, (
            f"unbalanced load on a floating body held by Coulomb friction: fᵀv − j(v) = {found[0]:.3e} > 0 at the "
            f"last pressures, α = {np.array2string(found[1], precision=4)}")
    elif beta is not None:
        status, message = Status.NOT_UNIQUE, (
            f"the solution is not unique: the rigid motion v = Rβ, β = {np.array2string(beta, precision=4)}, moves "
            "no closed or stuck contact node")
    elif violation:
        status, message = Status.CONTACT_NOT_CONVERGED, (
            f"iterative active set stopped at an answer that violates {violation}: not reported")
    elif step.unsupported:
        status, message = Status.OTHER_FAILURE, f"iterative method: {step.failure}"
    elif not ok:
        status, message = Status.CONTACT_NOT_CONVERGED, (
            f"iterative active set did not converge in {iters} Newton steps: {step.failure}" if step.failure else
            f"iterative active set did not converge ({iters} Newton steps: an active set cycled or the budget "
            f"of {max_iter} ran out)")
    elif not fp_ok:
        status, message = Status.FIXED_POINT_NOT_CONVERGED, f"Coulomb fixed point did not converge in {max_fp_iter} iterations"
    timings.update(**step.timings, **step.krylov_solver.timings, total=time.perf_counter() - t0)
    return ContactResult(u if status == Status.SOLVED else None, lam[:m], lam[m:], status, message, iters, fp_iters,
                         _states(free, m, gw), None, beta if beta is not None else found[1] if found else None,
                         timings, free=free, gw=gw, krylov_iterations=step.krylov,
                         krylov_steps=tuple(step.krylov_steps))


def _left_free(C, R, r, lam, free, m, k, tol):
    """The rigid motion β that an answer leaves free (`wcs.contact.solver.free_rigid_motion`: the
    closed, touching and stuck rows and, on discs, the rows across the slip hold none of it), or
    None; r = C u − [d; 0]."""
    G = (C @ R).T
    touching = np.abs(r[:m]) <= tol * max(np.abs(r).max(initial=0.0), 1e-300)
    held = free | np.r_[touching, np.zeros(k * m, bool)]
    return free_rigid_motion(np.c_[G, _across_slip(G, lam[m:], free, k)], np.r_[held, np.ones(m * (k > 1), bool)])


def _acting(C: sp.csr_matrix) -> np.ndarray:
    """The rows of C that act: ‖C_i‖ > NULL max‖C_j‖ (the others act on round-off only)."""
    norms = np.sqrt(np.asarray(C.multiply(C).sum(axis=1)).ravel())
    return norms > NULL * max(norms.max(initial=0.0), 1e-300)


def _scales(K, C, m, k):
    """c ≈ 1 / diag(W) without W (`wcs.contact.solver.disc_scales` over the rows that act,
    `_acting`), with the estimate w_i = Σ_j C_ij² / K_jj of W_ii; with c = 1/0 taken as 0 a
    tangent held by supports predicted its stick/slip from λ alone and cycled."""
    return disc_scales(C.multiply(C) @ (1.0 / K.diagonal()), _acting(C), k)


def _newton(step, c, u, lam, free0, gw, m, k, tol, max_iter, rtol, eta0=ETA_MAX):
    """The semismooth Newton iteration of the module docstring: (u, λ, free, steps, converged).

    (u, λ): the start; free0: the free set (closed normals, stuck tangents) of the first step
    (None: predicted from (u, λ)), solved to the forcing term eta0 (a warm set, usually the
    answer's: to `rtol`, so that it can end Newton at once). Stops when the answer of a step
    solved to `rtol` satisfies ‖λ − Π_B(z)‖∞ ≤ tol · max(max|λ|, force scale) and λ ∈ B to tol max|λ|; a 2D
    pattern met again at full accuracy is a cycle of full steps, and the steps from it on are
    shortened (`_step_length`). The force scale is max |Π_B(z)|:
    an open gap (z_n < 0) carries none (as `wcs.contact.solver._newton`)."""
    lo = np.r_[np.zeros(m), -np.tile(gw, k)]
    hi = np.r_[np.full(m, np.inf), np.tile(gw, k)]
    carried = hi > lo

    def merit(u, lam):
        phi = lam - project(lam + c * (step.C @ u - step.b), lo, hi, k)
        return phi @ phi
    seen, tight, eta, phi_old, damped = set(), set(), ETA_MAX, None, k == 1 and step.R is not None
    for it in range(max_iter + 1):
        z = lam + c * (step.C @ u - step.b)
        phi = lam - project(z, lo, hi, k)
        size = np.abs(phi).max(initial=0.0)
        if it > 0 or free0 is None:
            scale = max(np.abs(lam).max(initial=0.0), np.abs(np.clip(z, lo, hi))[carried].max(initial=0.0), 1e-300)
            in_b = np.abs(lam - project(lam, lo, hi, k)).max(initial=0.0) <= tol * np.abs(lam).max(initial=0.0)
            if it > 0 and eta <= rtol and size <= tol * scale and in_b:
                return u, lam, _by_node(_free(z, lo, hi, k, step.rows), m, k), it, True
            ratio = size / phi_old if phi_old else 1.0
            eta = rtol if phi_old is None or size <= tol * scale else min(ETA_MAX, max(rtol, 0.9 * min(ratio, 1.0) ** 2))
            phi_old = size
            free = _free(z, lo, hi, k, step.rows)
        else:
            free, eta = free0 & step.rows.acting, eta0
        # the pattern: the free set and the sign of each slip force (a stuck or frictionless tangent has none)
        slip = np.where(free[m:] | ~carried[m:], 0, np.sign(z[m:]))
        key = (free.tobytes(), slip.astype(np.int8).tobytes() if k == 1 else b"")
        if it == max_iter:
            break
        damped = damped or (k == 1 and key in tight)     # full steps cycled: shortened from here on
        if damped:               # a shortened step is the exact one: a loose step is no descent direction
            eta = rtol
        if key in seen:          # a pattern met again: solve it exactly (a loose step may have mispredicted)
            eta = rtol
        seen.add(key)
        if eta <= rtol:
            tight.add(key)
        try:
            u1, lam1 = step.solve(free, z, gw, c, k, eta, u, rtol)
        except _KrylovFailure as exc:
            step.failure = str(exc)
            break
        except _Unsupported as exc:
            step.failure, step.unsupported = str(exc), True
            break
        discs = k > 1 and np.any(~_stuck(free, m, k) & (gw > 0) & step.rows.disc)
        if (discs or damped) and (it > 0 or free0 is None):
            u, lam = _step_length(merit, u, lam, u1, lam1, phi @ phi)
        else:
            u, lam = u1, lam1
    return u, lam, _by_node(_free(lam + c * (step.C @ u - step.b), lo, hi, k, step.rows), m, k), it, False


def _step_length(merit, u, lam, u1, lam1, theta):
    """The step (u, λ) → (u1, λ1) shortened by halving until the merit θ = ‖Φ‖² decreases by
    Armijo's rule θ(t) ≤ (1 − 2 ARMIJO t) θ(0); the full step where none down to MIN_STEP does
    (the globalization of `wcs.contact.solver._step_length`, whose full steps on discs cycled
    with period 2 on a 3D tunnel). Both ends are in equilibrium
    (K u + Cᵀλ = f is linear), so only the complementarity is measured."""
    t = 1.0
    while t > MIN_STEP:
        ut, lt = u + t * (u1 - u), lam + t * (lam1 - lam)
        if merit(ut, lt) <= (1.0 - 2.0 * ARMIJO * t) * theta:
            return ut, lt
        t *= 0.5
    return u1, lam1


def _stuck(free, m, k):
    """Nodes whose tangents stick (any of their acting tangent rows in the free set)."""
    return free[m:].reshape(k, m).any(axis=0)


def _by_node(free, m, k):
    """The free set with every tangent row of a stuck node in it (a tangent held by supports
    too), as `solve_contact` reports it: `_states` reads a node's state from its first tangent."""
    return np.r_[free[:m], np.tile(_stuck(free, m, k), k)]


def _free(z, lo, hi, k, rows):
    """Closed normals and stuck tangents predicted from z (tangents with gw > 0 only), on rows that act."""
    m = len(z) // (1 + k)
    closed = z[:m] > 0
    stick = (np.linalg.norm(z[m:].reshape(k, m), axis=0) <= hi[m:m + m]) & (hi[m:m + m] > 0)
    return np.r_[closed, np.tile(stick, k)] & rows.acting


class _KrylovFailure(Exception):
    """A Krylov solve that did not reach its tolerance."""


class _Unsupported(Exception):
    """A step this method cannot take (yet): an active row with no unknown of its own to
    eliminate."""


class _Rows:
    """The contact rows grouped by node, with the unknowns each node has to itself."""

    def __init__(self, C: sp.csr_matrix, m: int, k: int):
        self.m, self.k = m, k
        self.acting = _acting(C)
        self.disc = self.acting[m:].reshape(k, m).any(axis=0)     # nodes with a tangent that acts
        Cc = C.tocoo()
        node = Cc.row % m if m else Cc.row
        n = C.shape[1]
        lo = np.full(n, m)
        hi = np.full(n, -1)
        np.minimum.at(lo, Cc.col, node)
        np.maximum.at(hi, Cc.col, node)
        own = (lo == hi)[Cc.col] & (Cc.data != 0)
        on, oc = node[own].astype(np.int64), Cc.col[own].astype(np.int64)
        pairs = np.unique(on * n + oc)                   # (node, own unknown), by node then unknown
        start = np.searchsorted(pairs // n, np.arange(m + 1))
        self.own = np.split(pairs % n, start[1:-1]) if m else []
        # B[i]: C on node i's rows (1 + k) and own unknowns, dense, padded to the widest node
        self.B = np.zeros((m, 1 + k, int(np.diff(start).max(initial=0))))
        np.add.at(self.B, (on, Cc.row[own] // m, np.searchsorted(pairs, on * n + oc) - start[on]), Cc.data[own])
        self.C = C
        self._pivots = {}

    def node_rows(self, i):
        return i + self.m * np.arange(1 + self.k)

    def pivots(self, i, active):
        """(rows, pivots, block⁻¹): the node's independent active rows, one own unknown each,
        and the inverse of C on them; rows dependent on the others are left out. _Unsupported
        where an active row is neither."""
        key = (i, active.tobytes())
        if key not in self._pivots:
            rows = self.node_rows(i)[active]
            own = self.own[i]
            B = self.B[i][active][:, :len(own)]
            if len(rows) == 1 and len(own) and B.any():     # one row (frictionless): the QRs below pick
                j = int(np.argmax(np.abs(B[0])))            # its largest entry, the first of equals
                self._pivots[key] = (rows, own[[j]], np.array([[1.0 / B[0, j]]]))
                return self._pivots[key]
            _, r, piv = sla.qr(B.T, mode="economic", pivoting=True) if len(own) else (None, np.zeros((0, 0)), [])
            diag = np.abs(np.diag(r)) if len(own) else np.zeros(0)
            rank = int(np.sum(diag > DEPENDENT * max(diag.max(initial=0.0), 1e-300)))
            keep = np.sort(np.asarray(piv[:rank], dtype=int))
            for j in np.setdiff1d(np.arange(len(rows)), keep):
                self._check_dependent(rows[keep], rows[j], i)
            chosen = np.sort(sla.qr(B[keep], mode="economic", pivoting=True)[2][:len(keep)]) if len(keep) else keep
            cols, block = own[chosen], B[keep][:, chosen]
            self._pivots[key] = (rows[keep], cols, np.linalg.inv(block))
        return self._pivots[key]

    def share_out(self, nodes, free):
        """Spanning a group of ranks (`wcs.group`): the pivots of the `nodes` not met before, each
        rank computing its share and the group gathering them (each node's alone: the same bits
        on every layout); a node with an unsupported row raises as the loop over the nodes in
        order (`_pivots`) would meet it first. Alone: nothing (`pivots` computes them on demand)."""
        comm = evaluation_comm()
        if comm is None:
            return
        asked = ((i, free[self.node_rows(i)]) for i in nodes)
        new = [(i, active) for i, active in asked if (i, active.tobytes()) not in self._pivots]
        lo, hi = share(len(new))

        def mine():
            out = []
            for i, active in new[lo:hi]:
                try:
                    out.append((i, active.tobytes(), self.pivots(i, active), ""))
                except _Unsupported as exc:
                    out.append((i, active.tobytes(), None, str(exc)))
            return out
        failed = []
        for part in comm.allgather(together(mine)):
            for i, key, value, error in part:
                if error:
                    failed.append((i, error))
                else:
                    self._pivots[(i, key)] = value
        if failed:
            raise _Unsupported(min(failed)[1])

    def _check_dependent(self, rows, row, i):
        """row is a combination of rows on all unknowns (not only on the node's own), else _Unsupported."""
        A = self.C[rows].toarray().T
        b = self.C[row].toarray().ravel()
        x = np.linalg.lstsq(A, b, rcond=None)[0] if len(rows) else np.zeros(0)
        if np.linalg.norm(A @ x - b) > 1e-8 * np.linalg.norm(b):
            raise _Unsupported(f"contact row {row} (node {i}) has no unknown of its own to eliminate (its slave "
                               "side is held by supports or shared with another contact node): not supported by the "
                               "iterative method")


class _Stepper:
    """One Newton step: eliminate the free (closed, stuck) rows, CG + GAMG on the rest."""

    def __init__(self, K, f, C, b, rows: _Rows, near_nullspace, R=None, krylov=None):
        self.K, self.f, self.C, self.b, self.rows, self.R = K, f, C, b, rows, R
        self.failure, self.unsupported = "", False
        self.timings = {"eliminate": 0.0}       # seconds: pivots and Z of the steps (Zᵀ Kt Z: Krylov's "matrix")
        self.n = K.shape[0]
        N = None if near_nullspace is None else np.asarray(near_nullspace, dtype=float).reshape(self.n, -1)
        self.krylov_solver = Krylov(N) if krylov is None else krylov
        self.krylov = 0
        self.krylov_steps = []      # CG iterations of each step (a rebuilt preconditioner's solve included)

    def solve(self, free, z, gw, c, k, eta, u_old, rtol):
        """(u, λ) of the step with the free set `free` (the slip data from z), from the iterate u_old
        (`_free_modes`: where the step leaves a floating body's rigid motion free, it keeps
        u_old's)."""
        t0 = time.perf_counter()
        n = self.n
        C, K = self.C, self.K
        rows, P, Binv = _pivots(self.rows, free, k)
        lam0, Kt = self._slip(free, z, gw, c, k)
        N = None
        if self.R is not None:      # the rigid modes the closed and stuck rows and the disc springs leave free
            held = C[rows] if self._springs is None else sp.vstack([C[rows], self._springs[3]])
            N = self.R @ _free_modes(held @ self.R)
            N[P] = 0.0              # on the unknowns O (C_A N = 0: Z N_O = N)
        Z, ub = _basis(C, rows, P, Binv, self.b[rows])
        rhs0 = self.f - C.T @ lam0
        blocks = self.krylov_solver.blocks      # the operator at its nodes' places (`NodeBlocks`), or as it is
        places = n if blocks is None else blocks.size
        A = RowBlocks(places, lambda lo, hi: _eliminated(Z, Kt, K, P, lo, hi, blocks))    # each rank builds its rows
        b = Z.T @ (rhs0 - Kt @ ub)
        pin = np.zeros(0, dtype=int)
        if N is not None and N.shape[1]:       # A N = 0: the step in the complement of the free modes
            b = b - N @ np.linalg.lstsq(N, b, rcond=None)[0]
            pin = pinned_dofs(N)
            A = RowBlocks(places, _pinned(A.rows, pin if blocks is None else blocks.home[pin]))
        # a step to the final tolerance solves for its correction from u_old's own unknowns (u_O = v_O, module
        # docstring); a loose one, or one that leaves rigid motions free, is solved whole (from v = 0)
        v = np.array(u_old, dtype=float) if eta <= rtol and not len(pin) else np.zeros(n)
        v[P] = 0.0
        r = b - Z.T @ (Kt @ (Z @ v))        # A v: Zᵀ Kt Z v (v vanishes where A adds diagonals)
        size = np.linalg.norm(r)
        tol = max(eta, MIN_TOLERANCE * np.linalg.norm(b) / size) if size > 0 else 1.0
        self.timings["eliminate"] += time.perf_counter() - t0
        springs = None if self._springs is None else (self._springs[3], self._springs[2])
        dv, its, ok = (self.krylov_solver.solve(A, r if blocks is None else blocks.embed(r), tol, (Z, P, springs, pin))
                       if tol < 1.0 else (np.zeros(places), 0, True))
        dv = dv if blocks is None else dv[blocks.home]
        v = v + dv
        if k == 1 and np.array_equal(free, self.rows.acting):    # glued 2D step: not kept (`Krylov`)
            self.krylov_solver.expire()
        self.krylov += its
        self.krylov_steps.append(its)
        if not ok:
            raise _KrylovFailure(self.krylov_solver.failure
                                 or f"CG did not reach the relative residual {tol:.1e} in {its} iterations")
        if len(pin):                # the free modes' amplitude kept: u − u_old vanishes on the pinned unknowns
            v = v + N @ np.linalg.solve(N[pin], u_old[pin] - v[pin])
        u = Z @ v + ub
        lam = lam0 + self._spring_force(u)
        res = rhs0 - Kt @ u
        lam[rows] = Binv.T @ res[P]
        return u, lam

    def _slip(self, free, z, gw, c, k):
        """The slipping tangents' known forces λ0 (2D: gw sign z; disc: gw ν) and K plus the disc
        springs Btᵀ (cγ/(1 − γ) ττᵀ) Bt of the module docstring."""
        m = self.rows.m
        lam0 = np.zeros((1 + k) * m)
        self._springs = None
        t = z[m:].reshape(k, m) * self.rows.acting[m:].reshape(k, m)    # a tangent held by supports: no force
        norm = np.linalg.norm(t, axis=0)
        slip = ~_stuck(free, m, k) & (gw > 0) & self.rows.disc & (norm > 0)
        nu = np.divide(t, norm, out=np.zeros_like(t), where=slip)
        lam0[m:] = (np.where(slip, gw, 0.0) * nu).ravel()
        if k == 1:
            return lam0, self.K
        gamma = np.divide(gw, norm, out=np.zeros_like(norm), where=slip)
        nodes = np.flatnonzero(slip & (gamma < 1))
        if not nodes.size:          # no spring: K itself (K + 0 was a copy of K beside it, each step)
            return lam0, self.K
        tau = np.stack([-nu[1, nodes], nu[0, nodes]])
        s = c[m + nodes] * gamma[nodes] / (1 - gamma[nodes])
        # ττᵀ r_t = τ (τ · Bt u): one row per slipping node, Q = Σ_j τ_j Bt_j
        Q = sp.diags(tau[0]) @ self.C[m + nodes] + sp.diags(tau[1]) @ self.C[2 * m + nodes]
        self._springs = (nodes, tau, s, Q.tocsr())
        return lam0, (self.K + Q.T @ sp.diags(s) @ Q).tocsr()

    def _spring_force(self, u):
        """The disc springs' part cγ/(1 − γ) τ (τ · Bt u) of λt (zero without discs)."""
        m = self.rows.m
        out = np.zeros(len(self.b))
        if self._springs is None:
            return out
        nodes, tau, s, Q = self._springs
        a = s * (Q @ u)
        out[m + nodes] = a * tau[0]
        out[2 * m + nodes] = a * tau[1]
        return out


def _free_modes(G: np.ndarray) -> np.ndarray:
    """β (r, q) spanning the rigid motions Rβ that the rows H of G = C_H R leave free: G's null
    space, columns scaled to unit norm, singular values below 1e-8 of the largest counted as
    zero (`wcs.contact.solver.free_rigid_motion`'s rule)."""
    r = G.shape[1]
    scale = np.maximum(np.linalg.norm(G, axis=0), 1e-300)
    if not G.shape[0]:
        return np.eye(r)
    _, sv, vt = np.linalg.svd(G / scale, full_matrices=G.shape[0] < r)
    rank = int(np.sum(sv > 1e-8 * sv[0])) if sv.size and sv[0] > 0 else 0
    return (vt[rank:] / scale).T


def _pinned(rows, pin):
    """The rows lo:hi of A + diag(A_pp) on the pinned unknowns p (springs as stiff as A there,
    `wcs.contact.solver.pinned_dofs`), from `rows` of A."""
    def pinned(lo, hi):
        block = rows(lo, hi).tocsr()
        local = pin[(pin >= lo) & (pin < hi)]
        if not len(local):
            return block
        diag = np.asarray(block[local - lo, local]).ravel()
        return (block + sp.csr_matrix((diag, (local - lo, local)), shape=block.shape)).tocsr()
    return pinned


def _pivots(rows: _Rows, free, k):
    """(rows, pivots P, C_AP⁻¹) of the free rows (`_Rows.pivots`, node by node; spanning a group
    of ranks, shared out over them first: `_Rows.share_out`)."""
    m = rows.m
    out, piv, blocks = [], [], []
    nodes = np.flatnonzero(free.reshape(1 + k, m).any(axis=0))
    rows.share_out(nodes, free)
    for i in nodes:
        r, p, inv = rows.pivots(i, free[rows.node_rows(i)])
        out.append(r)
        piv.append(p)
        blocks.append(inv)
    out = np.concatenate(out) if out else np.zeros(0, dtype=int)
    P = np.concatenate(piv) if piv else np.zeros(0, dtype=int)
    return out, P, _block_diagonal(blocks)


def _basis(C, rows, P, Binv, b_rows):
    """(Z, u_b) with u = Z x + u_b, x_P = 0, satisfying C_rows u = b_rows (module docstring)."""
    n = C.shape[1]
    O = np.setdiff1d(np.arange(n), P)
    X = (Binv @ C[rows][:, O]).tocoo()             # u_P = Binv b_A − X u_O
    Z = sp.csr_matrix((np.r_[np.ones(len(O)), -X.data], (np.r_[O, P[X.row]], np.r_[O, O[X.col]])), shape=(n, n))
    ub = np.zeros(n)
    ub[P] = Binv @ b_rows
    return Z, ub


def _eliminated(Z, Kt, K, P, lo=0, hi=None, blocks=None):
    """Zᵀ Kt Z on the unknowns O, kept at K's size (rows P: diag K, so the solve gives x_P = 0);
    its rows lo:hi only where given (a rank's share, `wcs.contact.distributed`).

    Z is the identity on O but on its rows P (u_P = W u_O, W = Z_P, `_basis`), so with
    D = diag(1_O) and G = Kt_{:P} W (= Kt_Pᵀ W: Kt is symmetric)
        Zᵀ Kt Z = D Kt D + D G + (D G)ᵀ + Wᵀ G_P:
    Kt without its rows and columns P, plus a correction S on the rows next to the pivots. The
    rows are built that way, Kt's copied once straight into the answer: no product of K's size
    (Zᵀ Kt Z as two sparse products held three matrices of K's size at once; the same entries
    up to the order of their sums).

    blocks (`NodeBlocks`): the operator at the node blocks' size instead, its rows lo:hi there
    (the unknowns at their nodes' places, a diagonal on the rest: `NodeBlocks`)."""
    n = K.shape[0]
    plo, phi = lo, hi
    if blocks is not None:
        phi = blocks.size if hi is None else hi
        lo, hi = blocks.reduced(plo, phi)
    hi = n if hi is None else hi
    pivot = np.zeros(n, dtype=bool)
    pivot[P] = True
    W = Z[P]
    G = (Kt[P].T @ W).tocsr()
    DG = sp.diags((~pivot).astype(float)) @ G
    S = (DG + DG.T + W.T @ G[P]).tocsr()[lo:hi]
    Pr = P[(P >= lo) & (P < hi)]
    S = (S + sp.csr_matrix((K.diagonal()[Pr], (Pr - lo, Pr)), shape=(hi - lo, n))).tocsr()
    touched = np.flatnonzero(np.diff(S.indptr))
    sub = Kt[lo + touched].tocsr()
    sub.data[pivot[sub.indices] | pivot[lo + touched].repeat(np.diff(sub.indptr))] = 0.0
    T = (sub + S[touched]).tocsr()
    del S, sub
    return _spliced(Kt, lo, hi, pivot, touched, T, blocks=blocks, padded=(plo, phi))


def _spliced(Kt, lo, hi, out, touched, T, chunk=4096, blocks=None, padded=None):
    """Rows lo:hi of Kt without the rows and columns `out`, but the rows `touched` (local) those
    of T (CSR, one row each): Kt's rows copied `chunk` rows at a time into arrays allocated
    once (nothing else of Kt's size held). With `blocks` (`NodeBlocks`), the rows `padded`
    (lo, hi) of the node blocks' operator: each unknown's row and columns at its place there,
    the places of no unknown a row of the blocks' diagonal alone."""
    m, n = hi - lo, Kt.shape[1]
    T.sort_indices()
    plain = np.ones(m, dtype=bool)      # rows copied from Kt
    plain[touched] = False
    plain &= ~out[lo:hi]
    place = (lambda i: i) if blocks is None else (lambda i: blocks.home[i])

    def kept(a, b):     # Kt's entries of the local rows a:b that stay, and where they start
        seg = Kt.indptr[lo + a:lo + b + 1]
        keep = np.repeat(plain[a:b], np.diff(seg))
        keep &= ~out[Kt.indices[seg[0]:seg[-1]]]
        return slice(seg[0], seg[-1]), seg - seg[0], keep

    counts = np.zeros(m, dtype=np.int64)
    for a in range(0, m, chunk):
        b = min(a + chunk, m)
        _, seg, keep = kept(a, b)
        counts[a:b] = np.diff(np.r_[0, np.cumsum(keep)][seg])
    counts[touched] = np.diff(T.indptr)
    if blocks is None:
        rows, size, alone = m, n, np.zeros(0, dtype=np.int64)
        every = counts
    else:
        plo, phi = padded
        rows, size = phi - plo, blocks.size
        every = np.ones(rows, dtype=np.int64)          # a row of the diagonal alone, where no unknown is
        mine = blocks.home[lo:hi] - plo
        every[mine] = counts
        alone = np.setdiff1d(np.arange(rows), mine)
    indptr = np.r_[0, np.cumsum(every)]
    start = indptr[:-1] if blocks is None else indptr[mine]
    index = np.int32 if max(indptr[-1], size) < np.iinfo(np.int32).max else np.int64
    indices, data = np.empty(indptr[-1], dtype=index), np.empty(indptr[-1])
    for a in range(0, m, chunk):
        b = min(a + chunk, m)
        span, _, keep = kept(a, b)
        c = np.where(plain[a:b], counts[a:b], 0)
        at = np.arange(c.sum()) + np.repeat(start[a:b] - np.r_[0, np.cumsum(c)[:-1]], c)
        indices[at] = place(Kt.indices[span][keep])
        data[at] = Kt.data[span][keep]
    c = np.diff(T.indptr)
    at = np.arange(T.nnz) + np.repeat(start[touched] - T.indptr[:-1], c)
    indices[at] = place(T.indices)
    data[at] = T.data
    if len(alone):
        indices[indptr[alone]] = padded[0] + alone
        data[indptr[alone]] = blocks.scale
    return sp.csr_matrix((data, indices, indptr.astype(index)), shape=(rows, size))


@dataclasses.dataclass(frozen=True)
class NodeBlocks:
    """The Newton steps' unknowns at their nodes, for GAMG's aggregation by nodes (PETSc's block
    size: the graph it coarsens is then the nodes', not the unknowns' — on the 3D Hertz at a/24,
    9.5e4 unknowns, its set-up's peak 70 MB above the operator instead of 230, in 2.3 s instead
    of 3.1). Unknown i of the model's reduced system is the displacement component home[i] of
    the mesh (node-major: d components a node), home strictly increasing (`node_blocks`); the
    operator is solved at the mesh's size d·nodes, each component no unknown has a row of the
    diagonal `scale` alone, its right-hand side 0: CG and the V-cycle leave it 0 (no entry
    couples it; its near-nullspace rows are 0, so no coarse level sees it), and the unknowns'
    iterates are those of the same preconditioner on the reduced operator."""
    home: np.ndarray
    size: int
    dim: int
    scale: float

    def reduced(self, lo: int, hi: int) -> tuple[int, int]:
        """The unknowns whose places are lo:hi."""
        return int(np.searchsorted(self.home, lo)), int(np.searchsorted(self.home, hi))

    def embed(self, x: np.ndarray) -> np.ndarray:
        out = np.zeros((self.size,) + np.shape(x)[1:])
        out[self.home] = x
        return out


def node_blocks(model, K) -> NodeBlocks | None:
    """The `NodeBlocks` of a 3D model's reduced unknowns (K: the data set's reduced stiffness, its
    diagonal's median the blocks' `scale`; the places are the model's, `_node_places`), or None
    where they have none. 2D models keep GAMG on the unknowns: there the nodes' aggregates cost
    the contact steps more CG iterations (the 2D tunnel at 2.3e5 unknowns: 42.7 a Newton step
    against 24.2, tests/bench/test_bench_krylov_counts.py) and their set-up's memory is small."""
    if model.dim != 3:
        return None
    if model not in _PLACES:
        _PLACES[model] = _node_places(model.elim.T, model.dim, model.nnodes)
    home = _PLACES[model]
    return None if home is None else NodeBlocks(home, model.dim * model.nnodes, model.dim,
                                                 float(np.median(K.diagonal())))


def _node_places(T, d: int, nodes: int) -> np.ndarray | None:
    """Each reduced unknown's place among the d·nodes components: unknown i belongs to the node
    of the largest entry of its column of the elimination T (u = T w + u0; supports and ties drop
    components, an inclined support's unknowns combine its node's; of equal entries the first),
    the unknowns of a node in order at its first places; None where the nodes do not follow the
    unknowns' order or a column is empty."""
    T = sp.csc_matrix(T)
    T.sort_indices()
    counts = np.diff(T.indptr)
    if T.shape != (d * nodes, T.shape[1]) or T.shape[1] == 0 or counts.min() == 0:
        return None
    column = np.repeat(np.arange(T.shape[1]), counts)
    largest = np.lexsort((-np.abs(T.data), column))[T.indptr[:-1]]     # each column's, stable: the first
    node = T.indices[largest] // d
    if np.any(np.diff(node) < 0):
        return None
    first = np.r_[0, np.flatnonzero(np.diff(node)) + 1]
    slot = np.arange(len(node)) - np.repeat(first, np.diff(np.r_[first, len(node)]))
    return None if slot.max() >= d else d * node + slot


def _block_diagonal(blocks) -> sp.csr_matrix:
    """The block-diagonal matrix of small dense square blocks."""
    sizes = np.array([len(b) for b in blocks], dtype=int)
    start = np.r_[0, np.cumsum(sizes)]
    r = [s + np.repeat(np.arange(n), n) for s, n in zip(start, sizes)]
    c = [s + np.tile(np.arange(n), n) for s, n in zip(start, sizes)]
    data = [np.ravel(b) for b in blocks]
    if not blocks:
        return sp.csr_matrix((0, 0))
    return sp.csr_matrix((np.concatenate(data), (np.concatenate(r), np.concatenate(c))), shape=(start[-1], start[-1]))


class Krylov:
    """CG preconditioned by GAMG, the hierarchy kept while it costs less than building a new one.

    The Newton steps' matrices are K's size (`_Stepper.solve`) and differ only on the rows of
    the contact nodes whose state changed, so a hierarchy built for an earlier step still
    preconditions a later one (CG needs only an SPD preconditioner: the answer is the solve's
    to its tolerance, the hierarchy changes its cost). It is kept by the ski-rental rule: each
    solve with a kept hierarchy adds the iterations it took beyond the fresh hierarchy's rate
    (iterations per digit of its first solve) to the hierarchy's excess, and the next solve
    builds a fresh one once the excess is above `REBUILD_ITERATIONS`, about the cost of a
    GAMG set-up in CG iterations (measured 40 on the 2D tunnel at 1.5e4 unknowns, 120 on 3D
    Hertz at 7e3, 70 on the 3D patch at 1e6), so the iterations lost to an aged hierarchy never
    exceed what rebuilding costs by more than one step's. A converged solve is kept, never
    repeated; a kept hierarchy whose solve fails is rebuilt and the solve repeated. `expire`
    drops the hierarchy for the next solve: the glued first step of a 2D cold start (every
    contact row closed and stuck) has aggregates across the contact surface, which cost the
    next step 130 of the 2D tunnel's 166 iterations and 337 against 32 on the Tresca pad; in
    3D (the block patch at 8e4 unknowns) it served the next step as well as a fresh one.
    A hierarchy inherited from another solver (`kept`: the nominal data's, for a data set
    started from its answer, `_solve_problem`) is used where the operator is, up to a scalar,
    the one it was built for in all but `REBUILD_ROWS` rows: GAMG of s·A is GAMG of A over s
    (aggregation by relative strength, smoothing and Chebyshev bounds scale-free, coarse
    operators PᵀAP scale by s), and CG's iterates are the same for a preconditioner times a
    constant, so data whose moduli all scale by one factor (K = s·K*) keep it, and a new E
    of one material gets a fresh one. The rows that changed are found by one product with a
    fixed probe vector w: row i changed where |(A w)_i − s (A* w)_i| > PROBE ‖A w‖∞, s the
    median of (A w)_i / (A* w)_i (most rows do not change; on a group of ranks the mean of
    their medians). Every decision is on iteration counts and matrices, never on timings: the
    same data give the same bits.
    A kept GAMG hierarchy keeps its coarse levels; its finest level (the Chebyshev smoother with
    its Jacobi diagonal, and the residual) takes each solve's own operator (`_attach`), and
    between solves holds a diagonal in its place (`release_operator`): no matrix of K's size is
    held besides the one being solved, and a new step's operator is built after the last one is
    freed (two had been alive at once, the kept hierarchy's and the step's: the 3D patch at
    1e4 unknowns peaked 9 MB above its first step). The V-cycle then smooths the operator it
    preconditions (the eigenvalue bounds of its Chebyshev smoother stay the hierarchy's).
    near_nullspace: (n, r) columns (orthonormalised here) that the matrices nearly annihilate;
    kept: a solver whose hierarchy to start from (not freed by this one: `close`).
    parts: the data set's subdomains (`wcs.contact.bddc.Parts`): the preconditioner is then BDDC
    of the step's operator (`solver.iterative.preconditioner: bddc`), built from the subdomain
    matrices and the step's elimination each solve is given, and kept and rebuilt by the same
    rule as GAMG's hierarchy at its own set-up cost (`wcs.contact.bddc.REBUILD_ITERATIONS`; on a
    group of ranks each holds its share of the subdomains).
    The solves span the group of ranks `wcs.group.spanning` set when the solver was made
    (rows distributed: `wcs.contact.distributed`; None: this process alone)."""

    REBUILD_ROWS = 40           # rows an inherited hierarchy's operator may differ in (≤ that many more iterations)
    REBUILD_ITERATIONS = 50     # excess iterations that buy a new hierarchy (class docstring)
    PROBE = 1e-10
    MAX_IT = 2000               # CG with GAMG takes 10–60 (1e-4 to 1e-12); beyond this it has failed

    def __init__(self, near_nullspace=None, kept: "Krylov | None" = None, parts=None, blocks=None):
        self.N, self.parts = near_nullspace, parts
        self.blocks = None if parts is not None else blocks
        self.comm = evaluation_comm()
        self.ksp = self.P = self.layout = self.built = None    # built: A w of the operator the hierarchy was built for
        self.fine = None            # the GAMG hierarchy's finest level (pc, level) that takes each solve's operator
        self.scale = 1.0            # s: the operators are s times (a few rows aside) the one the hierarchy was built for
        self.own = True             # this solver built the hierarchy it holds (and frees it)
        self.builds = 0             # hierarchies built
        self.failure = ""           # why the last solve failed before its CG (BDDC's set-up: `SetupFailure`)
        self.rate = self.excess = 0.0
        if kept is not None and kept.ksp is not None:
            self.ksp, self.P, self.layout, self.built, self.rate = kept.ksp, kept.P, kept.layout, kept.built, kept.rate
            self.fine = kept.fine
            self.own = False
        self.inherited = not self.own           # a hierarchy from another solver, not yet compared
        # seconds (matrix: this rank's rows of A built and put in PETSc's form)
        self.timings = {"gamg_setup" if parts is None else "bddc_setup": 0.0, "cg": 0.0, "matrix": 0.0}

    def solve(self, A: sp.csr_matrix, b: np.ndarray, rtol: float, step=None):
        """x with ‖b − A x‖ ≤ rtol ‖b‖ (unpreconditioned norm): (x, iterations, converged).
        step: (Z, P, springs, pin) of A's elimination (`wcs.contact.bddc.Parts.of`), which BDDC
        is built from (GAMG needs A alone)."""
        PETSc = linalg.petsc()
        n = A.shape[0]
        if n == 0:
            return np.zeros(0), 0, True
        t = time.perf_counter()
        if self.layout is None or self.layout.n != n:
            self.close()
            self.layout = Layout(self.comm, n, PETSc, 1 if self.blocks is None else self.blocks.dim)
        # what a new operator replaces goes before it is built (each a matrix of K's size): the last
        # solve's operator, and the hierarchy with its operator where it is to be built again
        rebuild = self.ksp is not None and not self.inherited and self.excess > (
            self.REBUILD_ITERATIONS if self.parts is None else REBUILD_ITERATIONS)
        if rebuild:
            self.close()
        else:
            self.release_operator()
        M = self.layout.matrix(A, PETSc)
        self.timings["matrix"] += time.perf_counter() - t
        if self.ksp is None:
            kept = False
        elif self.inherited:        # a hierarchy from another solve: is this its operator, up to a scalar?
            changed, self.scale = self._changed(self._product(M, PETSc))
            kept = changed <= self.REBUILD_ROWS
        else:
            kept = True
            if self.fine is not None:       # the finest level's operator at the coarse levels' scale (`_attach`)
                self.scale = self._changed(self._product(M, PETSc))[1]
        self.failure = ""
        try:
            if not kept:
                self._build(M, PETSc, step)
            x, its, ok = self._cg(M, b, rtol)
            if not ok and kept:         # the kept hierarchy failed: rebuild and solve again
                self._build(M, PETSc, step)
                x, more, ok = self._cg(M, b, rtol)
                its += more
                kept = False
        except SetupFailure as exc:
            self.failure = str(exc)
            return np.zeros(n), 0, False
        self.inherited = False
        digits = -np.log10(rtol)
        if kept:
            self.excess += max(its - self.rate * digits, 0.0)
        else:
            self.rate = its / digits
        return x, its, ok

    def _cg(self, M, b, rtol):
        t = time.perf_counter()
        self._attach(M)
        self.ksp.setTolerances(rtol=rtol, atol=0.0, max_it=self.MAX_IT)
        x, rhs = M.createVecs()
        rhs.setArray(b[self.layout.lo:self.layout.hi])
        self.ksp.solve(rhs, x)
        ok = self.ksp.getConvergedReason() > 0
        its = self.ksp.getIterationNumber()
        out = self.layout.gather(x.getArray())
        for o in (x, rhs):
            o.destroy()
        self.timings["cg"] += time.perf_counter() - t
        return out, its, ok

    def _attach(self, M):
        """The solve's operator M into the preconditioner: GAMG's finest level smooths and takes
        its residual with M / s (s: `scale`, 1 but for an inherited hierarchy); BDDC (and a
        one-level GAMG, a direct solve) keeps the operator it was built for, `P`."""
        if self.fine is None:
            self.ksp.setOperators(M, self.P)
            return
        F = M if self.scale == 1.0 else _scaled(M, 1.0 / self.scale)   # at the coarse levels' scale
        self._finest(F)
        self.ksp.setOperators(M, F)
        if F is not M:
            F.destroy()             # (the level holds it)

    def _finest(self, F):
        """F the operator of GAMG's finest level: its Chebyshev smoother's, with F's Jacobi
        diagonal, and its residual's."""
        pc, level = self.fine
        smoother = pc.getMGSmoother(level)
        smoother.setOperators(F, F)
        smoother.getPC().setReusePreconditioner(False)     # (the hierarchy's reuse reaches its levels)
        linalg.petsc_call("PCMGSetResidual", linalg.petsc_c().PCMGSetResidual(pc.handle, level, None, F.handle))

    def release_operator(self):
        """Let go of the last solve's operator (a matrix of K's size), keeping the hierarchy: a
        solve sets its own operator before its CG (`_attach`). GAMG's finest level holds an
        identity of the operator's layout meanwhile; BDDC the operator it was built for."""
        if self.ksp is None:
            return
        if self.fine is None:
            self.ksp.setOperators(self.P, self.P)
            return
        PETSc = linalg.petsc()
        ones = self.layout.vector(np.ones(self.layout.n), PETSc)
        hold = PETSc.Mat().createAIJ(size=((self.layout.hi - self.layout.lo, self.layout.n),) * 2, nnz=1,
                                     comm=self.layout.petsc)
        hold.setDiagonal(ones)
        hold.assemble()
        self._finest(hold)
        self.ksp.setOperators(hold, hold)
        for o in (hold, ones):
            o.destroy()

    def expire(self):
        """The next solve builds a fresh hierarchy."""
        self.excess = np.inf

    def _product(self, M, PETSc) -> np.ndarray:
        """This rank's rows of M w, w the fixed probe `probe(n)`."""
        w = probe(self.layout.n)
        wv, out = self.layout.vector(w, PETSc), M.createVecLeft()
        M.mult(wv, out)
        Mw = out.getArray().copy()
        wv.destroy()
        out.destroy()
        return Mw

    def _changed(self, Mw: np.ndarray) -> tuple[int, float]:
        """The rows of the operator (product Mw with the probe) that differ from a multiple s of
        the one the hierarchy was built for (class docstring), over the group, and s."""
        old = self.built
        if self.blocks is not None:     # the unknowns' rows (the diagonal's alone are the blocks' own)
            real = np.zeros(self.layout.n, dtype=bool)
            real[self.blocks.home] = True
            real = real[self.layout.lo:self.layout.hi]
            Mw, old = Mw[real], old[real]
        ratio = np.divide(Mw, old, out=np.zeros_like(Mw), where=old != 0)
        s = self._reduce(float(np.median(ratio))) / (1 if self.comm is None else self.comm.size)
        scale = self._reduce(float(np.abs(Mw).max(initial=0.0)), "max")
        return int(self._reduce(int(np.sum(np.abs(Mw - s * old) > self.PROBE * scale)))), s

    def _reduce(self, value, op="sum"):
        """value summed (or its max) over the group."""
        if self.comm is None:
            return value
        from mpi4py import MPI
        return self.comm.allreduce(value, op=MPI.MAX if op == "max" else MPI.SUM)

    def _build(self, M, PETSc, step):
        t = time.perf_counter()
        self.close()
        if self.parts is not None:
            Z, P, springs, pin = step
            ksp, self.P = self.parts.of(Z, P, springs, pin).build(M, PETSc, self.layout)
            self.ksp, self.own, self.excess = ksp, True, 0.0
            self.built = self._product(M, PETSc)
            self.builds += 1
            self.timings["bddc_setup"] += time.perf_counter() - t
            return
        if self.N is not None and self.N.shape[1]:
            N = self.N if self.blocks is None else self.blocks.embed(self.N)
            Q, r, _ = sla.qr(N, mode="economic", pivoting=True)
            rank = int(np.sum(np.abs(np.diag(r)) > 1e-10 * abs(r[0, 0])))
            vecs = [self.layout.vector(Q[:, j], PETSc) for j in range(rank)]
            M.setNearNullSpace(PETSc.NullSpace().create(vectors=vecs, comm=self.layout.petsc))
        ksp = PETSc.KSP().create(self.layout.petsc)
        ksp.setType("cg")
        ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        ksp.getPC().setType("gamg")
        ksp.setOperators(M, M)
        ksp.setUp()
        if self.N is not None and self.N.shape[1]:      # GAMG copied the near-nullspace at its set-up
            M.setNearNullSpace(PETSc.NullSpace().create(comm=self.layout.petsc))
        ksp.getPC().setReusePreconditioner(True)
        self.ksp, self.P, self.own, self.excess = ksp, M, True, 0.0
        levels = ksp.getPC().getMGLevels()
        if levels > 1:          # the finest level takes each solve's operator (`_attach`): nothing else holds M
            self.fine, self.P = (ksp.getPC(), levels - 1), None
            _forget_products(ksp.getPC(), levels)
        self.built = self._product(M, PETSc)
        self.builds += 1
        self.timings["gamg_setup"] += time.perf_counter() - t

    def close(self):
        """Free the hierarchy this solver built (a kept one stays its owner's, without this
        solver's last operator)."""
        if self.ksp is not None and self.own:
            self.ksp.destroy()
            if self.P is not None:
                self.P.destroy()
        elif self.ksp is not None:
            self.release_operator()
        self.ksp = self.P = self.built = self.fine = None
        self.scale = 1.0


class _Scale:
    """t·M for PETSc's python-context matrix (`_scaled`): its products and its diagonal."""

    def __init__(self, M, t: float):
        self.M, self.t = M, t

    def mult(self, mat, x, y):
        self.M.mult(x, y)
        y.scale(self.t)

    def getDiagonal(self, mat, d):
        self.M.getDiagonal(d)
        d.scale(self.t)


def _scaled(M, t: float):
    """t·M as a PETSc matrix without a copy of M (its products and its diagonal)."""
    PETSc = linalg.petsc()
    S = PETSc.Mat().createPython(M.getSizes(), context=_Scale(M, t), comm=M.getComm())
    S.setUp()
    return S


def probe(n: int) -> np.ndarray:
    """The probe vector of `Krylov`'s change test: w_i = 1 + frac((i + 1) φ), φ = (√5 − 1)/2, a
    Weyl sequence equidistributed in [1, 2) with no structure a finite element operator shares
    (a row r with (M − A)_r w = 0 while (M − A)_r ≠ 0 is as unlikely as for random entries). It
    is the same on every layout and every machine (an integer times a double, rounded once),
    and needs no random generator: numpy.random is not loaded by a solve (`wcs.cli.defer_unused_imports`)."""
    return 1.0 + np.modf(np.arange(1, n + 1) * ((5.0 ** 0.5 - 1.0) / 2.0))[0]


def _forget_products(pc, levels: int) -> None:
    """GAMG's coarse operators PᵀAP and smoothed prolongators are products that keep a
    reference to their factors, the finest operator among them, for a recomputation this
    solver never asks (a new hierarchy is built instead): dropped, so that the finest
    operator is freed once no level holds it (`Krylov.release_operator`)."""
    c = linalg.petsc_c()
    for level in range(levels - 1):
        linalg.petsc_call("MatProductClear", c.MatProductClear(pc.getMGSmoother(level).getOperators()[0].handle))
    for level in range(1, levels):
        linalg.petsc_call("MatProductClear", c.MatProductClear(pc.getMGInterpolation(level).handle))


def krylov_solve(A: sp.csr_matrix, b: np.ndarray, rtol: float, near_nullspace=None):
    """One CG + GAMG solve of the SPD A (`Krylov`): (x, iterations, converged)."""
    solver = Krylov(near_nullspace)
    try:
        return solver.solve(A, b, rtol)
    finally:
        solver.close()


def reduced_modes(T: sp.spmatrix, R: np.ndarray) -> np.ndarray:
    """The columns of R (rigid motions of the dofs) on the reduced unknowns w of u = T w, by
    least squares: (TᵀT)⁻¹ Tᵀ R (exact where a motion is in the range of T; T's columns are
    a support's free directions and glued slaves follow their masters)."""
    from scipy.sparse.linalg import splu
    T = sp.csc_matrix(T)
    return splu((T.T @ T).tocsc()).solve(np.asarray(T.T @ R))


def _solve_problem(model, p) -> ContactResult:
    """The model's contact problem by `solve_contact_iterative`, with its rigid modes as GAMG's
    near-nullspace and the study's tolerances (`solver.iterative.tolerance` for the Krylov solves).
    The model's first cold solve (its anchor, the nominal data: `Model.solve`) keeps its last
    GAMG hierarchy for the solves started from its answer (`Krylov`: reused where their operator
    is the anchor's up to a scalar); so a solve's preconditioner depends on its data and the
    anchor's only, never on the order of the data sets."""
    kept = _ANCHOR.get(model)
    from_anchor = kept is not None and p.warm is not None and p.warm.lam_n is kept[0]
    krylov = Krylov(contact_modes(model), kept[1] if from_anchor else None, _parts(model, p.coefficients),
                    node_blocks(model, p.K))
    res = solve_contact_iterative(p.K, p.f, p.Bn, p.Bt, p.d, p.w, g=p.g, F=p.F, R=p.R, warm=p.warm,
                                  near_nullspace=contact_modes(model), rtol=model.options.iterative.tolerance,
                                  reference=p.reference, krylov=krylov, **settings(model.options))
    if kept is None and p.warm is None and res.status == Status.SOLVED:
        krylov.release_operator()
        _ANCHOR[model] = (res.lam_n, krylov)
    else:
        krylov.close()
    return res


def preconditioner(model) -> tuple[str, str]:
    """(amg | bddc, why): the model's `solver.iterative.preconditioner`, `auto` resolved by
    `wcs.choose.preconditioner`."""
    chosen = model.options.iterative.preconditioner
    if chosen == "bddc":        # the evaluation's estimate (`wcs.scene.estimate`) is made for GAMG
        return chosen, (f"chosen in the study; the evaluation's estimate is the method's with amg: BDDC's set-up took "
                        f"{BDDC_SETUP_RATIO:g}x GAMG's CPU time and more (bench_bddc_*.csv)")
    if chosen != "auto":
        return chosen, "chosen in the study"
    return choose_preconditioner(PreconditionerFacts(model.elim.T.shape[1], model.options.ranks_per_evaluation))


def _parts(model, coefficients):
    """The data set's subdomains (`wcs.contact.bddc.Parts`) where the preconditioner is BDDC,
    from its stiffness coefficients (`ContactProblem.coefficients`); None: GAMG."""
    if preconditioner(model)[0] != "bddc":
        return None
    if coefficients is None:
        raise ValueError("BDDC needs the data set's stiffness coefficients (its subdomain matrices)")
    parts = parts_of(model.elim.T.shape[1], model.options.ranks_per_evaluation)
    return model_parts(model.smesh.mesh, model.K, model.elim.T, coefficients, contact_modes(model), parts,
                       range(*share(parts)))


_ANCHOR = weakref.WeakKeyDictionary()   # model → (its anchor's λn, the anchor solve's Krylov): `_solve_problem`
_MODES = weakref.WeakKeyDictionary()    # model → `contact_modes`
_PLACES = weakref.WeakKeyDictionary()   # model → its unknowns' places at their nodes (`node_blocks`)


def contact_modes(model) -> np.ndarray:
    """GAMG's near-nullspace for the contact steps, on the reduced unknowns: in 2D the rigid
    motions of each body on its own (3 columns a body, zero off it), in 3D the model's rigid
    motions of the whole mesh (`Model.near_nullspace`). A step eliminates only the closed and
    stuck rows, so where the fault opens or slips the bodies move against each other, which one
    set of modes for all bodies leaves out of every aggregate straddling the fault: on the 2D
    tunnel the CG iterations of a Newton step grew 29 → 41 → 53 over two refinements (h⁻⁰·⁴),
    with the bodies' own modes 11 → 15 → 15 (`tests/bench/test_bench_krylov_counts.py`). In 3D
    the bodies' 12 columns doubled the coarse grids and the CPU time of a contact solve (3D
    tunnel at 2.5e4 unknowns: 16.3 s against 8.0 s for 34 against 49 iterations)."""
    if model not in _MODES:
        if model.dim == 3:
            _MODES[model] = model.near_nullspace
        else:
            sm = model.smesh
            R = np.hstack([rigid_modes(sm.mesh.p, np.flatnonzero(sm.node_body == b), model.nnodes)
                           for b in range(len(sm.bodies))])
            _MODES[model] = reduced_modes(model.elim.T, R)
    return _MODES[model]


class IterativeAdjoint:
    r"""The adjoint of an iterative contact solution on its final active set, without W: what
    `wcs.model.sensitivity.ContactAdjoint` gives, (z, μ, σ) for one criterion's partials, by one CG +
    GAMG solve with the Newton step's elimination.

    In the slip frame (`wcs.contact.slipframe._slip_frame`: C turned by Q, the free rows A — closed
    normals, stuck tangents, ν⊥ rows with the compliance D = |s|/gw — and the fixed rows B),
    the last Newton step's system is [K, C_Aᵀ, C_Bᵀ; C_A, −D, 0; 0, 0, I] [u; λ_A; λ_B] =
    [f; d_A; h_B] (Tresca); its transpose with the partials (φ_w, φ_λ) as right-hand side is

        K z + C_Aᵀ μ_A = φ_w,   C_A z − D μ_A = φ_A,   μ_B = φ_B − C_B z,

    the module docstring's N-system with u eliminated instead of λ. The rows with compliance
    are springs (μ = (C z − φ)/D: K + C_Dᵀ D⁻¹ C_D, the step's cγ/(1 − γ) = gw/|s| at the
    answer), the equalities E are eliminated node by node (`_Rows.pivots`, z = Z x + z_b with
    C_E z_b = φ_E) and Zᵀ K Z x = Zᵀ(φ_w − K z_b) is solved by CG + GAMG to the study's
    Krylov tolerance; μ_E = C_EP⁻ᵀ (φ_w − K z)_P on the pivots. The operator and its GAMG
    hierarchy are built once for all criteria. As ContactAdjoint: a tangent tied to its
    closed node's normal (rollers on both sides: `Model.tied`) and a row acting on nothing carry
    μ = 0. Floating bodies (rigid modes R, K R = 0): the equalities then hold every rigid mode
    (the forward step checks it) and the system is regular, but z may be mostly a rigid motion
    whose deformation, which makes μ ~ K z, would lie below the round-off of K z (the mean
    pressure on the floating contact patch: μ wrong by 1e7 relative, worse the tighter CG).
    So the rigid part that fits the equalities best, R α with α = argmin ‖C_E R α − φ_E‖, is
    taken out first and the system solved for z − R α (K R α = 0 exactly, Kt R α = S R α with S
    the springs). Where φ_E is itself rigid to round-off (the mean pressure over the whole face
    of the floating Tresca pad) even that leaves μ as noise; μ must balance the rigid modes,
    Rᵀ(φ_w − C_Aᵀ μ_A) = 0 (N's last rows): measured ≤ 1e-9 of its terms where the gradient
    agrees with ContactAdjoint's, 1e-1 on that pad, so above `BALANCE` the solve is refused.
    Coulomb (λ_t = σ(g w + F λn) on a slipping tangent, `ContactAdjoint`'s N): on an open node
    (λn = 0 fixed) the coupling only adds σ F μt to the node's μn; on a closed node Nᵀ's normal
    row becomes C_n z − σ F μ_t = φ_n with μ_t = φ_t − C_t z, a constraint C_n + σ F C_t that is
    not C_n (the transpose is not symmetric), so the symmetric Tresca adjoint is kept and the
    coupled μ_t = y solved for by GMRES over those rows (`_coulomb`, one CG solve a product).
    Refused (`solve` gives None, `refusal` or `failure` says why): that imbalance, a row
    without an own unknown, CG or GMRES not converged."""

    def __init__(self, model, state):
        from wcs.contact.slipframe import _slip_frame
        res = state.raw
        m = res.lam_n.size
        C = model.contact_rows
        n = C.shape[0]
        k = n // m - 1
        Q, self.sigma, compliance, free = _slip_frame(model, state, m, k)
        if Q is not None:
            C = (Q @ C).tocsr()
        K = sp.csr_matrix(state.stiffness)        # the method factors no units: the data set's own
        rows = _Rows(C, m, k)
        spring = free & (compliance > 0)
        tied = np.r_[np.zeros(m, bool), model.tied[0] & np.tile(free[:m], k)] & (compliance == 0)
        self.E = free & ~spring & ~tied & rows.acting
        self.D, self.fixed = np.flatnonzero(spring), np.flatnonzero(~free)
        self.C, self.Q, self.m, self.n, self.R = C, Q, m, n, model.R_r
        self.refusal = self.failure = ""        # why every solve / the last solve gave None
        F = np.asarray(state.coefficients.coulomb, float)
        tang = self.fixed[self.fixed >= m]
        tang = tang[(self.sigma[tang - m] != 0) & (F[(tang - m) % m] > 0)]     # λ_t = σ(g w + F λn)
        closed = free[(tang - m) % m]
        self.coupled, self.closed = tang[~closed], tang[closed]     # slipping tangents of open / closed nodes
        self.F = F
        try:
            self.rows, self.P, self.Binv = _pivots(rows, self.E, k)
        except _Unsupported as exc:
            self.refusal = f"iterative adjoint: {exc}"
            return
        Cd = C[self.D]
        self.S = (Cd.T @ sp.diags(1.0 / compliance[self.D]) @ Cd).tocsr()
        self.Kt = (K + self.S).tocsr() if len(self.D) else K     # no spring: K itself, not a copy
        self.compliance = compliance[self.D]
        self.Z0 = _basis(C, self.rows, self.P, self.Binv, np.zeros(len(self.rows)))[0]
        Z0, Kt, P = self.Z0, self.Kt, self.P      # each rank of a group builds its rows, once for all criteria
        self.A = RowBlocks(K.shape[0], functools.lru_cache(maxsize=1)(lambda lo, hi: _eliminated(Z0, Kt, K, P, lo, hi)))
        self.rtol = model.options.iterative.tolerance
        self.krylov = Krylov(contact_modes(model), parts=_parts(model, model.stiffness_coefficients(state.coefficients)))
        self.springs = (Cd, 1.0 / self.compliance) if len(self.D) else None

    def solve(self, phi_w: np.ndarray, phi_lam_n: np.ndarray | None, phi_lam_t: np.ndarray | None = None):
        """(z, μ, σ) as `ContactAdjoint.solve` (μ in the slip frame), or None where refused (`refusal`)
        or a Krylov solve failed (`failure`)."""
        if self.refusal:
            return None
        m, n, C = self.m, self.n, self.C
        phi = np.zeros(n)
        if phi_lam_n is not None:
            phi[:m] += phi_lam_n
        if phi_lam_t is not None:
            t = np.r_[np.zeros(m), phi_lam_t]
            phi += t if self.Q is None else self.Q @ t
        if self.closed.size:        # Coulomb on closed slipping nodes (class docstring)
            y = self._coulomb(phi_w, phi)
            if y is None:
                return None
            phi = phi + self._normal_shift(y)
        out = self._tresca(phi_w, phi, check=True)
        if out is None:
            return None
        z, mu = out
        mu[self.fixed] = phi[self.fixed] - C[self.fixed] @ z
        node = (self.coupled - m) % m       # Nᵀ's open normal row: μn − Σ σ F μt = φn − Bn z
        np.add.at(mu, node, self.sigma[self.coupled - m] * self.F[node] * mu[self.coupled])
        return z, mu, self.sigma

    def _normal_shift(self, y):
        """Γᵀ y: the slipping tangents' σ F y added to their closed nodes' normal rows."""
        node = (self.closed - self.m) % self.m
        out = np.zeros(self.n)
        np.add.at(out, node, self.sigma[self.closed - self.m] * self.F[node] * y)
        return out

    def _coulomb(self, phi_w, phi):
        """μ_t = y on the slipping tangent rows of closed Coulomb nodes: the equality rows there are
        C_n z = φ_n + σ F μ_t with μ_t = φ_t − C_t z (Nᵀ's rows, as `ContactAdjoint`'s N couples
        λ_t = σ(g w + F λn)), so with z(y) the Tresca adjoint of φ + Γᵀy (linear in y),
        (I + C_t z(0, Γᵀ ·)) y = φ_t − C_t z(φ_w, φ): GMRES on the coupled rows (at most 200
        products, one CG solve each; 7 on the Coulomb pad of the tests, ‖C_t z(0, Γᵀ ·)‖ ~ F);
        None where a solve fails (`failure`)."""
        from scipy.sparse.linalg import LinearOperator, gmres
        Cc = self.C[self.closed]
        zero = np.zeros_like(phi_w)

        def response(phi_w, phi):
            out = self._tresca(phi_w, phi, check=False)
            if out is None:
                raise _KrylovFailure(self.failure)
            return Cc @ out[0]
        p = len(self.closed)
        try:
            b = phi[self.closed] - response(phi_w, phi)
            op = LinearOperator((p, p), matvec=lambda y: y + response(zero, self._normal_shift(y)), dtype=float)
            y, info = gmres(op, b, rtol=COUPLED * self.rtol, atol=0.0, restart=min(p, 50), maxiter=4)
        except _KrylovFailure:
            return None
        if info != 0:
            self.failure = (f"iterative adjoint: GMRES on the {p} Coulomb-coupled rows did not reach the relative "
                            f"residual {COUPLED * self.rtol:.1e}")
            return None
        return y

    def _tresca(self, phi_w, phi, check):
        """(z, μ on the equality and spring rows) of the Tresca adjoint system (class docstring) for
        the partials φ_w, φ (the fixed rows left to `solve`); None where CG fails or, with `check`,
        the multipliers leave a floating body unbalanced (`failure` says so)."""
        C = self.C
        rhs = phi_w + C[self.D].T @ (phi[self.D] / self.compliance)
        e, Ra = phi[self.rows], 0.0
        if self.R is not None:      # the best-fitting rigid part first (class docstring)
            CR = C[self.rows] @ self.R
            Ra = self.R @ np.linalg.lstsq(CR, e, rcond=None)[0]
            e = e - C[self.rows] @ Ra
            rhs = rhs - self.S @ Ra
        z, mu_E = self._equalities(rhs, e)
        if z is None:
            return None
        z = z + Ra
        mu = np.zeros(self.n)
        mu[self.rows] = mu_E
        mu[self.D] = (C[self.D] @ z - phi[self.D]) / self.compliance
        if check and self.R is not None:      # the rigid modes' equilibrium Rᵀ(φ_w − C_Aᵀ μ_A) = 0 (class docstring)
            load = C[np.r_[self.rows, self.D]].T @ mu[np.r_[self.rows, self.D]]
            off = np.max(np.abs(self.R.T @ (phi_w - load)) / np.maximum(
                np.abs(self.R).T @ (np.abs(phi_w) + np.abs(load)), 1e-300))
            if off > BALANCE:
                self.failure = (f"iterative adjoint: the multipliers leave a floating body unbalanced (relative "
                                f"{off:.1e} > {BALANCE:.0e}: its rigid motion's round-off; use solver.method "
                                "monolithic for gradients)")
                return None
        return z, mu

    def _equalities(self, rhs, e):
        """(y, μ_E) of Kt y + C_Eᵀ μ_E = rhs, C_E y = e by CG on the eliminated operator; (None,
        None) where CG fails (`failure` says so)."""
        yb = _basis(self.C, self.rows, self.P, self.Binv, e)[1]
        x, its, ok = self.krylov.solve(self.A, self.Z0.T @ (rhs - self.Kt @ yb), self.rtol,
                                       (self.Z0, self.P, self.springs, None))
        if not ok:
            self.failure = (f"iterative adjoint: {self.krylov.failure}" if self.krylov.failure else
                            f"iterative adjoint: CG did not reach the relative residual {self.rtol:.1e} in {its} iterations")
            return None, None
        y = self.Z0 @ x + yb
        return y, self.Binv.T @ (rhs - self.Kt @ y)[self.P]


class Iterative(Primal):
    """`solver.method: iterative`: anchored as monolithic (the nominal data cold, every other data
    set from their answer), K(c) assembled, no units; the adjoint by `IterativeAdjoint` on the
    iterative answer's active set (no W)."""

    def adjoint(self, model, state) -> IterativeAdjoint:
        """The contact adjoint of a solution of this method (`wcs.model.sensitivity.coefficient_gradients`)."""
        return IterativeAdjoint(model, state)

    def check(self, model) -> None:
        if model.options.iterative.preconditioner == "bddc" and model.dynamic:
            raise StudyError("bddc is built from the stiffness's subdomain matrices, and a time level's operator "
                             "holds the mass too: use amg (or auto) in a dynamic study",
                             path="solver.iterative.preconditioner")
        try:
            linalg.bootstrap_mpi()      # the PETSc libraries petsc4py binds to
            import petsc4py  # noqa: F401
        except ImportError as exc:
            raise StudyError(f"the iterative method needs PETSc ({exc}): install the wheel dolfinx-solver-real "
                             "(Python >= 3.12), or use monolithic", path="solver.method") from None

    def release(self, model) -> None:
        """Free the anchor's GAMG hierarchy (`_solve_problem`), the contact modes and the node places."""
        kept = _ANCHOR.pop(model, None)
        if kept is not None:
            kept[1].close()
        _MODES.pop(model, None)
        _PLACES.pop(model, None)

    def solve(self, model, c, Kr, rhs, u0, nominal, adjoint, warm=None, used=None) -> Solved:
        out = super().solve(model, c, Kr, rhs, u0, nominal, adjoint, warm, used)
        if used is None and out.raw is not None:
            out = dataclasses.replace(out, solver=f"iterative: {out.raw.iterations} Newton steps, "
                                                  f"{out.raw.krylov_iterations} CG iterations")
        return out


METHOD = Iterative("iterative", _solve_problem, anchored=True)
