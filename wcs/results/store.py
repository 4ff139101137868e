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

Beside the results file a run also holds `OUT.nc.lock`, an exclusive `flock`
for as long as it runs (the kernel drops it when the process dies, kill -9
included), so a second run on the same output is refused instead of sharing
its files. `check_output` refuses an output the run could not write before
anything is solved; a write that fails later raises `WriteError` (an I/O
fault, exit 1) and leaves every file written before it intact.
"""
from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import shutil
import signal
import threading
from pathlib import Path

import numpy as np

from ..errors import StudyError

META = "meta.json"
NAME_EXTRA = 14      # the longest name a run writes beside OUT, `.OUT.<pid>.part`, is 14 bytes longer


class WriteError(Exception):
    """A results file or store write failed (disk full, folder removed, ...): exit status 1."""


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


def lock_path(output: str | Path) -> Path:
    output = Path(output)
    return output.with_name(output.name + ".lock")


def stored_count(output: str | Path) -> int | None:
    """How many evaluations the store beside a results file holds (None: no store)."""
    folder = store_path(output)
    return sum(1 for _ in folder.glob("*.npz")) if folder.is_dir() else None


def check_output(output: str | Path, file: str | None = None, path: str | None = None, create: bool = True) -> None:
    """StudyError (exit 2) unless a run can write `output` and the files beside it: not a
    directory, names within the filesystem's limits, its folder creatable (created; with
    `create` false, as `wcs check` asks, nothing is created: the nearest existing folder above
    it must be a folder)."""
    if "\0" in str(output):               # no file system takes it (os calls raise ValueError)
        raise StudyError(f"the output name {str(output)!r} contains a NUL character", file=file, path=path)
    out = Path(output)
    if out.is_dir():
        raise StudyError(f"the output {out} is a directory; name a results file in it (e.g. {out / 'results.nc'})",
                         file=file, path=path)
    existing = out.absolute().parent
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise StudyError(f"cannot create the folder of the output {out}: {existing} is a file", file=file, path=path)
    size = len(os.fsencode(out.name))
    name_max = os.pathconf(existing, "PC_NAME_MAX")
    if size + NAME_EXTRA > name_max:
        raise StudyError(f"the output file name ({out.name[:24]}...) is {size} bytes; the filesystem allows "
                         f"{name_max - NAME_EXTRA} (the files beside it, e.g. .NAME.<pid>.part, add "
                         f"{NAME_EXTRA})", file=file, path=path)
    full = len(os.fsencode(str(store_path(out).absolute()))) + 80     # + a store record's name
    path_max = os.pathconf(existing, "PC_PATH_MAX")
    if full > path_max:
        raise StudyError(f"the output path is too long for the filesystem ({full} of at most {path_max} bytes "
                         f"with the store's files)", file=file, path=path)
    if not create:
        return
    try:
        out.absolute().parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise StudyError(f"cannot create the folder of the output {out}: {e.strerror or e}", file=file,
                         path=path) from None


class OutputLock:
    """An exclusive flock on OUT.lock held by one run (its pid inside); `release()` removes it.

    StudyError if another process holds it or the folder is not writable."""

    def __init__(self, output: str | Path, file: str | None = None, path: str | None = None):
        self.path = lock_path(output)
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as e:
                raise StudyError(f"cannot write beside the output {output}: {e.strerror or e}",
                                 file=file, path=path) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                who = writer(output) or "another process"
                raise StudyError(f"another `wcs run` ({who}) is writing {output}; wait for it to finish "
                                 f"or choose another output", file=file, path=path) from None
            except OSError as e:
                os.close(fd)
                raise StudyError(f"cannot lock {self.path} ({e.strerror or e}): choose an output on a "
                                 f"filesystem with file locks", file=file, path=path) from None
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:               # not a lock file its last holder removed while we opened it
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        self.fd = fd

    def release(self) -> None:
        if self.fd is None:
            return
        with contextlib.suppress(OSError):
            os.unlink(self.path)        # while still holding it: a waiting opener sees another inode
        os.close(self.fd)
        self.fd = None


def writer(output: str | Path) -> str | None:
    """'pid N' of the run holding the lock of `output` (None when no run holds it)."""
    try:
        fd = os.open(lock_path(output), os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        return None
    except BlockingIOError:
        pid = os.read(fd, 32).decode(errors="replace").strip()
        return f"pid {pid}" if pid.isdigit() else "a process"
    finally:
        os.close(fd)


def incomplete_run(run_file, n: int, study_file: str) -> str:
    """What a results file with `complete: no` and `n` evaluations is: a run still writing it or one
    that stopped, how much of it the file and the store beside it hold, and how to finish it."""
    stored, who = stored_count(run_file), writer(run_file)
    held = f"the file holds {n} evaluation{'s' * (n != 1)}" + (
        "" if stored is None else f", the store beside it ({store_path(run_file)}) {stored}")
    if who is not None:
        return f"the run is incomplete: it is still running ({who}); {held} so far; wait for it to finish"
    return (f"the run is incomplete: it stopped before the end; {held}; its worst values are not the run's. "
            f"Finish it with `wcs run {study_file} -o {run_file} --resume`")


@contextlib.contextmanager
def uninterrupted():
    """Hold SIGINT back while a file is written and renamed; deliver it afterwards (a Ctrl-C
    then ends the run between writes, never inside one)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    old = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
        if caught:
            signal.raise_signal(signal.SIGINT)


