"""What a dynamic study adds to the results file of `wcs run` / `wcs sweep`:
the `time` coordinate, `phi_history` (eval, criterion, time), each criterion's `over_time`, and
where the gradients came from (`gradients`, `certificate_note`): the adjoint through time
(`wcs.dynamics.adjoint`), finite differences where it is not differentiable or not covered."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import xarray as xr


ADJOINT = ("gradients through time by the adjoint (a reverse sweep over the levels' final active sets) where "
           "the search asked for them; where an evaluation's reduced history is not differentiable (its "
           "`message` says why: a peak tied between levels, a contact switch within reach, a source on a cell "
           "face) the search took finite differences of the reduced criterion (stage `fd`)")


def gradients(study) -> str:
    """The results file's `gradients` attribute of a dynamic study (and `wcs check`'s line): the
    adjoint through time (`wcs.dynamics.adjoint`)."""
    return ("adjoint through time; finite differences of the reduced criterion where an "
            "evaluation's message says it is not differentiable")


def level_times(dyn) -> np.ndarray:
    """t_n = n Δt, n = 0 … levels: the times of a dynamic study's levels (`step_levels`)."""
    return np.arange(dyn.levels + 1) * dyn.time_step


def history_variables(study, records: list[dict]) -> dict:
    """`phi_history` (eval, criterion, time) of a run's records (NaN where an evaluation failed)
    and the `time` coordinate."""
    t = level_times(study.dynamics)
    k = len(study.criteria)
    rows = [np.asarray(r["phi_history"], float) if r.get("phi_history") is not None
            else np.full((k, t.size), np.nan) for r in records]
    values = np.stack(rows) if rows else np.zeros((0, k, t.size))
    how = ", ".join(f"{c.name}: {c.over_time or 'max'}" for c in study.criteria)
    return {"time": ("time", t, {"units": "s", "long_name": "time of the level"}),
            "phi_history": (("eval", "criterion", "time"), values,
                            {"long_name": "criterion values at every time level; phi is each reduced by its "
                                          f"over_time ({how})"})}


def dynamic_results(ds: xr.Dataset, study, records: list[dict]) -> xr.Dataset:
    """A run's results file with what a dynamic study adds: `time`, `phi_history`, the reductions
    (`over_time` per criterion) and where the gradients came from (`gradients`,
    `certificate_note`)."""
    v = history_variables(study, records)
    ds = ds.assign_coords(time=v["time"]).assign(phi_history=v["phi_history"])
    ds["over_time"] = (("criterion",), np.array([c.over_time or "max" for c in study.criteria], dtype=object),
                       {"long_name": "reduction of each criterion's history: max | min | final | mean"})
    note = ADJOINT
    notes = [f"{n}; {note}" if n else note for n in map(str, ds["certificate_note"].values)]
    ds["certificate_note"] = ("criterion", np.array(notes, dtype=object), ds["certificate_note"].attrs)
    ds.attrs["gradients"] = gradients(study)
    ds["iterations"].attrs["long_name"] += "; a dynamic study: their sum over the time levels of the evaluation"
    dyn = study.dynamics
    ds.attrs.update({"dynamics_scheme": dyn.scheme, "time_step": dyn.time_step, "end_time": dyn.end_time})
    return ds
