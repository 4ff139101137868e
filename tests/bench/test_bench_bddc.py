"""BDDC against GAMG on the glued first Newton step of the 3D block-on-block patch
(`test_bench_iterative.patch`): CG to the relative residual 1e-8, one process, each through
`Krylov` as the iterative method builds it (BDDC: the data set's subdomains by coordinate
bisection of the cells, `wcs.contact.bddc.model_parts`, `parts_of` of them unless given). Per
preconditioner: CG iterations, wall seconds of the first solve, CPU seconds of its set-up (the
first solve's less a second solve's, which keeps the preconditioner: for BDDC the subdomain
matrices included) and of a solve, the process's resident-set growth, the distance to the
direct solve.

What the measurements showed (the numbers are the tables'): both preconditioners agree with the
direct solve; BDDC's CG iterations are of GAMG's order (fewer on the smaller meshes), but its
set-up costs many times GAMG's and grows faster than the unknowns, because all subdomains are
one MATIS local matrix in this process, so PCBDDC's dense work (coarse basis functions, the
deluxe scaling's Schur complements) spans every subdomain at once (`wcs.contact.bddc`
docstring). The set-up options
tried (Cholesky for the local solvers, no change of basis, plain scaling, no face or edge
constraints, other part counts) did not change that order: plain scaling or no edges multiplied
the iterations, no faces raised them, no change of basis made CG fail (indefinite), and many
parts of a small mesh ran MUMPS out of workspace (a failed set-up). Ill-conditioned (the block's
E and ν given: a stiffness contrast, or ν near 1/2), GAMG's iterations grow more than BDDC's, but
BDDC's set-up still costs more than GAMG's whole solve. `wcs.choose.preconditioner` (its
BDDC_SETUP_RATIO, BDDC_SETUP_RATIO_RANKS) rests on these tables.

On 2 ranks (one group, each rank its share of the subdomains: a distributed MATIS, or GAMG on
the rows, `wcs.contact.distributed`) the same step, the CPU seconds summed over the ranks, the
resident-set growth the largest of a rank's. BDDC's iterations and answer are the same on 1 and
2 ranks; its set-up's CPU time is shared out by the second rank, not reduced; GAMG's grows on 2
ranks of a loaded machine (MPI's waits count as CPU time).

Columns: the mesh size and face, the block's E and ν if given, unknowns, ranks, preconditioner,
parts (BDDC), CG iterations, wall seconds of the first solve, CPU seconds of the set-up and of a
solve, the peak resident-set growth (GB, the largest of a rank's), the relative distance to the
direct solve, and the machine's load (the wall column follows it: compare CPU seconds).

WCS_BENCH_BDDC="size face parts [E nu]" (default "0.1 0.05 auto"; parts "auto": `parts_of`; E nu:
the block's material), WCS_BENCH_BDDC_RANKS (default "1 2"); each preconditioner on each rank
count in its own `mpiexec -n` launch, so that the peak is its own. Command:
  cd tests/bench && WCS_BENCH_BDDC="0.05 0.02 auto" python -m pytest test_bench_bddc.py -m bench -s
Table: results/bench/bench_bddc_<size>_<face>[_E_nu].csv (docs/benchmarks.md; a row per
preconditioner and rank count).
"""
from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse.linalg import spsolve

from common import ROOT, write_table
from test_bench_iterative import patch, problem

from wcs import linalg  # noqa: E402

linalg.petsc()      # PETSc loaded before the timings, bound to its own BLAS as wcs loads it
from mpi4py import MPI  # noqa: E402

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


def bddc_parts(model, c, parts, owned=None):
    """The data set's subdomains (`model_parts`, as the iterative method makes them; this rank's: `owned`)."""
    return model_parts(model.smesh.mesh, model.K, model.elim.T, model.stiffness_coefficients(c),
                       model.near_nullspace, parts, owned)


