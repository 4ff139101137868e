"""What drives an extreme: the adjoint gradient at the extreme data set scaled by the box widths,

    d_i = |∂Φ/∂x_i| · (u_i − l_i),

the first-order change of Φ when x_i runs across its interval — comparable between parameters
of different units. The gradient is the run's own where the evaluation at the extreme kept
one; otherwise the extreme data set is solved again with the adjoint. Where the active set (or
the maximising region) changes within reach of the data set, Φ is not differentiable there and
its adjoint gradient is one-sided: the drivers are then one-sided differences instead, labelled
so (`drivers_note`), one solve per parameter and side,

    D⁺_i = (Φ(x + h_i e_i) − Φ(x)) / h_i · (u_i − l_i),   D⁻_i = (Φ(x) − Φ(x − h_i e_i)) / h_i · (u_i − l_i),

h_i = FD_STEP (u_i − l_i) (`wcs.search.scaling`: the quotient errs by O(h) and by the solve's
round-off / h), each side only where it stays in the box; `drivers_forward`, `drivers_backward`
keep them, d_i is the larger |D±_i| and its sign the sides' common one (0 where they
disagree: a kink in x_i). Where every side taken points out of the box at a corner (the
maximum: D⁺_i ≤ 0 at the lower bound, D⁻_i ≥ 0 at the upper; the minimum: reversed), the
extreme is a maximum (minimum) along every edge of the box leaving that corner, and the note
says so. Where there is no number the drivers are NaN and the note says why: the adjoint's
active-set system is singular; the solve failed. A parameter whose d_i is at most IDLE × the
largest, or IDLE × |Φ| at the extreme, does not move the criterion (to first order, at the
extreme): below |Φ| · 1e-9 an effect is the solves' round-off (eps · the condition number of the
stiffness, 1e6–1e8 on these meshes, is 1e-10–1e-8 of Φ), such as the 6e-10 Pa drivers of a
1e7 Pa mean pressure that no parameter moves.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from collections.abc import Callable

import numpy as np

from .extremes import Extreme, kinds
from ..search.scaling import FD_STEP

if TYPE_CHECKING:
    import xarray as xr


IDLE = 1e-9                     # d_i at most this share of the largest or of |Φ|: the parameter does not move Φ

NO_EXTREME = "no extreme found"
NONSMOOTH = ("the criterion is not differentiable at the extreme (the active set, the maximising region or the "
             "maximising contact node changes within reach of the data set)")


def idle(d: np.ndarray, value: float = 0.0) -> np.ndarray:
    """The parameters that do not move the criterion: d_i ≤ IDLE · max(max d, |Φ|), Φ = `value` at
    the extreme (all of them when both are 0)."""
    d = np.asarray(d, float)
    return d <= IDLE * max(np.max(d, initial=0.0), abs(value) if np.isfinite(value) else 0.0)


def drivers(ds: xr.Dataset, found: list[Extreme], evaluate: Callable) -> xr.Dataset:
    """`drivers` (extreme, criterion, param) = |∂Φ/∂x_i|·(u_i − l_i), `drivers_sign` (the sign of
    ∂Φ/∂x_i), `drivers_forward` / `drivers_backward` (one-sided differences, where Φ is not
    differentiable) and `drivers_note` of the results file `ds` at the `found` extremes.
    evaluate(x, gradients=True) -> Evaluation, with adjoint gradients (for an extreme whose row
    kept none) or without (the one-sided differences)."""
    crit = [str(c) for c in ds["criterion"].values]
    ext = kinds(ds)
    lower, upper = ds["param_lower"].values, ds["param_upper"].values
    width = upper - lower
    n = width.size
    grad = np.full((len(ext), len(crit), n), np.nan)
    sides = np.full((2, len(ext), len(crit), n), np.nan)           # backward, forward: ΔΦ/h
    notes = np.full((len(ext), len(crit)), NO_EXTREME, dtype=object)
    resolved, stepped = {}, {}
    for e in found:
        a, c = ext.index(e.kind), crit.index(e.criterion)
        if not e.found:
            continue
        g = ds["grad"].values[e.eval, c] if 0 <= e.eval < ds.sizes["eval"] else np.full(n, np.nan)
        rough = bool(ds["nonsmooth"].values[e.eval]) if 0 <= e.eval < ds.sizes["eval"] else False
        how = "the run's adjoint gradient at the extreme"
        if not np.all(np.isfinite(g)):
            k = e.x.tobytes()
            if k not in resolved:
                resolved[k] = evaluate(e.x)
            ev = resolved[k]
            if ev.status != 0:
                notes[a, c] = f"no gradient: the extreme data set did not solve again ({ev.message})"
                continue
            g = (ev.grad or {}).get(e.criterion)
            if g is None:
                notes[a, c] = "no gradient: the adjoint's active-set system is singular at the extreme"
                continue
            g, rough = np.asarray(g, float), bool(ev.nonsmooth)
            how = "the adjoint gradient of the extreme data set solved again"
        if rough:
            k = e.x.tobytes()
            if k not in stepped:
                stepped[k] = _one_sided(e.x, lower, upper, evaluate)
            steps = stepped[k]
            sides[:, a, c] = _quotients(steps, e.value, e.criterion, n)
            notes[a, c] = _one_sided_note(sides[:, a, c], e, lower, upper, steps)
            continue
        grad[a, c] = g
        notes[a, c] = how
    back, fwd = sides
    rough = np.isfinite(sides).any(axis=(0, 3))[..., None]       # (extreme, criterion, 1): one-sided drivers
    sb, sf = np.sign(back), np.sign(fwd)
    common = np.where(np.isnan(sb), sf, np.where(np.isnan(sf), sb, np.where(sb == sf, sf, 0.0)))
    d = np.where(rough, np.where(width > 0, np.fmax(np.abs(back), np.abs(fwd)) * width, 0.0), np.abs(grad) * width)
    sign = np.nan_to_num(np.where(rough, common, np.sign(grad)))
    dims = ("extreme", "criterion", "param")
    side_attrs = "a one-sided difference (the criterion is not differentiable at the extreme): "
    import xarray as xr
    return xr.Dataset({
        "drivers": (dims, d,
                    {"long_name": "what drives each extreme: |dPhi/dx_i| (u_i - l_i), the first-order change of "
                                  "the criterion across parameter i's interval (where the criterion is not "
                                  "differentiable: the larger one-sided difference, see drivers_note); NaN: no "
                                  "number (see drivers_note)",
                     "units": "criterion units"}),
        "drivers_sign": (dims, sign.astype(np.int8),
                         {"long_name": "sign of dPhi/dx_i at the extreme (+1: the criterion grows with x_i; "
                                       "one-sided differences: their common sign, 0 where they disagree)"}),
        "drivers_forward": (dims, fwd * width,
                            {"long_name": side_attrs + "(Phi(x + h_i e_i) - Phi(x)) / h_i (u_i - l_i), "
                                          f"h_i = {FD_STEP:g} (u_i - l_i); NaN: not taken (differentiable, or the "
                                          "step leaves the box)", "units": "criterion units"}),
        "drivers_backward": (dims, back * width,
                             {"long_name": side_attrs + "(Phi(x) - Phi(x - h_i e_i)) / h_i (u_i - l_i), "
                                           f"h_i = {FD_STEP:g} (u_i - l_i); NaN: not taken (differentiable, or the "
                                           "step leaves the box)", "units": "criterion units"}),
        "drivers_note": (dims[:2], notes, {"long_name": "where the gradient comes from, or why there is none"}),
    }, coords={"extreme": np.array(ext, dtype=object)})


def _one_sided(x, lower, upper, evaluate) -> list:
    """[(i, Δx_i, Evaluation)] of the steps h_i = FD_STEP (u_i − l_i) from x along each parameter
    with an interval, backward and forward where the step stays in the box."""
    out = []
    for i in np.flatnonzero(upper > lower):
        h = FD_STEP * (upper[i] - lower[i])
        for side in (-1.0, 1.0):
            y = x.copy()
            y[i] = x[i] + side * h
            if lower[i] <= y[i] <= upper[i]:
                out.append((i, y[i] - x[i], evaluate(y, False)))
    return out


def _quotients(steps, value: float, criterion: str, n: int) -> np.ndarray:
    """(2, n): the backward and the forward difference quotients ΔΦ/Δx_i of the steps (NaN where
    not taken or not solved)."""
    q = np.full((2, n), np.nan)
    for i, dx, ev in steps:
        phi = ev.phi.get(criterion, np.nan) if ev.status == 0 else np.nan
        q[int(dx > 0), i] = (phi - value) / dx
    return q


def _one_sided_note(q, e: Extreme, lower, upper, steps) -> str:
    """What the one-sided differences are, and whether they make the extreme a corner one."""
    failed = sum(ev.status != 0 for _, _, ev in steps)
    text = (f"one-sided differences: {NONSMOOTH}, so each parameter was stepped by {FD_STEP:g} of its interval, "
            "backward and forward where the step stays in the box; drivers are the larger side")
    if failed:
        return text + f" ({failed} of {len(steps)} steps did not solve: NaN there)"
    back, fwd = q
    at_lo, at_hi = e.x <= lower, e.x >= upper
    moving = upper > lower
    if np.all(at_lo | at_hi | ~moving):
        out = -1.0 if e.sense == "max" else 1.0          # the side of Φ' that certifies, moving inward
        inward = np.where(at_lo, fwd, -back)[moving]
        if np.all(out * inward >= 0):
            what = "maximum" if e.sense == "max" else "minimum"
            text += (f"; every one-sided difference points out of the box at this corner: a {what} along every "
                     "edge of the box leaving it")
    return text
