"""Running a study: drive a search strategy, evaluate what it asks, record everything.

    ds = wcs.run(study, output=None, resume=False, progress=None)

The runner builds the search `Problem` from the study (box, criteria, the
Lipschitz slip-limit profiles as linear constraints), creates the strategy
from the registry with `numpy.random.default_rng(seed)`, and answers its
batches. Every evaluation becomes one row of the results file, failures
included (status code, NaN criteria); the budget is a hard cap on rows.

Incremental writing: each finished evaluation goes at once to the evaluation
store (`wcs/store.py`, one atomically renamed file per evaluation), and the
NetCDF file is rewritten from memory (temp + rename) after an evaluation
whenever the time since the last rewrite is at least 20 times what that
rewrite cost — at most 5% overhead — and always at the end. A kill -9 loses
the evaluation in flight only; the NetCDF on disk is always a complete,
readable file of the evaluations up to its last rewrite (`complete: no` until
the run ends; `wcs report` and `wcs solve --worst` say so).

Faults: the output is checked (not a directory, a name the filesystem takes,
its folder creatable) and locked (`OUT.lock`, see `wcs/store.py`) before
anything is solved; a second run on the same output is refused. A failed
write stops the run with `WriteError` and leaves the store and the last
results file intact, so `--resume` continues from there.

Resume: the strategy is deterministic given its seed and the outcomes it is
sent, so `--resume` runs it again from the start and answers every point the
store holds (same exact bits, same study hash) from the store; only new
points are solved. An evaluation does not depend on what was solved before it
(the contact solver always starts from the nominal data's state, see
`Model.solve`), so a resumed run gives the same bits as an uninterrupted one,
and so does a run spread over MPI ranks. Fields of the worst case of each
criterion are re-solved at the end.

`evaluate_batch(points, gradients)` is the one place evaluations happen: the
seam where parallel workers (MPI) plug in.
"""
from __future__ import annotations

import datetime as _dt
import inspect
import itertools
import math
import sys
import time
from pathlib import Path

import numpy as np
import xarray as xr

from .errors import StudyError
from .search import Outcome, Problem, Worst
from .store import OutputLock, Store, WriteError, check_output, incomplete_run, key, store_path, stored_count

OTHER_FAILURE = 6            # wcs.evaluation.STATUS: "other failure"
WRITE_OVERHEAD = 0.04        # NetCDF rewrites take at most this share of the time between them (< 5% of solve time)


# ---------------------------------------------------------------- the search problem


def contact_length(evaluator, contact: str) -> float:
    """Length of the slave side of a contact pair (sum of its facet lengths)."""
    scene = evaluator.study.scene
    slave = scene["contacts"][contact]["slave"]
    mesh = evaluator.smesh.mesh
    facets = mesh.facets[:, evaluator.smesh.boundaries[slave]]
    d = mesh.p[:, facets[1]] - mesh.p[:, facets[0]]
    return float(np.sum(np.hypot(d[0], d[1])))


def lipschitz_constraints(study, evaluator):
    """A x <= b for |g[i+1] - g[i]| <= C ds of every slip-limit profile (None, None if none)."""
    rows, rhs, start = [], [], 0
    n = len(study.parameters)
    for entry in study.uncertain:
        count = entry.get("points", 1)
        if "points" in entry and "lipschitz" in entry:
            contact = entry["path"].split(".")[1]
            ds = contact_length(evaluator, contact) / (count - 1)
            bound = float(entry["lipschitz"]) * ds
            for i in range(start, start + count - 1):
                for sign in (1.0, -1.0):
                    a = np.zeros(n)
                    a[i + 1], a[i] = sign, -sign
                    rows.append(a)
                    rhs.append(bound)
        start += count
    if not rows:
        return None, None
    return np.array(rows), np.array(rhs)


def build_problem(study, evaluator) -> Problem:
    A, b = lipschitz_constraints(study, evaluator)
    return Problem(names=list(study.parameters.names),
                   lower=np.asarray(study.parameters.lower, float).copy(),
                   upper=np.asarray(study.parameters.upper, float).copy(),
                   criteria=[c.name for c in evaluator.criteria], A_ub=A, b_ub=b)


