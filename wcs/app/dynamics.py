"""`wcs solve` on a dynamic study: the levels at the nominal data, their history in the
results file (a `time` coordinate: `phi_history` (criterion, time), contact forces, energies;
the fields at the output times) and a ParaView time series, OUT.pvd over OUT-k.vtu."""
from __future__ import annotations

import resource
import sys
import time
from pathlib import Path

import numpy as np

from wcs.dynamics.history import REDUCED, DynamicEvaluation, reduced, simulate
from wcs.dynamics.loading import at_time_zero, check_sources
from wcs.dynamics.stepping import History, initial_state, level_solution
from wcs.errors import SolveError
from wcs.model.criteria import in_words
from wcs.model.evaluation import Evaluator
from wcs.model.fields import Data, fields_dataset
from wcs.results.dataset import solve_dataset, write_netcdf
from wcs.results.dynamics import gradients
from wcs.results.meshcheck import MEMORY_SHARE, SOLVE_GROWTH, SPLITS, planned, refined_nodes
from wcs.scene.estimate import machine_memory
from wcs.results.paraview import volume, vtu_text, _write
from wcs.results.store import WriteError
from wcs.status import Status


def history_dataset(study, ev, hist, x, others, wall_time: float) -> Data:
    """The results file of a dynamic solve: the layout of every `wcs solve` file (`solve_dataset`:
    the box, the data set x, the reduced criteria, status, limits, the mesh and the fields, here
    at the output times) and the history of the levels (energies, contact forces, every
    criterion at every level)."""
    model = ev.model
    evaluation = DynamicEvaluation(np.asarray(x, float), reduced(study, hist), Status.SOLVED, "solved",
                                   int(np.sum(hist.iterations)), wall_time, evaluator=ev,
                                   levels=(ev.map.coefficients(x, others), hist))
    solved = solve_dataset(study, ev, evaluation)
    solved["iterations"].attrs["long_name"] += "; a dynamic study: their sum over the time levels"
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
        solved["phi"].attrs["over_time"] = ", ".join(f"{c.name}: {c.over_time or 'max'}" for c in study.criteria)
    dyn = study.dynamics
    initial = dyn.initial if isinstance(dyn.initial, str) else str(dyn.initial.model_dump())
    attrs = {"dynamics_scheme": dyn.scheme, "time_step": dyn.time_step, "end_time": dyn.end_time, "initial": initial}
    coords = {"time": ("time", t, {"units": "s"}),
              "output_time": ("output_time", t[hist.output_levels], {"units": "s"}), "criterion": crit}
    for k, v in data.items():
        solved[k] = v
    for k, v in coords.items():
        if k not in solved.coords:      # output_time and criterion: the fields' and solve_dataset's
            solved.set_coord(k, v)
    solved.attrs.update(attrs)
    return solved


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
        wall_time = time.perf_counter() - t0
    except SolveError as e:
        which = "nominal" if point is None else "given"
        print(f"error: {args.study}: the {which} data set cannot be solved: {e}", file=sys.stderr)
        return 2 if Status(e.status).scene_fault else 1
    try:
        path = write_netcdf(history_dataset(study, ev, hist, x, others, wall_time), out)
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


OPERATOR = {"seed": "A = M/Δt² + C/Δt + K", "stabilized": "A = 2M/Δt² + C/Δt + K/2"}   # wcs.dynamics.schemes
LEVEL_METHOD = {"monolithic": "the condensed Newton on a factor of the level's operator {A}, factored once and "
                              "kept across the levels",
                "iterative": "active set with CG + algebraic multigrid on the level's operator {A}",
                "dd": "the domain decomposition, its subdomains' matrices those of the level's operator {A}"}
WARM = {"dd": "each level from the decomposition's glued start"}     # the others: from the last level
TIMED = 20          # `wcs check` times this many levels after the first (the first factors A)


def level_solves(study) -> str:
    """What one time level solves, in words."""
    if not study.scene.contacts:
        return "one linear solve"
    return "two contact solves (predictor and step)" if study.dynamics.scheme == "stabilized" else "one contact solve"


