r"""Benchmarks of the DD solver over MPI ranks: one large evaluation, and a whole study.

    python tests/bench/dd_bench.py solve STUDY [options]    # under mpiexec -n N: one DD solve on N ranks
    python tests/bench/dd_bench.py speedup STUDY [options]  # runs `solve` on 1 and 2 ranks, compares
    python tests/bench/dd_bench.py study STUDY [-o out.nc]  # under mpiexec -n N: `wcs run` with per-rank timings
    python tests/bench/dd_bench.py study-speedup STUDY      # runs `study` on 1 and 2 ranks, compares
    python tests/bench/dd_bench.py iterations               # PCG1/PCG2 table (H/h, seed's models)

It runs the `wcs` of the clone it is in (the clone's root goes first on sys.path).

`solve`: every rank builds the model (mesh, assembly: deterministic, identical), then
calls `solve_dd(..., comm=COMM_WORLD)` `--repeat` times (the first includes the
partition and the symbolic analyses; the others are what every further evaluation of a
study costs: their best wall time is kept, the machine being shared; `--new-data`: new
material data at every repeat, numeric refactors) and prints per-rank timings of the last: assemble (local
factorizations), Dirichlet solves, Neumann solves, coarse, contact solves, comm
(gathers, including waiting for the slowest rank). `--save F.npz` writes u, lam_n,
lam_t and the iteration history (rank 0) for comparisons.

`study`: `wcs run` of the study with per-rank timings from the runner's timing events
(`wcs.app.runner.Event`): building the model, the evaluations, waiting in the batch gathers.

`--mesh-scale s` multiplies every mesh size of the study (global and refinements) by s:
s = 0.4 takes the tunnel (1.5e4 unknowns) to about 1e5.

Threads: one BLAS/MKL thread per rank (wcs.linalg.configure_threads), so 2 ranks use
the 2 cores and 1 rank one of them.
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402
import yaml  # noqa: E402
from dd_common import build  # noqa: E402

import wcs  # noqa: E402
from wcs.dd import solver as dds  # noqa: E402
from wcs.linalg import configure_threads  # noqa: E402
from wcs.model.model import Model  # noqa: E402
from wcs.app.parallel import world  # noqa: E402
from wcs.app.runner import Runner  # noqa: E402
from wcs.scene.mesher2d import build_mesh  # noqa: E402

PARTS = ("assemble", "dirichlet", "neumann", "coarse", "contact", "comm", "wait")


def _scale_mesh(doc: dict, s: float) -> None:
    mesh = doc["scene"].get("mesh") or {}
    if "size" in mesh:
        mesh["size"] = float(mesh["size"]) * s
    for r in mesh.get("refine", []) or []:
        if "size" in r:
            r["size"] = float(r["size"]) * s
    doc["scene"]["mesh"] = mesh


def edited_study(path: Path, tmp: Path, mesh_scale: float = 1.0, budget: int | None = None,
                 solver: dict | None = None) -> Path:
    """A copy of the study (and its materials files) in tmp, with the mesh scaled."""
    doc = yaml.safe_load(Path(path).read_text())
    if mesh_scale != 1.0:
        _scale_mesh(doc, mesh_scale)
    if budget is not None:
        doc.setdefault("search", {})["budget"] = budget
    if solver is not None:
        doc["solver"] = solver
    for f in Path(path).parent.glob("materials*.yaml"):
        (tmp / f.name).write_text(f.read_text())
    out = tmp / Path(path).name
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


def reduced_system(model, scene):
    c = model.coefficients(scene)
    _, Kr, rhs, u0 = model.reduced_system(c, model.solve_heat(c) if model.thermal else None)
    return c, Kr, rhs, u0


def cmd_solve(a) -> int:
    comm = world()
    me = 0 if comm is None else comm.rank
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        path = edited_study(Path(a.study), Path(tmp), a.mesh_scale)
        study = wcs.load_study(path)
    model = Model(study.scene, build_mesh(study.scene), {"method": "monolithic"})
    c, Kr, rhs, u0 = reduced_system(model, study.scene)
    c0 = c
    t_model = time.perf_counter() - t0
    opts = {"tolerance": a.tolerance, "max_iterations": a.max_iterations,
            "dd": {"subdomains": a.subdomains, "relaxation": _relax(a.relaxation)}}
    if a.pair_size is not None:
        opts["dd"]["pair_size"] = a.pair_size
    walls, cpus = [], []
    for k in range(a.repeat):
        if a.new_data:            # every Young modulus × (1 + 0.01 k): numeric refactors, as in a study
            c = dataclasses.replace(c0, lam=(1 + 0.01 * k) * c0.lam, mu=(1 + 0.01 * k) * c0.mu)
            _, Kr, rhs, u0 = model.reduced_system(c, model.solve_heat(c) if model.thermal else None)
        if comm is not None:
            comm.Barrier()
        t, tc = time.perf_counter(), time.process_time()
        res = dds.solve_dd(model, study.scene, Kr, rhs, u0, opts, coefficients=c, comm=comm)
        walls.append(time.perf_counter() - t)
        cpus.append(time.process_time() - tc)
    info = res.info
    work = cpus[-1] - info["ranks"][me].get("comm_cpu", 0.0)     # this rank's CPU outside the gathers
    works = [work] if comm is None else comm.allgather(work)
    out = {"ranks": 1 if comm is None else comm.size, "ndof": int(Kr.shape[0]), "status": res.status.value,
           "message": res.message, "subdomains": info.get("subdomains"), "pairs": info.get("pairs"),
           "interface_dofs": info.get("interface_dofs"), "coarse": info.get("coarse"),
           "pcg1": info.get("pcg1"), "successive": info.get("successive"), "pcg2": info.get("pcg2"),
           "contact_nodes": int(model.zone.gap.size), "model_build": t_model, "walls": walls,
           "wall": min(walls[1:]) if len(walls) > 1 else walls[0],      # best after the first (shared machine)
           "per_rank": info.get("ranks"), "work_cpu": works}
    if me == 0:
        if a.save:
            hist = info.get("history", {})
            np.savez(a.save, u=res.u if res.u is not None else np.zeros(0),
                     lam_n=res.lam_n if res.lam_n is not None else np.zeros(0),
                     lam_t=res.lam_t if res.lam_t is not None else np.zeros(0),
                     pcg1_residuals=np.asarray(info.get("pcg1_residuals", [])),
                     dU=np.asarray(hist.get("dU", [])), residual=np.asarray(hist.get("residual", [])),
                     pcg2=np.asarray(hist.get("pcg2", [])))
        if a.json:
            Path(a.json).write_text(json.dumps(out, default=float, indent=1))
        if not a.quiet:
            print_solve(out)
    return 0 if res.status == dds.DDOutcome.CONVERGED else 1


def _relax(r):
    try:
        return float(r)
    except ValueError:
        return r


def print_solve(out: dict) -> None:
    print(f"{out['ranks']} rank(s): {out['ndof']} unknowns, {out['subdomains']} subdomains ({out['pairs']} pairs), "
          f"{out['interface_dofs']} interface DOFs, coarse {out['coarse']}, {out['contact_nodes']} contact nodes")
    print(f"  {out['status']}: PCG1 {out['pcg1']}, successive {out['successive']}, PCG2 {out['pcg2']}; "
          f"wall per solve {', '.join(f'{w:.3f}' for w in out['walls'])} s (model build {out['model_build']:.2f} s)")
    print("  rank  units " + " ".join(f"{p:>9s}" for p in PARTS) + "  messages")
    for r in out["per_rank"] or []:
        print(f"  {r['rank']:4d}  {r['units']:5d} " + " ".join(f"{r.get(p, 0.0):9.3f}" for p in PARTS)
              + f"  {r['messages']:8d}")


def _env():
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_", "MPI_LOCAL"))}
    env.setdefault("WCS_THREADS", "1")
    return env


def _mpiexec(n: int, args: list[str], timeout: float = 3600) -> subprocess.CompletedProcess:
    bindir = Path(sys.executable).parent
    cmd = [str(bindir / "mpiexec"), "-n", str(n), sys.executable, str(Path(__file__).resolve()), *args]
    return subprocess.run(cmd, env=_env(), capture_output=True, text=True, timeout=timeout)


def cmd_speedup(a) -> int:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in a.ranks:
            js, npz = Path(tmp) / f"r{n}.json", Path(tmp) / f"r{n}.npz"
            p = _mpiexec(n, ["solve", a.study, "--mesh-scale", str(a.mesh_scale), "--subdomains", str(a.subdomains),
                             "--tolerance", str(a.tolerance), "--relaxation", str(a.relaxation),
                             "--max-iterations", str(a.max_iterations), "--repeat", str(a.repeat),
                             "--json", str(js), "--save", str(npz), "--quiet"]
                         + (["--pair-size", str(a.pair_size)] if a.pair_size is not None else [])
                         + (["--new-data"] if a.new_data else []))
            if not js.exists():
                print(p.stdout, p.stderr, file=sys.stderr)
                return 2
            out = json.loads(js.read_text())
            out["arrays"] = dict(np.load(npz))
            rows.append(out)
            print_solve(out)
    base = rows[0]
    same = all(all(np.array_equal(base["arrays"][k], r["arrays"][k]) for k in base["arrays"]) for r in rows[1:])
    print(f"results of {', '.join(str(r['ranks']) for r in rows)} ranks bitwise identical "
          f"(u, lam_n, lam_t, PCG1 residuals, ‖ΔU‖ / Newton residual history): {same}")
    for r in rows[1:]:
        print(f"speed-up {r['ranks']} vs {base['ranks']} rank(s), one DD solve: {base['wall'] / r['wall']:.2f} "
              f"({base['wall']:.3f} s -> {r['wall']:.3f} s); CPU outside the gathers, last solve: "
              f"{base['work_cpu'][0]:.3f} s -> {', '.join(f'{w:.3f}' for w in r['work_cpu'])} s per rank "
              f"(work ratio {base['work_cpu'][0] / max(r['work_cpu']):.2f})")
    if a.out:
        summary = [{k: v for k, v in r.items() if k != "arrays"} for r in rows]
        for r in summary:
            r["bitwise_identical"] = same
            r["speedup"] = base["wall"] / r["wall"]
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(json.dumps({"study": a.study, "mesh_scale": a.mesh_scale, "runs": summary},
                                          default=float, indent=1))
    return 0 if same else 1


# ---- a whole study ---------------------------------------------------------------------------
def cmd_study(a) -> int:
    """`wcs run` with per-rank timings: model build, evaluations (solves), waiting in the batch
    gathers, from the runner's timing events."""
    comm = world()
    me = 0 if comm is None else comm.rank
    events = []
    t0 = time.perf_counter()
    study = wcs.load_study(a.study)
    ds = Runner(study, a.output, False, None, on_event=events.append).run()
    evals = [e for e in events if e.what == "evaluate"]
    tm = {"model_build": sum(e.seconds for e in events if e.what == "prepare"),
          "evaluate": sum(e.seconds for e in evals), "evaluations": len(evals),
          "gather": sum(e.seconds for e in events if e.what == "gather"),
          "wall": time.perf_counter() - t0, "rank": me, "evals_total": int(ds.sizes.get("eval", 0)),
          "batches": _records_per_stage(events)}
    allt = [tm] if comm is None else comm.allgather(tm)
    if me == 0:
        if a.json:
            Path(a.json).write_text(json.dumps(allt, default=float, indent=1))
        if not a.quiet:
            print_study(allt)
    return 0


