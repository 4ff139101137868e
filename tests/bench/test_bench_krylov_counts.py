"""Krylov iterations of `solver.method: iterative` under mesh refinement, beside the seed's
tunnel counts and the domain decomposition's (issue 25).

The 2D tunnel (studies/tunnel-fault.yaml) and the 3D tunnel (studies/tunnel-fault-3d.yaml,
every mesh size of it tripled so that three refinements fit this machine) at four mesh
levels: the study's mesh split 0–3 times (every triangle into four, every tetrahedron into
eight: h halved each level, `Evaluator(splits=)`), one nominal evaluation each with
`solver.method: iterative`: its unknowns and contact nodes, Newton steps, the CG iterations
of each Newton step (as the results file holds them: `krylov_iterations`, `krylov_step_max`),
and the CG iterations of one linear GAMG solve of the same mesh (the first Newton step's
system with every contact row closed and stuck: the linear elasticity of the glued bodies)
to the same tolerance. Beside them the seed's own counts for its DD on the tunnel ([21] §8,
physics note: 12 subdomains, 10,428 unknowns, 89 contact conditions, tolerance 1e-4: 21 PCG
iterations of the auxiliary problem, 15 successive approximations, 39 PCG iterations in all
— the issue quotes 38) and our DD's on the 2D tunnel at level 0 by test_dd_iterations.py's
method (12 subdomains, tolerance 1e-4; the seed's step with ω = 1 and with Aitken relaxation,
and step auto: interface Newton).

The growth goal (issue 25: Krylov iterations grow at most logarithmically under three
refinements), asserted for the linear solve's count and for the mean CG iterations of a Newton
step of the evaluation's cold solve (its first, from no contact state: the steps that find the
active set; the nominal evaluation may then be answered from its answer in a step or two, as the
3D tunnel's is, in one step with next to no CG iterations: no base to grow from) from level 0 to the
finest level measured: its ≤ its₀ · (1 + C · ln(n / n₀)), n the unknowns. Smoothed aggregation
AMG bounds the condition number of the preconditioned operator by c (1 + ln(H/h))² (Vaněk,
Brezina, Mandel, Numer. Math. 88 (2001)), so CG needs O(1 + ln(H/h)) iterations, with
ln(H/h) = ln(n/n₀)/d. The constant is not known a priori; C = 1/4 (a choice) lets the count grow
by ½ (2D) or ¾ (3D) of its level-0 value per unit of ln(H/h) — a factor 2.04 (2D) or 2.56 (3D)
over three halvings — and fails a growth like √n (h⁻¹ in 2D: ×8). The counts and the verdicts
are the table's (results/bench/bench_krylov_counts.csv, on docs/benchmarks.md) and the run's
output. What brought the 2D count per Newton step from ≈ n^0.28 growth to logarithmic
(`wcs.contact.iterative`): a converged solve is never repeated, a kept hierarchy is rebuilt once
its excess iterations pass a set-up's cost, the glued 2D first step's hierarchy is not kept (its
aggregates span the fault), and in 2D each body has its own rigid modes in the near-nullspace
(one set for both leaves the bodies' relative motion out of every aggregate that straddles the
fault; in 3D the bodies' 12 columns doubled the CPU time, so 3D keeps one set).

WCS_BENCH_KRYLOV="2d:3 3d:2" sets the finest level of each case (the default; both above 3 GB:
run under the big-memory lock; the 3D level 3, ≈ 1.5e6 unknowns, would not fit this machine at the
peak a cell of results/bench/bench_iterative.csv). Table: results/bench/bench_krylov_counts.csv.
"""
from __future__ import annotations

import math
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import STUDIES, write_table  # noqa: E402
from dd_common import build, run  # noqa: E402

from wcs.contact import iterative  # noqa: E402
from wcs.contact.iterative import Krylov, _Rows, _Stepper, node_blocks  # noqa: E402
from wcs.model.evaluation import Evaluator  # noqa: E402
from wcs.app.record import krylov_counts  # noqa: E402
from wcs.scene import estimate  # noqa: E402
from wcs.study import load_study  # noqa: E402

C = 0.25        # the growth constant of the module docstring
CASES = {"2d": ("tunnel-fault.yaml", 1.0), "3d": ("tunnel-fault-3d.yaml", 3.0)}    # study, mesh sizes × this
SEED = {"case": "seed [21] dd, tunnel", "unknowns": 10428, "contact_nodes": 89, "subdomains": 12,
        "dd_pcg1": 21, "dd_outer": 15, "dd_pcg_all": 39}
FIELDS = ["case", "level", "unknowns", "contact_nodes", "newton", "krylov", "krylov_step_max", "krylov_per_step",
          "krylov_steps", "cold_newton", "cold_krylov_per_step", "cold_krylov_steps", "linear_krylov", "tolerance", "solve_s", "peak_gb", "subdomains", "dd_pcg1", "dd_outer",
          "dd_pcg_all", "status"]


def study(name: str, coarsen: float) -> dict:
    """The study with `solver.method: iterative` and every mesh size times `coarsen`."""
    d = yaml.safe_load((STUDIES / name).read_text())
    mesh = d["scene"]["mesh"]
    mesh["size"] *= coarsen
    for r in mesh.get("refine", []):
        r["size"] *= coarsen
    d["solver"] = {**d.get("solver", {}), "method": "iterative"}
    return d


