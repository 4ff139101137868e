"""Search strategies: error of the worst value against the number of forward solves, and the
time of a whole study broken down.

Studies: studies/heated-plate.yaml (5 parameters, no contact), studies/validation/stacked-layers.yaml
(6 parameters, frictionless contact) and studies/tunnel-fault.yaml with its mesh coarsened 2x
(22 parameters: 6 + two Lipschitz slip-limit profiles of 8 points, Tresca friction on the fault).

Reference worst value per criterion:
- heated plate, stacked layers (monotone in every datum): all 2^5 / 2^6 vertices of the box
  (`sample` with design `vertices`), and the best any method found (if a method beats the
  vertices, the table says so: the criterion is not monotone);
- tunnel: no exhaustive answer (2^22 vertices, Lipschitz constraints): the best value found by
  any run here, including a long `auto` run and a long `local` run (budget LONG_BUDGET).

Error after k solves = max over criteria of (reference - best so far) / |reference|; a "solve" is
one evaluation (one row of the results file), with or without gradients (auto, local and the
global polish ask for adjoint gradients, which cost extra: see search_time_per_solve in the CSV).
LHS: the max of N Latin hypercube points, a fresh design per N (N = 8 ... 1024), median over seeds.

Outputs: search_convergence.csv/.png, search_solves_to_tolerance.csv (the README table),
study_time_breakdown.csv/.png.
"""
from __future__ import annotations

import dataclasses
import statistics
import time

import numpy as np
import pytest
import yaml

import wcs
from wcs.model.evaluation import Evaluator
from wcs.app.runner import Runner
from wcs.options import Search

from common import STUDIES, save_figure, write_table

pytestmark = pytest.mark.bench

BUDGET = 200                 # auto, local, global
LONG_BUDGET = 600            # the tunnel's reference runs
LHS_N = (8, 16, 32, 64, 128, 256, 512, 1024)
TOLS = (1e-3, 1e-4)
FLOOR = 1e-12                # errors below this are drawn at FLOOR


def tunnel_coarse(tmp_path, factor=2.0):
    """studies/tunnel-fault.yaml with every mesh size multiplied by `factor` (the bench's tunnel)."""
    doc = yaml.safe_load((STUDIES / "tunnel-fault.yaml").read_text())
    mesh = doc["scene"]["mesh"]
    mesh["size"] *= factor
    for r in mesh.get("refine", []):
        r["size"] *= factor
    path = tmp_path / "tunnel-fault-coarse.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))   # materials-rock.yaml is a shipped library
    return wcs.load_study(path)


class NaNGradients:
    """An Evaluator whose evaluations carry NaN rows instead of None for a criterion whose
    adjoint gradient is unavailable. The runner (wcs/app/record.py, `from_evaluation`)
    stacks `np.asarray(None, float)` there and the results dataset then fails to broadcast
    (seen on the tunnel before the adjoint handled redundant contact constraints); NaN rows
    are what it means (the archive treats non-finite gradients as absent)."""

    def __init__(self, evaluator):
        self._ev = evaluator

    def __getattr__(self, name):
        return getattr(self._ev, name)

    def evaluate(self, values, gradients: bool = False):
        ev = self._ev.evaluate(values, gradients=gradients)
        if ev.grad:
            n = len(self._ev.study.parameters)
            ev.grad = {c: (np.full(n, np.nan) if g is None else g) for c, g in ev.grad.items()}
        return ev


def run_with(study, evaluator, search: dict) -> dict:
    """One search run in memory on a shared evaluator -> phi (evals x criteria), status, wall times."""
    st = dataclasses.replace(study, search=Search.of(search))
    runner = Runner(st, False, evaluator=NaNGradients(evaluator))
    t = time.perf_counter()
    ds = runner.run()
    wall = time.perf_counter() - t
    grad = np.asarray(ds["grad"].values, float)
    asked = [i for i, st in enumerate(ds["stage"].values) if str(st) != "sample" or search["method"] != "sample"]
    return {"phi": np.asarray(ds["phi"].values, float), "status": np.asarray(ds["status"].values),
            "grad_finite": float(np.mean(np.isfinite(grad[asked]).all(axis=(1, 2)))) if asked and grad.size else 0.0,
            "stage": [str(s) for s in ds["stage"].values], "wall": wall,
            "eval_time": np.asarray(ds["wall_time"].values, float), "criteria": [str(c) for c in ds["criterion"].values]}


