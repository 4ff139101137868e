"""Progress of a run: one updating line on a terminal, one line per evaluation with
--verbose, nothing in logs (not a terminal, or --quiet) but the final summary.
"""
from __future__ import annotations

import math
import sys
import time

from .results import widest


def _g(v) -> str:
    return "nan" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.4g}"


def _clock(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"


class Progress:
    """`start(total, criteria)`, `update(done, record, best)` after each evaluation, `finish()`.

    mode: "line" (a single updating line), "verbose" (a line per evaluation) or "quiet".
    """

    def __init__(self, mode: str | None = None, stream=None, interval: float = 0.2):
        self.stream = stream or sys.stderr
        if mode is None:
            mode = "line" if getattr(self.stream, "isatty", lambda: False)() else "quiet"
        self.mode = mode
        self.interval = interval
        self._last = 0.0
        self._width = 0

    @classmethod
    def from_args(cls, args) -> "Progress":
        if getattr(args, "quiet", False):
            return cls("quiet")
        if getattr(args, "verbose", False):
            return cls("verbose")
        return cls(None)

    def start(self, total: int, criteria: list[str], label: str = "evals") -> None:
        self.total, self.criteria, self.label = total, criteria, label
        self.failed = 0
        self.t0 = time.perf_counter()

    def update(self, done: int, record: dict, best: dict) -> None:
        self.failed += record["status"] != 0
        if self.mode == "quiet":
            return
        if self.mode == "verbose":
            phi = " ".join(f"{c}={_g(float(v))}" for c, v in zip(self.criteria, record["phi"]))
            src = " (stored)" if record.get("from_store") else ""
            tail = "" if record["status"] == 0 else f"  status {record['status']}: {record['message']}"
            print(f"[{done}/{self.total}] {record['stage']:<7} {phi}  {record['wall_time']:.3g} s{src}{tail}",
                  file=self.stream, flush=True)
            return
        now = time.perf_counter()
        self._pending = (done, best)
        if now - self._last < self.interval and done < self.total:
            return
        self._draw(done, best, now)

    def _draw(self, done: int, best: dict, now: float, final: bool = False) -> None:
        self._last = now
        elapsed = now - self.t0
        eta = elapsed / done * (self.total - done) if done else 0.0
        line = (f"{self.label} {done}/{self.total}  best: "
                + " ".join(f"{c}={_g(best.get(c))}" for c in self.criteria)
                + (f"  {self.failed} failed" if self.failed else "")
                + (f"  [done in {_clock(elapsed)}]" if final else f"  [eta {_clock(eta)}]"))
        pad = max(0, self._width - len(line))
        self._width = len(line)
        self.stream.write("\r" + line + " " * pad)
        self.stream.flush()

    def finish(self) -> None:
        if self.mode == "line" and getattr(self, "_pending", None):
            self._draw(*self._pending, time.perf_counter(), final=True)   # the final count, not a throttled one
        if self.mode == "line" and self._width:
            self.stream.write("\n")
            self.stream.flush()


def summary_table(ds) -> str:
    """criterion, worst value, limit, margin, pass/fail ("pass where solved" when evaluations
    failed: the study's verdict, `wcs.verdict`, says what that leaves), certificate (one row per criterion); the
    minimum and the lower limit beside them when some criterion asks for its minimum. A fuzzy
    study's row is its widest level (`wcs.results.widest`)."""
    ds = widest(ds)
    ends = "best_value" in ds
    failed = int((ds["status"].values != 0).sum()) if "status" in ds else 0
    rows = [("criterion",) + (("best", "lower limit") if ends else ()) + ("worst", "limit", "margin", "result",
                                                                          "certificate")]
    for i, c in enumerate(ds["criterion"].values):
        w = float(ds["worst_value"].values[i])
        lim = float(ds["limit"].values[i])
        if math.isnan(lim):
            margin, verdict = "", "-"
        elif math.isnan(w):
            margin, verdict = "", "not established (no solved data set)"
        else:
            margin, verdict = f"{lim - w:.4g}", "pass" if w <= lim else "FAIL"
        low = ()
        if ends:
            b, blim = float(ds["best_value"].values[i]), float(ds["limit_lower"].values[i])
            low = (_g(b), "" if math.isnan(blim) else _g(blim))
            if not math.isnan(blim):
                verdict = (("not established (no solved data set)" if math.isnan(b) else "pass" if b >= blim
                            else "FAIL") if verdict in ("-", "pass") else verdict)
        cert = str(ds["certificate"].values[i])
        if ends and str(ds["best_certificate"].values[i]) != "not-searched":
            cert = f"min {ds['best_certificate'].values[i]}, max {cert}"
        if verdict == "pass" and failed:
            verdict = f"pass where solved ({failed} failed)"
        rows.append((str(c),) + low + (_g(w), "" if math.isnan(lim) else _g(lim), margin, verdict, cert))
    widths = [max(len(r[k]) for r in rows) for k in range(len(rows[0]))]
    return "\n".join("  ".join(s.ljust(w) for s, w in zip(r, widths)).rstrip() for r in rows)


def limits_broken(ds) -> list[str]:
    """Criteria whose worst value exceeds its limit or whose minimum falls below its lower limit
    (a fuzzy study: at its widest level); one without a value breaks nothing: its verdict is not
    established (`wcs.verdict`)."""
    ds = widest(ds)
    out = []
    for i, c in enumerate(ds["criterion"].values):
        w, lim = float(ds["worst_value"].values[i]), float(ds["limit"].values[i])
        broken = w > lim
        if "limit_lower" in ds:
            b, blim = float(ds["best_value"].values[i]), float(ds["limit_lower"].values[i])
            broken = broken or b < blim
        if broken:
            out.append(str(c))
    return out
