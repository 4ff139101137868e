"""The results of a run in a few lines for the terminal: the table of the criteria (worst and best
values, limits, margins, pass or fail, certificates) and the limits broken, which set the exit
status of `--fail-on-limit`."""
from __future__ import annotations

import math

from ..progress import _g
from .dataset import widest


def summary_table(ds) -> str:
    """criterion, worst value, limit, margin, pass/fail ("pass where solved" when evaluations
    failed: the study's verdict, `wcs.results.verdict`, says what that leaves), certificate (one row per criterion); the
    minimum and the lower limit beside them when some criterion asks for its minimum. A fuzzy
    study's row is its widest level (`widest`)."""
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
    established (`wcs.results.verdict`)."""
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
