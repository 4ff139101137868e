"""What drives an extreme: the adjoint gradient at the extreme data set scaled by the box widths,

    d_i = |∂Φ/∂x_i| · (u_i − l_i),

the first-order change of Φ when x_i runs across its interval — comparable between parameters
of different units. The gradient is the run's own where the evaluation at the extreme kept
one; otherwise the extreme data set is solved again with the adjoint. Where there is none the
drivers are NaN and the note says why: the active set (or the maximising region) changes
within reach of the data set, so Φ is not differentiable there; the adjoint's active-set
system is singular; the solve failed. A parameter whose d_i is at most IDLE × the largest
does not move the criterion (to first order, at the extreme).
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import xarray as xr

from .extremes import Extreme, kinds

IDLE = 1e-9                     # d_i at most this share of the largest: the parameter does not move Φ

NO_EXTREME = "no extreme found"
NONSMOOTH = ("no gradient: the criterion is not differentiable at the extreme (the active set or the "
             "maximising region changes within reach of the data set)")


def idle(d: np.ndarray) -> np.ndarray:
    """The parameters that do not move the criterion: d_i ≤ IDLE · max d (all of them when max d = 0)."""
    d = np.asarray(d, float)
    return d <= IDLE * np.max(d, initial=0.0)


def drivers(ds: xr.Dataset, found: list[Extreme], evaluate: Callable) -> xr.Dataset:
    """`drivers` (extreme, criterion, param) = |∂Φ/∂x_i|·(u_i − l_i), `drivers_sign` (the sign of
    ∂Φ/∂x_i) and `drivers_note` of the results file `ds` at the `found` extremes.
    evaluate(x) -> Evaluation with adjoint gradients (for an extreme whose row kept none)."""
    crit = [str(c) for c in ds["criterion"].values]
    ext = kinds(ds)
    width = ds["param_upper"].values - ds["param_lower"].values
    n = width.size
    grad = np.full((len(ext), len(crit), n), np.nan)
    notes = np.full((len(ext), len(crit)), NO_EXTREME, dtype=object)
    resolved = {}
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
            notes[a, c] = NONSMOOTH
            continue
        grad[a, c] = g
        notes[a, c] = how
    dims = ("extreme", "criterion", "param")
    return xr.Dataset({
        "drivers": (dims, np.abs(grad) * width,
                    {"long_name": "what drives each extreme: |dPhi/dx_i| (u_i - l_i), the first-order change of "
                                  "the criterion across parameter i's interval; NaN: no gradient (see drivers_note)",
                     "units": "criterion units"}),
        "drivers_sign": (dims, np.where(np.isfinite(grad), np.sign(grad), 0).astype(np.int8),
                         {"long_name": "sign of dPhi/dx_i at the extreme (+1: the criterion grows with x_i)"}),
        "drivers_note": (dims[:2], notes, {"long_name": "where the gradient comes from, or why there is none"}),
    }, coords={"extreme": np.array(ext, dtype=object)})
