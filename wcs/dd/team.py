r"""The units of a decomposition distributed over the ranks of an MPI communicator.

`Team(comm, units)` assigns every unit (linear subdomain or contact pair) to one
rank — pairs and linear subdomains separately, each by longest-processing-time
first on an estimated cost (local DOFs^1.5, the cost of a sparse 2D
factorization and of its solves), ties by unit index — so that every phase of the
method is balanced: PCG1 (all units), PCG2 (linear subdomains), the contact
solves (pairs). Every rank holds the whole (small) structure of the
decomposition, the replicated interface vectors and the coarse problem; a rank
assembles, factors and solves only the units it owns.

**Deterministic reductions.** An interface vector Σ_u R_uᵀ x_u is not summed by a
floating-point `Allreduce` (whose order depends on the MPI library and the
number of ranks). Each rank computes the contributions x_u of its own units,
the contributions are gathered to every rank (`Allgatherv` of the concatenated
local pieces, Σ_u |Γ_u| numbers — about twice the interface), and every rank
adds them **in unit order**, exactly as the serial loop does. The result is
bitwise the serial one for any number of ranks; the dot products of PCG then
act on identical replicated vectors, so the iterates are identical too.

`comm=None` (or a communicator of size 1) is the serial case: the same code
path without messages. Per-rank timings (seconds) accumulate in `timings`:
`assemble`, `dirichlet`, `neumann`, `coarse`, `contact`, `comm` (gathers,
including the wait for the slowest rank: load imbalance shows there); with the
environment variable WCS_DD_PROBE set, a Barrier before every gather separates that
wait (`wait`) from the transfer (diagnostics only: it costs a collective).
"""
from __future__ import annotations

import os
import time
from collections import defaultdict

import numpy as np


def unit_cost(u) -> float:
    return float(u.dofs.size) ** 1.5


def assign(units, size: int) -> dict:
    """unit index -> rank: LPT per kind (pairs, linear), deterministic."""
    owner = {}
    for kind in ("pair", "linear"):
        group = sorted((u for u in units if u.kind == kind), key=lambda u: (-unit_cost(u), u.index))
        load = [0.0] * size
        for u in group:
            r = min(range(size), key=lambda i: (load[i], i))
            owner[u.index] = r
            load[r] += unit_cost(u)
    return owner


class Team:
    """Owner of every unit, the gathers that sum interface vectors in unit order, timings."""

    def __init__(self, comm, units):
        self.comm = comm if comm is not None and comm.size > 1 else None
        self.size = 1 if self.comm is None else self.comm.size
        self.rank = 0 if self.comm is None else self.comm.rank
        self.owner = assign(units, self.size)
        self.kinds = {u.index: u.kind for u in units}
        self.timings = defaultdict(float)
        self.messages = 0
        self.probe = bool(os.environ.get("WCS_DD_PROBE"))

    def mine(self, u) -> bool:
        return self.owner[u.index] == self.rank

    def local(self, units):
        return [u for u in units if self.owner[u.index] == self.rank]

    # ---- reductions -----------------------------------------------------------------------
    def sum(self, units, pieces: dict, nif: int, tail: tuple = ()) -> np.ndarray:
        """Σ_u R_uᵀ x_u over `units` in their order; `pieces`: {unit index: x_u} for the
        units this rank owns (x_u of shape (|Γ_u|,) + tail). Same bits on every rank."""
        out = np.zeros((nif,) + tail)
        if self.comm is None:
            for u in units:
                out[u.gamma] += pieces[u.index]
            return out
        allp = self.gather_pieces(units, pieces, tail)
        for u in units:
            out[u.gamma] += allp[u.index]
        return out

    def gather_pieces(self, units, pieces: dict, tail: tuple = ()) -> dict:
        """{unit index: x_u} for every unit of `units` on every rank (Allgatherv)."""
        if self.comm is None:
            return dict(pieces)
        from mpi4py import MPI
        t = time.perf_counter()
        if self.probe:                       # diagnostics: separate the wait (imbalance) from the transfer
            self.comm.Barrier()
            self.timings["wait"] += time.perf_counter() - t
        width = int(np.prod(tail)) if tail else 1
        counts = [0] * self.size
        for u in units:
            counts[self.owner[u.index]] += u.gamma.size * width
        own = [u for u in units if self.owner[u.index] == self.rank]
        send = (np.concatenate([np.asarray(pieces[u.index], float).reshape(-1) for u in own])
                if own else np.zeros(0))
        displ = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)
        recv = np.empty(int(sum(counts)))
        self.comm.Allgatherv([send, MPI.DOUBLE], [recv, (counts, tuple(displ)), MPI.DOUBLE])
        allp, pos = {}, list(displ)
        for u in units:
            r = self.owner[u.index]
            n = u.gamma.size * width
            allp[u.index] = recv[pos[r]:pos[r] + n].reshape((u.gamma.size,) + tail)
            pos[r] += n
        self.messages += 1
        self.timings["comm"] += time.perf_counter() - t
        return allp

    def allgather(self, obj) -> list:
        """Python objects of every rank, in rank order (small, rare: status, final pieces)."""
        if self.comm is None:
            return [obj]
        t = time.perf_counter()
        out = self.comm.allgather(obj)
        self.messages += 1
        self.timings["comm"] += time.perf_counter() - t
        return out

    def first_error(self, error):
        """The first rank's error message (or None) on every rank: no rank is left waiting."""
        return next((e for e in self.allgather(error) if e), None)

    def report(self) -> list[dict]:
        """Per-rank timings, gathered (rank order)."""
        mine = dict(self.timings)
        mine["units"] = sum(1 for r in self.owner.values() if r == self.rank)
        mine["pairs"] = sum(1 for i, r in self.owner.items() if r == self.rank and self.kinds[i] == "pair")
        mine["messages"] = self.messages
        mine["rank"] = self.rank
        return self.allgather(mine) if self.comm is not None else [mine]
