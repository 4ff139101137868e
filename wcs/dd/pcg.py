r"""Preconditioned conjugate gradients on the interface with a balancing coarse space.

`Coarse(Z, apply_S)`: the S-orthogonal projection onto V_H = span Z
([21, (5.11)–(5.14)]),

    P = Z (Zᵀ S Z)⁻¹ Zᵀ S,

with the small dense matrix Zᵀ S Z factored once. `balance(U, SU, F − SU)` returns
U + Z (ZᵀSZ)⁻¹ Zᵀ (F − S U) (and its image under S from SZ), whose residual is orthogonal to V_H
([21, (5.15)]); from there every PCG residual stays in V_H^⊥ (Lemma 5.1) and
the preconditioner (I − P) Σ_u R_uᵀ D_u S_u† D_u R_u needs no pre-projection.

`pcg(...)` is Algorithm PCG1 / PCG2 of [21, §4.4, §6] (the same recurrence):

    H⁰ = F − S U⁰;  repeat  G = M⁻¹H;  β = (H,G)/(H_prev,G_prev);  P = G + βP
                            Z = S P;  α = (H,G)/(Z,P);  U += αP;  H −= αZ
    until ‖H‖ ≤ tol ‖F‖.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla


class CoarseSingular(RuntimeError):
    """S vanishes on part of the coarse space: the interface operator is singular."""


class Coarse:
    """S-orthogonal projection onto span Z (Z: (n, k) dense, k small)."""

    def __init__(self, Z: np.ndarray, apply_S, rtol: float = 1e-10, SZ: np.ndarray | None = None):
        """`SZ`: S Z when known (else k products with S at once)."""
        self.Z = Z
        if Z.shape[1] == 0:
            self.SZ = Z
            return
        SZ = apply_S(Z) if SZ is None else SZ
        G = 0.5 * (Z.T @ SZ + SZ.T @ Z)
        ev, V = np.linalg.eigh(G)
        if ev[0] <= rtol * max(ev[-1], 1e-300):
            raise CoarseSingular(f"coarse matrix ZᵀSZ is singular (eigenvalues {ev[0]:.3e} .. {ev[-1]:.3e}): "
                                 f"{int(np.sum(ev <= rtol * ev[-1]))} coarse mode(s) carry no energy")
        self.SZ = SZ
        self._cho = sla.cho_factor(G)

    @property
    def size(self) -> int:
        return self.Z.shape[1]

    def _solve(self, b):
        return sla.cho_solve(self._cho, b, check_finite=False)     # Zᵀ S Z was checked when factored

    def project_out(self, x: np.ndarray) -> np.ndarray:
        """(I − P) x."""
        if self.size == 0:
            return x
        return x - self.Z @ self._solve(self.SZ.T @ x)

    def balance(self, U: np.ndarray, SU: np.ndarray, residual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(U + Z α, S U + SZ α), α = (ZᵀSZ)⁻¹ Zᵀ r: the new residual r − SZ α is orthogonal
        to span Z; its image under S from SZ, without a product with S."""
        if self.size == 0:
            return U, SU
        alpha = self._solve(self.Z.T @ residual)
        return U + self.Z @ alpha, SU + self.SZ @ alpha


@dataclass
class PCGResult:
    x: np.ndarray
    Sx: np.ndarray              # S x (= F − H, the recursive residual)
    iterations: int
    converged: bool
    residuals: list = field(default_factory=list)   # ‖H‖ per iteration, first = initial


def pcg(apply_S, precondition, F: np.ndarray, U0: np.ndarray, *, tol: float, max_iter: int,
        coarse: Coarse | None = None, reference: float | None = None) -> PCGResult:
    """Balanced PCG for S U = F from U0 ([21, Algorithms PCG1, PCG2]).

    precondition(H) -> (I − P) Σ D S† D H. `reference`: the norm the stopping test
    ‖H‖ ≤ tol·reference uses (default ‖F‖).
    """
    U = U0.copy()
    SU = apply_S(U) if np.any(U) else np.zeros_like(F)      # from zero (Newton's steps, PCG1): no product
    if coarse is not None and coarse.size:
        U, SU = coarse.balance(U, SU, F - SU)
    H = F - SU
    ref = np.linalg.norm(F) if reference is None else reference
    hist = [float(np.linalg.norm(H))]
    if ref == 0.0 or hist[0] <= tol * ref:
        return PCGResult(U, SU, 0, True, hist)
    P = np.zeros_like(F)
    SP = np.zeros_like(F)
    hg_prev = None
    for it in range(1, max_iter + 1):
        G = precondition(H)
        hg = float(H @ G)
        P = G + (hg / hg_prev) * P if hg_prev else G
        SP = apply_S(P)
        pz = float(P @ SP)
        if pz <= 0:           # S not positive on the search direction: stop with what we have
            return PCGResult(U, F - H, it - 1, False, hist)
        alpha = hg / pz
        U += alpha * P
        H -= alpha * SP
        hg_prev = hg
        hist.append(float(np.linalg.norm(H)))
        if hist[-1] <= tol * ref:
            return PCGResult(U, F - H, it, True, hist)
    return PCGResult(U, F - H, max_iter, False, hist)
