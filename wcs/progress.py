"""Progress of long work: one line updated in place on a terminal — the phase, done/total and an
ETA from the times measured so far — one line per evaluation (and one per finished phase) with
--verbose, nothing in logs (stderr not a terminal) or with --quiet.

A command installs its `Progress` (`reporting`); the code of a long phase (meshing, assembly,
DD set-up, the worst cases' fields, the drivers, the mesh check, the report) marks it with
`phase(name, total)` and needs no argument for it: outside a command the current progress is
quiet. A search's line (`start`, `batch`, `update`, `finish`) stays on the screen when it ends;
a phase's line is cleared when the phase ends.
"""
from __future__ import annotations

import contextlib
import math
import shutil
import sys
import threading
import time
from collections import deque

INTERRUPTED = 130    # the exit status of a command stopped by Ctrl-C (SIGINT), as a shell's 128 + 2
WINDOW = 20          # the ETA of a search: the rate of its last WINDOW evaluations (wall clock)


def _g(v) -> str:
    return "nan" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.4g}"


def _clock(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"


class Phase:
    """A long phase of a command: `step()` after each of its `total` parts (None: not known ahead,
    the line shows the parts done and the time taken); its ETA is the measured time per part so far
    times the parts left. A context manager."""

    def __init__(self, progress: "Progress", name: str, total: int | None):
        self.progress, self.name, self.total = progress, name, total
        self.done = 0
        self.t0 = time.perf_counter()

    def step(self, n: int = 1) -> None:
        self.done += n
        self.progress._draw(time.perf_counter())

    def text(self, now: float) -> str:
        elapsed = now - self.t0
        if self.total is None:
            return f"{self.name}{f' {self.done}' if self.done else ''}  [{_clock(elapsed)}]"
        eta = f"eta {_clock(elapsed / self.done * (self.total - self.done))}" if self.done else "eta …"
        return f"{self.name} {self.done}/{self.total}  [{eta}]"

    def __enter__(self) -> "Phase":
        self.progress._open(self)
        return self

    def __exit__(self, *exc) -> None:
        self.progress._close(self)


class Progress:
    """`start(total, criteria)`, `batch(stage, size)` before each batch, `update(done, record,
    best)` after each evaluation, `finish()`; `phase(name, total)` for any other long phase.

    mode: "line" (a single updating line), "verbose" (a line per evaluation and per finished
    phase) or "quiet"; None: "line" on a terminal, else "quiet". tick: seconds between redraws of
    the line while nothing reports (the clock of a long evaluation or phase goes on; None: none);
    interval: seconds at least between two lines of a search (a phase draws each of its parts).
    """

    def __init__(self, mode: str | None = None, stream=None, interval: float = 0.2, tick: float | None = 1.0):
        self.stream = stream or sys.stderr
        if mode is None:
            mode = "line" if getattr(self.stream, "isatty", lambda: False)() else "quiet"
        self.mode = mode
        self.interval = interval
        self.tick = tick
        self._last = 0.0
        self._width = 0
        self._search = False               # a search's line is up (start .. finish)
        self._phases: list[Phase] = []
        self._lock = threading.RLock()
        self._ticker = None

    @classmethod
    def from_args(cls, args) -> "Progress":
        if getattr(args, "quiet", False):
            return cls("quiet")
        if getattr(args, "verbose", False):
            return cls("verbose")
        return cls(None)

    # ---- a search or a sweep ---------------------------------------------------------------
    def start(self, total: int, criteria: list[str], label: str = "evals", budget: bool = False) -> None:
        """total: the evaluations to make; budget: `total` is only their cap (a search stops by itself)."""
        self.total, self.criteria, self.label, self.budget = total, criteria, label, budget
        self.failed = 0
        self.done, self.best = 0, {}
        self.stage, self.stage_start, self.stage_end = "", 0, total
        self.t0 = time.perf_counter()
        self._times = deque(maxlen=WINDOW + 1)      # (time, done) of the last updates
        with self._lock:
            self._search = True
        self._start_ticker()

    def batch(self, stage: str, size: int) -> None:
        """A batch of `size` data sets of search stage `stage` is being answered."""
        if self._search:
            self.stage, self.stage_start, self.stage_end = stage, self.done, min(self.done + size, self.total)

    def update(self, done: int, record: dict, best: dict) -> None:
        self.failed += record["status"] != 0
        now = time.perf_counter()
        with self._lock:
            self.done, self.best = done, dict(best)
            self._times.append((now, done))
        if self.mode == "quiet":
            return
        if self.mode == "verbose":
            phi = " ".join(f"{c}={_g(float(v))}" for c, v in zip(self.criteria, record["phi"]))
            src = " (stored)" if record.get("from_store") else ""
            tail = "" if record["status"] == 0 else f"  status {record['status']}: {record['message']}"
            print(f"[{done}/{self.total}] {record['stage']:<7} {phi}  {record['wall_time']:.3g} s{src}{tail}",
                  file=self.stream, flush=True)
            return
        if now - self._last < self.interval and done < self.total:
            return
        self._draw(now)

    def eta(self) -> float | None:
        """Seconds left of the batch being answered: the measured time per evaluation times the
        evaluations left in it; None before the first is measured. The time per evaluation is
        the wall clock between the last WINDOW updates (solves, answers from the store, MPI ranks'
        batches as they come), from the first update on: the first evaluation's cold start (the
        analysis, the first factorization: in 3D many warm evaluations long) is no rate; until
        two updates are apart, the time since the start per evaluation."""
        if not self._times:
            return None
        (t_a, n_a), (t_b, n_b) = self._times[0], self._times[-1]
        rate = (t_b - t_a) / (n_b - n_a) if t_b > t_a else (t_b - self.t0) / n_b
        return rate * max(self.stage_end - self.done, 0)

    def _search_text(self, now: float, final: bool = False) -> str:
        count = f"{self.done} (budget {self.total})" if self.budget else f"{self.done}/{self.total}"
        stage = (f"  {self.stage} {min(self.done, self.stage_end) - self.stage_start}/"
                 f"{self.stage_end - self.stage_start}" if self.stage and not final and self.budget else "")
        eta = self.eta()
        clock = (f"[done in {_clock(now - self.t0)}]" if final else
                 f"[{_clock(now - self.t0)}, eta {'…' if eta is None else _clock(eta)}"
                 f"{' for ' + self.stage if self.budget and self.stage else ''}]")
        return (f"{self.label} {count}{stage}  best: "
                + " ".join(f"{c}={_g(self.best.get(c))}" for c in self.criteria)
                + (f"  {self.failed} failed" if self.failed else "") + "  " + clock)

    def finish(self) -> None:
        with self._lock:
            if self.mode == "line" and self._search:
                self._write(self._search_text(time.perf_counter(), final=True) + "\n")  # the final count
                self._width = 0
            self._search = False
        self._stop_ticker()

    # ---- any other long phase -----------------------------------------------------------------
    def phase(self, name: str, total: int | None = None) -> Phase:
        """A phase to enter (`with progress.phase("mesh check", 6) as p: ... p.step()`)."""
        return Phase(self, name, total)

    def _open(self, phase: Phase) -> None:
        with self._lock:
            self._phases.append(phase)
        self._start_ticker()
        self._draw(time.perf_counter())

    def _close(self, phase: Phase) -> None:
        with self._lock:
            self._phases.remove(phase)
            now = time.perf_counter()
            if self.mode == "verbose" and not self._phases and not self._search:
                count = "" if phase.total is None else f" {phase.done}/{phase.total}"
                print(f"{phase.name}{count} in {_clock(now - phase.t0)}", file=self.stream, flush=True)
            elif self.mode == "line":
                if self._phases or self._search:
                    self._draw(now)
                elif self._width:               # the phase is over: its line goes
                    self._write(" " * self._width + "\r")
                    self._width = 0
        if not self._phases and not self._search:
            self._stop_ticker()

    # ---- the line ------------------------------------------------------------------------------
    def _text(self, now: float) -> str:
        parts = ([self._search_text(now)] if self._search else []) + [p.text(now) for p in self._phases]
        return " › ".join(parts)

    def _draw(self, now: float) -> None:
        with self._lock:
            if self.mode != "line":
                return
            self._last = now
            line = self._text(now)[:shutil.get_terminal_size((120, 24)).columns - 1]   # one row: \r redraws it
            if line:
                self._write(line)
                self._width = len(line)

    def _write(self, text: str) -> None:
        pad = max(0, self._width - len(text.rstrip("\n")))
        end = "\n" if text.endswith("\n") else ""
        self.stream.write("\r" + text.rstrip("\n") + " " * pad + end)
        self.stream.flush()

    def _start_ticker(self) -> None:
        if self.mode != "line" or self.tick is None or self._ticker is not None:
            return
        stop = threading.Event()

        def run():
            while not stop.wait(self.tick):
                self._draw(time.perf_counter())
        self._ticker = (threading.Thread(target=run, name="wcs-progress", daemon=True), stop)
        self._ticker[0].start()

    def _stop_ticker(self) -> None:
        if self._ticker is not None and not self._phases and not self._search:
            thread, stop = self._ticker
            stop.set()
            thread.join()
            self._ticker = None


_current: list[Progress] = []


@contextlib.contextmanager
def reporting(progress: Progress):
    """`progress` is the current one (`phase`) while the block runs."""
    _current.append(progress)
    try:
        yield progress
    finally:
        _current.pop()


def current() -> Progress:
    """The progress a command installed (`reporting`); quiet outside one."""
    return _current[-1] if _current else Progress("quiet")


def phase(name: str, total: int | None = None) -> Phase:
    """A long phase of the current command: `with phase("mesh check", n) as p: ... p.step()`."""
    return current().phase(name, total)
