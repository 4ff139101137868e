"""The results file of a run or sweep: claimed before anything is solved, rewritten as the run
goes, marked incomplete until it ends.

Before anything is meshed or solved, rank 0 checks the output (not a directory, a name the
filesystem takes, its folder creatable) and locks it (`OUT.lock`, `wcs/results/store.py`), so a
second run on the same output is refused; with `--resume` the results file there must be
this study file's.

The NetCDF file is built from the ledger in memory and written whole (temp + rename,
`wcs.results.dataset.write_netcdf`) after an evaluation whenever the time since the last rewrite is
at least 1/WRITE_OVERHEAD times what that rewrite cost — at most 4% overhead — and always at
the end. Until the end it says `complete: no`, its certificates are `in-progress` and its
worst fields are those of the best evaluation solved in this session so far; at the end the
certificates are the search's and the worst fields are re-solved.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import datetime as _dt
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import StudyError
from .parallel import agree, rank
from .record import Ledger
from ..results.dataset import open_results, provenance, run_dataset, write_netcdf
from ..search.ranges import Extreme
from ..results.store import OutputLock, check_output
from ..study.fuzzy import alpha_cut
from ..results.verdict import attributes as verdict_attributes

if TYPE_CHECKING:
    import xarray as xr


WRITE_OVERHEAD = 0.04        # NetCDF rewrites take at most this share of the time between them (< 5% of solve time)


def check_resumable(output: Path, study_sha256: str) -> None:
    """StudyError unless the results file at `output` (if any) was written for this study file."""
    if not output.exists():
        return
    try:
        with open_results(output) as old:
            sha = old.attrs.get("study_sha256")
    except (OSError, ValueError) as e:
        raise StudyError(f"cannot read the results file to resume it: {e}", file=str(output)) from None
    if sha != study_sha256:
        raise StudyError(f"cannot resume: the results file was written for another study file "
                         f"(study_sha256 {str(sha)[:12]}..., this study {study_sha256[:12]}...); "
                         f"run with --fresh instead to start over", file=str(output))


def claim_output(comm, output: Path, where: tuple, resume_sha256: str | None) -> OutputLock | None:
    """Check and lock `output` on rank 0 (its lock; None on the other ranks); with
    `resume_sha256`, check the results file there is that study file's. where: (file, key path)
    that named the output, for the errors. Every rank raises, or none."""
    lock, error = None, None
    if rank(comm) == 0:
        try:
            check_output(output, *where)
            lock = OutputLock(output, *where)
            if resume_sha256 is not None:
                check_resumable(output, resume_sha256)
        except StudyError as e:
            error = e
            if lock is not None:
                lock.release()
                lock = None
    agree(comm, error)                # every rank raises, or every rank goes on
    return lock


@dataclass(frozen=True)
class Final:
    """What the end of a run adds to its file (criterion -> ...)."""
    worst: dict                 # criterion -> (value, data set, row) of its maximum over the widest level
    certificate: dict           # how the worst value is certified
    notes: dict                 # the search's notes
    fields: dict                # fields of the worst case, re-solved (None where none solved)
    extremes: list = ()         # every end of every range (`Extreme`), per α-level; worst..notes are the
                                # maxima of the widest level among them


def extremes_of(study, records: list, criteria: list[str], kind: str, found: list | None) -> list[Extreme]:
    """Every end the study asks for (each criterion's `sense`, at each α-level of a fuzzy study):
    the largest (smallest) value of the successful evaluations inside the level's α-cut (a crisp
    study: all of them), at the first row attaining it. Certified as the search certified it
    when the search (`found`, its `Extreme`s) ended at that value or data set, else
    `heuristic`; `grid` for a sweep; `in-progress` while the run goes (`found` None); `none`
    without a successful evaluation."""
    senses = {c.name: c.sense for c in study.criteria}
    n, p = len(records), len(study.parameters)
    X = np.array([r["x"] for r in records], float).reshape(n, p)
    P = np.array([r["phi"] for r in records], float).reshape(n, len(criteria))
    ok = np.array([r["status"] == 0 for r in records], bool)
    by = {(e.level, e.criterion, e.sense): e for e in found or []}
    out = []
    for level in ([None] if study.levels is None else study.levels):
        inside = ok
        if level is not None:
            lower, upper = alpha_cut(study, level)
            inside = ok & np.all((X >= lower) & (X <= upper), axis=1)
        for j, c in enumerate(criteria):
            for sense in ("max", "min"):
                if senses[c] not in (sense, "both"):
                    continue
                v = np.where(inside & np.isfinite(P[:, j]), P[:, j], np.nan)
                if np.isnan(v).all():
                    out.append(Extreme(c, sense, level, float("nan"), np.full(p, np.nan), "none",
                                       "no successful evaluation"))
                    continue
                row = int(np.nanargmax(v) if sense == "max" else np.nanargmin(v))
                e = by.get((level, c, sense))
                if found is None:
                    cert, note = "in-progress", ""
                elif kind == "sweep":
                    cert, note = "grid", ""
                elif e is not None and (e.value == v[row] or np.array_equal(e.x, X[row])):
                    cert, note = e.certificate, e.note
                else:
                    cert, note = "heuristic", "" if e is None else e.note
                out.append(Extreme(c, sense, level, float(v[row]), X[row].copy(), cert, note, row))
    return out


def widest_maxima(extremes: list[Extreme], criteria: list[str]) -> tuple[dict, dict, dict]:
    """(worst, certificate, notes) by criterion of the maxima over the widest level (the whole
    box of a crisp study): worst as (value, data set, row) where one was found;
    a criterion whose maximum is not searched (sense min) is `not-searched`."""
    levels = [e.level for e in extremes if e.level is not None]
    widest = min(levels) if levels else None
    worst, certificate, notes = {}, {c: "not-searched" for c in criteria}, {}
    for e in extremes:
        if e.sense == "max" and e.level == widest:
            certificate[e.criterion], notes[e.criterion] = e.certificate, e.note
            if e.eval >= 0:
                worst[e.criterion] = (e.value, e.x.copy(), e.eval)
    return worst, certificate, notes


class Writer:
    """Builds the results dataset from a ledger and writes it to `output` (rank 0; None: in
    memory only); `due()` says when a rewrite during the run keeps within WRITE_OVERHEAD."""

    def __init__(self, study, evaluator, output: Path | None, kind: str, sweep_paths: list[str] | None,
                 writes: bool, gradients: bool, layout: tuple[int, int] = (1, 1)):
        """sweep_paths: the swept paths of a sweep (None: a run); writes: whether this process
        writes the file (rank 0); gradients: whether the evaluator gives adjoint gradients;
        layout: (MPI ranks, ranks per evaluation) of the run."""
        self.study, self.evaluator = study, evaluator
        self.output, self.kind, self.sweep_paths, self.writes = output, kind, sweep_paths, writes
        self.gradients = gradients
        self.created = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        self.provenance = provenance(study, evaluator, layout)
        self.last_end = 0.0
        self.last_cost = 0.0             # seconds of the last write (building the dataset included)

    def dataset(self, ledger: Ledger, stats: dict, final: Final | None) -> xr.Dataset:
        """The results file of the ledger's records; `final` None: the run is still going."""
        criteria, records = ledger.criteria, ledger.records
        search = self.study.search
        if final is not None:
            worst, certificate, notes, fields = final.worst, final.certificate, final.notes, final.fields
            extremes, complete = final.extremes, "yes"
        else:
            extremes = extremes_of(self.study, records, criteria, self.kind, None)
            worst, certificate, notes = widest_maxima(extremes, criteria)
            fields, complete = ledger.live_fields, "no"
        attrs = {"created": self.created, "kind": self.kind, "complete": complete,
                 "study_file": str(self.study.file),
                 "search_method": search.method,
                 "budget": search.budget,
                 "evaluations": len(records),
                 "failed_evaluations": int(sum(r["status"] != 0 for r in records)),
                 "solves_this_session": int(stats["solved"]),
                 "answered_from_store": int(stats["from_store"]),
                 "gradients": "adjoint" if self.gradients else "unavailable",
                 "worst_fields": "re-solved from a cold start at the end of the run" if complete == "yes"
                 else "fields of the best evaluation solved in this session so far"}
        if self.kind == "sweep":
            attrs["sweep_grid"] = "; ".join(f"{p}: {list(v)}" for p, v in self.study.sweep.grid.items())
        ds = run_dataset(self.study, self.evaluator, records, worst=worst, certificate=certificate,
                         notes=notes, worst_fields=fields, attrs=attrs, sweep_paths=self.sweep_paths,
                         provenance_attrs=self.provenance, extremes=extremes)
        ds.attrs.update(verdict_attributes(ds))
        return ds

    def due(self) -> bool:
        """Whether a rewrite now keeps the writing within WRITE_OVERHEAD of the run's time."""
        return self.writes and time.perf_counter() - self.last_end >= self.last_cost / WRITE_OVERHEAD

    def write(self, ledger: Ledger, stats: dict, final: Final | None) -> xr.Dataset:
        """Build the dataset and write it (WriteError on an I/O fault: the last file stays whole)."""
        t0 = time.perf_counter()
        ds = self.dataset(ledger, stats, final)
        if self.output is not None and self.writes:
            write_netcdf(ds, self.output)
        t1 = time.perf_counter()
        self.last_cost, self.last_end = t1 - t0, t1
        return ds
