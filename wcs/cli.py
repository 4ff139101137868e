"""The `wcs` command: parse, call, print. Exit 0 done, 1 failure (with --fail-on-limit also a
verdict NOT ESTABLISHED), 2 bad input, 3 verdict FAIL with --fail-on-limit (a limit broken, or a
data set without equilibrium; `wcs/results/verdict.py`), 4 `compare`: the files differ, 130 interrupted
(Ctrl-C; `run` and `sweep` say how to resume).

Each command imports what it needs when it runs (`wcs/app/commands.py` for run and sweep,
`wcs/app/solve.py` for solve, `wcs/report/` for report, `wcs/results/compare.py` for compare;
`importing`), so `wcs --help` loads no numerical library and `wcs report` no solver."""
from __future__ import annotations

import argparse
import contextlib
import gc
import logging
import sys
import traceback
import warnings
from pathlib import Path

from .version import __version__
from .errors import StudyError
from .app.parallel import rank, world
from .progress import INTERRUPTED, Progress, phase, reporting


def _fmt(v) -> str:
    import numpy as np
    return f"{v:.4g}" if isinstance(v, (float, np.floating)) else str(v)


def _cell_sizes(mesh) -> tuple[float, float]:
    """Smallest and largest cell diameter (longest edge) of the mesh."""
    import numpy as np
    p, t = mesh.p, mesh.t
    edges = [np.hypot(*(p[:, t[a]] - p[:, t[b]])) for a, b in ((0, 1), (1, 2), (2, 0))]
    h = np.max(edges, axis=0)
    return float(h.min()), float(h.max())


def _words(value):
    """A scene entry as the study file writes it (a model: its given keys)."""
    return value.model_dump(by_alias=True, exclude_none=True) if hasattr(value, "model_dump") else value


def summary(study, ev) -> str:
    """What the study will do, in the words of the study file."""
    import numpy as np
    from .scene.estimate import DEFAULT_MAX_CELLS
    scene, sm = study.scene, ev.smesh
    mesh = sm.mesh
    lines = [f"study {study.name}  ({study.file})",
             f"  model: {scene.dimension}D plane {scene.plane}, P1 triangles, "
             f"{mesh.p.shape[1]} nodes, {mesh.t.shape[1]} cells, "
             f"{'thermal step + ' if scene.thermal else ''}elasticity"
             f"{' with contact' if scene.contacts else ''}"]
    lines.append("  bodies:")
    for b, name in enumerate(sm.bodies):
        regs = [(j, r) for j, (bb, r) in enumerate(sm.regions) if bb == name]
        desc = ", ".join(f"{r} [{ev.model.region_material[j]}, {int(np.sum(sm.cell_region == j))} cells]" for j, r in regs)
        held = ev.model.free_modes[name].shape[1]
        lines.append(f"    {name}: {desc}" + ("" if held == 0 else f"  (held by contact only: {held} rigid modes free)"))
    sizes = _cell_sizes(mesh)
    m = scene.mesh
    lines.append(f"  mesh: target size {'per body' if m.size is None else m.size}"
                 + (f", {len(m.refine)} refinement zone(s)" if m.refine else "")
                 + "".join(f", body {b}: {_words(v.mesh)}" for b, v in scene.bodies.items() if v.mesh)
                 + f"; cells from {sizes[0]:.3g} m to {sizes[1]:.3g} m")
    if study.estimated_cells is not None:
        lines.append(f"  mesh size: estimated {study.estimated_cells:.3g} cells before meshing "
                     f"(limit mesh.max_cells = {DEFAULT_MAX_CELLS if m.max_cells is None else m.max_cells:g}), "
                     f"{mesh.t.shape[1]} meshed, {2 * mesh.p.shape[1]} unknowns")
    lines.append("  boundaries:")
    for name, facets in sm.boundaries.items():
        lines.append(f"    {name}: {len(facets)} edges")
    for key, label in (("supports", "supports"), ("loads", "loads"), ("body_forces", "body forces")):
        for name, v in getattr(scene, key).items():
            lines.append(f"  {label[:-1] if label.endswith('s') else label} {name}: {_words(v)}")
    zone = ev.model.zone
    for k, (name, c) in enumerate(scene.contacts.items()):
        fr = c.friction
        how = zone.discretization[k] if zone is not None and getattr(zone, "discretization", None) else "node-to-node"
        nodes = int((zone.contact_of_node == k).sum()) if zone is not None else 0
        lines.append(f"  contact {name} ({how}, {nodes} contact nodes): slave {c.slave} / master {c.master}, "
                     + ("frictionless" if fr is None else f"Tresca g = {_fmt(fr.slip_limit)}"
                        if fr.slip_limit is not None else f"Coulomb F = {_fmt(fr.coefficient)}"))
    if scene.thermal:
        th = scene.thermal
        lines.append(f"  thermal: T0 = {th.reference}, temperature on {list(th.temperature)}, "
                     f"sources {th.sources}")
    return "\n".join(lines + plan(study, ev))


