"""`wcs solve` on a dynamic study: the levels at the nominal data, their history in the
results file (a `time` coordinate: `phi_history` (criterion, time), contact forces, energies;
the fields at the output times) and a ParaView time series, OUT.pvd over OUT-k.vtu."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import xarray as xr

from .loading import at_time_zero, damping_matrix, load_function
from .release import carried_over, reactions, released_dofs, released_model, released_names
from .spec import InitialVelocity
from .stepping import (dynamic_matrices, initial_state, level_solution, region_dynamics, rigid_velocity,
                       step_levels)

REDUCTIONS = {"max": np.max, "min": np.min, "final": lambda h: h[-1], "mean": np.mean}
REDUCED = {"max": "the peak over time", "min": "the least over time", "final": "at the end time",
           "mean": "the mean over the levels"}


def simulate(ev, x=(), others=None, load=None, damping=None):
    """The `History` of a study's levels at data vector x (`wcs.evaluation.Evaluator` ev):
    load(t) the load vector on the full DOFs at time t, damping an extra damping matrix on the
    full DOFs; None: the scene's own at x (`wcs.dynamics.loading`: time functions and point
    sources; absorbing layer and dashpots). The initial state is taken at the loads of t = 0;
    boundaries held by supports that take dashpots are released after it, loaded by their
    static reactions (`wcs.dynamics.release`)."""
    model, pmap, scene, dyn = ev.model, ev.map, ev.study.scene, ev.study.dynamics
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
    if damping is None:
        damping = damping_matrix(model, scene, c, rho, s, pmap.index)
    mats = dynamic_matrices(model, c, rho, visc, damping)
    return step_levels(model, c, mats, dyn, load, ev.criteria, start=(w, v, res))


def reduced(study, history) -> dict[str, float]:
    """Each criterion's history reduced by its `over_time` (default max, the peak)."""
    return {crit.name: float(REDUCTIONS[crit.over_time or "max"](np.asarray(history.phi[crit.name], float)))
            for crit in study.criteria}


def history_dataset(study, ev, hist) -> xr.Dataset:
    """The results file of a dynamic solve."""
    from wcs.results import provenance
    model = ev.model
    t = np.asarray(hist.time)
    crit = [c.name for c in study.criteria]
    units = {c.name: c.units for c in ev.criteria}
    joule, newton = ("J m-1", "N m-1") if model.dim == 2 else ("J", "N")
    nout = len(hist.output_levels)
    data = {
        "kinetic_energy": (("time",), np.asarray(hist.kinetic), {"units": joule}),
        "elastic_energy": (("time",), np.asarray(hist.elastic), {"units": joule}),
        "load_work": (("time",), np.asarray(hist.work), {"long_name": "work of the loads since t = 0"}),
        "viscous_dissipation": (("time",), np.asarray(hist.viscous), {"long_name": "since t = 0"}),
        "friction_dissipation": (("time",), np.asarray(hist.friction), {"long_name": "since t = 0"}),
        "numerical_dissipation": (("time",), hist.numerical,
                                  {"long_name": "initial + work - viscous - friction - (kinetic + elastic)"}),
        "contact_iterations": (("time",), np.asarray(hist.iterations, np.int64), {}),
        "coords": (("node", "dim"), model.smesh.mesh.p.T.copy(), {"units": "m"}),
        "displacement": (("output_time", "node", "dim"),
                         np.array(hist.displacement).reshape(nout, -1, model.dim), {"units": "m"}),
        "velocity": (("output_time", "node", "dim"),
                     np.array(hist.velocity).reshape(nout, -1, model.dim), {"units": "m s-1"}),
    }
    if model.zone is not None:
        data["contact_force"] = (("time",), hist.total_force,
                                 {"long_name": "resultant normal contact force", "units": newton})
        data["contact_normal_force"] = (("time", "contact_node"), np.array(hist.force_n), {"units": newton})
        data["contact_closed"] = (("time",), np.asarray(hist.closed, np.int64), {"long_name": "closed contact nodes"})
    if crit:
        data["phi_history"] = (("criterion", "time"), np.array([hist.phi[c] for c in crit]),
                               {"units": ", ".join(f"{c}: {units[c]}" for c in crit)})
        data["phi"] = (("criterion",), np.array([reduced(study, hist)[c] for c in crit]),
                       {"over_time": ", ".join(f"{c.name}: {c.over_time or 'max'}" for c in study.criteria)})
    dyn = study.dynamics
    initial = dyn.initial if isinstance(dyn.initial, str) else str(dyn.initial.model_dump())
    attrs = {**provenance(study, ev), "dynamics_scheme": dyn.scheme, "time_step": dyn.time_step,
             "end_time": dyn.end_time, "initial": initial}
    coords = {"time": ("time", t, {"units": "s"}),
              "output_time": ("output_time", t[hist.output_levels], {"units": "s"}), "criterion": crit}
    return xr.Dataset(data, coords=coords, attrs=attrs)


