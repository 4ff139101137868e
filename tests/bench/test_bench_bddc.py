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

from wcs.contact.bddc import Bddc, bisection, components, subdomain_stiffness, transformed
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


def bddc_parts(model, c, Z, P, parts):
    """Each subdomain's unknowns and its part of the step's operator."""
    mesh = model.smesh.mesh
    part = bisection(mesh.p[:, mesh.t].mean(axis=1), parts)
    coefficients = model.stiffness_coefficients(c)
    out = []
    for s in range(parts):
        dofs, K_s = subdomain_stiffness(mesh.t, model.K.local, model.K.group, coefficients, np.flatnonzero(part == s))
        w, Kr_s = transformed(dofs, K_s, model.elim.T)
        out.append(transformed(w, Kr_s, Z, P))
    return [o[0] for o in out], [o[1] for o in out]


@pytest.mark.bench
def test_bench_bddc_against_amg():
    size, face, parts, which = os.environ.get("WCS_BENCH_BDDC", "0.1 0.05 8 bddc").split()
    size, face, parts = float(size), float(face), int(parts)
    model = Evaluator(load_study(patch(size, face))).model
    c = model.nominal
    A, b, Z, P = glued_step(model, c)
    direct = spsolve(A.tocsc(), b)
    base = peak_gb()
    t = time.perf_counter()
    if which == "bddc":
        dofs, local = bddc_parts(model, c, Z, P, parts)
        solver = Bddc(dofs, local, components(model.elim.T, 3), model.near_nullspace)
    else:
        solver = Krylov(model.near_nullspace)
    t_parts = time.perf_counter() - t
    x, its, ok = solver.solve(A, b, 1e-8)
    setup = t_parts + solver.timings.get("bddc_setup", 0.0) + solver.timings.get("gamg_setup", 0.0)
    assert ok
    err = np.linalg.norm(x - direct) / np.linalg.norm(direct)
    row = [size, face, A.shape[0], which, parts if which == "bddc" else "", getattr(solver, "faces", ""), its, round(setup, 2),
           round(solver.timings["cg"], 2), round(peak_gb() - base, 3), f"{err:.1e}"]
    path = write_table(f"bench_bddc_{which}_{size}_{face}",
                       ["size", "face", "unknowns", "preconditioner", "parts", "faces_setups", "cg_its", "setup_s", "solve_s",
                        "peak_growth_gb", "rel_err_vs_direct"], [row])
    print(path.read_text())
