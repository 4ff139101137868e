r"""The units of a decomposition distributed over the ranks of an MPI communicator.

`Team(comm, units, dim, measured)` assigns every unit (linear subdomain or contact pair) to
one rank by its cost in each *phase* of an evaluation — the numeric factorization with the
dense Schur block, the load's condensation and the products with the coarse basis
(`assemble`: a data set's set-up), the dense Dirichlet and Neumann products of the PCG
iterations (`iterate`: all units), the local contact solves and the
linearisations (`contact`: pairs) — measured per unit in the first evaluation on this many
ranks (`measured`, gathered so every rank holds the same numbers), before it estimated from
the unit's sizes (`phase_costs`; measured on Hertz at 1.05e5 unknowns: the pair's rank
assembled 1.46 s against 0.85 s, its dense algebra beyond the estimate). A phase ends at a
gather, so an evaluation takes Σ_phase max_rank(load) seconds: the units, heaviest first
(ties by index), each go to the rank that keeps that sum least (ties: the lower rank).
Per kind longest-processing-time (the earlier rule) put Hertz's one pair (a third of the
iteration cost) with half of the linear subdomains on one rank. The assignment changes the
cost only: the results are bitwise the same for any (see below).

Every rank holds the whole (small) structure of the decomposition, the replicated
interface vectors and the coarse problem; a rank assembles, factors and solves only the
units it owns.

**Deterministic reductions.** An interface vector Σ_u R_uᵀ x_u is not summed by a
floating-point `Allreduce` (whose order depends on the MPI library and the
number of ranks). Each rank computes the contributions x_u of its own units,
the contributions are gathered to every rank (`Allgatherv` of the concatenated
local pieces, Σ_u |Γ_u| numbers — about twice the interface), and every rank
adds them **in unit order**, exactly as the serial loop does. The result is
bitwise the serial one for any number of ranks (and any assignment); the dot products of PCG then
act on identical replicated vectors, so the iterates are identical too.

`comm=None` (or a communicator of size 1) is the serial case: the same code
path without messages. Per-rank timings (seconds) accumulate in `timings`:
`assemble`, `dirichlet`, `neumann`, `coarse`, `contact`, `comm` (gathers,
including the wait for the slowest rank: load imbalance shows there), `comm_cpu` (the
process's CPU time in the gathers: MPI polls while it waits); with the
environment variable WCS_DD_PROBE set, a Barrier before every gather separates that
wait (`wait`) from the transfer (diagnostics only: it costs a collective).
"""
from __future__ import annotations

import os
import time
from collections import defaultdict
from contextlib import contextmanager

import numpy as np


PHASES = ("assemble", "iterate", "contact")
FLOPS = 4e9            # dense factorization flops per second (one core, measured on the Schur blocks)
ENTRIES = 1.25e9       # dense matrix entries per second of a matrix-vector product (memory bound)
PRODUCTS = 100         # S and S† products per unit in one solve (Hertz, 1e5 unknowns: 111 and 87)
NEWTON_STEPS = 30      # semismooth Newton steps of a pair's local contact solves in one solve (tunnel: 12 calls)


def phase_costs(u, dim: int) -> np.ndarray:
    """Estimated seconds of unit `u` in each of `PHASES`: the sparse factor (nested dissection:
    n^{3(d−1)/d} flops) plus its dense Schur block X (|X|³/3); `PRODUCTS` products with the
    dense S and S† on B (|B|² entries each); for a pair, the Cholesky factor of its condensed
    contact block (|c|³/3) and `NEWTON_STEPS` active-set systems on its d·m contact rows.
    Calibrated on Hertz (1e5 unknowns, 12 subdomains: measured factor times 25–410 ms
    against 24–390 ms estimated)."""
    n, x, b = float(u.dofs.size), float(u.X.size), float(u.B.size)
    assemble = (100 * n ** (3 * (dim - 1) / dim) + x ** 3 / 3) / FLOPS
    iterate = 2 * PRODUCTS * b * b / ENTRIES
    contact = 0.0
    if u.kind == "pair":
        rows = dim * float(u.rows.size)
        contact = (float(u.c.size) ** 3 / 3 + NEWTON_STEPS * rows ** 3 / 3) / FLOPS
    return np.array([assemble, iterate, contact])