def pvd_text(entries: list[tuple[float, str]]) -> str:
    """A ParaView collection: one file per time."""
    rows = "\n".join(f'    <DataSet timestep="{t!r}" part="0" file="{f}"/>' for t, f in entries)
    return ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="1.0" byte_order="LittleEndian">\n'
            f"  <Collection>\n{rows}\n  </Collection>\n</VTKFile>\n")


def write_series(ev, hist, c, out: Path) -> Path:
    """OUT.pvd over OUT-k.vtu (the volume at output level k, `wcs.paraview`)."""
    from wcs.fields import fields_dataset
    from wcs.paraview import volume, vtu_text, _write
    entries = []
    heat = ev.model.solve_heat(c) if ev.model.thermal else None
    for k, (n, u) in enumerate(zip(hist.output_levels, hist.displacement)):
        ds = fields_dataset(ev.model, level_solution(ev.model, c, u, None, heat))
        file = out.with_name(f"{out.stem}-{k:05d}.vtu")
        _write(file, vtu_text(*volume(ds)))
        entries.append((hist.time[n], file.name))
    pvd = out.with_suffix(".pvd")
    _write(pvd, pvd_text(entries))
    return pvd


def solve_dynamic(study, out: Path, args) -> int:
    """`wcs solve STUDY` of a dynamic study: run the levels, print the reduced criteria, write
    OUT.nc and the ParaView series."""
    from wcs.criteria import in_words
    from wcs.errors import SolveError
    from wcs.evaluation import Evaluator
    from wcs.results import write_netcdf
    from wcs.status import Status
    from wcs.store import WriteError
    t0 = time.perf_counter()
    ev = Evaluator(study)
    x = study.nominal()
    try:
        hist = simulate(ev, x)
    except SolveError as e:
        print(f"error: {args.study}: the nominal data set cannot be solved: {e}", file=sys.stderr)
        return 2 if Status(e.status).scene_fault else 1
    try:
        path = write_netcdf(history_dataset(study, ev, hist), out)
        pvd = write_series(ev, hist, ev.map.coefficients(x), out)
    except WriteError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    if not getattr(args, "quiet", False):
        dyn, m = study.dynamics, ev.smesh.mesh
        e = np.asarray(hist.kinetic) + np.asarray(hist.elastic)
        print(f"{study.name}: {m.p.shape[1]} nodes, {m.t.shape[1]} cells; {dyn.levels} levels of {dyn.time_step:g} s "
              f"({dyn.scheme} scheme), {time.perf_counter() - t0:.2f} s")
        print(f"  energy (kinetic + elastic): {e[0]:.6g} at t = 0, {e[-1]:.6g} at t = {hist.time[-1]:.6g} s; "
              f"work of the loads {hist.work[-1]:.4g}, dissipated: viscous {hist.viscous[-1]:.4g}, friction "
              f"{hist.friction[-1]:.4g}, numerical {hist.numerical[-1]:.4g}")
        what = {c.name: in_words(c.kind, list(c.regions)) for c in study.criteria}
        for crit in study.criteria:
            value = reduced(study, hist)[crit.name]
            print(f"  {crit.name} = {value:.6g}  ({what[crit.name]}, {REDUCED[crit.over_time or 'max']})")
        print(f"  wrote {path} and {pvd}")
    return 0


def check_dynamic(study, ev, args, summary: str) -> int:
    """`wcs check` of a dynamic study: the summary, the plan of the levels, the sources located
    in the mesh at the nominal data and at the corners of their uncertain points (StudyError,
    exit 2) and, for `initial: static`, the static solve that starts them (exit 2 where the
    scene has no static solution)."""
    from wcs.errors import SolveError
    from wcs.status import Status
    from .loading import check_sources
    dyn = study.dynamics
    check_sources(ev, study.nominal())
    for w in study.warnings:
        print(f"warning: {study.file}: {w}", file=sys.stderr)
    if not args.quiet:
        start = dyn.initial if isinstance(dyn.initial, str) else f"rest with velocities {dyn.initial.velocity}"
        print(summary)
        print(f"  dynamics: {dyn.levels} levels of {dyn.time_step:g} s to {dyn.levels * dyn.time_step:g} s, scheme "
              f"{dyn.scheme}, initial state {start}; fields every {dyn.output_every} levels, criteria at every level")
    if dyn.initial == "static":
        try:
            x = study.nominal()
            c0 = at_time_zero(ev.map.coefficients(x), study.scene, ev.map.slots(x), ev.map.index)
            initial_state(ev.model, c0, dyn)
        except SolveError as e:
            print(f"error: {study.file}: {e}", file=sys.stderr)
            return 2 if Status(e.status).scene_fault else 1
    if not args.quiet:
        print("ok")
    return 0
