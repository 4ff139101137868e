"""The command `wcs solve`: one forward solve at the nominal data, or at the worst data set of
a criterion of a run (`--worst`), written as OUT.nc and its ParaView files; a dynamic study's
levels (`wcs.app.dynamics`, loaded for it alone: a static solve loads neither the dynamics nor
the run's machinery).

Exit 0 done, 1 a failure (the data set cannot be solved, a failed write), 2 bad input or a data
set the scene cannot balance (StudyError, or a status that is the scene's fault).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from ..contact.methods import krylov_counts
from ..errors import StudyError
from ..group import spanning
from ..model.criteria import in_words
from ..model.evaluation import Evaluator
from ..model.validity import warnings as validity_warnings
from ..progress import phase
from ..results.dataset import open_results, widest, write_solution
from ..results.store import WriteError, check_output, incomplete_run
from ..status import Status
from ..study.load import load_study
from .parallel import groups, rank, world


def solve_worst(args) -> int:
    """`wcs solve STUDY --worst RUN.nc CRITERION`: the worst data set of a criterion as one scenario."""
    study = load_study(args.study)
    run_file, criterion = args.worst
    if not Path(run_file).is_file():
        raise StudyError("results file not found", file=str(run_file))
    try:
        with open_results(run_file) as whole:
            ds = widest(whole)                      # a fuzzy run: the worst case over its widest level
            crits = [str(c) for c in ds["criterion"].values]
            params = [str(p) for p in ds["param"].values]
            if criterion not in crits:
                raise StudyError(f"no criterion '{criterion}' in the run (it has: {', '.join(crits)})",
                                 file=str(run_file))
            x = ds["worst_x"].sel(criterion=criterion).values.astype(float)
            searched = str(ds["certificate"].sel(criterion=criterion).values) != "not-searched"
            sha = ds.attrs.get("study_sha256")
            if str(ds.attrs.get("complete", "yes")) == "no":
                n = int(ds.sizes.get("eval", 0))
                raise StudyError(incomplete_run(run_file, n, args.study), file=str(run_file))
            extra = {}
            if "sweep_value" in ds and int(ds["worst_eval"].sel(criterion=criterion)) >= 0:
                row = int(ds["worst_eval"].sel(criterion=criterion))
                extra = dict(zip(map(str, ds["sweep_path"].values), map(float, ds["sweep_value"].values[row])))
    except (OSError, KeyError, ValueError) as e:
        raise StudyError(f"not a results file of `wcs run` ({e})", file=str(run_file)) from None
    if params != list(study.parameters.names):
        raise StudyError(f"the run's parameters ({', '.join(params)}) are not this study's "
                         f"({', '.join(study.parameters.names)})", file=str(run_file))
    if not searched:
        raise StudyError(f"the run did not search the maximum of criterion '{criterion}' (its sense is min): "
                         "it has no worst data set; its minimum's is best_x", file=str(run_file))
    if not np.all(np.isfinite(x)):
        raise StudyError(f"the run has no solved data set for criterion '{criterion}'", file=str(run_file))
    if sha != study.sha256 and not getattr(args, "quiet", False):
        print(f"note: {run_file} was written for a different version of {args.study}", file=sys.stderr)
    out = Path(args.output or Path(study.output).with_name(f"{Path(study.output).stem}-worst-{criterion}.nc"))
    check_output(out, *((None, "-o") if args.output else (str(study.file), "output")))
    point = x
    if extra:
        point = dict(zip(study.parameters.names, map(float, x)))
        point.update(extra)
    group = solve_group(study)
    if study.dynamics is not None:              # the levels at the worst data, as `wcs solve` writes them
        from .dynamics import solve_dynamic
        return solve_dynamic(study, out, args, point)
    t0 = time.perf_counter()
    ev = Evaluator(study)
    with phase("solve"), spanning(group):
        res = ev.evaluate(point)
    if res.status != 0:
        if rank(group) == 0:
            print(f"error: the worst data set of '{criterion}' cannot be solved: {res.message}", file=sys.stderr)
        return 1
    _release(ev, res, group)
    if rank(group) != 0:                        # the group's other ranks helped solve; rank 0 writes
        return 0
    return _write_scenario(study, ev, res, out, args, [
        f"{study.name}: worst case of {criterion} from {run_file}, solved in {time.perf_counter() - t0:.2f} s"],
        worst_of=f"{run_file}: criterion {criterion}", layout=(group_size(group),) * 2)


def solve_nominal(args) -> int:
    """`wcs solve STUDY`: one forward solve at the nominal data."""
    study = load_study(args.study)
    out = Path(args.output or Path(study.output).with_name(Path(study.output).stem + "-nominal.nc"))
    check_output(out, *((None, "-o") if args.output else (str(study.file), "output")))
    group = solve_group(study)
    if study.dynamics is not None:
        from .dynamics import solve_dynamic
        return solve_dynamic(study, out, args)
    t0 = time.perf_counter()
    ev = Evaluator(study)
    with phase("solve"), spanning(group):
        res = ev.evaluate(study.nominal())
    if res.status != 0:
        if rank(group) == 0:
            print(f"error: {args.study}: the nominal data set cannot be solved: {res.message}", file=sys.stderr)
        return 2 if Status(res.status).scene_fault else 1
    _release(ev, res, group)
    if rank(group) != 0:                        # the group's other ranks helped solve; rank 0 writes
        return 0
    m = ev.smesh.mesh
    return _write_scenario(study, ev, res, out, args, [
        f"{study.name}: {m.p.shape[1]} nodes, {m.t.shape[1]} cells, {m.p.shape[0] * m.p.shape[1]} unknowns",
        f"  mesh {ev.timings['mesh']:.2f} s, assembly {ev.timings['assembly']:.2f} s, "
        f"solve {res.wall_time:.2f} s, total {time.perf_counter() - t0:.2f} s"], layout=(group_size(group),) * 2)


def solve_group(study):
    """The ranks `wcs solve` spans: its one data set on `solver.ranks_per_evaluation: k` ranks,
    all the ranks of the launch (the group; None: a serial run of k = 1). StudyError (exit 2)
    where the launch has another number of ranks (the rest would idle or write the same file),
    or a dynamic study is launched on more than one."""
    comm = world()
    n, k = (1 if comm is None else comm.size), study.solver.ranks_per_evaluation
    launch = "a serial run" if comm is None else f"mpiexec -n {n}"
    if study.dynamics is not None and n * k > 1:
        raise StudyError(f"wcs solve of a dynamic study runs on one rank, not on {k} per evaluation in {launch}: "
                         "run it without mpiexec and with solver.ranks_per_evaluation 1", file=str(study.file),
                         path="solver.ranks_per_evaluation")
    if n != k:
        raise StudyError(f"wcs solve solves one data set on {k} rank{'s' * (k > 1)} per evaluation, not on the "
                         f"{n} of {launch}: run it " + ("without mpiexec" if k == 1 else f"under mpiexec -n {k}"),
                         file=str(study.file), path="solver.ranks_per_evaluation")
    return groups(comm, k, str(study.file))[0]


def group_size(group) -> int:
    return 1 if group is None else group.size


def solver_counts(res) -> str:
    """What the solve took: its outer steps and Krylov iterations (as the results file's
    `iterations`, `krylov_iterations`, `krylov_step_max`)."""
    total, most = krylov_counts(res.krylov_steps)
    krylov = ("no Krylov iterations (direct factorization)" if total == 0 else
              "Krylov iterations not counted by this method" if total < 0 else
              f"{total} Krylov iterations ({most} at most in one step, "
              f"{total / max(res.iterations, 1):.1f} per step on average)")
    return f"  solver: {res.iterations} outer steps, {krylov}"


def _release(ev, res, group) -> None:
    """The solve's matrices go before its files are written (the evaluation's state, once rank 0
    made its fields from it, and the model's caches, on every rank of the group: PETSc's
    objects are freed together): the files' arrays and HDF5's libraries would otherwise stack
    on them."""
    if rank(group) == 0:
        res.field_data
    res.state = None
    with spanning(group):
        ev.model.release()


def _write_scenario(study, ev, res, out, args, header: list[str], **kw) -> int:
    """Write one solved scenario (results file + .vtu) and say what it gave."""
    try:
        out, vtu = write_solution(study, ev, res, out, **kw)
    except WriteError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    for w in validity_warnings(res.field_data):
        print(f"warning: {w}", file=sys.stderr)
    if not getattr(args, "quiet", False):
        print("\n".join(header + [solver_counts(res)]))
        what = {c.name: in_words(c.kind, list(c.regions)) for c in study.criteria}
        for name, v in res.phi.items():
            print(f"  {name} = {v:.6g}  ({what[name]})")
        print(f"  wrote {out} and {vtu}")
    return 0