def plan_line(study, ev) -> list[str]:
    """The search and solver lines of `wcs check` for a dynamic study (in place of the static
    ones): an evaluation is one simulation; each level's contact problem by the model's method
    (`wcs.dynamics.stepping.LevelSolver`), warm-started from the last level (the decomposition:
    from its glued start); the gradients as the results file records them
    (`wcs.results.dynamics.gradients`)."""
    s, dyn, method = study.search, study.dynamics, ev.model.solver_method
    chosen = f"{method} (auto)" if study.solver.method == "auto" else method
    how = (LEVEL_METHOD[method] if study.scene.contacts else "one sparse factor of {A}, kept across the levels"
           ).format(A=OPERATOR[dyn.scheme])
    return [f"  search: {s.method}, budget {s.budget} evaluations; one evaluation is one simulation "
            f"({dyn.levels} levels of {level_solves(study)} each); gradients: {gradients(study)}",
            f"  solver: each level ({dyn.scheme} scheme, Δt = {dyn.time_step:g} s) by {chosen}: {how}; "
            + WARM.get(method, "warm-started from the last level's contact forces")]


def history_bytes(hist: History) -> tuple[float, float]:
    """(bytes a level adds to a `History`, bytes an output level adds): its arrays counted."""
    def size(v) -> int:
        return np.asarray(v).nbytes
    levels = len(hist.time)
    per_level = sum(size(getattr(hist, k)) for k in ("time", "force_n", "force_t", "closed", "iterations", "kinetic",
                                                     "elastic", "work", "viscous", "friction"))
    per_level += sum(size(v) for v in hist.phi.values())
    out = size(hist.displacement) + size(hist.velocity)
    return per_level / levels, out / max(len(hist.output_levels), 1)


def peak_bytes(reset: bool = False) -> float:
    """This process's resident high-water mark (Linux: VmHWM of /proc/self/status; 0.0 where it
    cannot be read); reset=True first resets it to the resident set (writing 5 to
    /proc/self/clear_refs), and gives 0.0 where that is not allowed."""
    try:
        if reset:
            Path("/proc/self/clear_refs").write_text("5")
        line = next(v for v in Path("/proc/self/status").read_text().splitlines() if v.startswith("VmHWM:"))
    except (OSError, StopIteration):
        return 0.0
    return float(line.split()[1]) * 1024.0


def evaluation_estimate(ev, x) -> tuple[str, float, float]:
    """One evaluation's time and memory, measured on the first levels at data x: after one level
    run to build what every evaluation reuses (the released model, the caches), the set-up (the
    static state, the matrices) with the first level (which factors A) is timed alone, then with
    TIMED levels more; the evaluation is the first plus (levels − 1) × a later level's time. The
    memory is this process's peak over those levels (the model, both factors; its high-water mark
    reset before them, `peak_bytes`, so that what the process did before does not count) plus
    what the remaining levels add to the history (`history_bytes`). Returns (the line, peak
    bytes, seconds)."""
    dyn = ev.study.dynamics
    k = min(TIMED, dyn.levels - 1)

    def timed(levels: int) -> tuple[float, History]:
        t0 = time.perf_counter()
        hist = simulate(ev, x, dyn=dyn.model_copy(update={"end_time": levels * dyn.time_step}))
        return time.perf_counter() - t0, hist
    timed(1)
    mark = peak_bytes(reset=True)
    first, _ = timed(1)
    more, hist = timed(k + 1)
    level = max(more - first, 0.0) / k if k else 0.0
    per_level, per_output = history_bytes(hist)
    outputs = dyn.levels // dyn.output_every + 1
    rest = per_level * (dyn.levels - k) + per_output * (outputs - len(hist.output_levels))
    peak = peak_bytes() if mark else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0
    peak += rest
    seconds = first + (dyn.levels - 1) * level
    return (f"  one evaluation estimated at about {peak / 1e9:.3g} GB peak and {seconds:.2g} s: the static state "
            f"and the first level {first:.2g} s + {dyn.levels - 1} levels × {level:.2g} s (timed on {k} levels at "
            f"the nominal data); memory: this process's peak over them and the history of the other levels "
            f"({rest / 1e6:.3g} MB)"), peak, seconds


