"""The verdict of a results file: one word and its reasons, the same for the terminal, the exit
status of `--fail-on-limit`, the results file's `verdict` attributes and the report.

In order:

- FAIL: some data set of U_ad has no equilibrium (status 3: a floating body's load is not
  balanced by contact and friction — it slides off or lifts away), whatever the limits; or a
  worst value breaks its limit (a best value its lower limit) outside the mesh's estimated error.
- MARGINAL: a broken or kept limit lies within the extreme ± its estimated mesh error
  (`mesh_check_verdict`, wcs/results/meshcheck.py).
- NOT ESTABLISHED: a criterion with a limit has no value (every evaluation failed), or some
  evaluations failed otherwise (no convergence, a singular system, ...): the criteria are unknown
  there, and the largest may lie among them.
- INCOMPLETE RUN: the run stopped before its end (`complete: no`).
- PASS: every limit holds; NO LIMITS: the study sets none (failures are then named all the same).

A solution outside the model's validity (strains, rotations or displacements too large for
small-strain theory, wcs/model/validity.py) is named among the reasons of every verdict, as a warning
beside the word (the word and the exit status stay those of the limits: a rubber pad strained
by 20 % is warned of); a solution whose strains or displacements reach `MEANINGLESS` (a body
moving by its own size, a modulus in GPa where Pa is meant) makes a PASS NOT ESTABLISHED: the
numbers it rests on are not the physics'.

Every failure is named with where in U_ad it lies (`region`). A verdict whose margin is within
CLOSE of its limit while the mesh's share of the value was not estimated says so
(`unchecked`): a finer mesh may turn it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .dataset import widest
from ..status import Status, describe
from ..model.validity import meaningless
from ..model.validity import warnings as validity_warnings

CLOSE = 0.05          # a margin within 5 % of its limit: the order of a P1 mesh's share of a stress or pressure
SEPARATES = 0.25      # a parameter whose failed and solved data sets' mean positions in its interval differ by
                      # at least a quarter of it is named as the direction the failures lie in


@dataclass(frozen=True)
class Verdict:
    word: str                   # PASS | FAIL | MARGINAL | NOT ESTABLISHED | INCOMPLETE RUN | NO LIMITS
    reasons: tuple[str, ...]    # one sentence each, the deciding one first
    unchecked: tuple[str, ...]  # criteria whose margin is within CLOSE and whose mesh share is not estimated

    @property
    def label(self) -> str:
        """The word, with "mesh share unknown" where a margin inside CLOSE decides it unestimated."""
        return self.word + (" (mesh share unknown)" if self.unchecked and self.word in ("PASS", "FAIL") else "")

    @property
    def text(self) -> str:
        return f"{self.label}: " + "; ".join(self.reasons)


def _g(v: float) -> str:
    return f"{v:.4g}"


def region(x: np.ndarray, bad: np.ndarray, lower: np.ndarray, upper: np.ndarray, params: list[str]) -> str:
    """Where in the box the data sets `bad` lie against the others: a parameter that separates
    them by a threshold, else the parameters towards whose ends they lie (their mean positions in
    the interval differ by SEPARATES or more), else "spread over the box"."""
    x = np.asarray(x, float)
    finite = np.all(np.isfinite(x), axis=1)
    b, ok = bad & finite, ~bad & finite
    if not b.any():
        return "at data sets not recorded"
    if not ok.any():
        return "over the whole box (no data set solved)"
    span = np.where(upper > lower, upper - lower, 1.0)
    s = (x - lower) / span
    cuts, leans = [], []
    for j, p in enumerate(params):
        if upper[j] <= lower[j]:
            continue
        lo_b, hi_b, lo_ok, hi_ok = x[b, j].min(), x[b, j].max(), x[ok, j].min(), x[ok, j].max()
        if hi_ok < lo_b:
            cuts.append(f"{p} ≥ {_g(lo_b)} (every data set solved has {p} ≤ {_g(hi_ok)})")
        elif lo_ok > hi_b:
            cuts.append(f"{p} ≤ {_g(hi_b)} (every data set solved has {p} ≥ {_g(lo_ok)})")
        d = s[b, j].mean() - s[ok, j].mean()
        if abs(d) >= SEPARATES:
            leans.append((abs(d), f"{'high' if d > 0 else 'low'} {p} ({_g(lo_b)} … {_g(hi_b)} of "
                                  f"[{_g(lower[j])}, {_g(upper[j])}])"))
    if cuts:
        return "where " + " and where ".join(cuts)
    if leans:
        return "towards " + ", ".join(t for _, t in sorted(leans, reverse=True)[:3])
    return "spread over the box (no parameter separates them from the solved ones)"


def _status(ds) -> np.ndarray:
    """The status of each evaluation (a file without one: every evaluation of `phi` solved)."""
    if "status" in ds:
        return np.atleast_1d(ds["status"].values).astype(int)
    return np.zeros(ds.sizes.get("eval", 1) if "phi" in ds else 0, int)


def _x(ds, n: int, p: int) -> np.ndarray:
    return ds["x"].values.astype(float).reshape(n, p) if "x" in ds else np.full((n, p), np.nan)


def failures(ds) -> list[str]:
    """A sentence per kind of failure: no equilibrium first, then the others together, each
    with its count and where in U_ad it lies."""
    status = _status(ds)
    n = status.size
    params = [str(p) for p in ds["param"].values] if "param" in ds.coords else []
    p = len(params)
    lower = ds["param_lower"].values.astype(float) if "param_lower" in ds else np.full(p, np.nan)
    upper = ds["param_upper"].values.astype(float) if "param_upper" in ds else np.full(p, np.nan)
    x = _x(ds, n, p)
    out = []
    sliding = status == int(Status.UNSOLVABLE)
    if sliding.any():
        out.append(f"no equilibrium at {int(sliding.sum())} of {n} data sets (status 3: a floating body's load "
                   f"is not balanced by contact and friction) {region(x, sliding, lower, upper, params)}")
    other = (status != 0) & ~sliding
    if other.any():
        codes, counts = np.unique(status[other], return_counts=True)
        kinds = ", ".join(f"{k} × status {c} ({describe(int(c))})" for c, k in zip(codes, counts))
        out.append(f"{int(other.sum())} of {n} evaluations failed ({kinds}), the criteria unknown there, "
                   f"{region(x, other, lower, upper, params)}")
    return out


def _mesh(ds, criterion: str, extreme: str) -> str:
    """The mesh check's verdict of an extreme ("" where it has none)."""
    if "mesh_check_verdict" not in ds or extreme not in [str(e) for e in ds["extreme"].values]:
        return ""
    return str(ds["mesh_check_verdict"].sel(criterion=criterion, extreme=extreme).values)