def _records_per_stage(events) -> list:
    """[stage, records] of the run's batches, consecutive batches of one stage merged."""
    out = []
    for e in events:
        if e.what == "batch" and e.records:
            if out and out[-1][0] == e.stage:
                out[-1][1] += e.records
            else:
                out.append([e.stage, e.records])
    return out


def print_study(allt) -> None:
    print(f"{len(allt)} rank(s), {allt[0]['evals_total']} evaluations; records per stage: {allt[0]['batches']}")
    print("  rank  evals  evaluate    gather   wall")
    for r in allt:
        print(f"  {r['rank']:4d}  {r['evaluations']:5d}  {r['evaluate']:8.2f}  {r['gather']:8.2f}  {r['wall']:6.2f}")


def cmd_study_speedup(a) -> int:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        solver = None if a.method is None else {"method": a.method, **({"dd": {"subdomains": a.subdomains}}
                                                                      if a.method == "dd" else {})}
        path = edited_study(Path(a.study), Path(tmp), a.mesh_scale, a.budget, solver)
        for n in a.ranks:
            js = Path(tmp) / f"s{n}.json"
            p = _mpiexec(n, ["study", str(path), "-o", str(Path(tmp) / f"s{n}.nc"), "--json", str(js), "--quiet"])
            if not js.exists():
                print(p.stdout, p.stderr, file=sys.stderr)
                return 2
            allt = json.loads(js.read_text())
            print_study(allt)
            rows.append(allt)
        dss = [xr.open_dataset(Path(tmp) / f"s{n}.nc", engine="h5netcdf") for n in a.ranks]
        same = all(np.array_equal(dss[0][v].values, d[v].values, equal_nan=True)
                   for d in dss[1:] for v in ("x", "phi", "worst_value", "worst_x"))
        for d in dss:
            d.close()
    w = [max(r["wall"] for r in allt) for allt in rows]
    print(f"results bitwise identical (x, phi, worst_value, worst_x): {same}")
    for n, wn in zip(a.ranks[1:], w[1:]):
        print(f"speed-up of the study, {n} vs {a.ranks[0]} rank(s): {w[0] / wn:.2f} ({w[0]:.2f} s -> {wn:.2f} s)")
    if a.out:
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(json.dumps({"study": a.study, "mesh_scale": a.mesh_scale, "budget": a.budget,
                                           "method": a.method,
                                           "ranks": a.ranks, "per_rank": rows, "wall": w, "bitwise_identical": same},
                                          default=float, indent=1))
    return 0


