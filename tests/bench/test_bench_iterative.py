"""solver.method iterative at scale: the 3D block-on-block patch
(studies/validation/block-on-block-3d.yaml) with its contact face refined, frictionless, one
thread. Measured in one run, as ratios to the linear solve:

- `linear`: one CG + GAMG solve (set-up + solve, to the relative residual 1e-8) of the first
  Newton step's system — the linear elasticity of the same mesh with the two bodies glued;
- `cold`: the iterative contact solve from the glued start (`solve_contact_iterative`, Newton
  to 1e-8, CG to 1e-8); goal ≤ 10× linear;
- `warm`: the same contact solve after new loads and a new Young's modulus of the block,
  started from the cold answer; goal ≤ 3× linear;
- peak memory of the process (resident set); goal ≤ 8 GB. Beside it the peak and the resident
  set once the model is built (mesh, assembly, criteria: not the contact method's), the cells,
  the entries of the reduced K and the guard's estimate of one evaluation's peak
  (`wcs.scene.estimate.evaluation_cost`).

Columns: the mesh size and the contact face's size, unknowns, contact nodes, the seconds of the
model's build (`model_s`), of the linear solve and its CG iterations, of the cold solve with its
Newton steps and CG iterations (and its phases, `cold_timings_s`: rows, elimination, matrix,
GAMG set-up, CG), of the warm solve likewise, the two ratios to the linear solve, the peak and
the resident set once the model is built (`model_peak_gb`, `model_rss_gb`), the process's peak
(`peak_gb`), the cells, the entries of the reduced K and the guard's estimate (`estimate_gb`).
Each ratio's two times are taken in one run; the seconds carry the run's load (its stamp).

What the measurements taught (`wcs.fem`, `wcs.model`, `wcs.contact.iterative`): at 1e6 unknowns the
memory goal failed in the model's build before any solve, until the cell matrices were made chunk
by chunk from the gradients, the reduction's terms chunk by chunk and the strain operator without
COO triplets; the contact solve then still added more than the goal left, until the solve held
one copy of K (no K + 0 a step, PETSc on the step's arrays, K(c) not held beside the reduced K,
the reduced K on the pattern's indices, no strain matrix). The CG iterations of one linear solve
grow slowly under refinement (test_bench_krylov_counts.py asserts the growth).

WCS_BENCH_ITERATIVE="size face" sets the mesh size and the contact face's size (default
"0.0155 0.01": ≈ 1e6 unknowns, ≈ 1.2e4 contact nodes; above 3 GB: run it under the big-memory
lock). Table: results/bench/bench_iterative.csv (docs/benchmarks.md), one row a run.
"""
from __future__ import annotations

import os
import resource
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from common import ROOT, write_table

from wcs import linalg  # noqa: E402

linalg.petsc()      # PETSc loaded before the timings, bound to its own BLAS as wcs loads it

from wcs.contact.iterative import Krylov, _Rows, _Stepper, node_blocks, solve_contact_iterative
from wcs.scene.estimate import EvaluationFacts, evaluation_cost
from wcs.model.evaluation import Evaluator
from wcs import load_study

PATCH = ROOT / "studies" / "validation" / "block-on-block-3d.yaml"


def patch(size: float, face: float) -> dict:
    d = yaml.safe_load(PATCH.read_text())
    d["scene"]["mesh"] = {"size": size, "max_cells": 10**8,
                          "refine": [{"box": [0, 0, -2 * face, 1, 1, 2 * face], "size": face}]}
    d["solver"] = {"method": "iterative"}
    return d


def peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6


def rss_gb() -> float:
    """The resident set now (the model's share before the solves)."""
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e9


def problem(model, c):
    _, Kr, rhs, u0 = model.reduced_system(c, None)
    z = model.zone
    return dict(K=Kr, f=rhs, Bn=model.Bn_r, Bt=model.Bt_r, d=z.gap - z.Bn @ u0, w=z.weight, g=c.slip, R=model.R_r)


def measure(size: float, face: float) -> list:
    t = time.perf_counter()
    ev = Evaluator(load_study(patch(size, face)))
    model = ev.model
    t_model = time.perf_counter() - t
    c = model.nominal
    P = problem(model, c)
    n, m = P["K"].shape[0], P["Bn"].shape[0]
    N = model.near_nullspace
    model_peak, model_rss = peak_gb(), rss_gb()
    nnz = model.reduce.pattern.nnz
    estimate = evaluation_cost(EvaluationFacts(dimension=3, unknowns=n, stiffness_nnz=nnz, contact_rows=3 * m),
                               "iterative")[0] / 1e9

    t = time.perf_counter()          # the glued system of the first Newton step, solved once, fresh
    C = model.contact_rows
    blocks = node_blocks(model, P["K"])         # GAMG on the nodes, as the method's own (`_solve_problem`)
    def krylov():
        return Krylov(np.reshape(N, (n, -1)), blocks=blocks)
    step = _Stepper(P["K"], P["f"], C, np.r_[P["d"], np.zeros(2 * m)], _Rows(C, m, 2), N, krylov=krylov())
    step.solve(np.ones(3 * m, dtype=bool), np.zeros(3 * m), np.zeros(m), np.ones(3 * m), 2, 1e-8, np.zeros(n), 1e-8)
    t_linear, linear_its = time.perf_counter() - t, step.krylov
    step.krylov_solver.close()
    del step

    t = time.perf_counter()
    solver = krylov()
    cold = solve_contact_iterative(**P, tol=1e-8, rtol=1e-8, near_nullspace=N, krylov=solver)
    solver.close()
    t_cold = time.perf_counter() - t
    assert cold.status == 0, cold.message

    del P                            # an evaluation holds its own data set's matrices only
    upper = np.concatenate([[e.upper] * e.points for e in ev.study.uncertain])   # new load and block modulus
    P2 = problem(model, ev.map.coefficients(upper))
    t = time.perf_counter()
    solver = krylov()
    warm = solve_contact_iterative(**P2, tol=1e-8, rtol=1e-8, near_nullspace=N, warm=cold, krylov=solver)
    solver.close()
    t_warm = time.perf_counter() - t
    assert warm.status == 0, warm.message
    return [size, face, n, m, round(t_model, 1), round(t_linear, 2), linear_its, round(t_cold, 2), cold.iterations,
            cold.krylov_iterations, round(t_warm, 2), warm.iterations, warm.krylov_iterations,
            round(t_cold / t_linear, 2), round(t_warm / t_linear, 2), round(model_peak, 2), round(model_rss, 2),
            round(peak_gb(), 2), ev.smesh.mesh.t.shape[1], nnz, round(estimate, 2),
            {k: round(v, 1) for k, v in cold.timings.items()}]


@pytest.mark.bench
def test_bench_iterative_contact_at_scale():
    size, face = (float(v) for v in os.environ.get("WCS_BENCH_ITERATIVE", "0.0155 0.01").split())
    row = measure(size, face)
    path = write_table("bench_iterative", ["size", "face", "unknowns", "contact_nodes", "model_s", "linear_s",
                                           "linear_its", "cold_s", "newton", "krylov", "warm_s", "warm_newton",
                                           "warm_krylov", "cold_over_linear", "warm_over_linear", "model_peak_gb",
                                           "model_rss_gb", "peak_gb", "cells", "nnz", "estimate_gb",
                                           "cold_timings_s"], [row])
    print(path.read_text())