def assign(units, size: int, dim: int, measured: dict | None = None) -> dict:
    """unit index -> rank: heaviest unit first (total cost, ties by index), each to the rank
    that keeps Σ_phase max_rank(load) least (ties: the lower rank). Costs: `measured` ({unit
    index: seconds per phase}) where given, else the estimates `phase_costs`; a function of
    them only."""
    cost = measured if measured is not None else {u.index: phase_costs(u, dim) for u in units}
    load = np.zeros((size, len(PHASES)))
    owner = {}
    for u in sorted(units, key=lambda u: (-cost[u.index].sum(), u.index)):
        span = [(load + np.where(np.arange(size)[:, None] == r, cost[u.index], 0.0)).max(axis=0).sum()
                for r in range(size)]
        r = int(np.argmin(span))
        owner[u.index] = r
        load[r] += cost[u.index]
    return owner


class Team:
    """Owner of every unit, the gathers that sum interface vectors in unit order, timings."""

    def __init__(self, comm, units, dim: int = 2, measured: dict | None = None, refactor: bool = True):
        """`measured`: {number of ranks: {unit index: seconds per phase}} of an earlier
        evaluation (`Team.measured`), the costs the assignment uses for this many ranks;
        `refactor` False: the units keep their factors (the same stiffness data as the last
        evaluation), so the assembly weighs nothing (measured on Hertz: by the first
        evaluation's costs the pair's rank took 3 linear subdomains, and on the same data
        the other rank did 3× its products)."""
        self.comm = comm if comm is not None and comm.size > 1 else None
        self.size = 1 if self.comm is None else self.comm.size
        self.rank = 0 if self.comm is None else self.comm.rank
        costs = (measured or {}).get(self.size)
        self.assigned_by = "measured"
        if costs is None or any(u.index not in costs for u in units):
            costs, self.assigned_by = {u.index: phase_costs(u, dim) for u in units}, "estimate"
        if not refactor:
            costs = {i: np.where(np.arange(len(PHASES)) == PHASES.index("assemble"), 0.0, c) for i, c in costs.items()}
        self.owner = assign(units, self.size, dim, costs)
        self.cost = sum((costs[u.index] for u in units if self.owner[u.index] == self.rank), np.zeros(len(PHASES)))
        self.spent = defaultdict(lambda: [0.0] * len(PHASES))     # own units' measured seconds per phase
        self.kinds = {u.index: u.kind for u in units}
        self.timings = defaultdict(float)
        self.messages = 0
        self.probe = bool(os.environ.get("WCS_DD_PROBE"))
        self._plans = {}                   # `_Plan` of every unit list summed (by unit indices)

    def mine(self, u) -> bool:
        return self.owner[u.index] == self.rank

    def local(self, units):
        return [u for u in units if self.owner[u.index] == self.rank]

    def each(self, phase: str, units, f) -> dict:
        """{u.index: f(u)} for this rank's units of `units`, each call's seconds charged to
        the unit's `phase`."""
        out, j, owner, rank, clock = {}, PHASES.index(phase), self.owner, self.rank, time.perf_counter
        for u in units:
            if owner[u.index] == rank:
                t = clock()
                out[u.index] = f(u)
                self.spent[u.index][j] += clock() - t
        return out

    def charge(self, u, phase: str, since: float) -> None:
        """Charge the seconds since `since` to unit `u`'s `phase` (a unit this rank owns)."""
        self.spent[u.index][PHASES.index(phase)] += time.perf_counter() - since

    def measured(self) -> dict:
        """{unit index: seconds per phase} of every unit, gathered: the same on every rank."""
        return {i: np.asarray(c) for part in self.allgather(dict(self.spent)) for i, c in part.items()}

    # ---- reductions -----------------------------------------------------------------------
    def sum(self, units, pieces: dict, nif: int, tail: tuple = ()) -> np.ndarray:
        """Σ_u R_uᵀ x_u over `units` in their order; `pieces`: {unit index: x_u} for the
        units this rank owns (x_u of shape (|Γ_u|,) + tail). Same bits on every rank.

        A vector (no tail) by one gather and one `np.bincount` over the pieces in unit order
        (`_Plan`): bincount adds its weights one by one in input order from 0, so every entry
        is ((0 + x_a) + x_b) + … in unit order, the bits of the loop over the units. Measured on
        Hertz's 11 units (1.05e5 unknowns): 67–71 → 32–33 µs a sum on 2 ranks (the gather alone
        13 µs), 23–34 → 12–25 µs serial; a solve sums about 110 times."""
        if tail:
            out = np.zeros((nif,) + tail)
            allp = self.gather_pieces(units, pieces, tail)
            for u in units:
                out[u.gamma] += allp[u.index]
            return out
        plan = self._plan(units)
        send = np.concatenate([pieces[i] for i in plan.own]) if plan.own else np.zeros(0)
        if self.comm is None:
            values = send
        else:
            values = self._allgatherv(send, plan.counts, plan.displ)[plan.order]
        return np.bincount(plan.gamma, values, minlength=nif).astype(float, copy=False)   # int64 when empty

    def _plan(self, units) -> "_Plan":
        key = tuple(u.index for u in units)
        plan = self._plans.get(key)
        if plan is None:
            plan = self._plans[key] = _Plan(units, self.owner, self.rank, self.size)
        return plan

    def gather_pieces(self, units, pieces: dict, tail: tuple = ()) -> dict:
        """{unit index: x_u} for every unit of `units` on every rank (Allgatherv)."""
        if self.comm is None:
            return dict(pieces)
        width = int(np.prod(tail)) if tail else 1
        counts = [0] * self.size
        for u in units:
            counts[self.owner[u.index]] += u.gamma.size * width
        own = [u for u in units if self.owner[u.index] == self.rank]
        send = (np.concatenate([np.asarray(pieces[u.index], float).reshape(-1) for u in own])
                if own else np.zeros(0))
        displ = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)
        recv = self._allgatherv(send, counts, tuple(displ))
        allp, pos = {}, list(displ)
        for u in units:
            r = self.owner[u.index]
            n = u.gamma.size * width
            allp[u.index] = recv[pos[r]:pos[r] + n].reshape((u.gamma.size,) + tail)
            pos[r] += n
        return allp

    @contextmanager
    def _message(self):
        """One collective message, counted and timed (`comm`, `comm_cpu`); with `probe` its wait
        for the slowest rank first, apart (`wait`: the imbalance, not the transfer)."""
        t, c = time.perf_counter(), time.process_time()
        if self.probe:
            self.comm.Barrier()
            self.timings["wait"] += time.perf_counter() - t
        yield
        self.messages += 1
        self.timings["comm"] += time.perf_counter() - t
        self.timings["comm_cpu"] += time.process_time() - c

    def _allgatherv(self, send: np.ndarray, counts, displ) -> np.ndarray:
        """Every rank's `send` concatenated in rank order (`counts` numbers from each)."""
        from mpi4py import MPI
        recv = np.empty(int(sum(counts)))
        with self._message():
            self.comm.Allgatherv([np.asarray(send, float), MPI.DOUBLE], [recv, (counts, displ), MPI.DOUBLE])
        return recv

    def allgather(self, obj) -> list:
        """Python objects of every rank, in rank order (small, rare: status, final pieces)."""
        if self.comm is None:
            return [obj]
        with self._message():
            return self.comm.allgather(obj)

    def first_error(self, error):
        """The first rank's error message (or None) on every rank: no rank is left waiting."""
        return next((e for e in self.allgather(error) if e), None)

    def report(self) -> list[dict]:
        """Per-rank timings, gathered (rank order)."""
        mine = dict(self.timings)
        mine["units"] = sum(1 for r in self.owner.values() if r == self.rank)
        mine["pairs"] = sum(1 for i, r in self.owner.items() if r == self.rank and self.kinds[i] == "pair")
        mine["messages"] = self.messages
        mine["estimate"] = dict(zip(PHASES, self.cost.tolist()))      # the seconds the assignment counted
        mine["assigned_by"] = self.assigned_by                          # "measured" or "estimate"
        mine["rank"] = self.rank
        return self.allgather(mine) if self.comm is not None else [mine]


