"""`solver.ranks_per_evaluation` (issue 25, "Distributed"): one 3D contact evaluation by the
iterative method on 1 rank and on 2 ranks (one group of 2), in one run — the 3D block-on-block
patch of test_bench_iterative.py, each evaluation whole (the data set's K(c), the contact
solve, the criteria), cold (the nominal data set) and warm (the upper corner, from the nominal
answer). Goal: 2 ranks ≥ 1.6× faster than 1. Written: the ratios, where the time goes at each
rank count (model build; per evaluation: solvability LP, rows, elimination, PETSc matrix,
GAMG set-up, CG, the rest = K(c) and criteria), the iterations, the peak memory of each rank
and the machine's load (2 cores shared with other jobs). The control rows `laplace after ...`:
CG + GAMG on a 3D Laplacian of as many unknowns, distributed the same way, on 1 and 2 ranks
right after each rank count's evaluations — what the machine gives PETSc itself at that
moment (its gamg_setup_s and cg_s columns). Table bench_ranks_model: the scaling model of
docs/scaling.md (scaling_model.py) from this run's cold evaluation on one rank.

Measured since K(c)'s assembly and the pivots are shared out over the group (2.0e5 unknowns,
3022 contact nodes, the default mesh; wcs 74a95d0, load 19–22 throughout):
  1 rank cold 104.1 s (GAMG set-up 37.0, CG 44.4, matrix 9.0, elimination 3.3, rest 9.9), warm
  83.1 s; 2 ranks cold 65.1 s (1.60×: set-up 19.9, CG 29.2, matrix 4.6, elimination 3.7, rest
  7.3), warm 59.7 s (1.39×); 1.80 GB on one rank, 1.83 / 1.87 GB a rank on two. The control:
  0.95× after the 1-rank run, 0.58× after the 2-rank run — no second core was free, so these
  ratios measure the share of an oversubscribed machine two processes get against one (a fair
  scheduler gives each process its share), not the code's scaling: the 1.6× goal is not shown.
  Model (bench_ranks_model) from this loaded run: 101 s (C = 0) to 225 s (C = 1/4) for 1e8
  unknowns on 512 ranks — the measured phases' seconds carry the load 22 of their run.

Measured at 1.02e6 unknowns, 11821 contact nodes (WCS_BENCH_RANKS="0.0155 0.01", wcs 99ac1b8, an
idle machine: load 1.0 on one rank, 2.1 on two): 1 rank cold 126.0 s (GAMG set-up 35.8, CG 66.5,
matrix 9.3, elimination 2.2, rest 11.8), warm 95.4 s; 2 ranks cold 75.6 s (1.67×: set-up 25.1, CG
33.2, matrix 5.1), warm 53.3 s (1.79×); model build 109 s on one rank, 118 s on two (replicated);
peak 7.43 GB on one rank, 7.86 / 8.15 GB a rank on two (the model is replicated on each). The
control: 1.55× after the 1-rank run, 1.39× after the 2-rank run (a 3D Laplacian of 1.03e6
unknowns, 10 CG iterations: its set-up does not halve). The 1.6× goal holds cold and warm.

Measured before (the model, K(c), pivots, criteria replicated on every rank of the group):
  0.05/0.025  5.7e4 unknowns, 1933 contact nodes, load 7.2: 1 rank cold 6.2 s (GAMG set-up 2.2,
              CG 2.5, replicated: elimination 0.4, K(c) and criteria 0.6, solvability 0.07), warm
              5.1 s; 2 ranks cold 8.3 s (0.75×), warm 9.3 s (0.54×); the PETSc-only control 0.44×
              (set-up 0.34 → 0.75 s): the machine gave no second core, so the 1.6× goal could not be
              measured here. Replicated share at 1 rank: 17 % cold, 11 % warm — with PETSc's own 2-rank
              efficiency on an idle machine (issue 25: set-up 1.75×, solve 1.8×) that predicts
              ≈ 1.55× cold and ≈ 1.6× warm.
  0.03/0.02   1.52e5 unknowns, 3016 contact nodes, load 10–12 (big-memory lock held): 1 rank cold
              47.8 s (GAMG set-up 15.1, CG 23.6, matrix 4.1, elimination 1.9, K(c) and criteria 2.7),
              warm 40.2 s; 2 ranks cold 34.7 s (1.38×: set-up 10.9, CG 15.3, matrix 2.7, elimination
              2.0, rest 3.5), warm 23.7 s (1.70×: set-up 10.1, CG 7.5); 2.06 / 2.11 GB a rank (the
              model is replicated); the control 0.93× at that moment.
  0.025/0.02  2.00e5 unknowns, 3022 contact nodes, load 3.3–4.8 (lock held): 1 rank cold 35.0 s
              (GAMG set-up 11.2, CG 18.6, matrix 2.4, elimination 1.2, rest 1.5), warm 26.8 s; 2 ranks
              cold 23.5 s (1.49×: set-up 7.1 = 1.57×, CG 10.2 = 1.83×, matrix 1.2 = 1.95×, elimination
              1.5 and rest 3.2 replicated), warm 18.1 s (1.48×); 2.65 / 2.71 GB a rank; the control 0.95×.
              The goal 1.6× is not reached here; the replicated part (elimination's pivots and Z, K(c),
              criteria: 8 % at 1 rank) bounds it at ≈ 1.85× with perfect scaling of the rest.

WCS_BENCH_RANKS="size face" sets the mesh (default "0.025 0.02": ≥ 2e5 unknowns). Run it under the big-memory
lock: `flock /tmp/wcs-bigmem.lock prlimit --as=... pytest -m bench tests/bench/test_bench_ranks.py`.
Tables: results/bench/bench_ranks.csv, results/bench/bench_ranks_model.csv.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import scaling_model
from common import ROOT, write_table

BIN = Path(sys.executable).parent
# the contact solve's timings; matrix: Zᵀ Kt Z (this rank's rows) into PETSc's form
PARTS = ("solvability", "rows", "eliminate", "matrix", "gamg_setup", "cg")


def run(ranks: int, out: Path, *args) -> dict:
    """ranks_bench.py ARGS OUT on `ranks` ranks: its JSON, with the machine's load after it."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_"))}
    env["PYTHONPATH"] = str(ROOT)
    done = subprocess.run([str(BIN / "mpiexec"), "-n", str(ranks), sys.executable, str(Path(__file__).with_name(
        "ranks_bench.py")), *map(str, args), str(out)], env=env, capture_output=True, text=True, timeout=3600)
    assert done.returncode == 0, done.stderr[-3000:]
    return {**json.loads(out.read_text()), "load": os.getloadavg()[0]}


