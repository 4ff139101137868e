"""Benchmark of the contact solver at ~1e5 unknowns; all ratios measured in one run.

Two blocks (tests/test_contact_solver.two_blocks, N=150: 112 950 unknowns, 151 contact
nodes), Tresca partial slip. Reference: one SuperLU factor + solve of the same K with the
symmetric settings of wcs.linalg. Re-solve: new Young moduli (new K values, same pattern)
and a new load, warm-started from the previous result. Writes results/bench/contact_solver.csv.

Run: .venv/bin/python tests/bench/test_bench_contact.py   (or `make bench`)
"""
import pathlib
import sys
import time

import numpy as np
import pytest
import scipy.sparse.linalg as spla

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
from tests.contact.test_solver import args, two_blocks  # noqa: E402

from common import write_table  # noqa: E402

from wcs import linalg  # noqa: E402
from wcs.contact import solver as cs  # noqa: E402
from wcs.contact.qp import solve_contact_qp  # noqa: E402
from wcs.status import Status  # noqa: E402



def best_of(fn, repeat=3):
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def run(N=150, with_qp=True):
    P0 = two_blocks(N)
    P1 = two_blocks(N, E=(1.3, 0.8), shear=0.005)
    m = len(P0["w"])
    g = np.full(m, 0.006)
    K = P0["K"].tocsc()
    t_slu, _ = best_of(lambda: spla.splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                         options={"SymmetricMode": True}).solve(P0["f"]))
    t_first, r0 = best_of(lambda: cs.solve_contact(*args(P0), g=g))
    assert r0.status == Status.SOLVED, r0.message

    def resolve():  # each repeat: back to data set 0, then the timed switch to data set 1
        base = cs.solve_contact(*args(P0), g=g, warm=r0)
        t = time.perf_counter()
        r = cs.solve_contact(*args(P1), g=g, warm=base)
        return time.perf_counter() - t, r
    t_re, r1 = min((resolve() for _ in range(3)), key=lambda x: x[0])
    assert r1.status == Status.SOLVED, r1.message
    cold1 = cs.solve_contact(*args(P1), g=g)
    rows = {
        "unknowns": K.shape[0], "contact_nodes": m, "backend": linalg.backend(),
        "superlu_factor_solve_s": t_slu, "first_solve_s": t_first, "resolve_s": t_re,
        "first_over_superlu": t_first / t_slu, "resolve_over_superlu": t_re / t_slu,
        "newton_iterations_first": r0.iterations, "newton_iterations_resolve": r1.iterations,
        "newton_iterations_cold_data1": cold1.iterations,
        "resolve_vs_cold_rel_diff_u": np.linalg.norm(r1.u - cold1.u) / np.linalg.norm(cold1.u),
        "first_factor_s": r0.timings["factor"], "first_newton_s": r0.timings["newton"],
        "resolve_factor_s": r1.timings["factor"], "resolve_newton_s": r1.timings["newton"],
        "stick_nodes": int(np.sum(r0.active == cs.STICK)), "slip_nodes": int(np.sum(r0.active == cs.SLIP)),
    }
    rows["goal_first_le_3x_superlu"] = bool(rows["first_over_superlu"] <= 3.0)
    rows["goal_resolve_le_half_superlu"] = bool(rows["resolve_over_superlu"] <= 0.5)
    import os
    rows["load_average_1min"] = os.getloadavg()[0]
    if with_qp:
        t = time.perf_counter()
        q = solve_contact_qp(*args(P0), g=g)
        rows["qp_s"] = time.perf_counter() - t
        rows["qp_over_superlu"] = rows["qp_s"] / t_slu
        rows["qp_vs_newton_rel_diff_u"] = np.linalg.norm(q.u - r0.u) / np.linalg.norm(r0.u)
    write_table("contact_solver", ["quantity", "value"], [list(kv) for kv in rows.items()])
    return rows


@pytest.mark.bench
def test_bench_contact():
    rows = run()
    # the speed goals (first solve <= 3x, re-solve <= 0.5x one SuperLU factor+solve) are recorded in the
    # table, not asserted: on a shared 2-core machine a busy neighbour moves these ratios several-fold
    assert rows["newton_iterations_resolve"] <= rows["newton_iterations_cold_data1"]
    assert rows.get("qp_vs_newton_rel_diff_u", 0.0) < 1e-6


if __name__ == "__main__":
    for k, v in run().items():
        print(f"{k:32s} {v:.4g}" if isinstance(v, float) else f"{k:32s} {v}")
