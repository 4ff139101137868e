"""Forward solver: accuracy against wall time, and evaluation time against size.

Charts (results/bench/):
- forward_hertz.png: error of peak pressure and contact width (vs the closed form)
  against wall time of one evaluation, one curve per method, points along refinement;
- forward_tunnel.png, forward_tresca.png: error of the criteria against a fine reference;
- scaling.png: time of an evaluation (re-solve with new data) against unknowns, with one
  sparse factorization-and-solve (PARDISO and tuned SuperLU) of the same stiffness as the floor.
"""
from __future__ import annotations

import copy

import numpy as np
import pytest
import scipy.sparse.linalg as spla
import yaml

import wcs
from wcs import linalg

from common import STUDIES, measure, save_figure, write_table

pytestmark = pytest.mark.bench
METHODS = [("monolithic", {}), ("qp", {}), ("dd", {"subdomains": 4}), ("dd", {"subdomains": 8})]
SLOW = 3.0                 # seconds: above this an evaluation is timed once
# finest Hertz size per method: the generic QP (cvxpy) and the DD cost tens of seconds an evaluation
# at h = 0.002 (1.2e5 unknowns; dd-4 stagnated there and fell back)
FINEST = {"monolithic": 0.002, "qp": 0.004, "dd": 0.004}


def study_from(doc: dict, tmp_path, name: str):
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return wcs.load_study(path)


def method_label(method, dd):
    return method if method != "dd" else f"dd-{dd['subdomains']}"


def timed_evaluation(study, repeat=3):
    """(median wall time of an evaluation with new data, spread, the evaluation at the nominal data).

    The first evaluation (nominal data) builds the mesh and the model and gives the accuracy;
    the timed ones move the first parameter by 1e-4 relative each time, so every timed
    evaluation refactors and re-solves (an unchanged K would skip the factorization). One
    timed repeat only when an evaluation costs more than SLOW seconds."""
    x = study.nominal()
    first = study.evaluate(x)
    if first.status != 0:
        return np.nan, 0.0, first
    k = iter(range(1, 100))

    def moved():
        y = x.copy()
        y[0] *= 1.0 + 1e-4 * next(k)
        return study.evaluate(y)
    t1, _, _ = measure(moved, 1)
    if t1 > SLOW:
        return t1, 0.0, first
    med, spread, _ = measure(moved, repeat)
    return med, spread, first


def hertz_errors(ev):
    E, nu, R, p_top = 2.0e11, 0.3, 1.0, 1.0786e8
    P = 2 * p_top * R
    a = np.sqrt(4 * P * R / (np.pi * E / (2 * (1 - nu**2))))
    p0 = 2 * P / (np.pi * a)
    c = ev.state.contact
    x, F = c.zone.coords[:, 0], c.force_n
    return abs(c.pressure.max() / p0 - 1), abs(2 * np.sqrt((x**2 * F).sum() / F.sum()) / a - 1)


def test_hertz_error_against_time(tmp_path):
    import matplotlib.pyplot as plt
    base = yaml.safe_load((STUDIES / "validation" / "hertz.yaml").read_text())
    rows = []
    for method, dd in METHODS:
        for h in (0.016, 0.008, 0.004, 0.002):
            if h < FINEST[method]:
                continue
            doc = copy.deepcopy(base)
            doc["scene"]["mesh"]["refine"][0]["size"] = h
            doc["solver"] = {"method": method, **({"dd": dd} if dd else {})}
            try:
                study = study_from(doc, tmp_path, f"hertz-{method}-{h}")
                t, spread, ev = timed_evaluation(study)
            except wcs.StudyError as e:                     # a method not available in this build
                rows.append([method_label(method, dd), h, 0, np.nan, 0, np.nan, np.nan, str(e)[:60]])
                continue
            ep, ew = hertz_errors(ev) if ev.status == 0 else (np.nan, np.nan)
            n = 2 * ev.evaluator.smesh.mesh.p.shape[1]
            rows.append([method_label(method, dd), h, n, t, spread, ep, ew, ev.message])
    write_table("forward_hertz", ["method", "h", "unknowns", "seconds", "spread", "err_peak", "err_width", "status"], rows)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    for k, (ax, what) in enumerate(zip(axes, ("peak pressure", "contact half-width"))):
        for label in dict.fromkeys(r[0] for r in rows):
            pts = [(r[3], r[5 + k]) for r in rows if r[0] == label and np.isfinite(r[3]) and np.isfinite(r[5 + k])]
            if pts:
                ax.loglog(*zip(*pts), "o-", label=label)
            fell = [(r[3], r[5 + k]) for r in rows if r[0] == label and "after dd" in str(r[7])
                    and np.isfinite(r[3]) and np.isfinite(r[5 + k])]
            if fell:
                ax.loglog(*zip(*fell), "kx", ms=9, label=f"{label}: DD failed, monolithic fallback")
        ax.set_xlabel("wall time of one evaluation [s]")
        ax.set_ylabel(f"relative error of the {what} [-]")
        ax.set_title(f"Hertz: {what} vs closed form\n(h = a/3, a/6, a/12, a/25 along each curve)", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, "forward_hertz")