def row(r: dict, case: str, one: dict) -> list:
    e = r[case]
    parts = [round(e["contact"].get(p, 0.0), 2) for p in PARTS]
    rest = round(e["seconds"] - e["contact"]["total"], 2)
    return [r["ranks"], case, r["unknowns"], r["contact_nodes"], round(r["model_s"], 1), round(e["seconds"], 2),
            round(one[case]["seconds"] / e["seconds"], 2), *parts, rest, e["newton"], e["krylov"],
            "/".join(f"{p:.2f}" for p in r["peak_gb_ranks"]), round(r["load"], 1)]


def control(folder: Path, side: int, tag: str) -> list[dict]:
    """The PETSc-only control on 1 and 2 ranks, now: what the machine gives PETSc itself."""
    return [run(k, folder / f"laplace{k}-{tag}.json", "laplace", side) for k in (1, 2)]


def control_rows(lap: list[dict], after: str) -> list[list]:
    """The control's rows (set-up and solve in the gamg_setup_s and cg_s columns)."""
    one = lap[0]["setup"] + lap[0]["solve"]
    return [[k, f"laplace after {after}", r["unknowns"], 0, 0.0, round(r["setup"] + r["solve"], 2),
             round(one / (r["setup"] + r["solve"]), 2), 0.0, 0.0, 0.0, 0.0, round(r["setup"], 2), round(r["solve"], 2),
             0.0, 0, r["iterations"], "", round(r["load"], 1)] for k, r in zip((1, 2), lap)]


def model_rows(one: dict) -> list[list]:
    """The scaling model (scaling_model.py, docs/scaling.md) from this run's cold evaluation on
    one rank: each phase at the measured size, and for 1e8 unknowns on 512 ranks with the
    iterations flat (C = 0) and growing by 1 + ln(N/N1)/4."""
    cold = one["cold"]
    seconds = {**{p: cold["contact"].get(p, 0.0) for p in PARTS},
               "rest": cold["seconds"] - cold["contact"]["total"]}
    cases = [("measured", one["unknowns"], 1, 0.0), ("predicted C=0", 1e8, 512, 0.0),
             ("predicted C=1/4", 1e8, 512, 0.25)]
    out = []
    for name, n, p, c in cases:
        t = scaling_model.predict(seconds, one["unknowns"], cold["krylov"], n, p, c)
        out.append([name, f"{n:.3g}", p, round(n / p), *(round(t[k], 2) for k in MODEL_PHASES),
                    round(sum(t.values()), 1)])
    return out


MODEL_PHASES = ("solvability", "rows", "eliminate", "matrix", "rest", "gamg_setup", "cg", "communication")


@pytest.mark.bench
def test_bench_one_and_two_ranks_per_evaluation(tmp_path):
    size, face = (float(v) for v in os.environ.get("WCS_BENCH_RANKS", "0.025 0.02").split())
    one = run(1, tmp_path / "one.json", size, face)
    side = round(one["unknowns"] ** (1 / 3))           # the control: PETSc alone, as many unknowns, now
    lap1 = control(tmp_path, side, "one")
    two = run(2, tmp_path / "two.json", size, face)
    lap2 = control(tmp_path, side, "two")
    for case in ("cold", "warm"):           # the same answer to the solver's tolerance
        for c, v in one[case]["phi"].items():
            assert two[case]["phi"][c] == pytest.approx(v, rel=1e-6), (case, c)
    rows = [row(r, case, one) for r in (one, two) for case in ("cold", "warm")]
    rows += control_rows(lap1, "1 rank") + control_rows(lap2, "2 ranks")
    path = write_table("bench_ranks", ["ranks", "case", "unknowns", "contact_nodes", "model_s", "evaluation_s",
                                       "speedup_over_1_rank", *(f"{p}_s" for p in PARTS), "rest_s", "newton",
                                       "krylov", "peak_gb_per_rank", "load"], rows)
    print(path.read_text())
    path = write_table("bench_ranks_model", ["case", "unknowns", "ranks", "unknowns_per_rank",
                                             *(f"{p}_s" for p in MODEL_PHASES), "evaluation_s"], model_rows(one))
    print(path.read_text())
