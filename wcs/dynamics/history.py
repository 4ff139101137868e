"""The worst-scenario search over a dynamic study: the evaluation of one data
set is one simulation of its time levels, and each criterion's value is its history reduced by
`over_time` (max, the peak, by default; `reduced`).

`DynamicEvaluator` is the `Evaluator` of such a study: `evaluate(x)` runs the levels and returns
an `Evaluation` whose `phi` are the reduced values, `history` the criteria at every level and
`fields` the solution fields at the output levels (an `output_time` dimension); with
`gradients`, dΦ/dx by the adjoint through time (`wcs.dynamics.adjoint`), None for a criterion
whose reduced history is not differentiable there (the evaluation's message says why; the
strategies that want a gradient then take finite differences, `wcs.search.ascent`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from wcs.errors import SolveError
from wcs.model.evaluation import Evaluation, Evaluator
from wcs.model.fields import Data, fields_dataset
from wcs.status import Status

from . import adjoint
from .loading import at_time_zero, damping_cells, damping_matrix, load_function
from .release import carried_over, reactions, released_dofs, released_model, released_names
from .spec import InitialVelocity
from .stepping import (dynamic_matrices, initial_state, level_solution, region_dynamics, rigid_velocity,
                       step_levels)

REDUCTIONS = {"max": np.max, "min": np.min, "final": lambda h: h[-1], "mean": np.mean}
REDUCED = {"max": "the peak over time", "min": "the least over time", "final": "at the end time",
           "mean": "the mean over the levels"}


def simulate(ev, x=(), others=None, load=None, damping=None, dyn=None, record: dict | None = None):
    """The `History` of a study's levels at data vector x (`wcs.model.evaluation.Evaluator` ev):
    load(t) the load vector on the full DOFs at time t, damping an extra damping matrix on the
    full DOFs; None: the scene's own at x (`wcs.dynamics.loading`: time functions and point
    sources; absorbing layer and dashpots). The initial state is taken at the loads of t = 0;
    boundaries held by supports that take dashpots are released after it, loaded by their
    static reactions (`wcs.dynamics.release`). dyn: the levels to run (None: the study's
    `dynamics:` block; `wcs check` times the first few levels with a shorter one). record: a dict
    that receives what the adjoint through time needs (`wcs.dynamics.adjoint`): the levels' model,
    map and data, the start, the held reactions, every level's state and (stabilized) predictor."""
    model, pmap, scene = ev.model, ev.map, ev.study.scene
    dyn = ev.study.dynamics if dyn is None else dyn
    c = pmap.coefficients(x, others)
    heat = model.solve_heat(c) if model.thermal else None
    c0 = at_time_zero(c, scene, pmap.slots(x, others), pmap.index)
    w, v, res = initial_state(model, c0, dyn)
    names, held = released_names(scene), 0.0
    if names:
        u = model.elim.T @ w + model.elim.U0 @ c.support_values
        if dyn.initial == "static":
            held = reactions(model, c0, u, res, heat) * released_dofs(model, names)
        model, pmap = released_model(ev)
        c = pmap.coefficients(x, others)
        w, res = carried_over(model, c, u, res)
        v = rigid_velocity(model, dyn.initial) if isinstance(dyn.initial, InitialVelocity) \
            else np.zeros(model.elim.T.shape[1])
    rho, visc = region_dynamics(model, pmap, x, others)
    s = pmap.slots(x, others)
    if load is None:
        load = load_function(model, scene, c, s, pmap.index, heat)
    if load is None and names:
        constant = model.mechanical_load(c, heat) + held
        load = lambda t: constant                       # noqa: E731 - constant in time
    elif names:
        load = lambda t, own=load: own(t) + held        # noqa: E731 - the released supports' reactions
    cells = None
    if damping is None:
        damping = damping_matrix(model, scene, c, rho, s, pmap.index)
        cells = damping_cells(model, scene, c, rho, s, pmap.index)
    mats = dynamic_matrices(model, c, rho, visc, damping, cells)
    states = predictors = None
    if record is not None:
        states, predictors = [], []
        record.update(model=model, map=pmap, c=c, mats=mats, start=(w, v, res), held=held, states=states,
                      predictors=predictors)
    return step_levels(model, c, mats, dyn, load, ev.criteria, start=(w, v, res), states=states,
                       predictors=predictors)