class _Plan:
    """How `Team.sum` gathers and adds the pieces of a list of units: this rank's units (in
    unit order), the numbers each rank sends (its units' pieces in unit order, concatenated)
    and where they land, `order`: the received numbers' positions in unit order, `gamma`: the
    interface position of each of those."""

    def __init__(self, units, owner: dict, rank: int, size: int):
        self.own = [u.index for u in units if owner[u.index] == rank]
        sizes = np.array([u.gamma.size for u in units], dtype=np.int64)
        ranks = np.array([owner[u.index] for u in units], dtype=np.int64)
        self.counts = [int(sizes[ranks == r].sum()) for r in range(size)]
        self.displ = tuple(int(x) for x in np.concatenate([[0], np.cumsum(self.counts)[:-1]]))
        start = np.zeros(len(units), dtype=np.int64)          # each unit's first number in the buffer
        for r in range(size):
            mine = np.flatnonzero(ranks == r)
            start[mine] = self.displ[r] + np.concatenate([[0], np.cumsum(sizes[mine])[:-1]])
        self.order = (np.concatenate([s + np.arange(n) for s, n in zip(start, sizes)]) if len(units)
                      else np.zeros(0, dtype=np.int64))
        self.gamma = (np.concatenate([u.gamma for u in units]) if len(units) else np.zeros(0, dtype=np.int64))
