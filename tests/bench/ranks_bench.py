"""One 3D contact evaluation by `solver.method: iterative` on the ranks of `mpiexec -n k` (k = 1:
the sequential solve; k > 1: one group, `solver.ranks_per_evaluation: k`), for
test_bench_ranks.py: `mpiexec -n k python ranks_bench.py SIZE FACE OUT.json`; with
`laplace SIDE OUT.json` instead, the PETSc-only control (`laplace`).

The 3D block-on-block patch of test_bench_iterative.py (its contact face refined to FACE, the
rest meshed at SIZE), built on every rank (the model is replicated). Timed: the nominal data
set (cold: Newton from the glued start) and the upper corner of the box (new loads and a new
modulus of the block: warm from the nominal answer), each a whole evaluation (the data set's
K(c), the contact solve, the criteria), with the contact solve's own timings (rows, eliminate,
matrix, gamg_setup, cg: rank 0's). Rank 0 writes the JSON.
"""
from __future__ import annotations

import json
import sys
import time

import numpy as np

import cvxpy  # noqa: F401  (the floating block's solvability check imports it on first use: seconds, once a process)
from wcs import linalg  # noqa: E402

PETSc = linalg.petsc()      # loaded before the timings, bound to its own BLAS as wcs loads it

from test_bench_iterative import patch, peak_gb
from wcs.model.evaluation import Evaluator
from wcs.group import spanning
from wcs.app.parallel import groups, world
from wcs.scene import estimate
from wcs.study import load_study


def evaluation(ev, x, comm) -> dict:
    """One evaluation at x spanning `comm`: its seconds (every rank done), contact timings, counts."""
    if comm is not None:
        comm.Barrier()
    t = time.perf_counter()
    out = ev.evaluate(x)
    if comm is not None:
        comm.Barrier()
    wall = time.perf_counter() - t
    assert out.status == 0, out.message
    raw = out.state.raw
    return {"seconds": wall, "newton": raw.iterations, "krylov": raw.krylov_iterations,
            "contact": {k: v for k, v in raw.timings.items()}, "phi": {k: float(v) for k, v in out.phi.items()}}


def main(size: float, face: float, out: str) -> None:
    estimate.BYTES_PER_CELL[3] = 8.0e3          # the bench's measured bytes a cell (test_bench_iterative.py)
    comm = world()
    k = 1 if comm is None else comm.size
    d = patch(size, face)
    d["solver"]["ranks_per_evaluation"] = k
    study = load_study(d)
    group = groups(comm, k)[0]
    t = time.perf_counter()
    ev = Evaluator(study)
    model_s = time.perf_counter() - t
    upper = np.concatenate([[e.upper] * e.points for e in study.uncertain])
    with spanning(group):
        cold = evaluation(ev, study.nominal(), group)
        warm = evaluation(ev, upper, group)
    row = {"ranks": k, "size": size, "face": face, "unknowns": int(ev.model.near_nullspace.shape[0]),
           "contact_nodes": int(ev.model.Bn_r.shape[0]), "model_s": model_s, "cold": cold, "warm": warm,
           "peak_gb": peak_gb()}
    peaks = [peak_gb()] if comm is None else comm.gather(peak_gb())
    if comm is None or comm.rank == 0:
        row["peak_gb_ranks"] = peaks
        with open(out, "w") as fh:
            json.dump(row, fh)


def laplace(side: int, out: str) -> None:
    """The control: CG + GAMG to 1e-8 on the 7-point Laplacian of a side³ grid, distributed as
    the contact solves are (`wcs.contact.distributed.Layout`): what this machine gives PETSc
    itself on this many ranks now (set-up, solve)."""
    import scipy.sparse as sp
    from wcs.contact.distributed import Layout
    comm = world()
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(side, side))
    I = sp.identity(side)
    A = (sp.kron(sp.kron(T, I), I) + sp.kron(sp.kron(I, T), I) + sp.kron(sp.kron(I, I), T)).tocsr()
    layout = Layout(comm, A.shape[0], PETSc)
    barrier = comm.Barrier if comm is not None else (lambda: None)
    barrier()
    t = time.perf_counter()
    M = layout.matrix(A, PETSc)
    ksp = PETSc.KSP().create(layout.petsc)
    ksp.setType("cg")
    ksp.getPC().setType("gamg")
    ksp.setOperators(M, M)
    ksp.setTolerances(rtol=1e-8)
    ksp.setUp()
    barrier()
    t1 = time.perf_counter()
    x, b = M.createVecs()
    b.set(1.0)
    ksp.solve(b, x)
    barrier()
    t2 = time.perf_counter()
    if comm is None or comm.rank == 0:
        with open(out, "w") as fh:
            json.dump({"unknowns": A.shape[0], "setup": t1 - t, "solve": t2 - t1,
                       "iterations": ksp.getIterationNumber()}, fh)


if __name__ == "__main__":
    if sys.argv[1] == "laplace":
        laplace(int(sys.argv[2]), sys.argv[3])
    else:
        main(float(sys.argv[1]), float(sys.argv[2]), sys.argv[3])
