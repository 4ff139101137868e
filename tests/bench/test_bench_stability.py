"""Stability map: where each contact method fails, and what its evaluation reports.

Families (one chart each; every point is one evaluation at the scene's data; marker = converged /
slow / failed, colour = the evaluation's `status` (wcs.status.Status), number = iterations):

- stability_friction.png — the monolithic semismooth Newton on the Tresca pad
  (studies/validation/tresca-pad.yaml, coarse mesh) against the Tresca slip limit g, and the
  Coulomb fixed point against the friction coefficient F (0.05 ... 1.5), for load cases from a
  light press to 10 MPa, an off-centre press, lift-off of a floating pad pulled up by a traction
  (no equilibrium: status 3 is the right answer) and lift-off of a pad whose top is displaced up
  1 mm (held: the contact opens everywhere and the solve must converge).
- stability_materials.png — Hertz (studies/validation/hertz.yaml, h = 0.008) with
  (a) both bodies nearly incompressible, ν = 0.3 ... 0.4999 (P1 elements lock), and
  (b) stiffness contrasts E_cylinder / E_block from 1 to 1e-6 and the ligament-on-CoCrMo pair
  (7e4 Pa vs 2.08e11 Pa), both ways round. The load is scaled with E* so that the closed-form
  half-width stays a = 0.05 m; each point reports the solve status AND the error of the peak
  pressure and the half-width against the closed form, for the monolithic solver and the DD
  (4 subdomains, no fallback, so its own failures show).
- DD successive approximations against contact-pair size and friction: test_dd_stability.py
  (dd_stability.png).

Slow: converged with more than SLOW_NEWTON Newton iterations (Coulomb: summed over the fixed
point) or more than SLOW_FIXED_POINT fixed-point steps, or DD with more than SLOW_DD successive
approximations. Outputs: stability_friction.csv/.png, stability_materials.csv/.png.
"""
from __future__ import annotations

import copy
import time

import numpy as np
import pytest
import yaml

import wcs
from wcs.errors import SolveError
from wcs.model.evaluation import Evaluator
from wcs.status import Status

from common import STUDIES, save_figure, write_table

pytestmark = pytest.mark.bench

SLOW_NEWTON = 25
SLOW_FIXED_POINT = 30
SLOW_DD = 50
STATUS_COLOURS = {0: "tab:green", 1: "tab:red", 2: "tab:orange", 3: "tab:purple", 4: "black", 5: "tab:brown",
                  6: "tab:gray"}
CLASS_MARKERS = {"converged": "o", "slow": "s", "failed": "X"}


def load(doc, tmp_path, name):
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return wcs.load_study(path)


def cold_solve(study):
    """The scene's own data solved from a cold start (Model.solve at the nominal scene: what
    the first evaluation of a study does before anything else; a later evaluation starts from
    this answer). -> dict with status, message, iterations, fixed_point, state, seconds."""
    ev = Evaluator(study)
    t = time.perf_counter()
    try:
        state = ev.model.solve(ev.model.nominal)
    except SolveError as e:
        return {"status": e.status, "message": str(e), "iterations": 0, "fixed_point": "", "state": None,
                "solver": "", "seconds": time.perf_counter() - t}
    raw = getattr(state, "raw", None)
    return {"status": 0, "message": f"solved ({state.solver})", "iterations": int(state.iterations),
            "fixed_point": getattr(raw, "fixed_point_iterations", "") if raw is not None else "",
            "state": state, "solver": state.solver, "seconds": time.perf_counter() - t}


def classify(r, method="monolithic"):
    if r["status"] != 0:
        return "failed"
    if method == "dd":
        if r["solver"] != "dd":
            return "slow"                     # fell back to the monolithic solver
        return "slow" if r["iterations"] > SLOW_DD else "converged"
    fp = r["fixed_point"] or 0
    return "slow" if r["iterations"] > SLOW_NEWTON or fp > SLOW_FIXED_POINT else "converged"


