"""The interface operators of the decomposition: S = Σ_u R_uᵀ S_u R_u over units with its
balancing Neumann–Neumann preconditioner and coarse space ([21, (5.9)–(5.14)]), and the
products of the linearised pairs."""
from __future__ import annotations

import time

import numpy as np

from .kernels import _orth
from .pcg import Coarse
from .team import Team


class InterfaceOperator:
    """S = Σ_u R_uᵀ S_u R_u over `units` (linear uses of each unit) with the balancing
    Neumann–Neumann preconditioner M⁻¹ = (I − P) Σ_u R_uᵀ D_u S_u† D_u R_u ([21, (5.14)]).

    Coarse space V_H = span{R_uᵀ D_u Y_u}: `traces[i]` the rigid-motion traces Y_u of every
    unit (local DOFs × modes), not only the kernels Z_u ⊂ span Y_u of the floating ones
    ([21, (5.11)] needs those; a subdomain held by a roller or a sliver of a support has a
    small Neumann eigenvalue on the others and needs them too).
    `team`: the distribution of the units over MPI ranks (`Team(None, units)`: serial);
    each rank solves its own units' local problems, the pieces are summed in unit order.
    `coarse`: the coarse projection when known (kept for the data set: S and S0; interface
    Newton's J_k, on the glued operator's basis — the same units, weights and traces — with
    J_k Z from the glued S Z and the pairs' changes)."""

    def __init__(self, units, nif: int, weights: list[np.ndarray], traces: list[np.ndarray],
                 team: Team | None = None, coarse: Coarse | None = None):
        self.units, self.nif, self.weights = units, nif, weights
        self.team = team if team is not None else Team(None, units)
        self.weight = {u.index: w for u, w in zip(units, weights)}
        self.applications = 0
        if coarse is not None:
            self.coarse = coarse
            return
        tm = self.team.timings
        t, inner = time.perf_counter(), tm["dirichlet"] + tm["comm"]
        self.coarse = Coarse(self._basis(units, nif, weights, traces), self.apply)   # ZᵀSZ: k applications at once
        tm["coarse"] += time.perf_counter() - t - (tm["dirichlet"] + tm["comm"] - inner)

    @staticmethod
    def _basis(units, nif, weights, traces) -> np.ndarray:
        """An orthonormal basis of V_H = span{R_uᵀ D_u Y_u}."""
        Zs = [(u.gamma, w[:, None] * y[u.B]) for u, w, y in zip(units, weights, traces) if y.shape[1] and u.B.size]
        k = sum(z.shape[1] for _, z in Zs)
        Z = np.zeros((nif, k))
        j = 0
        for g, z in Zs:
            Z[g, j:j + z.shape[1]] = z
            j += z.shape[1]
        return _orth(Z)

    def apply(self, U: np.ndarray) -> np.ndarray:
        self.applications += 1
        tm = self.team.timings
        t = time.perf_counter()
        pieces = self.team.each(_product_phase(U), self.units, lambda u: u.apply_S(U[u.gamma]))   # local Dirichlet solves
        tm["dirichlet"] += time.perf_counter() - t
        return self.team.sum(self.units, pieces, self.nif, U.shape[1:])

    def precondition(self, H: np.ndarray) -> np.ndarray:
        tm = self.team.timings
        t = time.perf_counter()
        w = self.weight
        pieces = self.team.each("iterate", self.units,
                                lambda u: w[u.index] * u.neumann(w[u.index] * H[u.gamma]))   # local Neumann solves
        tm["neumann"] += time.perf_counter() - t
        out = self.team.sum(self.units, pieces, self.nif, H.shape[1:])
        t = time.perf_counter()
        out = self.coarse.project_out(out)
        tm["coarse"] += time.perf_counter() - t
        return out

    def load(self) -> np.ndarray:
        t = time.perf_counter()
        pieces = self.team.each("assemble", self.units, lambda u: u.condensed_load())
        self.team.timings["dirichlet"] += time.perf_counter() - t
        return self.team.sum(self.units, pieces, self.nif)


def pairs_apply(team, lin_pairs, nif, x):
    """Σ_p R_pᵀ S_p^A R_p x over the linearised pairs (own ones solved, pieces summed; x may
    have columns)."""
    pieces = team.each(_product_phase(x), lin_pairs, lambda p: p.apply_S(x[p.gamma]))
    return team.sum(lin_pairs, pieces, nif, x.shape[1:])


def _product_phase(x: np.ndarray) -> str:
    """The `Team` phase the units' products with x are charged to: `iterate` for a vector (PCG's
    products, every evaluation), `assemble` for columns (the coarse basis: Zᵀ S Z and J_k Z, a
    data set's set-up, kept while its stiffness data stay — as the factorizations, which an
    evaluation on the same data does not count either). Charged to `iterate`, the first
    evaluation's coarse products made the tunnel's pairs (×0.33) weigh 30–31 ms there against
    16–17 ms without them (its linear units 5–12 → 4–11 ms), and on the same data the pairs'
    ranks took too few linear units (their products 32 against 54 ms a solve)."""
    return "iterate" if x.ndim == 1 else "assemble"