def get_strategy(name: str):
    """The strategy factory registered under `name` (search.method)."""
    try:
        from .search.registry import STRATEGIES
    except ImportError as e:
        raise RuntimeError(f"no search strategies are available ({e})") from None
    if name not in STRATEGIES:
        raise StudyError(f"unknown search method '{name}' (available: {', '.join(sorted(STRATEGIES))})",
                         path="search.method")
    return STRATEGIES[name]


# ---------------------------------------------------------------- the runner


class Runner:
    """Evaluates points for a run or a sweep, keeps the record, writes the results file."""

    def __init__(self, study, output=None, resume=False, progress=None, kind="run", evaluator=None, where=None):
        """where: (file, key path) that named the output, for its errors (default: the study's
        `output` when `output` is None)."""
        from .parallel import agree, rank, world
        self.comm = world()
        self.root = rank(self.comm) == 0          # only rank 0 writes files and shows progress
        self.study = study
        self.kind = kind
        if where is None:
            where = (str(study.file), "output") if output is None else (None, None)
        self.output = None if output is False else Path(output or study.output)
        self.store = self.lock = None
        if self.output is not None:                # before anything is meshed or solved
            error = None
            if self.root:
                try:
                    check_output(self.output, *where)
                    self.lock = OutputLock(self.output, *where)
                    if resume:
                        self._check_resumable()
                except StudyError as e:
                    error = e
                    self.release()
            agree(self.comm, error)                # every rank raises, or every rank goes on
        try:
            self._prepare(study, progress, kind, resume, evaluator)
        except BaseException:
            self.release()
            raise

    def _prepare(self, study, progress, kind, resume, evaluator) -> None:
        from .evaluation import Evaluator
        from .parallel import agree
        self.evaluator = evaluator or Evaluator(study)
        # MPI: with the DD solver every evaluation is spread over all ranks (its subdomains);
        # otherwise each rank solves its share of a batch (evaluation-level parallelism)
        self.split_batches = self.comm is not None and self.evaluator.model.solver_method != "dd"
        if self.comm is not None and not self.split_batches:
            self.evaluator.model.comm = self.comm
        self.criteria = [c.name for c in self.evaluator.criteria]
        self.names = list(study.parameters.names)
        self.progress = progress if self.root else None
        self.records: list[dict] = []
        self.memo: dict[str, int] = {}         # key -> row of its first evaluation in this run
        self.best: dict[str, float] = {}
        self.best_row: dict[str, int] = {}
        self.live_fields: dict = {}            # criterion -> fields of its best so far (this session)
        self.final = None                      # (worst, certificate, notes, fields) when finished
        self.stats = {"solved": 0, "from_store": 0, "solve_time": 0.0, "write_time": 0.0, "writes": 0,
                      "field_solves": 0}
        self.created = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        from .results import provenance
        self._provenance = provenance(study, self.evaluator)
        self._last_write_end = 0.0
        self._last_write_cost = 0.0
        try:
            self._has_gradients = "gradients" in inspect.signature(self.evaluator.evaluate).parameters
        except (TypeError, ValueError):
            self._has_gradients = False
        if self.output is not None:
            error = None
            if self.root:
                try:
                    self.store = Store(store_path(self.output), study.sha256, kind=kind, fresh=not resume)
                except (StudyError, WriteError) as e:
                    error = e
            agree(self.comm, error)
            if not self.root:                      # the others read the store rank 0 prepared
                self.store = Store(store_path(self.output), study.sha256, kind=kind, fresh=False)

    def release(self) -> None:
        """Give the output up to the next run (the lock; the process's end does it too)."""
        if self.lock is not None:
            self.lock.release()
            self.lock = None

    def _check_resumable(self) -> None:
        if not self.output.exists():
            return
        try:
            with xr.open_dataset(self.output, engine="h5netcdf") as old:
                sha = old.attrs.get("study_sha256")
        except (OSError, ValueError) as e:
            raise StudyError(f"cannot read the results file to resume it: {e}", file=str(self.output)) from None
        if sha != self.study.sha256:
            raise StudyError(f"cannot resume: the results file was written for another study file "
                             f"(study_sha256 {str(sha)[:12]}..., this study {self.study.sha256[:12]}...); "
                             f"run without --resume to start over", file=str(self.output))

    # ---- evaluation (the seam for parallel workers) ----------------------------------------
    def evaluate_batch(self, points, gradients: bool, on_result=None) -> list:
        """Solve each point (a parameter vector or a {path: value} mapping); never raises for a
        failing data set: the Evaluation carries the status. `on_result(i, ev)` as each finishes."""
        out = []
        for i, p in enumerate(points):
            ev = self._evaluate_one(p, gradients)
            out.append(ev)
            if on_result is not None:
                on_result(i, ev)
        return out

    def _evaluate_one(self, point, gradients: bool):
        from .evaluation import Evaluation
        from .study import parameter_vector
        t0 = time.perf_counter()
        try:
            if gradients and self._has_gradients:
                return self.evaluator.evaluate(point, gradients=True)
            return self.evaluator.evaluate(point)
        except (KeyboardInterrupt, StudyError):
            raise
        except Exception as e:  # noqa: BLE001 - failures are data
            try:
                x = parameter_vector(self.study, point)
            except Exception:  # noqa: BLE001
                x = np.full(len(self.names), np.nan)
            nan = {c: float("nan") for c in self.criteria}
            return Evaluation(x, nan, OTHER_FAILURE, f"{type(e).__name__}: {e}", 0, time.perf_counter() - t0)

    # ---- records ------------------------------------------------------------------------------
    def _record_from_evaluation(self, ev, stage: str, gradients: bool, sweep=None) -> dict:
        ok = ev.status == 0
        phi = np.array([float(ev.phi.get(c, np.nan)) if ok else np.nan for c in self.criteria])
        grad = None
        g = getattr(ev, "grad", None)
        if ok and gradients and g:
            grad = np.stack([np.asarray(g[c], float) if g.get(c) is not None else np.full(len(self.names), np.nan)
                             for c in self.criteria])
        rec = {"x": np.asarray(ev.x, float).copy(), "phi": phi, "status": int(ev.status),
               "message": str(ev.message), "iterations": int(ev.iterations or 0),
               "wall_time": float(ev.wall_time), "grad": grad,
               "nonsmooth": int(bool(getattr(ev, "nonsmooth", False))), "stage": stage}
        if sweep is not None:
            rec["sweep"] = np.asarray(sweep, float)
        return rec

    @staticmethod
    def _to_store(rec: dict) -> dict:
        out = {k: np.asarray(v) for k, v in rec.items()
               if k not in ("grad", "stage", "from_store") and v is not None}
        if rec.get("grad") is not None:
            out["grad"] = rec["grad"]
        return out

    def _from_store(self, stored: dict, stage: str) -> dict:
        rec = {"x": stored["x"].astype(float), "phi": stored["phi"].astype(float),
               "status": int(stored["status"]), "message": str(stored["message"]),
               "iterations": int(stored["iterations"]), "wall_time": float(stored["wall_time"]),
               "grad": stored["grad"].astype(float) if "grad" in stored else None,
               "nonsmooth": int(stored["nonsmooth"]), "stage": stage, "from_store": True}
        if "sweep" in stored:
            rec["sweep"] = stored["sweep"].astype(float)
        return rec

    def _append(self, k: str, rec: dict, ev=None) -> None:
        row = len(self.records)
        self.records.append(rec)
        self.memo.setdefault(k, row)
        if rec["status"] == 0:
            for j, c in enumerate(self.criteria):
                v = rec["phi"][j]
                if math.isfinite(v) and (c not in self.best or v > self.best[c]):
                    self.best[c], self.best_row[c] = float(v), row
                    fields = None
                    if ev is not None and getattr(ev, "state", None) is not None:
                        try:
                            fields = ev.fields
                        except Exception:  # noqa: BLE001 - fields are a convenience during the run
                            fields = None
                    self.live_fields[c] = fields
        if self.progress is not None:
            self.progress.update(len(self.records), rec, self.best)
        self._maybe_write()

    def _outcome(self, row: int) -> Outcome:
        r = self.records[row]
        grad = None if r["grad"] is None else {c: r["grad"][j].copy() for j, c in enumerate(self.criteria)}
        return Outcome(x=r["x"].copy(), phi={c: float(r["phi"][j]) for j, c in enumerate(self.criteria)},
                       status=r["status"], grad=grad, nonsmooth=bool(r["nonsmooth"]))

    # ---- answering a batch ------------------------------------------------------------------
    def answer(self, points, stage: str, gradients: bool, budget: int | None,
               sweeps=None) -> list[Outcome]:
        """One Outcome per point, in order, until the budget is spent (then a shorter list)."""
        points = list(points)
        rows: list[int] = []
        pending: list[tuple[str, object, object]] = []   # (key, point, sweep values) to solve

        def flush():
            if not pending:
                return
            batch = list(pending)
            pending.clear()

            def done(i, ev, rec=None):
                k, _, sv = batch[i]
                rec = rec or self._record_from_evaluation(ev, stage, gradients, sv)
                self.stats["solved"] += 1
                self.stats["solve_time"] += rec["wall_time"]
                if self.store is not None and self.root:
                    self.store.put(k, self._to_store(rec))
                self._append(k, rec, ev)
                rows.append(len(self.records) - 1)

            if not self.split_batches:        # serial, or every rank takes part in every (DD) solve
                self.evaluate_batch([p for _, p, _ in batch], gradients, done)
                return
            # MPI: rank r solves points r, r+N, ...; all ranks then append every record in batch order
            size, me = self.comm.size, self.comm.rank
            mine = [(i, self._record_from_evaluation(self._evaluate_one(batch[i][1], gradients), stage,
                                                     gradients, batch[i][2]))
                    for i in range(me, len(batch), size)]
            for i, rec in sorted((r for part in self.comm.allgather(mine) for r in part), key=lambda t: t[0]):
                done(i, None, rec)

        used = len(self.records)
        for i, p in enumerate(points):
            sv = None if sweeps is None else np.asarray(sweeps[i], float)
            x = self._vector(p)
            k = key(self.study.sha256, x, sv)
            row = self.memo.get(k)
            want_grad = gradients and self._has_gradients
            if row is not None and not (want_grad and self.records[row]["status"] == 0
                                        and self.records[row]["grad"] is None):
                flush()
                rows.append(row)
                continue
            if budget is not None and used >= budget:
                break
            used += 1
            stored = self.store.get(k) if self.store is not None else None
            if stored is not None and not (want_grad and int(stored["status"]) == 0 and "grad" not in stored):
                flush()
                self.stats["from_store"] += 1
                self._append(k, self._from_store(stored, stage))
                rows.append(len(self.records) - 1)
                continue
            pending.append((k, p, sv))
        flush()
        return [self._outcome(r) for r in rows]

    def _vector(self, p) -> np.ndarray:
        from collections.abc import Mapping

        from .study import parameter_vector
        if isinstance(p, Mapping):
            return parameter_vector(self.study, p)
        return np.ascontiguousarray(p, dtype=float)

    # ---- the search ---------------------------------------------------------------------------
    def run(self, strategy=None) -> xr.Dataset:
        try:
            return self._search(strategy)
        finally:
            self.release()

    def sweep(self) -> xr.Dataset:
        try:
            return self._sweep()
        finally:
            self.release()

    def _search(self, strategy) -> xr.Dataset:
        search = dict(self.study.search)
        budget = int(search.get("budget", 200))
        seed = int(search.get("sample", {}).get("seed", 0))
        factory = strategy or get_strategy(search.get("method", "auto"))
        problem = build_problem(self.study, self.evaluator)
        gen = factory(problem, search, np.random.default_rng(seed))
        if self.progress is not None:
            self.progress.start(budget, self.criteria)
        result = None
        try:
            batch = next(gen)
            while True:
                pts = np.atleast_2d(np.asarray(batch.points, float))
                if len(self.records) >= budget and len(pts):
                    outcomes = []
                else:
                    outcomes = self.answer(pts, batch.stage, bool(batch.gradients), budget)
                short = len(outcomes) < len(pts)
                batch = gen.send(outcomes)
                if short and len(self.records) >= budget:   # told it is out of budget and it asks again
                    gen.close()
                    break
        except StopIteration as stop:
            result = stop.value
        finally:
            if self.progress is not None:
                self.progress.finish()
        return self.finish(result)

    def _sweep(self) -> xr.Dataset:
        grid = (self.study.sweep or {}).get("grid")
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
        return self.finish(None, paths)

    # ---- the end ------------------------------------------------------------------------------
    def _worst(self):
        worst = {}
        for c in self.criteria:
            if c in self.best_row:
                r = self.best_row[c]
                worst[c] = (self.best[c], self.records[r]["x"].copy(), r)
        return worst

    def finish(self, result: Worst | None, sweep_paths=None) -> xr.Dataset:
        worst = self._worst()
        certificate, notes = {}, {}
        for c in self.criteria:
            if self.kind == "sweep":
                certificate[c] = "grid"
            elif c not in worst:
                certificate[c] = "none"
            elif isinstance(result, Worst) and c in result.certificate and (
                    result.value.get(c) == worst[c][0]
                    or np.array_equal(np.asarray(result.x.get(c, [])), worst[c][1])):
                certificate[c] = str(result.certificate[c])
            else:
                certificate[c] = "heuristic"
            if isinstance(result, Worst) and c in result.notes:
                notes[c] = str(result.notes[c])
        # a DD solve spread over the ranks is collective: then every rank re-solves the worst cases
        solves_here = self.root or (self.comm is not None and not self.split_batches)
        fields = self._worst_fields(worst) if solves_here else {c: None for c in self.criteria}
        self.final = (worst, certificate, notes, fields, sweep_paths)
        return self._write(force=True)

    def _worst_fields(self, worst: dict) -> dict:
        """Fields of each criterion's worst case, re-solved (an evaluation does not depend on history)."""
        fields, by_key = {}, {}
        for c in self.criteria:
            if c not in worst:
                fields[c] = None
                continue
            rec = self.records[worst[c][2]]
            k = key(self.study.sha256, rec["x"], rec.get("sweep"))
            if k not in by_key:
                point = rec["x"]
                if rec.get("sweep") is not None:
                    point = self._sweep_mapping(rec)
                ev = self._evaluate_one(point, False)
                self.stats["field_solves"] += 1
                by_key[k] = ev.fields if ev.status == 0 else None
            fields[c] = by_key[k]
        return fields

    def _sweep_mapping(self, rec) -> dict:
        m = dict(zip(self.names, map(float, rec["x"])))
        m.update(zip(self.final_sweep_paths(), map(float, rec["sweep"])))
        return m

    def final_sweep_paths(self) -> list[str]:
        return list((self.study.sweep or {}).get("grid", {}))

    # ---- the file -----------------------------------------------------------------------------
    def dataset(self) -> xr.Dataset:
        from .results import run_dataset
        search = self.study.search
        if self.final is not None:
            worst, certificate, notes, fields, sweep_paths = self.final
            complete = "yes"
        else:
            worst, fields = self._worst(), self.live_fields
            certificate = {c: "in-progress" for c in self.criteria}
            notes, complete = {}, "no"
            sweep_paths = self.final_sweep_paths() if self.kind == "sweep" else None
        attrs = {"created": self.created, "kind": self.kind, "complete": complete,
                 "study_file": str(self.study.file),
                 "search_method": str(search.get("method", "auto")),
                 "budget": int(search.get("budget", 200)),
                 "evaluations": len(self.records),
                 "failed_evaluations": int(sum(r["status"] != 0 for r in self.records)),
                 "solves_this_session": int(self.stats["solved"]),
                 "answered_from_store": int(self.stats["from_store"]),
                 "gradients": "adjoint" if self._has_gradients else "unavailable",
                 "worst_fields": "re-solved from a cold start at the end of the run" if complete == "yes"
                 else "fields of the best evaluation solved in this session so far"}
        if self.kind == "sweep":
            attrs["sweep_grid"] = "; ".join(f"{p}: {list(v)}" for p, v in (self.study.sweep or {})["grid"].items())
        return run_dataset(self.study, self.evaluator, self.records, worst=worst, certificate=certificate,
                           notes=notes, worst_fields=fields, attrs=attrs, sweep_paths=sweep_paths,
                           provenance_attrs=self._provenance)

    def _maybe_write(self) -> None:
        if not self.root:
            return
        now = time.perf_counter()
        if now - self._last_write_end >= self._last_write_cost / WRITE_OVERHEAD:
            self._write()

    def _write(self, force: bool = False) -> xr.Dataset:
        from .results import write_netcdf
        t0 = time.perf_counter()
        ds = self.dataset()
        if self.output is not None and self.root:
            write_netcdf(ds, self.output)
        t1 = time.perf_counter()
        self._last_write_cost = t1 - t0
        self._last_write_end = t1
        self.stats["write_time"] += t1 - t0
        self.stats["writes"] += 1
        return ds


