r"""One time level of each scheme, as pure functions over the reduced matrices.

Notation: M, C, K the reduced mass, damping (viscous a⁽¹⁾ plus any extra damping, e.g. the
seed's absorbing α) and stiffness; w, v the reduced displacement and velocity at t_n; τ = Δt;
f(t) the reduced load (the supports' K u₀ already taken off). Every level solves for the
increment Δ = w_{n+1} − w_n one contact problem

    A Δ + Bnᵀλn + Btᵀλt = r,   Bn Δ ≤ d − Bn w_n,   friction on the slip increment Bt Δ,

so λ is the contact force of the level [N/m in 2D] and the slip limit is the physical g·w.
A is symmetric positive definite (M/τ² dominates): no floating body is ever singular.

seed — [101, (10)]: u'' ≈ (u_{n+1} − 2u_n + u_{n−1})/τ², u' ≈ (u_{n+1} − u_n)/τ, everything
else at t_{n+1} (backward Euler in the velocity: first order, dissipative). Divided by τ²:
A = M/τ² + C/τ + K, r = f(t_{n+1}) − K w_n + M v_n/τ, then v_{n+1} = Δ/τ.

stabilized — the contact-stabilized Newmark rule of Deuflhard, Krause and Ertel (Int. J.
Numer. Meth. Engng 73 (2008) 1274–1290): the trapezoidal rule (Newmark β = 1/4, γ = 1/2,
energy conserving without contact) whose predictor w_n + τ v_n is first projected in the
M-norm onto the admissible set,

    δ̃ = argmin { ½ (δ − τ v_n)ᵀ M (δ − τ v_n) : Bn δ ≤ d − Bn w_n }   (frictionless contact),

then A = 2M/τ² + C/τ + K/2, r = (f_n + f_{n+1})/2 − K w_n + 2M δ̃/τ², and
v_{n+1} = v_n + 2(Δ − δ̃)/τ. Then M(v_{n+1} − v_n) = τ(f̄ − K w̄ − C Δ/τ − Bᵀλ), w̄ = w_n + Δ/2:
λ is the mean contact force over the step, and the viscous force takes the step's strain rate
Δ/τ (second order, the midpoint's), not the mean of the velocities: near a closed contact the
velocities carry the jumps the projection takes out of the displacements, and C (v_n + v_{n+1})/2
let the scheme gain energy (measured +0.4 % in one step of the viscous two-bar impact). The projection removes the velocity that would carry the contact
nodes into the obstacle, so the contact force does not oscillate and the scheme never gains
energy; it loses what the projection takes (measured: `wcs.dynamics.energy`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True)
class Matrices:
    """The reduced mass M, damping C (None: none) and stiffness K."""
    M: sp.csr_matrix
    C: sp.csr_matrix | None
    K: sp.csr_matrix


def _sum(*terms) -> sp.csr_matrix:
    A = terms[0]
    for t in terms[1:]:
        if t is not None:
            A = A + t
    return sp.csr_matrix(A)


def seed_operator(m: Matrices, tau: float) -> sp.csr_matrix:
    """A = M/τ² + C/τ + K: [101, (10)] (ρ + Δt α + Δt² a⁽⁰⁾ + Δt a⁽¹⁾) divided by Δt²."""
    return _sum(m.M / tau**2, m.C / tau if m.C is not None else None, m.K)


def seed_load(m: Matrices, tau: float, w, v, f_next) -> np.ndarray:
    """r = f(t_{n+1}) − K w_n + M v_n / τ."""
    return f_next - m.K @ w + m.M @ v / tau


def seed_velocity(tau: float, v, step) -> np.ndarray:
    """v_{n+1} = Δ/τ."""
    return step / tau


def stabilized_operator(m: Matrices, tau: float) -> sp.csr_matrix:
    """A = 2M/τ² + C/τ + K/2."""
    return _sum(2 * m.M / tau**2, m.C / tau if m.C is not None else None, m.K / 2)


def predictor_load(m: Matrices, tau: float, v) -> np.ndarray:
    """The load of the projection problem (operator M): M τ v_n."""
    return m.M @ (tau * v)


def stabilized_load(m: Matrices, tau: float, w, predicted, f_now, f_next) -> np.ndarray:
    """r = (f_n + f_{n+1})/2 − K w_n + 2M δ̃/τ²."""
    return (f_now + f_next) / 2 - m.K @ w + 2 * (m.M @ predicted) / tau**2


def stabilized_velocity(tau: float, v, step, predicted) -> np.ndarray:
    """v_{n+1} = v_n + 2(Δ − δ̃)/τ."""
    return v + 2 * (step - predicted) / tau
