"""The record of a run: one `Record` per evaluation, in evaluation order, and the store behind it.

A `Record` is the one form of an evaluation that everything after the solve reads: the
results file (`wcs.results.dataset.run_dataset`, one row each), the evaluation store (`to_store` /
`from_store`, one file each, `wcs/results/store.py`), the progress display, and the search (an
`Outcome` built from it). Failures are records too (status code, NaN criteria).

The `Ledger` keeps a run's records with the first row of each store key (the exact bits of
the data set, `wcs.results.store.key`), so a point asked again is answered without a solve, and the
best value of each criterion with its row. Behind it the store holds every record of the
runs of this study file on this output: `--resume` asks the same questions again and gets
the stored answers (a point whose stored record lacks gradients that are now wanted is
solved again).
"""
from __future__ import annotations

import math
from typing import NotRequired, TypedDict

import numpy as np

from ..contact.methods import krylov_counts
from ..errors import StudyError
from .parallel import agree, rank
from ..search import Outcome
from ..results.store import Store, WriteError, store_path


class Record(TypedDict):
    """One evaluation (k criteria, n parameters)."""
    x: np.ndarray                      # (n,) the data set, physical units
    phi: np.ndarray                    # (k,) criterion values in criterion order; NaN unless solved
    status: int                        # a wcs.status.Status code (0 solved)
    message: str                       # the solver's message
    iterations: int                    # solver iterations
    krylov_iterations: NotRequired[int]  # Krylov iterations in all (-1: not counted), `krylov_counts`
    krylov_step_max: NotRequired[int]  # the most Krylov iterations of one outer step (-1: not counted)
    wall_time: float                   # seconds of the evaluation
    grad: np.ndarray | None            # (k, n) dPhi/dx where asked for and solved, else None
    nonsmooth: int                     # 1: the active set (or the max over regions) changes within reach
    stage: str                         # the search stage that asked for it
    sweep: NotRequired[np.ndarray]     # a sweep's values of the swept paths
    phi_history: NotRequired[np.ndarray]   # (k, levels + 1) a dynamic study's criteria at every time level
    from_store: NotRequired[bool]      # answered from the store, not solved in this session


def from_evaluation(ev, criteria: list[str], n: int, stage: str, gradients: bool, sweep=None) -> Record:
    """The record of an `Evaluation` (gradients kept only where asked for and solved)."""
    ok = ev.status == 0
    phi = np.array([float(ev.phi.get(c, np.nan)) if ok else np.nan for c in criteria])
    grad = None
    g = getattr(ev, "grad", None)
    if ok and gradients and g:
        grad = np.stack([np.asarray(g[c], float) if g.get(c) is not None else np.full(n, np.nan)
                         for c in criteria])
    rec = {"x": np.asarray(ev.x, float).copy(), "phi": phi, "status": int(ev.status),
           "message": str(ev.message), "iterations": int(ev.iterations or 0),
           "wall_time": float(ev.wall_time), "grad": grad,
           "nonsmooth": int(bool(getattr(ev, "nonsmooth", False))), "stage": stage}
    rec["krylov_iterations"], rec["krylov_step_max"] = krylov_counts(getattr(ev, "krylov_steps", None))
    if sweep is not None:
        rec["sweep"] = np.asarray(sweep, float)
    if ok and getattr(ev, "history", None) is not None:
        rec["phi_history"] = np.asarray(ev.history, float)
    return rec


def to_store(rec: Record) -> dict:
    """The arrays the store keeps of a record (not its stage: a stored answer takes the stage
    of the question)."""
    out = {k: np.asarray(v) for k, v in rec.items()
           if k not in ("grad", "stage", "from_store") and v is not None}
    if rec.get("grad") is not None:
        out["grad"] = rec["grad"]
    return out