def verdict(ds) -> Verdict:
    """The verdict of a results file (a run's, a sweep's or a solve's; a fuzzy study's at its widest level)."""
    ds = widest(ds)
    names = [str(c) for c in ds["criterion"].values] if "criterion" in ds.coords else []
    status = _status(ds)
    ok = status == 0
    phi = ds["phi"].values.astype(float).reshape(status.size, len(names)) if "phi" in ds else None

    def column(var, j, pick=None):
        if var in ds:
            return float(np.ravel(ds[var].values)[j])
        if pick is None:
            return math.nan
        col = phi[ok, j] if phi is not None else np.array([])
        col = col[np.isfinite(col)]
        return float(pick(col)) if col.size else math.nan

    broken, marginal, unknown, unchecked, held = [], [], [], [], []
    for j, c in enumerate(names):
        ends = [("worst", column("worst_value", j, np.max), column("limit", j), 1.0)]
        if "limit_lower" in ds:
            ends.append(("best", column("best_value", j, np.min), column("limit_lower", j), -1.0))
        for extreme, value, limit, sign in ends:
            if not math.isfinite(limit):
                continue
            if not math.isfinite(value):
                unknown.append(c)
                continue
            margin = sign * (limit - value)
            pct = 100 * margin / abs(limit) if limit else math.inf
            said = (f"{c} {'worst' if sign > 0 else 'best'} {_g(value)} against its "
                    f"{'limit' if sign > 0 else 'lower limit'} {_g(limit)} ({pct:+.2g} %)")
            mesh = _mesh(ds, c, extreme)
            if mesh == "MARGINAL":
                marginal.append(said)
            elif margin < 0:
                broken.append(said)
            else:
                held.append(said)
            if mesh not in ("PASS", "FAIL", "MARGINAL") and abs(margin) <= CLOSE * abs(limit):
                unchecked.append(c)
    fails, invalid = failures(ds), validity_warnings(ds)
    sliding = bool(fails) and fails[0].startswith("no equilibrium")
    other_failed = bool((status != 0).any())
    limits = bool(broken or marginal or unknown or held)
    mesh_said = str(ds.attrs.get("mesh_check", "")) or "no mesh check in the file"
    tail = ([f"the margin of {', '.join(dict.fromkeys(unchecked))} is within {CLOSE:.0%} of its limit and the "
             f"mesh's share of it is not estimated (mesh check: {mesh_said}): a finer mesh may turn the verdict"]
            if unchecked else [])
    if sliding or broken:
        broke = [f"limit broken: {'; '.join(broken)}"] if broken else []
        return Verdict("FAIL", tuple(fails[:sliding] + broke + fails[sliding:] + invalid + tail), tuple(unchecked))
    if marginal:
        return Verdict("MARGINAL", tuple([f"the limit lies within the extreme ± its estimated mesh error: "
                                          f"{'; '.join(marginal)}"] + fails + invalid), tuple(unchecked))
    if unknown or (limits and (other_failed or meaningless(ds))):
        why = [f"no value for {', '.join(dict.fromkeys(unknown))} (every evaluation failed)"] if unknown else []
        return Verdict("NOT ESTABLISHED", tuple(why + fails + invalid + tail), tuple(unchecked))
    if str(ds.attrs.get("complete", "yes")) == "no":
        return Verdict("INCOMPLETE RUN", tuple([f"no limit is broken among the {status.size} evaluations in the "
                                                "file, but the run did not finish"] + fails + invalid),
                       tuple(unchecked))
    if limits:
        return Verdict("PASS", tuple([f"every limit holds: {'; '.join(held)}"] + invalid + tail), tuple(unchecked))
    return Verdict("NO LIMITS", tuple(["the study sets no limits; worst values are reported only"] + fails + invalid),
                   ())


def attributes(ds) -> dict:
    """The results file's `verdict` (the word) and `verdict_reasons` (one reason a line)."""
    v = verdict(ds)
    return {"verdict": v.label, "verdict_reasons": "\n".join(v.reasons)}