def _reference_errors(tmp_path, name, doc_of, sizes, fine):
    """Criteria errors against the finest monolithic solve, per method and size."""
    import matplotlib.pyplot as plt
    ref = study_from(doc_of(fine, "monolithic", {}), tmp_path, f"{name}-ref")
    ref_phi = ref.evaluate(ref.nominal()).phi
    rows = []
    for method, dd in METHODS:
        for h in sizes:
            if method == "qp" and h < sizes[1]:
                continue
            try:
                study = study_from(doc_of(h, method, dd), tmp_path, f"{name}-{method}-{h}")
                t, spread, ev = timed_evaluation(study, repeat=2)
            except wcs.StudyError:
                continue
            n = 2 * ev.evaluator.smesh.mesh.p.shape[1]
            for crit, value in ev.phi.items():
                err = abs(value / ref_phi[crit] - 1) if ev.status == 0 else np.nan
                rows.append([method_label(method, dd), h, n, t, spread, crit, err, ev.message])
    write_table(f"forward_{name}", ["method", "h", "unknowns", "seconds", "spread", "criterion", "rel_error",
                                    "status"], rows)
    crits = list(ref_phi)
    fig, axes = plt.subplots(1, len(crits), figsize=(5 * len(crits), 4), squeeze=False)
    for ax, crit in zip(axes[0], crits):
        for label in dict.fromkeys(r[0] for r in rows):
            pts = [(r[3], r[6]) for r in rows if r[0] == label and r[5] == crit and np.isfinite(r[6]) and r[6] > 0]
            if pts:
                ax.loglog(*zip(*pts), "o-", label=label)
        ax.set_xlabel("wall time of one evaluation [s]")
        ax.set_ylabel(f"relative error of {crit} vs fine reference [-]")
        ax.set_title(f"{name}: {crit} (points: mesh refinement)", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, f"forward_{name}")
    return rows


def test_tunnel_error_against_time(tmp_path):
    base = yaml.safe_load((STUDIES / "tunnel-fault.yaml").read_text())
    base["scene"]["materials"] = str((STUDIES / base["scene"]["materials"]).resolve()) \
        if isinstance(base["scene"]["materials"], str) and (STUDIES / base["scene"]["materials"]).exists() \
        else base["scene"]["materials"]

    def doc_of(scale, method, dd):
        doc = copy.deepcopy(base)
        mesh = doc["scene"]["mesh"]
        mesh["size"] = mesh["size"] * scale
        for r in mesh.get("refine", []):
            r["size"] = r["size"] * scale
        doc["solver"] = {"method": method, **({"dd": dd} if dd else {})}
        return doc
    _reference_errors(tmp_path, "tunnel", doc_of, (2.0, 1.0, 0.5), 0.25)