def mesh_check_estimate(study, ev, peak: float, seconds: float) -> tuple[str, str]:
    """(the line, the fault or ""): what the mesh check of `wcs run` costs a dynamic study, each of
    its solves a whole simulation: on each planned refined mesh (`planned`), up to one simulation
    per extreme, its time one evaluation's `seconds` grown as nodes^SOLVE_GROWTH (as a static
    solve's, level by level: the levels stay as many), its memory the evaluation's `peak` grown as
    the nodes. The fault: the largest refined mesh's simulation beyond MEMORY_SHARE of the
    machine's memory (the mesh check would not fit)."""
    if study.scene.mesh.file is not None:
        return "  mesh check: not available (a mesh read from a file has no geometry to refine on)", ""
    mesh, zone = ev.smesh.mesh, ev.model.zone
    splits, why = planned(study, mesh.t.shape[1], 0 if zone is None else len(zone.gap))
    if not splits:
        return f"  mesh check: will not run ({why})", ""
    n_ext = sum(2 if c.sense == "both" else 1 for c in study.criteria)
    growth = [refined_nodes(mesh, s) / mesh.p.shape[1] for s in splits]
    total = sum(n_ext * seconds * r ** SOLVE_GROWTH[mesh.dim()] for r in growth)
    need, memory = peak * growth[-1], MEMORY_SHARE * machine_memory()
    meshes = "split once and twice" if splits == SPLITS else f"split once only ({why})"
    line = (f"  mesh check (after the search; `run --no-mesh-check` skips it): up to {n_ext} extreme data set(s) "
            f"simulated again ({study.dynamics.levels} levels each) on the mesh {meshes}, "
            + " and ".join(f"{ev.model.dim * refined_nodes(mesh, s)} unknowns" for s in splits)
            + f"; about {total:.2g} s and {need / 1e9:.3g} GB peak (one evaluation's time grown as "
            f"nodes^{SOLVE_GROWTH[mesh.dim()]:g}, its memory as the nodes)")
    fault = "" if need <= memory else (
        f"the mesh check would need about {need / 1e9:.3g} GB for a simulation on the mesh split "
        f"{'once' if splits[-1] == 1 else f'{splits[-1]} times'}, beyond the {memory / 1e9:.3g} GB it may take "
        f"({MEMORY_SHARE:.0%} of this machine's {machine_memory() / 1e9:.3g} GB); run it with "
        f"`wcs run --no-mesh-check`, or coarsen the mesh (`mesh.size`, `refine`)")
    return line, fault


def check_dynamic(study, ev, args, summary: str) -> int:
    """`wcs check` of a dynamic study: the summary, the plan of the levels, the sources located
    in the mesh at the nominal data and at the corners of their uncertain points (StudyError,
    exit 2) and, for `initial: static`, the static solve that starts them (exit 2 where the
    scene has no static solution); then one evaluation's time and memory, from its first levels
    (`evaluation_estimate`), and the mesh check's from them (`mesh_check_estimate`: exit 2 where
    it would not fit in memory, even with --quiet)."""
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
    try:
        line, peak, seconds = evaluation_estimate(ev, study.nominal())
    except SolveError as e:
        print(f"error: {study.file}: the nominal data set's first levels cannot be solved: {e}", file=sys.stderr)
        return 2 if Status(e.status).scene_fault else 1
    mesh_line, fault = mesh_check_estimate(study, ev, peak, seconds)
    if not args.quiet:
        print(line)
        print(mesh_line)
    if fault:
        print(f"error: {study.file}: {fault}", file=sys.stderr)
        return 2
    if not args.quiet:
        print("ok")
    return 0