def plan(study, ev) -> list[str]:
    """What the study asks of the scene, in the words of the study file (2D and 3D): the parameters
    with their boxes and nominal values, the fuzzy levels, the criteria with their units, senses
    and limits, the search, the solver and the output."""
    from .model.criteria import in_words
    from .report.timeline import in_time
    scene, lines = study.scene, []
    p = study.parameters
    lines.append(f"  parameters ({len(p.names)}):")
    nominal = study.nominal()
    for n, lo, hi, x0 in zip(p.names, p.lower, p.upper, nominal):
        lines.append(f"    {n}: [{_fmt(lo)}, {_fmt(hi)}]  nominal {_fmt(x0)}")
    if study.levels is not None:
        cores = ", ".join(f"{e.path} [{_fmt(e.core[0])}, {_fmt(e.core[1])}]"
                          for e in study.uncertain if e.core is not None) or "none (every number crisp)"
        lines.append(f"  fuzzy: levels {', '.join(f'{a:g}' for a in study.levels)}, searched from the core "
                     f"(α = 1) outwards; the boxes above are the supports; cores: {cores}")
    lines.append("  criteria:")
    senses = {c.name: c.sense for c in study.criteria}
    over = {c.name: c.over_time or "max" for c in study.criteria} if study.dynamics is not None else {}
    for c in ev.criteria:
        lim, low = study.limits.get(c.name), study.lower_limits.get(c.name)
        what = in_words(c.kind, c.rois) if c.name not in over else in_time(in_words(c.kind, c.rois), over[c.name])
        lines.append(f"    {c.name}: {what} ({c.kind}) [{c.units}]"
                     + (f", sense {senses[c.name]}" if senses[c.name] != "max" else "")
                     + (f", lower limit {_fmt(low)}" if low is not None else "")
                     + (f", limit {_fmt(lim)}" if lim is not None else ""))
    if study.dynamics is not None:
        from .app.dynamics import plan_line
        lines += plan_line(study, ev)
        lines.append(f"  output: {study.output}")
        return lines
    s = study.search
    method = study.solver.method
    solver = (f"{method} ({ev.model.solver_reason})" if method != "auto"
              else f"auto -> {ev.model.solver_method} ({ev.model.solver_reason})")
    if ev.model.solver_method == "iterative" and scene.contacts:
        from .contact.iterative import preconditioner
        which, why = preconditioner(ev.model)
        solver += (f"; preconditioner: {which} ({why})" if study.solver.iterative.preconditioner != "auto"
                   else f"; preconditioner: auto -> {which} ({why})")
    k = study.solver.ranks_per_evaluation
    lines.append(f"  search: {s.method}, budget {s.budget} solves; solver: {solver}"
                 + ("" if scene.contacts else " (no contact: one direct solve per data set)")
                 + (f"; each solve on {k} ranks: run it under mpiexec -n with a multiple of {k}" if k > 1 else ""))
    lines.append(f"  output: {study.output}")
    return lines


