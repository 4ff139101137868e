"""BDDC against GAMG on the glued first Newton step of the 3D block-on-block patch
(`test_bench_iterative.patch`): CG to the relative residual 1e-8, one process, the subdomains
by coordinate bisection of the cells (`wcs.contact.bddc`). Per preconditioner: CG iterations
(BDDC: and whether the set-up with the faces' change of basis was needed, `Bddc.faces`),
set-up and solve seconds (BDDC's set-up includes making the subdomains' matrices from the cell
matrices), the process's resident-set growth over the solve, and the answer's distance to the
direct solve's.

Measured (2 cores shared, load ≈ 15; rows of this bench before the faces column was added):
  0.1/0.05   1.1e4 unknowns: bddc 8 parts 10 its, set-up 5.6 s, CG 0.28 s, +0.20 GB;
                             amg 17 its, set-up 0.4 s, CG 0.07 s
  0.05/0.02  8.0e4 unknowns: bddc 16 parts 34 its, set-up 201 s, CG 13.4 s, +1.68 GB;
                             bddc 32 parts 21 its, set-up 72 s, CG 8.3 s, +1.61 GB;
                             amg 18 its, set-up 1.9 s, CG 0.59 s
  all within 4e-10 of the direct solve. BDDC's set-up in one process (all subdomains' LU, the
  change of basis) is 15–100× GAMG's: not yet a usable preconditioner here.

WCS_BENCH_BDDC="size face parts preconditioner" (default "0.1 0.05 8 bddc"); one preconditioner
per process, so that the peak is its own. Table: results/bench/bench_bddc.csv.
"""
from __future__ import annotations

import os
import resource
import time

import numpy as np
import pytest
from scipy.sparse.linalg import spsolve

from common import write_table
from test_bench_iterative import patch, problem

import dolfinx_solver  # noqa: F401  (PETSc loaded before the timings)
from petsc4py import PETSc  # noqa: F401

from wcs.contact.bddc import model_parts, parts_of
from wcs.contact.iterative import Krylov, _Rows, _basis, _eliminated, _pivots
from wcs.model.evaluation import Evaluator
from wcs import load_study


def peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6


def glued_step(model, c):
    """(A, b, Z, P) of the first Newton step: every contact row closed and stuck."""
    P_ = problem(model, c)
    K, f = P_["K"], P_["f"]
    m = P_["Bn"].shape[0]
    C = model.contact_rows
    rows, P, Binv = _pivots(_Rows(C, m, 2), np.ones(3 * m, dtype=bool), 2)
    Z, ub = _basis(C, rows, P, Binv, np.r_[P_["d"], np.zeros(2 * m)][rows])
    return _eliminated(Z, K, K, P), Z.T @ (f - K @ ub), Z, P


def bddc_parts(model, c, parts):
    """The data set's subdomains (`model_parts`, as the iterative method makes them)."""
    return model_parts(model.smesh.mesh, model.K, model.elim.T, model.stiffness_coefficients(c),
                       model.near_nullspace, parts)


@pytest.mark.bench
def test_bench_bddc_against_amg():
    size, face, parts, which = os.environ.get("WCS_BENCH_BDDC", "0.1 0.05 auto bddc").split()
    size, face = float(size), float(face)
    model = Evaluator(load_study(patch(size, face))).model
    c = model.nominal
    A, b, Z, P = glued_step(model, c)
    direct = spsolve(A.tocsc(), b)
    parts = parts_of(A.shape[0]) if parts == "auto" else int(parts)
    base = peak_gb()
    t, cpu = time.perf_counter(), time.process_time()
    solver = Krylov(model.near_nullspace, parts=bddc_parts(model, c, parts) if which == "bddc" else None)
    step = (Z, P, None, None)
    x, its, ok = solver.solve(A, b, 1e-8, step)
    wall, cpu = time.perf_counter() - t, time.process_time() - cpu
    assert ok
    err = np.linalg.norm(x - direct) / np.linalg.norm(direct)
    again = time.process_time()
    assert solver.solve(A, b, 1e-8, step)[1] == its and solver.builds == 1     # the kept preconditioner
    cg_cpu = time.process_time() - again
    row = [size, face, A.shape[0], which, parts if which == "bddc" else "", its, round(wall, 2),
           round(cpu - cg_cpu, 2), round(cg_cpu, 2), round(peak_gb() - base, 3), f"{err:.1e}"]
    path = write_table(f"bench_bddc_{which}_{size}_{face}",
                       ["size", "face", "unknowns", "preconditioner", "parts", "cg_its", "wall_s",
                        "setup_cpu_s", "solve_cpu_s", "peak_growth_gb", "rel_err_vs_direct"], [row])
    print(path.read_text())
