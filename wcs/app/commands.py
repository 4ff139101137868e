"""The commands `wcs run`, `wcs sweep` and `wcs solve --worst`: a run's messages and exit status.

Exit 0 done, 1 failure (no evaluation solved, a failed write, the worst case not solvable; with
--fail-on-limit also a verdict NOT ESTABLISHED: failed evaluations leave the criteria unknown
somewhere in U_ad), 3 with --fail-on-limit a verdict FAIL (a worst value breaks its limit, or a
data set has no equilibrium; `wcs/results/verdict.py`); bad input raises StudyError, which
`wcs.cli.main` turns into exit 2.
"""
from __future__ import annotations

import shlex
import sys
import time
from pathlib import Path

import numpy as np

from ..contact.methods import krylov_counts
from ..errors import StudyError
from ..group import spanning
from ..model.criteria import KINDS, in_words
from ..model.evaluation import Evaluator
from ..model.validity import warnings as validity_warnings
from ..progress import INTERRUPTED, current, phase
from ..results.dataset import open_results, widest, write_solution
from ..results.store import WriteError, check_output, incomplete_run, store_path, stored_count, writer
from ..status import Status, describe
from ..study.load import load_study
from .parallel import groups, rank, world


def _finish_command(args, study, ds, out: Path) -> int:
    from ..results import meshcheck
    from ..results.summary import limits_broken, summary_table
    from ..results.verdict import verdict
    n, failed = int(ds.sizes.get("eval", 0)), int(ds.attrs.get("failed_evaluations", 0))
    if not getattr(args, "quiet", False):
        print(f"{study.name}: {n} evaluations ({failed} failed), "
              f"{ds.attrs.get('solves_this_session')} solved now, {ds.attrs.get('answered_from_store')} "
              f"from the store; wrote {out}")
        print(summary_table(ds))
        print(criteria_in_words(study))
        if "mesh_check_value" in ds:
            print(meshcheck.summary(ds))
    v = verdict(ds)
    if not getattr(args, "quiet", False):
        print(f"verdict: {v.text}")
    for w in validity_warnings(ds):
        print(f"warning: {w}", file=sys.stderr)
    if failed == n:
        codes, counts = np.unique(ds["status"].values, return_counts=True)
        why = ", ".join(f"{m} with status {c} ({describe(int(c))})" for c, m in zip(codes, counts))
        first = f"; the first: {ds['message'].values[0]}" if n else ""
        print(f"error: no evaluation solved ({why or 'none run'}{first}); {out} records their statuses",
              file=sys.stderr)
        return 1
    if not getattr(args, "fail_on_limit", False):
        return 0
    broken = limits_broken(ds)
    if broken:
        print(f"limit broken: {', '.join(broken)}", file=sys.stderr)
    if broken or v.word == "FAIL":
        if (ds["status"].values == Status.UNSOLVABLE).any():      # the verdict's first reason: where
            print(f"fail: {v.reasons[0]}", file=sys.stderr)
        return 3
    if v.word == "NOT ESTABLISHED":
        print(f"verdict not established: {'; '.join(v.reasons)}", file=sys.stderr)
        return 1
    return 0


def criteria_in_words(study) -> str:
    """What each criterion is: its reduction over its regions (in a dynamic study also over time,
    "the peak over time of ...") and its units."""

    def what(c):
        words = in_words(c.kind, list(c.regions))
        return words if study.dynamics is None else in_time(words, c.over_time or "max")
    return "\n".join(f"  {c.name}: {what(c)} [{KINDS[c.kind].units}]" for c in study.criteria)


def resume_command(args, how: str = "--resume") -> str:
    """The command line that continues (`how`: --resume) or restarts (--fresh) the `wcs run`/`wcs
    sweep` of `args`, as typed (its study, -o and flags; under MPI with its launcher and rank count)."""
    comm = world()
    words = ([] if comm is None else ["mpiexec", "-n", str(comm.size)]) + ["wcs", args.command, str(args.study)]
    words += ["-o", str(args.output)] if args.output else []
    words += [how] + [flag for flag, on in (("--fail-on-limit", getattr(args, "fail_on_limit", False)),
                                                   ("--no-mesh-check", getattr(args, "no_mesh_check", False))) if on]
    return " ".join(map(shlex.quote, words))


