"""`wcs solve` on a dynamic study: the levels at the nominal data, their history written to
the results file (a `time` coordinate, `phi_history` (criterion, time)) and a ParaView time
series (OUT.pvd over one OUT-k.vtm per output level)."""
from __future__ import annotations

import numpy as np

from .stepping import dynamic_matrices, region_dynamics, step_levels

REDUCTIONS = {"max": np.max, "min": np.min, "final": lambda h: h[-1], "mean": np.mean}


def simulate(ev, x=(), others=None, load=None, damping=None):
    """The `History` of a study's levels at data vector x (`wcs.evaluation.Evaluator` ev):
    load(t) the reduced load (None: the data set's own, constant), damping an extra damping
    matrix on the full DOFs (absorbing boundaries)."""
    model = ev.model
    c = ev.map.coefficients(x, others)
    rho, visc = region_dynamics(model, ev.map, x, others)
    mats = dynamic_matrices(model, c, rho, visc, damping)
    return step_levels(model, c, mats, ev.study.dynamics, load, ev.criteria)


def reduced(study, history) -> dict[str, float]:
    """Each criterion's history reduced by its `over_time` (default max, the peak)."""
    out = {}
    for crit in study.criteria:
        values = np.asarray(history.phi[crit.name], float)
        out[crit.name] = float(REDUCTIONS[crit.over_time or "max"](values))
    return out