def draw_status(ax, xs, ys, rows, xkey, ykey, annotate="iterations"):
    for r in rows:
        x, y = xs.index(r[xkey]), ys.index(r[ykey])
        ax.scatter(x, y, marker=CLASS_MARKERS[r["class"]], s=110, color=STATUS_COLOURS[r["status"]],
                   edgecolors="k", linewidths=0.4)
        ax.annotate(str(r.get("note", r[annotate])), (x, y), textcoords="offset points", xytext=(0, 8), ha="center", fontsize=7)
    ax.set_xticks(range(len(xs)), [f"{x:g}" if isinstance(x, float) else str(x) for x in xs], fontsize=8)
    ax.set_yticks(range(len(ys)), ys, fontsize=8)
    ax.set_xlim(-0.5, len(xs) - 0.5)
    ax.set_ylim(-0.6, len(ys) - 0.4)
    ax.grid(alpha=0.3)


def legend(fig, rows):
    import matplotlib.pyplot as plt
    handles = [plt.Line2D([], [], marker=m, color="0.5", ls="", label=c) for c, m in CLASS_MARKERS.items()]
    handles += [plt.Line2D([], [], marker="o", color=STATUS_COLOURS[s], ls="",
                           label=f"status {s}: {Status(s).description}")
                for s in sorted({r["status"] for r in rows})]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=8)


# ---------------------------------------------------------------- friction and load (Newton, Coulomb)

LOADS = [  # label, edit of the scene (pad: 1 m wide on a steel base)
    ("press 0.01 MPa, shear 0.2×", lambda sc: sc["loads"].update(pad_top={"traction": [2.0e3, -1.0e4]})),
    ("press 1 MPa, shear 0.05×", lambda sc: sc["loads"].update(pad_top={"traction": [5.0e4, -1.0e6]})),
    ("press 1 MPa, shear 0.2× (nominal)", lambda sc: None),
    ("press 10 MPa, shear 0.2×", lambda sc: sc["loads"].update(pad_top={"traction": [2.0e6, -1.0e7]})),
    ("off-centre press 1 MPa,\nshear 0.1× (partly open)", None),
    ("pulled up 0.1 MPa, floating\n(lift-off: no equilibrium)", lambda sc: sc["loads"].update(
        pad_top={"traction": [0.0, 1.0e5]})),
    ("top lifted 1 mm, held\n(lift-off: contact open)", None),
    ("top pressed 1 mm + slid 0.1 mm, held", None),
]


def _off_centre(sc):
    sc["boundaries"]["pad_top_right"] = {"body": "pad", "segment": [[1.0, 1.5], [1.5, 1.5]]}
    sc["loads"] = {"pad_top_right": {"traction": [1.0e5, -1.0e6]}}


def _held(u):
    def edit(sc):
        sc["loads"] = {}
        sc["supports"]["pad_top"] = {"u": u}
    return edit


LOADS[4] = (LOADS[4][0], _off_centre)
LOADS[6] = (LOADS[6][0], _held([0.0, 1.0e-3]))
LOADS[7] = (LOADS[7][0], _held([1.0e-4, -1.0e-3]))
SLIPS = [0.0, 3.0e4, 1.0e5, 3.0e5, 1.0e6, 1.0e7]
COEFFICIENTS = [0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5]


