"""Running a study: drive a search strategy, evaluate what it asks, record everything.

    ds = wcs.run(study, output=None, resume=False, progress=None)

The runner builds the search `Problem` from the study (`wcs/app/problem.py`), creates the
strategy registered under `search.method` with `numpy.random.default_rng(seed)`, drives it
through `wcs.search.ranges` (the ends of each criterion's range its `sense` asks for, and the
α-levels of a fuzzy study, core first) and answers its batches. Every evaluation becomes one `Record` (`wcs/app/record.py`), failures
included (status code, NaN criteria); the budget is a hard cap on records.

Incremental writing: each finished evaluation goes at once to the evaluation store (one
atomically renamed file per evaluation; under MPI written by the rank that solved it, before
the batch's gather), and the results file is rewritten while the run
goes (`wcs/app/writer.py`). A kill -9 loses the evaluation in flight only; the NetCDF file on
disk is always a complete, readable file of the evaluations up to its last rewrite
(`complete: no` until the run ends; `wcs report` and `wcs solve --worst` say so).

Faults: the output is checked and locked before anything is solved; a second run on the
same output is refused. A run without `resume` starts afresh: an earlier run's results file and
store at its output are removed (`wcs run` asks for `--fresh` first). Ctrl-C (KeyboardInterrupt)
rewrites the results file with every evaluation finished, marked incomplete, and goes on up. A failed write stops the run with `WriteError` and leaves the store
and the last results file intact, so `--resume` continues from there.

Resume: the strategy is deterministic given its seed and the outcomes it is sent, so
`--resume` runs it again from the start and answers every point the store holds (same exact
bits, same study hash) from the store; only new points are solved. An evaluation does not
depend on what was solved before it (the contact solver always starts from the nominal
data's state, see `Model.solve`), so a resumed run gives the same bits as an uninterrupted
one, and so does a run spread over MPI ranks: with the DD solver every evaluation is spread
over all ranks (its subdomains), otherwise rank r solves points r, r + N, ... of each batch
and every rank records every outcome in batch order. With `solver.ranks_per_evaluation: k`
group g of k ranks solves points g, g + N/k, ..., each solve spanning the group, and rank 0's
group the closing solves (`wcs.app.parallel.groups`): the same bits for the same k (on any N),
the serial run's to the solver's tolerance. Fields of the worst case of each criterion are
re-solved at the end.

Timing: `on_event(Event)` is told what the run spends its time on — building the model
("prepare"), each evaluation ("evaluate", with its stage), each batch answered ("batch",
with its stage and the records it added), each MPI gather of a batch ("gather") and each
write of the results file ("write").

`CheckedRunner`, the run of `wcs run`, adds to the results file after the search what drives
each extreme, how far the nominal case leaves small-strain theory and the mesh's share.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import contextlib
import inspect
import itertools
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import StudyError
from ..model.evaluation import Evaluation
from ..group import spanning
from .parallel import groups, rank, world
from .problem import build_problem
from ..progress import phase, reporting
from .record import Ledger, from_evaluation, open_store
from ..search import STRATEGIES, Outcome
from ..search.ranges import ranges
from ..status import Status
from ..results.store import WriteError, key
from ..study.data import parameter_vector
from ..study.fuzzy import alpha_cut
from ..study.load import load_study
from ..dynamics.history import evaluator_for
from ..model.validity import warnings as validity_warnings
from ..results import meshcheck
from ..results.dataset import scalars, write_netcdf
from ..results.drivers import drivers
from ..results.extremes import support_extremes
from ..results.verdict import attributes as verdict_attributes
from .writer import Final, Writer, claim_output, extremes_of, widest_maxima

if TYPE_CHECKING:
    import xarray as xr


def get_strategy(name: str):
    """The strategy factory registered under `name` (search.method)."""
    if name not in STRATEGIES:
        raise StudyError(f"unknown search method '{name}' (available: {', '.join(sorted(STRATEGIES))})",
                         path="search.method")
    return STRATEGIES[name]


@dataclass(frozen=True)
class Event:
    """A timing the run reports: `what` took `seconds` (wall clock, on this rank)."""
    what: str                # "prepare" | "evaluate" | "batch" | "gather" | "write"
    seconds: float
    stage: str = ""          # the search stage of an evaluation, a batch or a gather
    records: int = 0         # records a batch added (solved or from the store)


class Runner:
    """Answers the batches of a search (or a sweep's grid) for a study: from this run's records,
    from the store, or by solving (spread over MPI ranks), and keeps the results file written."""

    def __init__(self, study, output=None, resume=False, progress=None, kind="run", evaluator=None, where=None,
                 on_event: Callable[[Event], None] | None = None):
        """output: the results file (None: the study's `output`; False: in memory only).
        where: (file, key path) that named the output, for its errors (default: the study's
        `output` when `output` is None). on_event: told every `Event`."""
        self.comm = world()
        self.root = rank(self.comm) == 0          # only rank 0 writes files and shows progress
        # groups of ranks_per_evaluation ranks answer the batches, each solve spanning its group
        self.group, self.group_index, self.groups = groups(self.comm, study.solver.ranks_per_evaluation,
                                                           str(study.file))
        self.lead = self.root or self.group is not None and self.group_index == 0   # solves the closing evaluations
        self.study = study
        self.kind = kind
        self.on_event = on_event
        if where is None:
            where = (str(study.file), "output") if output is None else (None, None)
        self.output = None if output is False else Path(output or study.output)
        self.lock = None
        if self.output is not None:                # before anything is meshed or solved
            self.lock = claim_output(self.comm, self.output, where, study.sha256 if resume else None)
        try:
            with self._reporting(progress):
                self._prepare(study, progress, kind, resume, evaluator)
        except BaseException:
            self.release()
            raise

    def _prepare(self, study, progress, kind, resume, evaluator) -> None:
        t0 = time.perf_counter()
        # MPI: each rank solves its share of a batch, with the DD solver too (its model is serial:
        # a whole `dd` study on 2 ranks measured faster so than with each DD solve spread over them)
        self.evaluator = evaluator or evaluator_for(study)
        self.criteria = [c.name for c in self.evaluator.criteria]
        self.names = list(study.parameters.names)
        self.sweep_paths = list(study.sweep.grid if study.sweep else {}) if kind == "sweep" else None
        self.progress = progress if self.root else None
        self.final: Final | None = None        # set when the run is finished
        self.stats = {"solved": 0, "from_store": 0, "solve_time": 0.0, "write_time": 0.0, "writes": 0,
                      "field_solves": 0}
        try:
            self.has_gradients = "gradients" in inspect.signature(self.evaluator.evaluate).parameters
        except (TypeError, ValueError):
            self.has_gradients = False
        self.writer = Writer(study, self.evaluator, self.output, kind, self.sweep_paths, self.root,
                             self.has_gradients, (1 if self.comm is None else self.comm.size,
                                                  1 if self.group is None else self.group.size))
        if self.output is not None and self.root and not resume:       # a new run: no earlier results beside it
            try:
                self.output.unlink(missing_ok=True)
            except OSError as e:
                raise WriteError(f"cannot remove the earlier results file {self.output}: {e.strerror or e}") from None
        store = None if self.output is None else open_store(self.comm, self.output, study.sha256, kind, resume)
        self.ledger = Ledger(self.criteria, store, writes=self.root)
        self._report(Event("prepare", time.perf_counter() - t0))

    def _reporting(self, progress=None):
        """The run's progress is the current one (its phases: meshing, the worst cases' fields, ...)."""
        progress = progress if progress is not None else getattr(self, "progress", None)
        return reporting(progress) if progress is not None and self.root else contextlib.nullcontext()

    def release(self) -> None:
        """Give the output up to the next run (the lock; the process's end does it too)."""
        if self.lock is not None:
            self.lock.release()
            self.lock = None

    def _report(self, event: Event) -> None:
        if self.on_event is not None:
            self.on_event(event)

    # ---- evaluation (the seam for parallel workers) ----------------------------------------
    def evaluate(self, point, gradients: bool, stage: str) -> Evaluation:
        """Solve a point (a parameter vector or a {path: value} mapping); never raises for a
        failing data set: the Evaluation carries the status."""
        t0 = time.perf_counter()
        try:
            if gradients and self.has_gradients:
                ev = self.evaluator.evaluate(point, gradients=True)
            else:
                ev = self.evaluator.evaluate(point)
        except (KeyboardInterrupt, StudyError):
            raise
        except Exception as e:  # noqa: BLE001 - failures are data
            try:
                x = parameter_vector(self.study, point)
            except Exception:  # noqa: BLE001
                x = np.full(len(self.names), np.nan)
            nan = {c: float("nan") for c in self.criteria}
            ev = Evaluation(x, nan, Status.OTHER_FAILURE, f"{type(e).__name__}: {e}", 0, time.perf_counter() - t0)
        self._report(Event("evaluate", time.perf_counter() - t0, stage))
        return ev

    def _append(self, k: str, rec: dict, ev=None, kept: bool = False) -> int:
        row = self.ledger.append(k, rec, ev, kept)
        if self.progress is not None:
            self.progress.update(len(self.ledger.records), rec, self.ledger.best)
        if self.writer.due():
            self._write()
        return row

    # ---- answering a batch ------------------------------------------------------------------
    def answer(self, points, stage: str, gradients: bool, budget: int | None,
               sweeps=None) -> list[Outcome]:
        """One Outcome per point, in order, until the budget is spent (then a shorter list)."""
        t0 = time.perf_counter()
        ledger = self.ledger
        before = len(ledger.records)
        want_grad = gradients and self.has_gradients
        points = list(points)
        if self.progress is not None:
            self.progress.batch(stage, len(points))
        rows: list[int] = []
        pending: list[tuple[str, object, object]] = []   # (key, point, sweep values) to solve

        def flush():
            if not pending:
                return
            batch = list(pending)
            pending.clear()

            def done(i, ev, rec=None, kept=False):
                k, _, sv = batch[i]
                rec = rec or from_evaluation(ev, self.criteria, len(self.names), stage, gradients, sv)
                self.stats["solved"] += 1
                self.stats["solve_time"] += rec["wall_time"]
                rows.append(self._append(k, rec, ev, kept))

            if self.comm is None:             # serial
                for i, (_, p, _) in enumerate(batch):
                    done(i, self.evaluate(p, gradients, stage))
                return
            # MPI: group g solves points g, g+G, ... (G groups; each rank its own group where
            # ranks_per_evaluation is 1) and its rank 0 stores each record as soon as it is solved
            # (a crash mid-batch loses only the evaluations in flight); all ranks then append every
            # record in batch order
            keeper = self.group is None or self.group.rank == 0
            mine, fault = [], None
            with spanning(self.group):
                for i in range(self.group_index, len(batch), self.groups):
                    k, p, sv = batch[i]
                    rec = from_evaluation(self.evaluate(p, gradients, stage), self.criteria, len(self.names),
                                          stage, gradients, sv)
                    if keeper and fault is None:
                        try:
                            self.ledger.keep(k, rec)
                        except WriteError as e:     # told to every rank after the gather
                            fault = str(e)
                    mine.append((i, rec))
            t = time.perf_counter()
            parts = self.comm.allgather((mine, fault) if keeper else ([], None))
            self._report(Event("gather", time.perf_counter() - t, stage))
            faults = [f for _, f in parts if f is not None]
            if faults:
                raise WriteError(faults[0])
            for i, rec in sorted((r for part, _ in parts for r in part), key=lambda t: t[0]):
                done(i, None, rec, kept=True)

        used = len(ledger.records)
        for i, p in enumerate(points):
            sv = None if sweeps is None else np.asarray(sweeps[i], float)
            k = key(self.study.sha256, self._vector(p), sv)
            row = ledger.row(k, want_grad)
            if row is not None:
                flush()
                rows.append(row)
                continue
            if budget is not None and used >= budget:
                break
            used += 1
            stored = ledger.stored(k, want_grad, stage)
            if stored is not None:
                flush()
                self.stats["from_store"] += 1
                rows.append(self._append(k, stored))
                continue
            pending.append((k, p, sv))
        flush()
        outcomes = [ledger.outcome(r) for r in rows]
        self._report(Event("batch", time.perf_counter() - t0, stage, len(ledger.records) - before))
        return outcomes

    def _vector(self, p) -> np.ndarray:
        if isinstance(p, Mapping):
            return parameter_vector(self.study, p)
        return np.ascontiguousarray(p, dtype=float)

    # ---- the search ---------------------------------------------------------------------------
    def run(self, strategy=None) -> xr.Dataset:
        try:
            with self._reporting():
                return self._search(strategy)
        except KeyboardInterrupt:
            self._keep()
            raise
        finally:
            self.release()

    def sweep(self) -> xr.Dataset:
        try:
            with self._reporting():
                return self._sweep()
        except KeyboardInterrupt:
            self._keep()
            raise
        finally:
            self.release()

    def _keep(self) -> None:
        """Ctrl-C: the results file rewritten with every evaluation finished, marked incomplete
        (`--resume` finishes it; the store holds them already, a failed write loses nothing)."""
        with contextlib.suppress(WriteError):
            self.writer.write(self.ledger, self.stats, None)

    def _search(self, strategy) -> xr.Dataset:
        search = self.study.search
        budget = search.budget
        factory = strategy or get_strategy(search.method)
        problem = build_problem(self.study, self.evaluator)
        senses = {c.name: c.sense for c in self.study.criteria}
        levels = self.study.levels
        cuts = None if levels is None else [(a, *alpha_cut(self.study, a)) for a in levels]
        gen = ranges(factory, problem, search, np.random.default_rng(search.sample.seed),
                     {c: senses[c] for c in self.criteria}, cuts)
        if self.progress is not None:
            self.progress.start(budget, self.criteria, budget=True)
        result = None
        try:
            batch = next(gen)
            while True:
                pts = np.atleast_2d(np.asarray(batch.points, float))
                if len(self.ledger.records) >= budget and len(pts):
                    outcomes = []
                else:
                    outcomes = self.answer(pts, batch.stage, bool(batch.gradients), budget)
                short = len(outcomes) < len(pts)
                batch = gen.send(outcomes)
                if short and len(self.ledger.records) >= budget:   # told it is out of budget and it asks again
                    gen.close()
                    break
        except StopIteration as stop:
            result = stop.value
        finally:
            if self.progress is not None:
                self.progress.finish()
        return self.finish(result)

    def _sweep(self) -> xr.Dataset:
        grid = self.study.sweep.grid if self.study.sweep else None
        if not grid:
            raise StudyError("the study has no `sweep:` block with a `grid`", file=str(self.study.file), path="sweep")
        paths = list(grid)
        combos = list(itertools.product(*(grid[p] for p in paths)))
        points = [dict(zip(paths, map(float, c))) for c in combos]
        if self.progress is not None:
            self.progress.start(len(points), self.criteria)
        try:
            self.answer(points, "sweep", False, None, sweeps=[list(map(float, c)) for c in combos])
        finally:
            if self.progress is not None:
                self.progress.finish()
        return self.finish(None)

    # ---- the end ------------------------------------------------------------------------------
    def finish(self, result: list | None) -> xr.Dataset:
        """The end: every extreme (`Extreme`, per criterion sense and α-level) from the records,
        certified as the search (`result`, its extremes; None for a sweep) left it, and the fields
        of each criterion's worst case re-solved."""
        extremes = extremes_of(self.study, self.ledger.records, self.criteria, self.kind, result or [])
        worst, certificate, notes = widest_maxima(extremes, self.criteria)
        with spanning(self.group):            # rank 0's group solves them; rank 0 keeps them
            fields = self._worst_fields(worst) if self.lead else {c: None for c in self.criteria}
        self.final = Final(worst, certificate, notes, fields, extremes)
        return self._write()

    def _worst_fields(self, worst: dict) -> dict:
        """Fields of each criterion's worst case, re-solved (an evaluation does not depend on history)."""
        fields, by_key = {}, {}
        records = [self.ledger.records[worst[c][2]] for c in self.criteria if c in worst]
        with phase("worst cases' fields", len({key(self.study.sha256, r["x"], r.get("sweep")) for r in records})) \
                as progress:
            for c in self.criteria:
                if c not in worst:
                    fields[c] = None
                    continue
                rec = self.ledger.records[worst[c][2]]
                k = key(self.study.sha256, rec["x"], rec.get("sweep"))
                if k not in by_key:
                    point = rec["x"]
                    if rec.get("sweep") is not None:
                        point = dict(zip(self.names, map(float, rec["x"])))
                        point.update(zip(self.sweep_paths, map(float, rec["sweep"])))
                    ev = self.evaluate(point, False, "worst-fields")
                    self.stats["field_solves"] += 1
                    by_key[k] = ev.field_data if ev.status == 0 else None
                    progress.step()
                fields[c] = by_key[k]
        return fields

    def _write(self) -> xr.Dataset:
        ds = self.writer.write(self.ledger, self.stats, self.final)
        self.stats["write_time"] += self.writer.last_cost
        self.stats["writes"] += 1
        self._report(Event("write", self.writer.last_cost))
        return ds


# ---------------------------------------------------------------- public API


def _as_study(study):
    return load_study(study) if isinstance(study, (str, Path)) else study


class CheckedRunner(Runner):
    """A run whose results file also says how far its nominal case leaves small-strain theory
    (`wcs/model/validity.py`), what drives each extreme (`wcs/results/drivers.py`) and, unless
    `mesh_check` is False, how much of it is the mesh (`wcs/results/meshcheck.py`): all are added after
    the search, under the run's lock, and the file is written again."""

    def __init__(self, *args, mesh_check: bool = True, **kw):
        self.mesh_check = mesh_check
        super().__init__(*args, **kw)

    def finish(self, result) -> xr.Dataset:
        ds = super().finish(result)
        if self.kind != "run" or not self.lead:
            return ds
        with spanning(self.group):      # rank 0's group solves them, as the worst cases' fields
            return self._checked(ds)

    def _checked(self, ds) -> xr.Dataset:
        found = support_extremes(ds)
        with phase("drivers") as progress:              # solves: as many as the extremes need
            def solve(x, gradients=True):
                progress.step()
                return self.evaluate(x, gradients, "drivers")
            parts = [drivers(ds, found, solve)]
        with phase("nominal case"):
            parts.append(self.nominal())
        parts.append(meshcheck.mesh_check(self.study, ds, found)
                     if self.mesh_check else meshcheck.skipped("skipped (--no-mesh-check)"))
        for part in parts:
            ds = ds.assign_coords(part.coords).assign(part.data_vars)
            ds.attrs.update(part.attrs)
        ds.attrs["small_strain"] = "\n".join(validity_warnings(ds))    # with the nominal case
        ds.attrs.update(verdict_attributes(ds))      # read again with the mesh's share
        if self.output is not None and self.root:
            write_netcdf(ds, self.output)
        return ds

    def nominal(self) -> xr.Dataset:
        """`nominal_small_strain_*` (wcs/model/validity.py) of the nominal data set, solved once more
        (NaN where it fails: its status is the search's business)."""
        ev = self.evaluate(self.study.nominal(), False, "nominal")
        ok = ev.status == 0
        return scalars({f"nominal_{name}": ((), float(ev.field_data[name].values) if ok else np.nan,
                                 dict(ev.field_data[name].attrs) if ok else {})
                 for name in ("small_strain_displacement", "small_strain_gradient")})


def run(study, output=None, resume=False, progress=None, *, strategy=None, on_event=None) -> xr.Dataset:
    """The whole worst-scenario study -> xarray.Dataset (the results file's layout).

    output: results file (default: the study's `output`; False: keep it in memory only).
    resume: continue an interrupted run of the same study file from its store.
    progress: a `wcs.progress.Progress` (None: silent).
    strategy: a strategy factory (problem, config, rng) -> generator; default: the registry's
              entry for `search.method`.
    on_event: told every timing `Event` of the run.
    """
    study = _as_study(study)
    return Runner(study, output, resume, progress, on_event=on_event).run(strategy)


def sweep(study, output=None, resume=False, progress=None, *, on_event=None) -> xr.Dataset:
    """The full factorial grid of the study's `sweep:` block, in the layout of a run."""
    study = _as_study(study)
    return Runner(study, output, resume, progress, kind="sweep", on_event=on_event).sweep()
