"""`wcs solve` on a dynamic study: the levels at the nominal data, their history in the
results file (a `time` coordinate: `phi_history` (criterion, time), contact forces, energies;
the fields at the output times) and a ParaView time series, OUT.pvd over OUT-k.vtu."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import xarray as xr

from wcs.dynamics.adjoint import refusal
from wcs.dynamics.history import REDUCED, reduced, simulate
from wcs.dynamics.loading import at_time_zero, check_sources
from wcs.dynamics.stepping import initial_state, level_solution
from wcs.errors import SolveError
from wcs.model.criteria import in_words
from wcs.model.evaluation import Evaluator
from wcs.model.fields import fields_dataset
from wcs.results.dataset import provenance, write_netcdf
from wcs.results.paraview import volume, vtu_text, _write
from wcs.results.store import WriteError
from wcs.status import Status


def history_dataset(study, ev, hist) -> xr.Dataset:
    """The results file of a dynamic solve."""
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


def solve_dynamic(study, out: Path, args, point=None) -> int:
    """`wcs solve STUDY` of a dynamic study: run the levels, print the reduced criteria, write
    OUT.nc and the ParaView series; `point` a data set (a vector or {dotted path: value}; `solve
    --worst`), else the nominal data."""
    t0 = time.perf_counter()
    ev = Evaluator(study)
    x, others = study.data_set(study.nominal() if point is None else point)
    try:
        hist = simulate(ev, x, others)
    except SolveError as e:
        which = "nominal" if point is None else "given"
        print(f"error: {args.study}: the {which} data set cannot be solved: {e}", file=sys.stderr)
        return 2 if Status(e.status).scene_fault else 1
    try:
        path = write_netcdf(history_dataset(study, ev, hist), out)
        pvd = write_series(ev, hist, ev.map.coefficients(x, others), out)
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
    dyn = study.dynamics
    check_sources(ev, study.nominal())
    for w in study.warnings:
        print(f"warning: {study.file}: {w}", file=sys.stderr)
    if not args.quiet:
        start = dyn.initial if isinstance(dyn.initial, str) else f"rest with velocities {dyn.initial.velocity}"
        print(summary)
        print(f"  dynamics: {dyn.levels} levels of {dyn.time_step:g} s to {dyn.levels * dyn.time_step:g} s, scheme "
              f"{dyn.scheme}, initial state {start}; fields every {dyn.output_every} levels, criteria at every level")
        if study.parameters.names:
            solves = ("one linear solve" if not study.scene.contacts else "two contact solves (predictor and step)"
                      if dyn.scheme == "stabilized" else "one contact solve")
            why = refusal(study)
            how = (f"no adjoint gradient through time ({why}): finite differences of the reduced criteria where the "
                   "search asks for gradients") if why else \
                ("gradients by the adjoint through time (one reverse sweep of the levels), finite differences of "
                 "the reduced criteria where an evaluation is not differentiable")
            print(f"  search over time: one evaluation is one simulation ({dyn.levels} levels of {solves} each, "
                  f"not the one solve estimated above); {how}")
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