def cmd_check(args) -> int:
    """Load, mesh and assemble the study, and solve its nominal data set once: what the nominal
    solve refuses as bad input (status 3, the solvability condition) `check` refuses too (exit 2);
    any other failure there is a solver failure, not the input's (exit 1, as `solve`)."""
    with importing(args):
        from .model.evaluation import Evaluator
        from .status import Status
        from .results.store import check_output
        from .study.load import load_study
        from .scene.summary3d import summary3d
    study = load_study(args.study)
    check_output(study.output, str(study.file), "output", create=False)   # what `run` refuses before solving
    ev = Evaluator(study)
    if study.dynamics is not None:
        from .app.dynamics import check_dynamic
        return check_dynamic(study, ev, args, summary3d(study, ev.smesh) if study.scene.dimension == 3
                             else summary(study, ev))
    with phase("nominal solve"):
        res = ev.evaluate(study.nominal())
    for w in study.warnings:
        print(f"warning: {study.file}: {w}", file=sys.stderr)
    if not args.quiet:
        print("\n".join([summary3d(study, ev.smesh), *plan(study, ev)]) if study.scene.dimension == 3
              else summary(study, ev))
    if res.status != 0:
        print(f"error: {study.file}: the nominal data set cannot be solved "
              f"(status {res.status}, {Status(res.status).description}): {res.message}", file=sys.stderr)
        return 2 if Status(res.status).scene_fault else 1
    if not args.quiet:
        print(f"  nominal solve: {res.message} in {res.wall_time:.2f} s; "
              + ", ".join(f"{k} = {v:.4g}" for k, v in res.phi.items()))
        p = study.parameters                                # a solve away from the nominal state
        with phase("a solve at the centre of the box"):
            warm = ev.evaluate((p.lower + p.upper) / 2).wall_time
        print(mesh_check_cost(study, ev, warm))
        print("ok")
    return 0


def mesh_check_cost(study, ev, warm_solve: float) -> str:
    """What the mesh check of `wcs run` will cost: the refined meshes' unknowns and a time estimate
    from the study's mesh (`warm_solve`: seconds of a solve at the centre of the box)."""
    from .results.meshcheck import SPLITS, cost, planned
    if study.scene.mesh.file is not None:
        return "  mesh check: not available (a mesh read from a file has no geometry to refine on)"
    n_ext = sum(2 if c.sense == "both" else 1 for c in study.criteria)
    splits, why = planned(study, ev.smesh.mesh.t.shape[1], 0 if ev.model.zone is None else len(ev.model.zone.gap))
    if not splits:
        return f"  mesh check: will not run ({why})"
    levels = cost(ev, warm_solve, n_ext, splits)
    meshes = "split once and twice" if splits == SPLITS else f"split once only ({why})"
    return (f"  mesh check (after the search; `run --no-mesh-check` skips it): up to {n_ext} extreme data set(s) "
            f"solved again on the mesh {meshes}, "
            + " and ".join(f"{n} unknowns" for _, n, _ in levels)
            + f"; about {sum(t for _, _, t in levels):.2g} s (assembly and solves taken as growing with the unknowns, "
            f"the dense contact condensation as the cube of its rows)")


def cmd_solve(args) -> int:
    with importing(args):
        from .app.solve import solve_nominal, solve_worst
    return solve_worst(args) if getattr(args, "worst", None) else solve_nominal(args)


def cmd_run(args) -> int:
    with importing(args):
        from .app.commands import cmd_run as run
    return run(args)


def cmd_sweep(args) -> int:
    with importing(args):
        from .app.commands import cmd_sweep as sweep
    return sweep(args)


def cmd_report(args) -> int:
    with importing(args):
        from .report import cmd_report as report
    return report(args)


def cmd_compare(args) -> int:
    with importing(args):
        from .results.compare import cmd_compare as compare
    return compare(args)


DEFERRED = ("numpy.random", "numpy.testing", "numpy.f2py")


