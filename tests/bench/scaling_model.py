"""The scaling model of docs/scaling.md: the time of one cold contact evaluation by the
iterative method with N unknowns on P ranks, predicted from the per-phase seconds measured on
one rank at N1 unknowns (test_bench_ranks.py) — weak scaling from N1 unknowns a rank.

Assumptions (docs/scaling.md says where each comes from):
- every phase but the solvability check is distributed by rows (`LOCAL`, `MULTIGRID`): its
  work is the measured one scaled by the unknowns a rank, N / P / N1;
- the active set takes the same Newton steps (semismooth Newton: mesh-independent in practice);
- CG + GAMG's iterations, and with them the GAMG set-up's levels, grow by 1 + C ln(N / N1):
  C = 0 (smoothed aggregation's scaled studies: iterations flat) or C = 1/4 (this repository's
  own bound on Krylov growth, test_bench_krylov_counts.py);
- communication: per CG iteration 2 allreduces of depth log2 P and, on each of the multigrid's
  levels, `EXCHANGES` neighbour exchanges of a rank's surface (6 faces of a cube of n / 3
  nodes a rank, 3 components, 8 bytes), each one latency `LATENCY` plus bytes / `BANDWIDTH`.
"""
from __future__ import annotations

import math

LOCAL = ("rows", "eliminate", "matrix", "rest")     # a rank's own rows: ∝ unknowns a rank
MULTIGRID = ("gamg_setup", "cg")                     # ∝ unknowns a rank × the iterations' growth
LATENCY = 5e-6          # s, one message or one level of an allreduce's tree (an HPC interconnect)
BANDWIDTH = 5e9         # bytes/s a rank's link
EXCHANGES = 4           # neighbour exchanges a level a V-cycle (smoothing before, after; residual; correction)
COARSENING = 8.0        # unknowns a coarse unknown, level to level (smoothed aggregation in 3D)
COARSEST = 1e3          # unknowns of the coarsest level


def levels(n: float) -> int:
    """The multigrid's levels on n unknowns."""
    return 1 + max(0, math.ceil(math.log(n / COARSEST, COARSENING)))


def communication(n: float, p: int, iterations: float) -> float:
    """Seconds of messages of `iterations` CG iterations on n unknowns over p ranks (none on one)."""
    if p == 1:
        return 0.0
    surface = 6 * (n / p / 3) ** (2 / 3) * 3 * 8                    # bytes a rank sends each exchange
    one = 2 * LATENCY * math.log2(p) + levels(n) * EXCHANGES * (LATENCY + surface / BANDWIDTH)
    return iterations * one


def predict(seconds: dict, n1: int, krylov1: int, n: float, p: int, c: float) -> dict:
    """{phase: seconds} of one cold evaluation with n unknowns on p ranks, from `seconds` (the
    phases of `LOCAL`, `MULTIGRID` and "solvability") measured on one rank at n1 unknowns with
    krylov1 CG iterations in all; c the iterations' growth constant."""
    share = n / p / n1
    growth = 1 + c * math.log(n / n1)
    out = {phase: seconds[phase] * share for phase in LOCAL}
    out.update({phase: seconds[phase] * share * growth for phase in MULTIGRID})
    out["solvability"] = seconds["solvability"]          # a small problem on the rigid modes, on every rank
    out["communication"] = communication(n, p, krylov1 * growth)
    return out