def from_store(stored: dict, stage: str) -> Record:
    """The record of a stored evaluation, answering a question of `stage`."""
    rec = {"x": stored["x"].astype(float), "phi": stored["phi"].astype(float),
           "status": int(stored["status"]), "message": str(stored["message"]),
           "iterations": int(stored["iterations"]), "wall_time": float(stored["wall_time"]),
           "grad": stored["grad"].astype(float) if "grad" in stored else None,
           "nonsmooth": int(stored["nonsmooth"]), "stage": stage, "from_store": True}
    for key in ("krylov_iterations", "krylov_step_max"):     # -1: stored before they were counted
        rec[key] = int(stored[key]) if key in stored else -1
    if "sweep" in stored:
        rec["sweep"] = stored["sweep"].astype(float)
    if "phi_history" in stored:
        rec["phi_history"] = stored["phi_history"].astype(float)
    return rec


def outcome(rec: Record, criteria: list[str]) -> Outcome:
    """What the search strategy is told of a record."""
    grad = None if rec["grad"] is None else {c: rec["grad"][j].copy() for j, c in enumerate(criteria)}
    return Outcome(x=rec["x"].copy(), phi={c: float(rec["phi"][j]) for j, c in enumerate(criteria)},
                   status=rec["status"], grad=grad, nonsmooth=bool(rec["nonsmooth"]))


def open_store(comm, output, study_sha256: str, kind: str, resume: bool) -> Store:
    """The store beside `output`: rank 0 prepares it (emptied unless resuming), then the other
    ranks open it to read. Every rank raises, or none."""
    error, store = None, None
    if rank(comm) == 0:
        try:
            store = Store(store_path(output), study_sha256, kind=kind, fresh=not resume)
        except (StudyError, WriteError) as e:
            error = e
    agree(comm, error)
    if store is None:
        store = Store(store_path(output), study_sha256, kind=kind, fresh=False)
    return store


class Ledger:
    """The records of this run in order, the row of each key, the best of each criterion.

    store: the evaluation store (None: nothing is kept beyond this run); `writes`: whether `append`
    writes solved records to it (rank 0; under MPI each group's rank 0 `keep`s what it solves)."""

    def __init__(self, criteria: list[str], store: Store | None = None, writes: bool = True):
        self.criteria = criteria
        self.store = store
        self.writes = writes
        self.records: list[Record] = []
        self.memo: dict[str, int] = {}         # key -> row of its first evaluation in this run
        self.best: dict[str, float] = {}
        self.best_row: dict[str, int] = {}
        self.live_fields: dict = {}            # criterion -> fields of its best so far (this session)

    def row(self, k: str, gradients: bool) -> int | None:
        """The row of this run answering key `k` (None: not asked yet, or solved without the
        gradients now wanted)."""
        row = self.memo.get(k)
        if row is not None and gradients and self.records[row]["status"] == 0 and self.records[row]["grad"] is None:
            return None
        return row

    def stored(self, k: str, gradients: bool, stage: str) -> Record | None:
        """The stored record of key `k` (None: not stored, or stored without the gradients now wanted)."""
        stored = self.store.get(k) if self.store is not None else None
        if stored is None or (gradients and int(stored["status"]) == 0 and "grad" not in stored):
            return None
        return from_store(stored, stage)

    def keep(self, k: str, rec: Record) -> None:
        """Store a solved record under key `k` (WriteError where it cannot be written)."""
        if self.store is not None:
            self.store.put(k, to_store(rec))

    def append(self, k: str, rec: Record, ev=None, kept: bool = False) -> int:
        """Add a record under key `k` (a solved one goes to the store first, unless `kept` there
        already by the rank that solved it); its row. `ev`: the Evaluation it came from, whose
        fields are kept while it is a criterion's best."""
        if self.writes and not kept and not rec.get("from_store"):
            self.keep(k, rec)
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
                            fields = ev.field_data
                        except Exception:  # noqa: BLE001 - fields are a convenience during the run
                            fields = None
                    self.live_fields[c] = fields
        return row

    def outcome(self, row: int) -> Outcome:
        return outcome(self.records[row], self.criteria)