def write_atomic(path: Path, write) -> None:
    """`write(fh)` into a temporary beside `path`, then rename: `path` is the old or the new
    whole file, and a failed write leaves no temporary behind. WriteError on any I/O fault."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.part")
    with uninterrupted():
        try:
            with open(tmp, "wb") as fh:
                write(fh)
            os.replace(tmp, path)
        except OSError as e:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise WriteError(f"cannot write {path}: {e.strerror or e}") from None


class Store:
    """Append-only records keyed by `key(...)`; `put` adds, `get` answers from the records held
    when the store was opened and those this process put: under MPI every rank stores what it
    solves while the others read, and each rank must find the same answers in the same order."""

    def __init__(self, folder: str | Path, study_sha256: str, kind: str = "run", fresh: bool = False):
        self.folder = Path(folder)
        self.study_sha256 = study_sha256
        try:
            if fresh and self.folder.exists():
                shutil.rmtree(self.folder)
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise WriteError(f"cannot prepare the evaluation store {self.folder}: {e.strerror or e}") from None
        meta = self.folder / META
        if meta.exists():
            info = json.loads(meta.read_text())
            if info.get("study_sha256") != study_sha256:
                raise StudyError(
                    f"the evaluation store {self.folder} belongs to another study file "
                    f"(study_sha256 {info.get('study_sha256', '?')[:12]}..., this study "
                    f"{study_sha256[:12]}...); run with --fresh instead to start over", file=str(self.folder))
        else:
            text = json.dumps({"study_sha256": study_sha256, "kind": kind}).encode()
            write_atomic(meta, lambda fh: fh.write(text))
        self.keys = {f.stem for f in self.folder.glob("*.npz")}

    def __len__(self) -> int:
        return sum(1 for _ in self.folder.glob("*.npz"))

    def _file(self, k: str) -> Path:
        return self.folder / f"{k}.npz"

    def get(self, k: str) -> dict | None:
        f = self._file(k)
        if k not in self.keys or not f.exists():
            return None
        try:
            with np.load(f, allow_pickle=False) as z:
                return {name: z[name] for name in z.files}
        except (OSError, ValueError, KeyError):      # unreadable: as if never stored
            return None

    def put(self, k: str, record: dict) -> None:
        write_atomic(self._file(k), lambda fh: np.savez(fh, **record))
        self.keys.add(k)