def run(ranks: int, out: Path, *args) -> dict:
    """This file's `main(ARGS OUT)` under `mpiexec -n ranks`: rank 0's JSON."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_"))}
    env["PYTHONPATH"] = str(ROOT)
    done = subprocess.run([str(Path(sys.executable).parent / "mpiexec"), "-n", str(ranks), sys.executable, __file__,
                           *map(str, args), str(out)], env=env, capture_output=True, text=True, timeout=7200,
                          cwd=Path(__file__).parent)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(out.read_text())


def main(size, face, parts, which, *rest) -> None:
    """The glued step by CG with `which` (amg | bddc) on the ranks of this launch (one group):
    iterations, wall seconds of the first solve, CPU seconds (summed over the ranks) of its
    set-up (the first solve's less a second's, which keeps the preconditioner) and of a solve,
    the largest resident-set growth of a rank, the distance to the direct solve (rank 0)."""
    from wcs.app.parallel import world
    from wcs.group import share, spanning
    *soft, out = rest
    comm = world()
    study = patch(float(size), float(face))
    if soft:            # the block's material: a stiffness contrast to the base (E 2e10), or near incompressible
        E, nu = map(float, soft)
        study["scene"]["materials"]["soft"] = {"E": E, "nu": nu}
        study["uncertain"] = {"materials.soft.E": [0.8 * E, 1.2 * E]}
    ranks = 1 if comm is None else comm.size
    study["solver"]["ranks_per_evaluation"] = ranks
    model = Evaluator(load_study(study)).model
    c = model.nominal
    A, b, Z, P = glued_step(model, c)
    parts = parts_of(A.shape[0], ranks) if parts == "auto" else int(parts)
    total = (lambda v: v) if comm is None else (lambda v: comm.allreduce(v))
    base = peak_gb()
    if comm is not None:
        comm.Barrier()
    t, cpu = time.perf_counter(), time.process_time()
    with spanning(comm):
        solver = Krylov(model.near_nullspace, parts=bddc_parts(model, c, parts, range(*share(parts)))
                        if which == "bddc" else None)
        step = (Z, P, None, None)
        x, its, ok = solver.solve(A, b, 1e-8, step)
        cpu = time.process_time() - cpu
        if comm is not None:
            comm.Barrier()
        wall = time.perf_counter() - t
        assert ok
        again = time.process_time()
        assert solver.solve(A, b, 1e-8, step)[1] == its and solver.builds == 1     # the kept preconditioner
        cg_cpu = time.process_time() - again
        solver.close()
    growth = peak_gb() - base
    cpu, cg_cpu, growth = total(cpu), total(cg_cpu), growth if comm is None else comm.allreduce(growth, op=MPI.MAX)
    if comm is None or comm.rank == 0:
        direct = spsolve(A.tocsc(), b)
        err = np.linalg.norm(x - direct) / np.linalg.norm(direct)
        Path(out).write_text(json.dumps(
            {"unknowns": A.shape[0], "parts": parts if which == "bddc" else "", "its": its, "wall": wall,
             "setup_cpu": cpu - cg_cpu, "solve_cpu": cg_cpu, "growth": growth, "err": err}))


@pytest.mark.bench
def test_bench_bddc_against_amg(tmp_path):
    size, face, parts, *soft = os.environ.get("WCS_BENCH_BDDC", "0.1 0.05 auto").split()
    rows = []
    for ranks in map(int, os.environ.get("WCS_BENCH_BDDC_RANKS", "1 2").split()):
        for which in ("amg", "bddc"):
            r = run(ranks, tmp_path / f"{which}{ranks}.json", size, face, parts, which, *soft)
            assert r["err"] <= 1e-6
            rows.append([size, face, " ".join(soft), r["unknowns"], ranks, which, r["parts"], r["its"],
                         round(r["wall"], 2), round(r["setup_cpu"], 2), round(r["solve_cpu"], 2),
                         round(r["growth"], 3), f"{r['err']:.1e}", round(os.getloadavg()[0], 1)])
    path = write_table(f"bench_bddc_{size}_{face}{'_' + '_'.join(soft) if soft else ''}",
                       ["size", "face", "soft_E_nu", "unknowns", "ranks", "preconditioner", "parts", "cg_its",
                        "wall_s", "setup_cpu_s", "solve_cpu_s", "peak_growth_gb", "rel_err_vs_direct", "load"], rows)
    print(path.read_text())


if __name__ == "__main__":
    main(*sys.argv[1:])
