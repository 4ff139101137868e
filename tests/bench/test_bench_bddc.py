"""BDDC against GAMG on the glued first Newton step of the 3D block-on-block patch
(`test_bench_iterative.patch`): CG to the relative residual 1e-8, one process, each through
`Krylov` as the iterative method builds it (BDDC: the data set's subdomains by coordinate
bisection of the cells, `wcs.contact.bddc.model_parts`, `parts_of` of them unless given). Per
preconditioner: CG iterations, wall seconds of the first solve, CPU seconds of its set-up (the
first solve's less a second solve's, which keeps the preconditioner: for BDDC the subdomain
matrices included) and of a solve, the process's resident-set growth, the distance to the
direct solve.

Measured (2 cores shared by 6 engineers: CPU seconds, the wall column is load):
  unknowns   preconditioner  parts  its  set-up CPU  solve CPU  +RSS
  1.11e4     amg                    17     0.15       0.03      0.00 GB
  1.11e4     bddc              4    11     2.16       0.17      0.09 GB
  2.60e4     amg                    18     0.43       0.11      0.00 GB
  2.60e4     bddc             10    14     7.43       0.51      0.23 GB
  8.03e4     amg                    18     1.71       0.45      0.00 GB
  8.03e4     bddc             32    21    61.5        3.27      1.60 GB
  8.03e4     bddc             64    17    57.3        2.45      0.95 GB   (peak resident 4.3 GB)
  all within 5e-10 of the direct solve. BDDC's set-up is 14x, 17x, 36x GAMG's: it grows faster
  than the unknowns because all subdomains are one MATIS local matrix in this process, so
  PCBDDC's dense work (coarse basis functions, the deluxe scaling's Schur complements) spans
  every subdomain at once (`wcs.contact.bddc` docstring); set-up options tried at 1.1e4 and
  2.6e4 (Cholesky for the local solvers, no change of basis, plain scaling, no face or edge
  constraints, 5/10/20 parts) and 64 parts at 8.0e4 change it by at most 40% (plain scaling or
  no edges: 4x the iterations; no faces: 20 against 14; no change of basis: CG failed indefinite
  at 5 parts; 20 parts of 2.6e4: MUMPS out of workspace, a failed set-up).
  Ill-conditioned at 1.1e4 (the block's E and ν, "0.1 0.05 auto amg 2e3 0.35"): contrast 1e7
  (E 2e3): amg 29 its, 0.24 s CPU in all, bddc 18 its, 2.33 s; ν = 0.499: amg 127 its, 0.42 s,
  bddc 62 its, 3.14 s. GAMG's iterations grow more, BDDC's set-up still costs more. `wcs.choose.preconditioner` reads this table.

WCS_BENCH_BDDC="size face parts preconditioner [E nu]" (default "0.1 0.05 auto bddc"; parts
"auto": `parts_of`; E nu: the block's material); one preconditioner per process, so that the peak is its own. Command:
  cd tests/bench && WCS_BENCH_BDDC="0.05 0.02 auto bddc" python -m pytest test_bench_bddc.py -m bench -s
Table: results/bench/bench_bddc_<preconditioner>_<size>_<face>.csv.
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

from wcs import linalg  # noqa: E402

linalg.petsc()      # PETSc loaded before the timings, bound to its own BLAS as wcs loads it

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
    size, face, parts, which, *soft = os.environ.get("WCS_BENCH_BDDC", "0.1 0.05 auto bddc").split()
    size, face = float(size), float(face)
    study = patch(size, face)
    if soft:            # the block's material: a stiffness contrast to the base (E 2e10), or near incompressible
        E, nu = map(float, soft)
        study["scene"]["materials"]["soft"] = {"E": E, "nu": nu}
        study["uncertain"] = {"materials.soft.E": [0.8 * E, 1.2 * E]}
    model = Evaluator(load_study(study)).model
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
    row = [size, face, " ".join(soft), A.shape[0], which, parts if which == "bddc" else "", its, round(wall, 2),
           round(cpu - cg_cpu, 2), round(cg_cpu, 2), round(peak_gb() - base, 3), f"{err:.1e}"]
    path = write_table(f"bench_bddc_{which}_{size}_{face}{'_' + '_'.join(soft) if soft else ''}",
                       ["size", "face", "soft_E_nu", "unknowns", "preconditioner", "parts", "cg_its", "wall_s",
                        "setup_cpu_s", "solve_cpu_s", "peak_growth_gb", "rel_err_vs_direct"], [row])
    print(path.read_text())