def best_so_far(phi: np.ndarray) -> np.ndarray:
    p = np.where(np.isfinite(phi), phi, -np.inf)
    return np.maximum.accumulate(p, axis=0)


def rel_error(best: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(evals,) max over criteria of the relative shortfall of the best so far."""
    err = (ref[None, :] - best) / np.abs(ref[None, :])
    err = np.where(np.isfinite(err), err, np.inf)
    return np.max(np.maximum(err, 0.0), axis=1)


def solves_to(err: np.ndarray, tol: float):
    hit = np.flatnonzero(err <= tol)
    return int(hit[0]) + 1 if hit.size else None


CASES = [
    # name, loader, monotone (vertex reference), LHS sizes, LHS seeds
    ("heated-plate", lambda tmp: wcs.load_study(STUDIES / "heated-plate.yaml"), True, LHS_N, (0, 1, 2)),
    ("stacked-layers", lambda tmp: wcs.load_study(STUDIES / "validation" / "stacked-layers.yaml"), True, LHS_N,
     (0, 1, 2)),
    ("tunnel-fault (mesh x2)", tunnel_coarse, False, LHS_N[:-1], (0,)),
]


def test_search_error_against_solves(tmp_path):
    import matplotlib.pyplot as plt
    curve_rows, table_rows = [], []
    fig, axes = plt.subplots(1, len(CASES), figsize=(5.2 * len(CASES), 4.4))
    for ax, (name, load, monotone, lhs_sizes, seeds) in zip(axes, CASES):
        t0 = time.perf_counter()
        study = load(tmp_path)
        ev = Evaluator(study)
        n = len(study.parameters)
        runs = {}
        for method in ("auto", "local", "global"):
            runs[method] = run_with(study, ev, {"method": method, "budget": BUDGET,
                                                "sample": {"design": "lhs", "n": 32, "seed": 0}})
        lhs = {}
        for N in lhs_sizes:
            lhs[N] = [run_with(study, ev, {"method": "sample", "budget": N,
                                           "sample": {"design": "lhs", "n": N, "seed": s}}) for s in seeds]
        extra = {}
        if monotone:
            extra["vertices"] = run_with(study, ev, {"method": "sample", "budget": 2 ** n,
                                                     "sample": {"design": "vertices", "n": 2 ** n, "seed": 0}})
        else:
            extra["auto-long"] = run_with(study, ev, {"method": "auto", "budget": LONG_BUDGET, "kkt_tol": 1e-9,
                                                      "sample": {"design": "lhs", "n": 64, "seed": 7}})
            extra["local-long"] = run_with(study, ev, {"method": "local", "budget": LONG_BUDGET, "local": {"starts": 6},
                                                       "sample": {"design": "lhs", "n": 96, "seed": 11}})
        crits = runs["auto"]["criteria"]
        all_runs = list(runs.values()) + [r for rs in lhs.values() for r in rs] + list(extra.values())
        best_all = np.max(np.stack([best_so_far(r["phi"])[-1] for r in all_runs]), axis=0)
        if monotone:
            ref = best_so_far(extra["vertices"]["phi"])[-1]
            beyond = (best_all - ref) / np.abs(ref)
            note = "vertices" + ("" if np.all(beyond <= 1e-9) else
                                 f" (a method beat them by {beyond.max():.1e}: not monotone; reference = best of all)")
            ref = np.maximum(ref, best_all)
        else:
            ref = best_all
            note = f"best of all runs (incl. auto and local with budget {LONG_BUDGET})"

        row = {"study": name, "parameters": n, "reference": note,
               "auto_evals_with_gradient": runs["auto"]["grad_finite"]}
        for method, r in runs.items():
            err = rel_error(best_so_far(r["phi"]), ref)
            k = np.arange(1, len(err) + 1)
            ax.loglog(k, np.maximum(err, FLOOR), "-", label=f"{method} ({len(err)} solves)")
            for i, e in enumerate(err):
                curve_rows.append([name, method, "", i + 1, e, r["eval_time"][: i + 1].sum()])
            for tol in TOLS:
                row[f"{method}_{tol:g}"] = solves_to(err, tol)
            row[f"{method}_final_error"] = float(err[-1])
            row[f"{method}_seconds_per_solve"] = float(np.mean(r["eval_time"]))
        lhs_med = []
        for N, rs in lhs.items():
            errs = [float(rel_error(best_so_far(r["phi"]), ref)[-1]) for r in rs]
            lhs_med.append((N, statistics.median(errs), min(errs), max(errs)))
            for s, e in zip(seeds, errs):
                curve_rows.append([name, "lhs", s, N, e, rs[0]["eval_time"].sum()])
        Ns, med, lo, hi = map(np.array, zip(*lhs_med))
        ax.errorbar(Ns, np.maximum(med, FLOOR), yerr=[np.maximum(med, FLOOR) - np.maximum(lo, FLOOR),
                                                      np.maximum(hi, FLOOR) - np.maximum(med, FLOOR)],
                    fmt="ko--", ms=4, capsize=3, label=f"LHS max of N (median of {len(seeds)} seeds)")
        for tol in TOLS:
            hit = [N for N, m in zip(Ns, med) if m <= tol]
            row[f"lhs_{tol:g}"] = int(hit[0]) if hit else f">{int(Ns[-1])}"
        row["lhs_final_error"] = float(med[-1])
        row["lhs_seconds_per_solve"] = float(np.mean(np.concatenate([r["eval_time"] for rs in lhs.values() for r in rs])))
        for tol in TOLS:
            ax.axhline(tol, color="0.6", lw=0.8, ls=":")
        ax.set_xlabel("forward solves (evaluations) [-]")
        ax.set_ylabel("relative error of the worst value (max over criteria) [-]")
        nograd = "" if runs["auto"]["grad_finite"] > 0.5 else \
            f"\nadjoint gradients unavailable in {100 * (1 - runs['auto']['grad_finite']):.0f}% of auto's solves"
        ax.set_title(f"{name}: {n} parameters, {len(crits)} criteria\nreference: "
                     + ("2^%d vertices" % n if monotone else "best of all runs") + nograd, fontsize=9)
        ax.set_ylim(FLOOR / 3, 3)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="lower left")
        row["bench_seconds"] = time.perf_counter() - t0
        table_rows.append(row)
        print(row, flush=True)
    fig.suptitle(f"Worst-value error against forward solves (errors below {FLOOR:g} drawn at {FLOOR:g})")
    fig.tight_layout()
    save_figure(fig, "search_convergence")
    write_table("search_convergence", ["study", "method", "seed", "solves", "rel_error", "cumulative_eval_seconds"],
                curve_rows)
    header = list(table_rows[0])
    write_table("search_solves_to_tolerance", header, [[r.get(h) for h in header] for r in table_rows])
    for r in table_rows:                                   # with gradients auto certifies long before LHS
        if r["auto_evals_with_gradient"] > 0.5:
            assert r["auto_0.001"] is not None, r


BREAKDOWN_STUDY = "knee-replacement.yaml"
BREAKDOWN_BUDGET = 60


def test_study_time_breakdown(tmp_path):
    """One whole run of studies/knee-replacement.yaml (its own mesh, search auto, budget capped
    at BREAKDOWN_BUDGET), written to a NetCDF file, instrumented from the outside: mesh and
    assembly from Evaluator.timings, solves and gradients from the evaluations' wall times split
    by the measured cost of the adjoint, I/O from the runner's write_time."""
    import matplotlib.pyplot as plt
    study = wcs.load_study(STUDIES / BREAKDOWN_STUDY)
    study = dataclasses.replace(study, search=study.search.model_copy(
        update={"budget": min(BREAKDOWN_BUDGET, study.search.budget)}))
    out = tmp_path / "breakdown.nc"
    t0 = time.perf_counter()
    runner = Runner(study, out, evaluator=NaNGradients(Evaluator(study)))
    t_setup = time.perf_counter() - t0
    t1 = time.perf_counter()
    ds = runner.run()
    t_run = time.perf_counter() - t1
    total = time.perf_counter() - t0
    ev = runner.evaluator
    # the adjoint's cost per evaluation, timed on its own (wcs.model.sensitivity.gradients on a solved state)
    # at a few of the run's points; the rest of an evaluation with gradients is its forward solve
    from wcs.model.sensitivity import gradients as adjoint
    inner = ev._ev
    xs = np.asarray(ds["x"].values)[:: max(1, len(ds["x"]) // 8)][:8]
    tn, ta = [], []
    for x in xs:
        for _ in range(2):
            t = time.perf_counter()
            e = inner.evaluate(x)
            tn.append(time.perf_counter() - t)
            if e.state is not None:
                ta.append(_time(lambda: adjoint(inner, e.state, x)))
    tn, ta = statistics.median(tn), statistics.median(ta) if ta else 0.0
    tg = tn + ta
    grads_available = sum(g is not None and bool(np.all(np.isfinite(g)))
                          for g in (inner.evaluate(xs[-1], gradients=True).grad or {}).values())
    grad_asked = np.isfinite(np.asarray(ds["grad"].values)).any(axis=(1, 2))
    wt = np.asarray(ds["wall_time"].values, float)
    t_grad = min(ta * int(grad_asked.sum()), wt[grad_asked].sum())
    t_solves = wt.sum() - t_grad
    st = runner.stats
    t_io = st["write_time"]
    t_other = max(0.0, t_run - wt.sum() - t_io)      # strategy, records, worst-field re-solves, first anchor
    parts = [("mesh (gmsh)", ev.timings["mesh"]), ("assembly (affine parts)", ev.timings["assembly"]),
             ("forward solves", t_solves), ("adjoint gradients", t_grad), ("NetCDF I/O", t_io),
             ("other (strategy, bookkeeping,\nworst fields, store)", t_other + max(0.0, t_setup - sum(ev.timings.values())))]
    rows = [[k.replace("\n", " "), v, v / total] for k, v in parts]
    rows += [["total", total, 1.0], ["evaluations", len(wt), ""], ["with gradients", int(grad_asked.sum()), ""],
             ["seconds per evaluation without gradients (median)", tn, ""],
             ["seconds per evaluation with gradients (median: forward + adjoint)", tg, ""],
             ["adjoint seconds per evaluation (median)", ta, ""], ["netcdf writes", st["writes"], ""],
             ["unknowns", 2 * ev.smesh.mesh.p.shape[1], ""],
             ["criteria with an adjoint gradient at the last point", grads_available, ""]]
    write_table("study_time_breakdown", ["part", "seconds", "share"], rows)
    fig, ax = plt.subplots(figsize=(7, 3.8))
    names = [k for k, _ in parts][::-1]
    vals = [v for _, v in parts][::-1]
    ax.barh(names, vals, color="tab:blue")
    for i, v in enumerate(vals):
        ax.text(v, i, f" {v:.2f} s ({100 * v / total:.0f}%)", va="center", fontsize=8)
    ax.set_xlabel("wall time [s]")
    ax.set_xlim(0, max(vals) * 1.35)
    ax.set_title(f"{study.name}: whole run, {len(wt)} evaluations ({int(grad_asked.sum())} with gradients), "
                 f"{2 * ev.smesh.mesh.p.shape[1]} unknowns, total {total:.1f} s", fontsize=9)
    fig.tight_layout()
    save_figure(fig, "study_time_breakdown")
    print({k: round(v, 3) for k, v in parts}, "total", round(total, 2), "tn", tn, "tg", tg, flush=True)


def _time(f):
    t = time.perf_counter()
    f()
    return time.perf_counter() - t