def defer_unused_imports() -> None:
    """numpy's submodules of `DEFERRED` loaded on their first use, not by scipy's import.

    scipy's array-API layer copies numpy's namespace (`scipy._external.array_api_compat.numpy`,
    on `import scipy.linalg`): `from numpy import *` reads each of numpy's lazily loaded
    submodules, which imports them and what they import in turn (unittest, secrets, hmac). A
    solve calls none of them; they were a large part of scipy's import, in time and in resident
    memory, of every wcs process and every rank. Each is registered instead as a lazy
    module (`importlib.util.LazyLoader`, the standard library's deferred import) and bound on
    numpy as its import would bind it: the same module, executed when an attribute of it is
    first read (`np.random.default_rng` in a search) or when it is imported by name. A module
    already imported is left as it is."""
    import importlib.util

    for name in DEFERRED:
        if name in sys.modules:
            continue
        spec = importlib.util.find_spec(name)      # imports numpy first
        spec.loader = importlib.util.LazyLoader(spec.loader)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        setattr(sys.modules["numpy"], name.split(".")[1], module)   # as an import binds a submodule on its package


@contextlib.contextmanager
def importing(args):
    """A command's imports, in a process that is the command (`main` read sys.argv: `args.process`):
    without the cyclic garbage collector, their objects then frozen out of its passes (`gc.freeze`).
    The imports create some 1e5 objects that live as long as the process (functions, classes,
    pydantic validators): each collection during the imports traced those made so far again, and
    each full one after them all of them, a tenth of a second of CPU in a 1e4-unknown solve. What
    the imports leave in reference cycles stays (some hundred objects). Called by a host process
    (`main(argv)`: a test, a script), the host's collector is left as it is; so are its modules
    (`defer_unused_imports` is for the process alone)."""
    if not args.process:
        yield
        return
    defer_unused_imports()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        gc.enable()


QUIET = "print nothing but warnings and errors (no progress, no summary)"
VERBOSE = ("show what is otherwise held back: the traceback of an internal error, the warnings of the "
           "libraries (numpy, scipy, cvxpy, ...), one line per evaluation instead of the progress line "
           "and one per finished phase")


def _common(p) -> None:
    """-q/--quiet and -v/--verbose, the same for every command (both: tracebacks and warnings, no
    progress)."""
    p.add_argument("-q", "--quiet", action="store_true", help=QUIET)
    p.add_argument("-v", "--verbose", action="store_true", help=VERBOSE)