def linear_krylov(model, rtol: float) -> int:
    """CG iterations of one GAMG-preconditioned solve of the glued bodies' elasticity (every
    contact row closed and stuck: the first Newton step's elimination), fresh hierarchy, GAMG on
    the nodes as the method's (`node_blocks`)."""
    c = model.nominal
    _, Kr, rhs, u0 = model.reduced_system(c, None)
    z, Cr = model.zone, model.contact_rows
    m = z.gap.size
    k = Cr.shape[0] // m - 1
    rows = _Rows(Cr, m, k)
    N = model.near_nullspace
    step = _Stepper(Kr, rhs, Cr, np.r_[z.gap - z.Bn @ u0, np.zeros(k * m)], rows, N,
                    krylov=Krylov(np.reshape(N, (Kr.shape[0], -1)), blocks=node_blocks(model, Kr)))   # as the method's own
    step.solve(rows.acting.copy(), np.zeros((1 + k) * m), np.zeros(m), np.ones((1 + k) * m), k, rtol, np.zeros(Kr.shape[0]), rtol)
    step.krylov_solver.close()
    return step.krylov


def level(case: str, splits: int) -> dict:
    name, coarsen = CASES[case]
    with tempfile.TemporaryDirectory() as tmp:      # the study's material files beside it
        for f in (STUDIES).glob("materials*.yaml"):
            (Path(tmp) / f.name).write_text(f.read_text())
        path = Path(tmp) / name
        path.write_text(yaml.safe_dump(study(name, coarsen), sort_keys=False))
        ev = Evaluator(load_study(path), splits=splits)
    solves, solve = [], iterative.solve_contact_iterative

    def spy(*args, **kwargs):
        solves.append(solve(*args, **kwargs))
        return solves[-1]
    iterative.solve_contact_iterative = spy
    try:
        t = time.perf_counter()
        res = ev.evaluate(ev.study.nominal())
        solve_s = time.perf_counter() - t
    finally:
        iterative.solve_contact_iterative = solve
    cold = solves[0]            # the model's first solve, from no contact state (`wcs.contact.iterative._solve_problem`)
    steps = tuple(res.krylov_steps or ())
    total, most = krylov_counts(res.krylov_steps)
    rtol = ev.model.options.iterative.tolerance
    return {"case": f"{case} tunnel" + (f" (sizes ×{coarsen:g})" if coarsen != 1 else ""), "level": splits,
            "unknowns": ev.model.contact_rows.shape[1], "contact_nodes": ev.model.zone.gap.size,
            "newton": res.iterations, "krylov": total, "krylov_step_max": most,
            "krylov_per_step": round(total / max(res.iterations, 1), 1), "krylov_steps": " ".join(map(str, steps)),
            "cold_newton": cold.iterations, "cold_krylov_per_step": round(sum(cold.krylov_steps) / max(cold.iterations, 1), 1),
            "cold_krylov_steps": " ".join(map(str, cold.krylov_steps)),
            "linear_krylov": linear_krylov(ev.model, rtol), "tolerance": rtol, "solve_s": round(solve_s, 1),
            "peak_gb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6, 2),
            "status": int(res.status)}


def dd_rows() -> list[dict]:
    """Our DD on the 2D tunnel as test_dd_iterations.py runs it: the seed's step (ω = 1, Aitken)
    and step auto."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        s, model = build("tunnel-fault.yaml", Path(tmp))
        for step, relax in (("seed", 1.0), ("seed", "aitken"), ("auto", "")):
            dd = {"subdomains": 12, "step": step, **({"relaxation": relax} if relax else {})}
            _, out = run(s, model, {"tolerance": 1e-4, "max_iterations": 100, "dd": dd}, compare=False)
            rows.append({"case": f"2d tunnel, wcs dd {step}" + (f" ω={relax}" if relax else ""),
                         "level": 0, "unknowns": out["ndof"], "contact_nodes": out["contact_nodes"], "tolerance": 1e-4,
                         "subdomains": out["subdomains"], "dd_pcg1": out["pcg1"], "dd_outer": out["successive"],
                         "dd_pcg_all": out["pcg1"] + out["pcg2"], "solve_s": round(out["time_dd"], 1),
                         "status": out["status"]})
    return rows


def grows_at_most_logarithmically(rows: list[dict], key: str) -> tuple[bool, str]:
    first, last = rows[0], rows[-1]
    bound = first[key] * (1 + C * math.log(last["unknowns"] / first["unknowns"]))
    return last[key] <= bound, f"{key}: {first[key]} → {last[key]} (bound {bound:.1f})"


@pytest.mark.bench
def test_bench_krylov_counts(monkeypatch):
    # the resource guard's 16 kB a 3D cell is `wcs check`'s peak with the direct method; the
    # iterative method measured ≈ 7.5 kB a cell (test_bench_iterative.py)
    monkeypatch.setitem(estimate.BYTES_PER_CELL, 3, 8.0e3)
    finest = dict(item.split(":") for item in os.environ.get("WCS_BENCH_KRYLOV", "2d:3 3d:2").split())
    rows, verdicts = [SEED, *dd_rows()], []
    for case, top in finest.items():
        mine = []
        for splits in range(int(top) + 1):
            mine.append(level(case, splits))
            print(mine[-1], flush=True)
            rows.append(mine[-1])
            path = write_table("bench_krylov_counts", FIELDS, [[r.get(k, "") for k in FIELDS] for r in rows])
            assert mine[-1]["status"] == 0
        if len(mine) > 1:
            verdicts += [(case, *grows_at_most_logarithmically(mine, key)) for key in ("linear_krylov", "cold_krylov_per_step")]
    print(path.read_text())
    for case, ok, text in verdicts:
        print(f"{case}: {text}: {'ok' if ok else 'FAILS'}")
    assert all(ok for _, ok, _ in verdicts), verdicts