def pad_doc(base, load_edit, friction):
    doc = copy.deepcopy(base)
    sc = doc["scene"]
    sc["mesh"] = {"size": 0.1, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": 0.025}]}
    load_edit(sc)
    contact = sc["contacts"]["interface"]
    contact.pop("friction", None)
    if friction:
        contact["friction"] = friction
    doc["uncertain"] = {"materials.rubber.E": [0.9e7, 1.1e7]}
    doc["criteria"] = [{"name": "pressure", "kind": "contact_pressure", "regions": ["interface"]}]
    doc["solver"] = {"method": "monolithic"}
    return doc


def test_friction_and_load(tmp_path):
    import matplotlib.pyplot as plt
    base = yaml.safe_load((STUDIES / "validation" / "tresca-pad.yaml").read_text())
    rows = []
    for family, values, law in (("tresca", SLIPS, "slip_limit"), ("coulomb", COEFFICIENTS, "coefficient")):
        for li, (label, edit) in enumerate(LOADS):
            for v in values:
                friction = {law: v} if v else None
                study = load(pad_doc(base, edit, friction), tmp_path, f"{family}-{li}-{v:g}")
                r = cold_solve(study)
                raw = getattr(r["state"], "raw", None) if r["state"] is not None else None
                active = getattr(raw, "active", None)
                counts = [int(np.sum(active == k)) for k in (0, 1, 2)] if active is not None else ["", "", ""]
                rows.append({"family": family, "load": label.replace("\n", " "), "label": label, "value": v,
                             "status": r["status"], "class": classify(r), "iterations": r["iterations"],
                             "fixed_point": r["fixed_point"], "open": counts[0], "stick": counts[1],
                             "slip": counts[2], "seconds": r["seconds"],
                             "message": r["message"].replace("\n", " ")[:200]})
                if family == "coulomb" and r["status"] == 0:
                    rows[-1]["note"] = f"{r['iterations']}/{r['fixed_point']}"
    header = [h for h in rows[0] if h not in ("label", "note")]
    write_table("stability_friction", header, [[r[h] for h in header] for r in rows])
    fig, axes = plt.subplots(1, 2, figsize=(15, 6.5))
    ys = [lab for lab, _ in LOADS]
    for ax, family, values, xlabel in (
            (axes[0], "tresca", SLIPS, "Tresca slip limit g [Pa] (0 = frictionless)"),
            (axes[1], "coulomb", COEFFICIENTS, "Coulomb friction coefficient F [-]")):
        fr = [r for r in rows if r["family"] == family]
        draw_status(ax, values, ys, fr, "value", "label")
        ax.set_xlabel(xlabel)
        ax.set_title(("(a) semismooth Newton, Tresca" if family == "tresca" else
                      "(b) Coulomb fixed point over Tresca")
                     + "\nnumber: Newton iterations of a cold solve" + (" summed / fixed-point steps"
                                                                        if family == "coulomb" else ""), fontsize=9)
    axes[1].set_yticklabels([])
    legend(fig, rows)
    fig.suptitle("Friction and load: Tresca pad (rubber 10 MPa on steel), monolithic solver")
    fig.tight_layout(rect=(0, 0.09, 1, 0.96))
    save_figure(fig, "stability_friction")
    for r in rows:
        print({k: r[k] for k in ("family", "load", "value", "status", "class", "iterations", "fixed_point")},
              flush=True)
    # a held pad lifted off must converge with the contact open; a floating pad pulled up must report status 3
    lifted = [r for r in rows if r["label"] == LOADS[6][0]]
    assert all(r["status"] == 0 and r["stick"] == 0 and r["slip"] == 0 for r in lifted), lifted
    pulled = [r for r in rows if r["label"] == LOADS[5][0]]
    assert all(r["status"] == 3 for r in pulled), pulled


# ---------------------------------------------------------------- materials (ν → 0.5, stiffness contrast)

R, A = 1.0, 0.05                   # cylinder radius, target half-width
NUS = [0.3, 0.45, 0.49, 0.499, 0.4999]
E_STEEL = 2.0e11
CONTRASTS = [  # label, (E_cyl, nu_cyl), (E_block, nu_block)
    ("1", (2.08e11, 0.3), (2.08e11, 0.3)),
    ("1e-2", (2.08e9, 0.3), (2.08e11, 0.3)),
    ("1e-4", (2.08e7, 0.3), (2.08e11, 0.3)),
    ("1e-6", (2.08e5, 0.3), (2.08e11, 0.3)),
    ("ligament on\nCoCrMo", (7.0e4, 0.49), (2.08e11, 0.3)),
    ("CoCrMo on\nligament", (2.08e11, 0.3), (7.0e4, 0.49)),
]
MATERIAL_METHODS = [("monolithic", {"method": "monolithic"}),
                    ("dd-4", {"method": "dd", "fallback": False, "dd": {"subdomains": 4}})]


def hertz_doc(base, cyl, block, solver, h=0.008):
    doc = copy.deepcopy(base)
    sc = doc["scene"]
    sc["mesh"]["refine"][0]["size"] = h
    sc["materials"] = {"cyl": {"E": cyl[0], "nu": cyl[1]}, "blk": {"E": block[0], "nu": block[1]}}
    sc["bodies"]["cylinder"]["regions"][0]["material"] = "cyl"
    sc["bodies"]["block"]["regions"][0]["material"] = "blk"
    e_star = 1.0 / ((1 - cyl[1] ** 2) / cyl[0] + (1 - block[1] ** 2) / block[0])
    P = np.pi * A ** 2 * e_star / (4 * R)           # load per unit length of the whole cylinder
    p_top = P / (2 * R)
    sc["loads"]["cyl_top"] = {"pressure": float(p_top)}
    doc["uncertain"] = {"loads.cyl_top.pressure": [0.9 * p_top, 1.1 * p_top]}
    doc["solver"] = solver
    return doc, P


def hertz_errors(state, P):
    p0 = 2 * P / (np.pi * A)
    c = state.contact
    x, F = c.zone.coords[:, 0], c.force_n
    return abs(c.pressure.max() / p0 - 1), abs(2 * np.sqrt((x ** 2 * F).sum() / F.sum()) / A - 1)


def test_materials(tmp_path):
    import matplotlib.pyplot as plt
    base = yaml.safe_load((STUDIES / "validation" / "hertz.yaml").read_text())
    rows = []
    cases = [("nu", f"{nu:g}", (E_STEEL, nu), (E_STEEL, nu)) for nu in NUS] + \
            [("contrast", lab, cyl, blk) for lab, cyl, blk in CONTRASTS]
    for family, label, cyl, blk in cases:
        for mlabel, solver in MATERIAL_METHODS:
            doc, P = hertz_doc(base, cyl, blk, solver)
            study = load(doc, tmp_path, f"hertz-{family}-{label.replace(chr(10), '')}-{mlabel}")
            r = cold_solve(study)
            ep, ew = hertz_errors(r["state"], P) if r["status"] == 0 else (np.nan, np.nan)
            rows.append({"family": family, "case": label.replace("\n", " "), "label": label, "method": mlabel,
                         "status": r["status"], "class": classify(r, solver["method"]), "iterations": r["iterations"],
                         "err_peak": ep, "err_width": ew, "seconds": r["seconds"], "solver": r["solver"],
                         "message": r["message"].replace("\n", " ")[:200]})
            print({k: rows[-1][k] for k in ("family", "case", "method", "status", "class", "iterations",
                                            "err_peak", "err_width", "seconds")}, flush=True)
    header = [h for h in rows[0] if h != "label"]
    write_table("stability_materials", header, [[r[h] for h in header] for r in rows])

    fig, axes = plt.subplots(2, 2, figsize=(13, 9), gridspec_kw={"height_ratios": [1, 1.3]})
    for col, family, xlabel in ((0, "nu", "Poisson ratio ν of both bodies"),
                                (1, "contrast", "E_cylinder / E_block")):
        fr = [r for r in rows if r["family"] == family]
        xs = list(dict.fromkeys(r["label"] for r in fr))
        ax = axes[0, col]
        for mlabel, _ in MATERIAL_METHODS:
            for k, (key, ls) in enumerate((("err_peak", "-"), ("err_width", "--"))):
                pts = [(xs.index(r["label"]), r[key]) for r in fr if r["method"] == mlabel and np.isfinite(r[key])]
                if pts:
                    ax.semilogy(*zip(*pts), "o" + ls, label=f"{mlabel}: {'peak pressure' if k == 0 else 'half-width'}")
        ax.set_xticks(range(len(xs)), xs, fontsize=8)
        ax.set_ylabel("relative error vs Hertz closed form [-]")
        ax.set_title(f"({'a' if col == 0 else 'b'}) accuracy, h = 0.008 m = a/6", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax = axes[1, col]
        draw_status(ax, xs, [m for m, _ in MATERIAL_METHODS], fr, "label", "method")
        ax.set_xlabel(xlabel)
        ax.set_title("solve status (number: Newton iterations / DD successive approximations)", fontsize=9)
    legend(fig, rows)
    fig.suptitle("Nearly incompressible materials and stiffness contrasts: Hertz cylinder on a block")
    fig.tight_layout(rect=(0, 0.07, 1, 0.96))
    save_figure(fig, "stability_materials")
    mono = [r for r in rows if r["method"] == "monolithic"]
    assert all(r["status"] == 0 for r in mono if r["family"] == "contrast"), mono