def previous_run(out: Path) -> str | None:
    """What an earlier run left at `out` (None: nothing; a run holding the lock there is the lock's
    business): a complete or partial results file and the evaluation store beside it."""
    store = stored_count(out)
    if writer(out) is not None or out.is_dir() or (not out.exists() and store is None):
        return None                   # a folder: `check_output` names the fault
    kept = [] if store is None else [f"its evaluation store {store_path(out)} holds {store}"]
    if out.exists():
        try:
            with open_results(out) as ds:
                state = "complete" if str(ds.attrs.get("complete", "yes")) == "yes" else "partial"
                kept.insert(0, f"a {state} results file of {int(ds.sizes.get('eval', 0))} evaluations")
        except (OSError, ValueError):
            kept.insert(0, "a file that is not a results file")
    else:
        kept[0] = f"a partial run: {kept[0]}"
    return "; ".join(kept)


def _refuse_previous(args, out: Path) -> None:
    """StudyError (exit 2) when an earlier run is at `out` and neither --resume nor --fresh says
    what to do with it: a run is not discarded by omission, complete or partial (a complete one
    is the evidence a report was made from; --resume answers its every evaluation from the store)."""
    if getattr(args, "resume", False) or getattr(args, "fresh", False):
        return
    found = previous_run(out)
    if found is not None:
        raise StudyError(f"an earlier run is here ({found}): say what to do with it: --resume continues it "
                         f"(solving only what its store lacks), --fresh discards it and starts over",
                         file=str(out))


def _interrupted(args, out: Path) -> int:
    """Ctrl-C: what is kept and the command that continues, exit 130."""
    n = stored_count(out)
    if rank(world()) == 0:
        print("interrupted: " + (f"before any evaluation was stored; start again with `{resume_command(args, '--fresh')}`"
                                 if not n else f"the {n} evaluations finished are kept in {store_path(out)}; "
                                 f"continue with `{resume_command(args)}`"),
              file=sys.stderr, flush=True)
    return INTERRUPTED


def _write_failure(e: WriteError, args, out: Path) -> int:
    """One line for a failed write (the store keeps every evaluation finished before it), exit 1;
    under MPI the other ranks are stopped with it."""
    n = stored_count(out)
    kept = "" if n is None else f"; the store {store_path(out)} keeps every evaluation finished so far ({n})"
    if n is not None:
        kept += f": continue with `{resume_command(args)}`"
    print(f"error: {e}{kept}", file=sys.stderr, flush=True)
    comm = world()
    if comm is not None:
        comm.Abort(1)
    return 1


def _command(args, kind: str) -> int:
    from .runner import CheckedRunner
    study = load_study(args.study)
    if rank(world()) == 0:
        for w in study.warnings:          # also in the results file and the report
            print(f"warning: {study.file}: {w}", file=sys.stderr)
    if args.output:
        out, where = Path(args.output), (None, "-o")
    else:
        out, where = Path(study.output), (str(study.file), "output")
        if kind == "sweep":
            out = out.with_name(out.stem + "-sweep.nc")
    _refuse_previous(args, out)
    try:
        r = CheckedRunner(study, out, bool(getattr(args, "resume", False)), current(), kind=kind,
                          where=where, mesh_check=not getattr(args, "no_mesh_check", False))
        ds = r.run() if kind == "run" else r.sweep()
    except WriteError as e:
        return _write_failure(e, args, out)
    except KeyboardInterrupt:
        return _interrupted(args, out)
    return _finish_command(args, study, ds, out) if rank(world()) == 0 else 0


def cmd_run(args) -> int:
    return _command(args, "run")


def cmd_sweep(args) -> int:
    return _command(args, "sweep")


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


def _write_scenario(study, ev, res, out, args, header: list[str], **kw) -> int:
    """Write one solved scenario (results file + .vtu) and say what it gave."""
    try:
        out, vtu = write_solution(study, ev, res, out, **kw)
    except WriteError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    for w in validity_warnings(res.fields):
        print(f"warning: {w}", file=sys.stderr)
    if not getattr(args, "quiet", False):
        print("\n".join(header + [solver_counts(res)]))
        what = {c.name: in_words(c.kind, list(c.regions)) for c in study.criteria}
        for name, v in res.phi.items():
            print(f"  {name} = {v:.6g}  ({what[name]})")
        print(f"  wrote {out} and {vtu}")
    return 0
