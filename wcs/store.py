"""The evaluation store: every finished evaluation of a run, one small file each.

A run's store is a folder beside its results file (`OUT.nc.store/`). Each
evaluation is one `.npz` named by its key, the SHA-256 of the study hash and
the exact bits of the data set (plus, for sweeps, the exact bits of the swept
values), written to a temporary name and renamed: a kill -9 leaves either the
whole record or none. The store is what `--resume` replays from: the search
is deterministic, so asking the same questions again finds the answers here
and only new points are solved.

A record holds what the results file needs of an evaluation (x, phi per
criterion, status, message, iterations, wall time, gradients, non-smoothness)
and, for contact models, the contact solver's final state (`warm_*`): the
next solve in the run started from it, so a resumed run restores it before
its first new solve and gives the same bits as an uninterrupted run.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np

META = "meta.json"


def key(study_sha256: str, x: np.ndarray, extra: np.ndarray | None = None) -> str:
    """The store key of a data set: exact input bits, never a rounded value."""
    h = hashlib.sha256(study_sha256.encode())
    h.update(np.ascontiguousarray(x, dtype="<f8").tobytes())
    if extra is not None and len(extra):
        h.update(b"|")
        h.update(np.ascontiguousarray(extra, dtype="<f8").tobytes())
    return h.hexdigest()


def store_path(output: str | Path) -> Path:
    output = Path(output)
    return output.with_name(output.name + ".store")


class Store:
    """Append-only records keyed by `key(...)`; `get` answers, `put` adds."""

    def __init__(self, folder: str | Path, study_sha256: str, kind: str = "run", fresh: bool = False):
        self.folder = Path(folder)
        self.study_sha256 = study_sha256
        if fresh and self.folder.exists():
            shutil.rmtree(self.folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        meta = self.folder / META
        if meta.exists():
            info = json.loads(meta.read_text())
            if info.get("study_sha256") != study_sha256:
                from .errors import StudyError
                raise StudyError(
                    f"the evaluation store {self.folder} belongs to another study file "
                    f"(study_sha256 {info.get('study_sha256', '?')[:12]}..., this study "
                    f"{study_sha256[:12]}...); run without --resume to start over", file=str(self.folder))
        else:
            tmp = meta.with_suffix(".part")
            tmp.write_text(json.dumps({"study_sha256": study_sha256, "kind": kind}))
            os.replace(tmp, meta)

    def __len__(self) -> int:
        return sum(1 for _ in self.folder.glob("*.npz"))

    def _file(self, k: str) -> Path:
        return self.folder / f"{k}.npz"

    def get(self, k: str) -> dict | None:
        f = self._file(k)
        if not f.exists():
            return None
        try:
            with np.load(f, allow_pickle=False) as z:
                return {name: z[name] for name in z.files}
        except (OSError, ValueError, KeyError):      # unreadable: as if never stored
            return None

    def put(self, k: str, record: dict) -> None:
        tmp = self.folder / f".{k}.{os.getpid()}.part"
        with open(tmp, "wb") as fh:
            np.savez(fh, **record)
        os.replace(tmp, self._file(k))