# ---- iteration table ---------------------------------------------------------------------------
def _pad_off_centre(doc: dict, scale: float) -> None:
    """The Tresca pad pressed on the right half of its top (the contact opens on the left),
    frictionless, E_pad = 1e-2 E_base, pad held sideways by a roller (tests/bench dd stability)."""
    sc = doc["scene"]
    sc["mesh"] = {"size": 0.1 * scale, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": 0.05 * scale}]}
    sc["materials"]["rubber"] = {"E": 2.1e9, "nu": 0.3}
    sc["boundaries"]["pad_left"] = {"body": "pad", "segment": [[0.5, 1.0], [0.5, 1.5]]}
    sc["supports"]["pad_left"] = {"u": [0.0, None]}
    sc["boundaries"]["pad_top_right"] = {"body": "pad", "segment": [[1.0, 1.5], [1.5, 1.5]]}
    sc["loads"] = {"pad_top_right": {"traction": [0.0, -1.0e6]}}
    sc["contacts"]["interface"].pop("friction", None)
    doc["uncertain"] = {"loads.pad_top_right.traction.1": [-2.0e6, -0.5e6]}
    doc["criteria"] = [{"name": "pressure", "kind": "contact_pressure", "regions": ["interface"]}]


ITER_FIELDS = ["case", "h", "subdomains_asked", "relaxation", "tolerance", "ndof", "subdomains", "pairs",
               "interface_dofs", "coarse_pcg1", "contact_nodes", "open_nodes", "slip_nodes", "pcg1", "successive",
               "pcg2", "status", "err_u", "err_lam_n", "time_dd", "time_mono"]


def _iter_row(study, model, opts, **extra) -> dict:
    c, Kr, rhs, u0 = reduced_system(model, study.scene)
    t = time.perf_counter()
    res = dds.solve_dd(model, study.scene, Kr, rhs, u0, opts, coefficients=c)
    row = {**extra, "tolerance": opts["tolerance"], "ndof": int(Kr.shape[0]), "status": res.status.value,
           "time_dd": time.perf_counter() - t, "contact_nodes": int(model.zone.gap.size)}
    i = res.info
    row.update({k: i.get(k) for k in ("subdomains", "pairs", "interface_dofs", "pcg1", "successive", "pcg2")})
    row["coarse_pcg1"] = (i.get("coarse") or {}).get("pcg1")
    act = i.get("active")
    if act is not None:
        row["open_nodes"], row["slip_nodes"] = int((act == 0).sum()), int((act == 2).sum())
    if res.u is not None:
        t = time.perf_counter()
        mono = model.solve(model.nominal)
        row["time_mono"] = time.perf_counter() - t
        row["err_u"] = float(np.linalg.norm(res.u - mono.u) / np.linalg.norm(mono.u))
        row["err_lam_n"] = float(np.linalg.norm(res.lam_n - mono.contact.force_n)
                                 / max(np.linalg.norm(mono.contact.force_n), 1e-300))
    print({k: row.get(k) for k in ("case", "h", "subdomains", "relaxation", "pcg1", "successive", "pcg2",
                                   "open_nodes", "status", "err_u")}, flush=True)
    return row


def cmd_iterations(a) -> int:
    rows = []

    def load(name, edit=None):
        with tempfile.TemporaryDirectory() as tmp:
            return build(name, Path(tmp), edit)

    for scale in (1.0, 0.5, 0.25):
        study, model = load("validation/tresca-pad.yaml", lambda d, s=scale: _pad_off_centre(d, s))
        for n in (8, 16):
            for relax in a.relaxations:
                rows.append(_iter_row(study, model, {"tolerance": 1e-4, "max_iterations": 100,
                                                     "dd": {"subdomains": n, "relaxation": _relax(relax)}},
                                      case="pad-off-centre", h=0.05 * scale, subdomains_asked=n, relaxation=relax))
    if not a.no_seed:
        for name, n in (("tunnel-fault.yaml", 12), ("knee-replacement.yaml", 13)):
            study, model = load(name)
            for label, dd in (("1.0", {"relaxation": 1.0}), ("aitken", {"relaxation": "aitken"}),
                              ("anderson", {"relaxation": "anderson"}),
                              ("anderson-0.1", {"relaxation": "anderson", "mixing": 0.1})):
                rows.append(_iter_row(study, model, {"tolerance": 1e-4, "max_iterations": 100,
                                                     "dd": {"subdomains": n, **dd}},
                                      case=name.removesuffix(".yaml"), h="", subdomains_asked=n, relaxation=label))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    with open(a.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=ITER_FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    print(f"{'case':16s} {'h':>6s} {'N':>3s} {'relax':>12s} {'ndof':>6s} {'nΓ':>5s} {'PCG1':>5s} {'succ':>5s} "
          f"{'PCG2':>5s} {'open':>9s} status")
    for r in rows:
        print(f"{r['case']:16s} {r['h']!s:>6s} {r['subdomains']!s:>3s} {r['relaxation']!s:>12s} {r['ndof']:6d} "
              f"{r['interface_dofs']!s:>5s} {r['pcg1']!s:>5s} {r['successive']!s:>5s} {r['pcg2']!s:>5s} "
              f"{str(r.get('open_nodes', '')) + '/' + str(r['contact_nodes']):>9s} {r['status']}")
    return 0


def main(argv=None) -> int:
    configure_threads()              # the process edge: one BLAS/OpenMP thread per rank
    ap = argparse.ArgumentParser(prog="python tests/bench/dd_bench.py", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name in ("solve", "speedup"):
        p = sub.add_parser(name)
        p.add_argument("study")
        p.add_argument("--mesh-scale", type=float, default=1.0)
        p.add_argument("--subdomains", type=int, default=12)
        p.add_argument("--pair-size", type=float, default=None)
        p.add_argument("--tolerance", type=float, default=1e-4)
        p.add_argument("--relaxation", default="aitken")
        p.add_argument("--max-iterations", type=int, default=100)
        p.add_argument("--repeat", type=int, default=2)
        p.add_argument("--new-data", action="store_true",
                       help="new material data at every repeat (numeric refactors), as in a study")
        p.add_argument("--quiet", action="store_true")
        if name == "solve":
            p.add_argument("--save")
            p.add_argument("--json")
        else:
            p.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
            p.add_argument("--out")
    p = sub.add_parser("study")
    p.add_argument("study")
    p.add_argument("-o", "--output", default=False)
    p.add_argument("--json")
    p.add_argument("--quiet", action="store_true")
    p = sub.add_parser("study-speedup")
    p.add_argument("study")
    p.add_argument("--mesh-scale", type=float, default=1.0)
    p.add_argument("--budget", type=int, default=None)
    p.add_argument("--method", default=None, help="the study's solver.method (default: the study's own)")
    p.add_argument("--subdomains", type=int, default=12, help="dd.subdomains with --method dd")
    p.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    p.add_argument("--out")
    p = sub.add_parser("iterations")
    p.add_argument("--relaxations", nargs="+", default=["aitken", "anderson"])
    p.add_argument("--no-seed", action="store_true")
    p.add_argument("--out", default=str(ROOT / "results" / "bench" / "dd_iterations_nonlinear.csv"))
    a = ap.parse_args(argv)
    return {"solve": cmd_solve, "speedup": cmd_speedup, "study": cmd_study, "study-speedup": cmd_study_speedup,
            "iterations": cmd_iterations}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
