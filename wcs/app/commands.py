"""The commands `wcs run` and `wcs sweep`: a run's messages and exit status (`wcs solve` is
`wcs.app.solve`).

Exit 0 done, 1 failure (no evaluation solved, a failed write; with --fail-on-limit also a
verdict NOT ESTABLISHED: failed evaluations leave the criteria unknown somewhere in U_ad), 3 with
--fail-on-limit a verdict FAIL (a worst value breaks its limit, or a data set has no equilibrium;
`wcs/results/verdict.py`); bad input raises StudyError, which `wcs.cli.main` turns into exit 2.
"""
from __future__ import annotations

import shlex
import sys
from pathlib import Path

import numpy as np

from ..errors import StudyError
from ..model.criteria import KINDS, in_words
from ..model.validity import warnings as validity_warnings
from ..progress import INTERRUPTED, current
from ..report.timeline import in_time
from ..results import meshcheck
from ..results.dataset import open_results
from ..results.store import WriteError, store_path, stored_count, writer
from ..results.summary import limits_broken, summary_table
from ..results.verdict import verdict
from ..status import Status, describe
from ..study.load import load_study
from .parallel import rank, world
from .runner import CheckedRunner


def _finish_command(args, study, ds, out: Path) -> int:
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