# ---------------------------------------------------------------- public API and commands


def _as_study(study):
    if isinstance(study, (str, Path)):
        from .study import load_study
        return load_study(study)
    return study


def run(study, output=None, resume=False, progress=None, *, strategy=None) -> xr.Dataset:
    """The whole worst-scenario study -> xarray.Dataset (study-format.md §4).

    output: results file (default: the study's `output`; False: keep it in memory only).
    resume: continue an interrupted run of the same study file from its store.
    progress: a `wcs.progress.Progress` (None: silent).
    strategy: a strategy factory (problem, config, rng) -> generator; default: the registry's
              entry for `search.method`.
    """
    study = _as_study(study)
    return Runner(study, output, resume, progress).run(strategy)


def sweep(study, output=None, resume=False, progress=None) -> xr.Dataset:
    """The full factorial grid of the study's `sweep:` block, in the layout of a run."""
    study = _as_study(study)
    return Runner(study, output, resume, progress, kind="sweep").sweep()


def _is_root() -> bool:
    from .parallel import rank, world
    return rank(world()) == 0


def _finish_command(args, study, ds, out: Path) -> int:
    from .evaluation import STATUS
    from .progress import limits_broken, summary_table
    n, failed = int(ds.sizes.get("eval", 0)), int(ds.attrs.get("failed_evaluations", 0))
    if not getattr(args, "quiet", False):
        print(f"{study.name}: {n} evaluations ({failed} failed), "
              f"{ds.attrs.get('solves_this_session')} solved now, {ds.attrs.get('answered_from_store')} "
              f"from the store; wrote {out}")
        print(summary_table(ds))
    if failed == n:
        codes, counts = np.unique(ds["status"].values, return_counts=True)
        why = ", ".join(f"{m} with status {c} ({STATUS.get(int(c), 'unknown')})" for c, m in zip(codes, counts))
        first = f"; the first: {ds['message'].values[0]}" if n else ""
        print(f"error: no evaluation solved ({why or 'none run'}{first}); {out} records their statuses",
              file=sys.stderr)
        return 1
    broken = limits_broken(ds)
    if broken and getattr(args, "fail_on_limit", False):
        print(f"limit broken: {', '.join(broken)}", file=sys.stderr)
        return 3
    return 0