def test_tresca_error_against_time(tmp_path):
    base = yaml.safe_load((STUDIES / "validation" / "tresca-pad.yaml").read_text())

    def doc_of(h, method, dd):
        doc = copy.deepcopy(base)
        doc["scene"]["mesh"] = {"size": 4 * h, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": h}]}
        doc["solver"] = {"method": method, **({"dd": dd} if dd else {})}
        return doc
    _reference_errors(tmp_path, "tresca", doc_of, (0.04, 0.02, 0.01), 0.0025)


def test_time_per_evaluation_against_unknowns(tmp_path):
    import matplotlib.pyplot as plt
    base = yaml.safe_load((STUDIES / "validation" / "tresca-pad.yaml").read_text())
    rows = []
    for h in (0.1, 0.05, 0.025, 0.0125, 0.0075, 0.005, 0.0035):   # 1.2e3 ... 4.5e5 unknowns
        doc = copy.deepcopy(base)
        doc["scene"]["mesh"] = {"size": h}
        doc["uncertain"]["materials.rubber.E"] = [0.9e7, 1.1e7]     # a new K each evaluation: the pad unit rescaled
        study = study_from(doc, tmp_path, f"scale-{h}")
        x0 = study.nominal()
        study.evaluate(x0)                                   # mesh, assembly, first solve
        names = study.parameters.names
        xs = []
        for k in range(3):
            x = x0.copy()
            x[names.index("loads.pad_top.traction.0")] *= 0.9 + 0.05 * k
            x[names.index("contacts.interface.friction.slip_limit")] *= 1.0 + 0.05 * k
            x[names.index("materials.rubber.E")] *= 1.0 - 0.02 * k
            xs.append(x)
        it = iter(xs)
        t_eval, s_eval, ev = measure(lambda: study.evaluate(next(it)), 3)
        model = ev.evaluator.model
        c = ev.evaluator.map.coefficients(x0)
        K = model.K(model.stiffness_coefficients(c))
        Kr = (model.Tt @ K @ model.elim.T).tocsr()
        b = np.ones(Kr.shape[0])
        t_par, _, _ = measure(lambda: linalg.factorize(Kr, "pardiso", spd=False).solve(b), 2) \
            if linalg.backend() == "pardiso" else (np.nan, 0, None)
        Kc = Kr.tocsc()
        t_lu, _, _ = measure(lambda: spla.splu(Kc, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                               options={"SymmetricMode": True}).solve(b), 2)
        n = Kr.shape[0]
        rows.append([h, n, model.zone.gap.size, t_eval, s_eval, t_par, t_lu, t_eval / t_lu, t_eval / t_par,
                     ev.iterations])
        print(rows[-1], flush=True)
    write_table("scaling", ["h", "unknowns", "contact_nodes", "eval_seconds", "eval_spread",
                            "pardiso_solve_seconds", "superlu_solve_seconds", "eval_over_superlu",
                            "eval_over_pardiso", "newton_iterations"], rows)
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    n = [r[1] for r in rows]
    ax.loglog(n, [r[3] for r in rows], "o-", label="wcs evaluation (Tresca re-solve, new data)")
    ax.loglog(n, [r[5] for r in rows], "s--", label="floor: one PARDISO factor+solve")
    ax.loglog(n, [r[6] for r in rows], "^--", label="one SuperLU factor+solve (tuned)")
    ax.set_xlabel("unknowns [-]")
    ax.set_ylabel("wall time [s]")
    ax.set_title("Time per evaluation against problem size")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    ax2.semilogx(n, [r[8] for r in rows], "o-", label="evaluation / PARDISO factor+solve (floor ratio)")
    ax2.semilogx(n, [r[7] for r in rows], "^--", label="evaluation / SuperLU factor+solve")
    ax2.axhline(1.0, color="0.5", lw=0.8)
    ax2.set_xlabel("unknowns [-]")
    ax2.set_ylabel("ratio [-]")
    ax2.set_title("Floor ratio (same run, medians)")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend()
    fig.suptitle("Tresca pad, uniform mesh; evaluation = new load, slip limit and pad stiffness (numeric "
                 "refactor + contact re-solve); floor = analysis + factorization + solve of the same K")
    fig.tight_layout()
    save_figure(fig, "scaling")