def _previous(p) -> None:
    """--resume / --fresh: what to do with the results of an earlier run at the output."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--resume", action="store_true",
                   help="continue the run at the output from its evaluation store (only what it lacks is solved)")
    g.add_argument("--fresh", action="store_true",
                   help="discard the run at the output (results file and evaluation store) and start over")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="wcs", description="Worst-scenario analysis of contact problems of elastic bodies.")
    ap.add_argument("--version", action="version", version=f"wcs {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)
    def add(name, func, help):
        p = sub.add_parser(name, help=help)
        p.add_argument("study", help="study file (YAML)")
        _common(p)
        p.set_defaults(func=func)
        return p
    add("check", cmd_check, "validate a study and print what it will do")
    p = add("solve", cmd_solve, "one forward solve at the nominal data (or a worst case of a run)")
    p.add_argument("-o", "--output", help="results file (.nc) in an existing folder; ParaView files beside it: "
                                          "OUT.vtm, a multiblock of OUT.vtu (volume) and OUT-contact.vtu (contact surface)")
    p.add_argument("--worst", nargs=2, metavar=("RUN.nc", "CRITERION"),
                   help="solve the worst data set of CRITERION found by a run instead of the nominal one")
    p = add("run", cmd_run, "the worst-scenario study: search U_ad for the maximum of every criterion")
    p.add_argument("-o", "--output", help="results file (.nc) in an existing folder; default: the study's `output`")
    _previous(p)
    p.add_argument("--fail-on-limit", action="store_true",
                   help="exit 3 when the verdict is FAIL (a worst value breaks its limit, or a data set has no "
                        "equilibrium), 1 when failed evaluations leave it not established")
    p.add_argument("--no-mesh-check", action="store_true",
                   help="skip re-solving the extreme data sets on the mesh refined once and twice")
    p = add("sweep", cmd_sweep, "evaluate the full factorial grid of the study's `sweep:` block")
    p.add_argument("-o", "--output", help="results file (.nc) in an existing folder")
    _previous(p)
    p = sub.add_parser("report", help="an HTML repository-safety report of a results file")
    p.add_argument("results", help="results file (.nc) of `wcs run` or `wcs sweep`")
    p.add_argument("-o", "--output", help="report file (.html) in an existing folder; default: beside the results file")
    _common(p)
    p.set_defaults(func=cmd_report)
    p = sub.add_parser("compare", help="exit 0 when two results files of one study agree, 4 with a table when not")
    p.add_argument("a", help="results file (.nc)")
    p.add_argument("b", help="results file (.nc) of the same study")
    p.add_argument("--rtol", type=float, default=None,
                   help="relative tolerance R for floating-point values: they agree when |a - b| <= A + "
                        "R max(|a|, |b|) (NaN equals NaN). Without --rtol and --atol the comparison is bitwise")
    p.add_argument("--atol", type=float, default=None,
                   help="absolute tolerance A for floating-point values (default with --rtol: a floor per quantity, 1e-12 "
                        "times its largest magnitude in either file: gaps with the node coordinates (a gap is a "
                        "difference of positions), other lengths (displacement, slip) together, stresses and "
                        "pressures in Pa together, each criterion by its units, each parameter by its box; so a "
                        "closed gap of 1e-14 m on a 100 m model is round-off, not a 100%% difference; --rtol 0 "
                        "applies the floors alone)")
    _common(p)
    p.set_defaults(func=cmd_compare)
    return ap


def output_folder(output: str) -> None:
    """StudyError (exit 2) unless the folder of `-o OUTPUT` exists: a typed path is not created
    (a typo would silently make folders and put the results where nobody looks)."""
    folder = Path(output).absolute().parent
    if not folder.is_dir():
        what = "is not a directory" if folder.exists() else "does not exist"
        raise StudyError(f"the directory {folder} {what}; create it first or name an existing one",
                         file=f"-o {output}")


@contextlib.contextmanager
def held_back(verbose: bool):
    """The libraries' warnings (numpy's and scipy's RuntimeWarnings, cvxpy's "Solution may be
    inaccurate", skfem's logged notes) kept from stderr, where they came before the line that
    matters: what they warn of is judged by wcs and said in its own words. `verbose` shows them."""
    root = logging.getLogger()
    quiet = logging.NullHandler()
    with warnings.catch_warnings():
        if not verbose:
            warnings.simplefilter("ignore")
            root.addHandler(quiet)           # without a handler, logging prints them on stderr
        try:
            yield
        finally:
            root.removeHandler(quiet)


def main(argv=None) -> int:
    """The `wcs` command on `argv` (None: this process' command line, the process being the
    command: `importing`)."""
    args = build_parser().parse_args(argv)
    args.process = argv is None
    verbose = getattr(args, "verbose", False)
    progress = Progress.from_args(args) if rank(world()) == 0 else Progress("quiet")
    try:
        with held_back(verbose), reporting(progress):
            if args.func is not cmd_report:               # a command that solves: one BLAS thread per process
                with importing(args):
                    from .linalg import configure_threads
                configure_threads()
            if getattr(args, "output", None):
                output_folder(args.output)
            return args.func(args)
    except StudyError as e:
        print(f"error: {e.in_file(getattr(args, 'study', None) or getattr(args, 'results', None) or args.a)}",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return INTERRUPTED
    except Exception as e:  # noqa: BLE001 - the last line of defence: one line, not a traceback
        if verbose:
            traceback.print_exc()
        print(f"error: internal failure ({type(e).__name__}: {e}); rerun with --verbose for details",
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