def _write_failure(e: WriteError, args, out: Path) -> int:
    """One line for a failed write (the store keeps every evaluation finished before it), exit 1;
    under MPI the other ranks are stopped with it."""
    from .parallel import world
    n = stored_count(out)
    kept = "" if n is None else f"; the store {store_path(out)} keeps every evaluation finished so far ({n})"
    if n is not None and args.command == "run":
        kept += f": continue with `wcs run {args.study} -o {out} --resume`"
    print(f"error: {e}{kept}", file=sys.stderr, flush=True)
    comm = world()
    if comm is not None:
        comm.Abort(1)
    return 1


def _command(args, kind: str) -> int:
    from .progress import Progress
    from .study import load_study
    study = load_study(args.study)
    if args.output:
        out, where = Path(args.output), (None, "-o")
    else:
        out, where = Path(study.output), (str(study.file), "output")
        if kind == "sweep":
            out = out.with_name(out.stem + "-sweep.nc")
    try:
        r = Runner(study, out, bool(getattr(args, "resume", False)), Progress.from_args(args), kind=kind, where=where)
        ds = r.run() if kind == "run" else r.sweep()
    except WriteError as e:
        return _write_failure(e, args, out)
    return _finish_command(args, study, ds, out) if _is_root() else 0


def cmd_run(args) -> int:
    return _command(args, "run")