def reduced(study, history) -> dict[str, float]:
    """Each criterion's history reduced by its `over_time` (default max, the peak)."""
    return {crit.name: float(REDUCTIONS[crit.over_time or "max"](np.asarray(history.phi[crit.name], float)))
            for crit in study.criteria}



def evaluator_for(study, **kw) -> Evaluator:
    """The evaluator of a study: its levels for a dynamic study, one static solve otherwise."""
    return (DynamicEvaluator if getattr(study, "dynamics", None) is not None else Evaluator)(study, **kw)


@dataclass
class DynamicEvaluation(Evaluation):
    history: np.ndarray | None = None       # (criterion, time): every criterion at every level
    levels: object = field(default=None, repr=False)    # (coefficients, History) of the simulation

    @property
    def field_data(self):
        """The fields at the output levels (`Data`, `output_time` first); the small-strain
        measures are their largest over those times (built on first access)."""
        if self._data is None and self.levels is not None:
            self._data = output_fields(self.evaluator.model, *self.levels)
        return self._data


def output_fields(model, c, hist) -> Data:
    """The fields (`wcs.model.fields.fields_dataset`) of each output level of a `History`, stacked
    along `output_time` (its first dimension); the mesh (with its bodies' and regions' names)
    once; `small_strain_*` the largest over the output times."""
    from wcs.contact.solver import ContactResult
    heat = model.solve_heat(c) if model.thermal else None
    parts = []
    for n, u in zip(hist.output_levels, hist.displacement):
        res = None
        if model.zone is not None:
            res = ContactResult(None, hist.force_n[n], hist.force_t[n], Status.SOLVED, "")
        parts.append(fields_dataset(model, level_solution(model, c, u, res, heat)))
    first = parts[0]
    fixed = ("coords", "cells", "cell_body", "cell_region", "contact_coords", "contact_pair")
    out = Data(coords=first.coords)
    for name, v in first.data_vars.items():
        if name in fixed:
            out[name] = v
            continue
        stack = np.stack([p[name].values for p in parts])
        if "small_strain" in name:      # fmax: a level's NaN skipped
            out[name] = (v.dims, np.fmax.reduce(stack, axis=0),
                         {**v.attrs, "long_name": f"{v.attrs.get('long_name', name)}, the largest over the output times"})
        else:
            out[name] = (("output_time",) + v.dims, stack, v.attrs)
    t = np.asarray(hist.time)[hist.output_levels]
    out.set_coord("output_time", ("output_time", t, {"units": "s", "long_name": "time of the output level"}))
    return out


class DynamicEvaluator(Evaluator):
    """The `Evaluator` of a dynamic study: one evaluation is one simulation of the levels."""

    def evaluate(self, values, gradients: bool = False) -> DynamicEvaluation:
        """The levels at a parameter vector or a mapping {dotted path: value} (others nominal):
        phi the criteria reduced over time, history every level's values; with `gradients`, also
        dΦ/dx of every criterion by the adjoint through time (`wcs.dynamics.adjoint`), None where
        the reduced history is not differentiable (the message says why; the search then takes
        finite differences). A level that fails makes the evaluation fail with its status and
        message (NaN criteria)."""
        t0 = time.perf_counter()
        study = self.study
        x, others = study.data_set(values)
        names = [c.name for c in self.criteria]
        record = {}
        try:
            hist = simulate(self, x, others, record=record) if gradients else simulate(self, x, others)
        except SolveError as e:
            nan = {n: float("nan") for n in names}
            return DynamicEvaluation(x, nan, e.status, str(e), 0, time.perf_counter() - t0, evaluator=self)
        phi = reduced(study, hist)
        history = np.array([hist.phi[n] for n in names], float).reshape(len(names), -1)
        c = self.map.coefficients(x, others)
        message = f"solved ({len(hist.time) - 1} time levels)"
        grad = None
        if gradients:
            out = adjoint.gradients(self, x, others, hist, record)
            grad = out.grad
            message += "".join(f"; {n}: finite-difference gradient, {why}" for n, why in out.why.items() if why)
        return DynamicEvaluation(x, phi, Status.SOLVED, message, int(np.sum(hist.iterations)),
                                 time.perf_counter() - t0, evaluator=self, grad=grad,
                                 history=history, levels=(c, hist))
