r"""The energies of a level and what a step adds to the balance

    kinetic + elastic = initial + work of the loads − viscous − friction − numerical,

with kinetic ½ vᵀMv, elastic ½ uᵀKu (the full displacement, supports included), the work of
the loads f̄ᵀΔ over a step, the viscous dissipation τ ėᵀ C ė with ė = Δ/τ the step's rate
(the one both schemes' viscous force takes) and the friction dissipation λtᵀ Bt Δ (force times
slip increment, ≥ 0). The numerical dissipation is what remains: the scheme's own
loss (backward Euler's damping, the stabilized rule's projection).
"""
from __future__ import annotations

import numpy as np


def kinetic(M, v) -> float:
    return 0.5 * float(v @ (M @ v))


def elastic(K, u) -> float:
    return 0.5 * float(u @ (K @ u))


def viscous(C, tau: float, rate) -> float:
    """τ ėᵀ C ė (C None: 0)."""
    return 0.0 if C is None else tau * float(rate @ (C @ rate))


def friction(lam_t, slip_increment) -> float:
    """λtᵀ Bt Δ: the work the friction force takes from the bodies over the step."""
    return float(np.dot(lam_t, slip_increment)) if lam_t is not None else 0.0


def body_velocities(model, M, velocity) -> np.ndarray:
    """(nbodies, d) each body's mean velocity, its momentum over its mass: Σ (M v)_i / Σ (M 1)_i
    over the body's DOFs of each component (M the full mass matrix, velocity on the full DOFs)."""
    d = model.dim
    Mv, M1 = M @ velocity, M @ np.ones(M.shape[0])
    out = np.empty((len(model.smesh.bodies), d))
    for b in range(len(model.smesh.bodies)):
        nodes = np.flatnonzero(model.smesh.node_body == b)
        for i in range(d):
            out[b, i] = Mv[d * nodes + i].sum() / M1[d * nodes + i].sum()
    return out