def cmd_sweep(args) -> int:
    return _command(args, "sweep")


def solve_worst(args) -> int:
    """`wcs solve STUDY --worst RUN.nc CRITERION`: the worst data set of a criterion as one scenario."""
    from .evaluation import Evaluator
    from .results import write_solution
    from .study import load_study
    study = load_study(args.study)
    run_file, criterion = args.worst
    if not Path(run_file).is_file():
        raise StudyError("results file not found", file=str(run_file))
    try:
        with xr.open_dataset(run_file, engine="h5netcdf") as ds:
            crits = [str(c) for c in ds["criterion"].values]
            params = [str(p) for p in ds["param"].values]
            if criterion not in crits:
                raise StudyError(f"no criterion '{criterion}' in the run (it has: {', '.join(crits)})",
                                 file=str(run_file))
            x = ds["worst_x"].sel(criterion=criterion).values.astype(float)
            sha = ds.attrs.get("study_sha256")
            if str(ds.attrs.get("complete", "yes")) == "no":
                n = int(ds.sizes.get("eval", 0))
                raise StudyError(incomplete_run(run_file, n, args.study), file=str(run_file))
            extra = {}
            if "sweep_value" in ds and int(ds["worst_eval"].sel(criterion=criterion)) >= 0:
                row = int(ds["worst_eval"].sel(criterion=criterion))
                extra = dict(zip(map(str, ds["sweep_path"].values), map(float, ds["sweep_value"].values[row])))
    except (OSError, KeyError, ValueError) as e:
        raise StudyError(f"not a results file of `wcs run` ({e})", file=str(run_file)) from None
    if params != list(study.parameters.names):
        raise StudyError(f"the run's parameters ({', '.join(params)}) are not this study's "
                         f"({', '.join(study.parameters.names)})", file=str(run_file))
    if not np.all(np.isfinite(x)):
        raise StudyError(f"the run has no solved data set for criterion '{criterion}'", file=str(run_file))
    if sha != study.sha256 and not getattr(args, "quiet", False):
        print(f"note: {run_file} was written for a different version of {args.study}", file=sys.stderr)
    out = Path(args.output or Path(study.output).with_name(f"{Path(study.output).stem}-worst-{criterion}.nc"))
    check_output(out, *((None, "-o") if args.output else (str(study.file), "output")))
    t0 = time.perf_counter()
    ev = Evaluator(study)
    point = x
    if extra:
        point = dict(zip(study.parameters.names, map(float, x)))
        point.update(extra)
    res = ev.evaluate(point)
    if res.status != 0:
        print(f"error: the worst data set of '{criterion}' cannot be solved: {res.message}", file=sys.stderr)
        return 1
    try:
        out, vtu = write_solution(study, ev, res, out, worst_of=f"{run_file}: criterion {criterion}")
    except WriteError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    if not getattr(args, "quiet", False):
        print(f"{study.name}: worst case of {criterion} from {run_file}, solved in "
              f"{time.perf_counter() - t0:.2f} s")
        for name, v in res.phi.items():
            print(f"  {name} = {v:.6g}")
        print(f"  wrote {out} and {vtu}")
    return 0
