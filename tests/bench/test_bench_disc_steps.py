"""Newton steps of `solver.method: iterative` on the 3D tunnel's friction discs, with and without the
trial full step (`wcs.contact.iterative`: the watchdog on steps whose full end only sticks more nodes).

studies/tunnel-fault-3d.yaml (1.6e4 unknowns, 529 fault nodes) and, with WCS_BENCH_DISCS=finer,
its finer mesh of tests/contact/test_tresca_newton_3d.py (0.55 m near the tunnel, 1.6 m along the
fault: 3.9e4 unknowns). One evaluator per rule: the nominal data set (cold, the anchor), then
corners of the box warm from the nominal answer, as a study evaluates them: the six scalar data at
their bounds and the slip limit all at one bound (the box's 2^7 corners with a constant slip limit),
the first WCS_BENCH_DISC_CORNERS (default 16) in a fixed random order. Per data set: Newton steps
and CG iterations of each rule (`before`: every step on discs that fails Armijo shortened; `after`:
the trial full step), the CPU time of each (user + system of this process), and the largest
relative difference of the criteria between the two (the answer is unique; the path changes).
Writes results/bench/disc_steps.csv.
"""
import itertools
import os
import resource
from pathlib import Path

import numpy as np
import pytest
import yaml

from common import write_table

STUDIES = Path(__file__).resolve().parents[2] / "studies"


def _cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _run(doc, sets):
    """(steps, CG iterations, CPU seconds, criteria) of each data set, one evaluator in order."""
    from wcs import load_study
    from wcs.model.evaluation import Evaluator
    ev = Evaluator(load_study({**doc, "solver": {"method": "iterative"}}))
    out = []
    for x in sets:
        t = _cpu()
        res = ev.evaluate(x, gradients=False)
        raw = res.state.raw if res.state is not None else None
        out.append((raw.iterations if raw else -1, raw.krylov_iterations if raw else -1, _cpu() - t,
                    dict(res.phi), int(res.status)))
    return out


@pytest.mark.bench
def test_disc_steps(monkeypatch):
    import wcs.contact.iterative as it
    from wcs import load_study
    monkeypatch.chdir(STUDIES)
    rows = []
    meshes = ["coarse"] + (["finer"] if os.environ.get("WCS_BENCH_DISCS") == "finer" else [])
    for mesh in meshes:
        doc = yaml.safe_load((STUDIES / "tunnel-fault-3d.yaml").read_text())
        if mesh == "finer":
            doc["scene"]["mesh"]["refine"][0]["size"], doc["scene"]["mesh"]["refine"][1]["size"] = 0.55, 1.6
        study = load_study(doc)
        lo, hi = study.parameters.lower, study.parameters.upper
        corners = list(itertools.product([0, 1], repeat=7))
        pick = np.random.default_rng(0).permutation(len(corners))[:int(os.environ.get("WCS_BENCH_DISC_CORNERS", 16))]
        names, sets = ["nominal"], [study.nominal()]
        for i in pick:
            bits = corners[i]
            names.append("corner " + "".join(map(str, bits)))
            sets.append(lo + np.r_[bits[:6], np.full(len(lo) - 6, bits[6])] * (hi - lo))
        after = _run(doc, sets)
        with monkeypatch.context() as mp:       # the rule before: no trial step
            mp.setattr(it, "_sticks_more", lambda *a: False)
            before = _run(doc, sets)
        for name, b, a in zip(names, before, after):
            diff = max((abs(a[3][c] - b[3][c]) / max(abs(b[3][c]), 1e-300) for c in b[3]), default=0.0)
            rows.append([mesh, name, b[4], a[4], b[0], a[0], b[1], a[1], f"{b[2]:.2f}", f"{a[2]:.2f}", f"{diff:.1e}"])
        solved = [(b, a) for b, a in zip(before, after) if b[4] == 0 and a[4] == 0]
        rows.append([mesh, "total (both solved)", "", "", sum(b[0] for b, _ in solved), sum(a[0] for _, a in solved),
                     sum(b[1] for b, _ in solved), sum(a[1] for _, a in solved),
                     f"{sum(b[2] for b, _ in solved):.1f}", f"{sum(a[2] for _, a in solved):.1f}", ""])
    write_table("disc_steps", ["mesh", "data set", "status before", "status after", "steps before", "steps after",
                               "CG before", "CG after", "CPU s before", "CPU s after", "criteria rel diff"], rows)
    for r in rows:
        if r[1].startswith("total"):
            assert r[5] <= r[4], r          # fewer Newton steps in all (counts, deterministic)
        elif r[2] == 0:
            assert r[3] == 0, r             # no new failure
            assert float(r[10]) <= 1e-7, r  # the same answer
