"""Where the seed's successive approximations break ([21, §7]): a scene family from
converging to failing.

Scene: the Tresca pad (studies/validation/tresca-pad.yaml, coarse mesh) with the pad held
sideways by a roller on its left side (so it is split like the base), pressed off-centre
(1 MPa on the right half of its top) so that the contact opens in part.
Axes: (a) pair thickness δ/H (solver.dd.pair_size: the contact band's thickness over the mean
subdomain diameter) × stiffness ratio E_pad/E_base, frictionless; (b) Tresca slip limit g ×
E_pad/E_base at δ/H = 0.3. Each point: the seed's plain successive approximations (step seed,
ω = 1) and interface Newton (step newton), and what step auto picks from its power estimate
of ρ(S0⁻¹ dS_con) at U⁰ (the seed's step below solver.dd.seed_rho); 8 subdomains, tolerance
1e-8, budget 100.

Writes results/bench/dd_stability.csv and .png (stamped). Run by `make bench`, or
.venv/bin/python tests/bench/test_dd_stability.py
"""
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import pytest  # noqa: E402

from common import save_figure, write_table  # noqa: E402
from dd_common import build, run  # noqa: E402

RATIOS = [1e-3, 1e-2, 1e-1, 1.0]
PAIRS = [0.15, 0.3, 0.6, 1.2]
SLIPS = [0.0, 1e5, 3e5, 1e6, 1e9]
E_BASE = 2.1e11


def scene(ratio, slip):
    def edit(doc):
        sc = doc["scene"]
        sc["mesh"] = {"size": 0.1, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": 0.05}]}
        sc["materials"]["rubber"] = {"E": E_BASE * ratio, "nu": 0.3}
        sc["boundaries"]["pad_left"] = {"body": "pad", "segment": [[0.5, 1.0], [0.5, 1.5]]}
        sc["supports"]["pad_left"] = {"u": [0.0, None]}
        sc["boundaries"]["pad_top_right"] = {"body": "pad", "segment": [[1.0, 1.5], [1.5, 1.5]]}
        sc["loads"] = {"pad_top_right": {"traction": [0.0, -1.0e6]}}     # off-centre: the contact opens in part
        sc["contacts"]["interface"]["friction"] = {"slip_limit": slip} if slip else None
        if not slip:
            sc["contacts"]["interface"].pop("friction")
        doc["uncertain"] = {"loads.pad_top_right.traction.1": [-2.0e6, -0.5e6]}
        doc["criteria"] = [{"name": "pressure", "kind": "contact_pressure", "regions": ["interface"]}]
    return edit


def main():
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        points = [("a", r, ps, 0.0) for r in RATIOS for ps in PAIRS] + \
                 [("b", r, 0.3, g) for r in RATIOS for g in SLIPS]
        for panel, ratio, ps, slip in points:
            study, model = build("validation/tresca-pad.yaml", tmp, scene(ratio, slip))
            for step in ("auto", "seed", "newton"):
                dd = {"subdomains": 8, "pair_size": ps, "step": step, **({"relaxation": 1.0} if step == "seed" else {})}
                if step == "newton" and picked["step"] == "newton":       # auto's run was this run
                    rows.append({**picked, "method": "newton"})
                    continue
                res, out = run(study, model, {"tolerance": 1e-8, "max_iterations": 100, "dd": dd}, compare=False)
                row = {"panel": panel, "E_ratio": ratio, "pair_size": ps, "slip_limit": slip, "method": step,
                       "step": res.info.get("step"), "rho": res.info.get("rho", ""), "status": out["status"],
                       "outer": out["successive"], "pcg2": out["pcg2"], "message": res.message}
                if step == "auto":
                    picked = row
                rows.append(row)
                print({k: row[k] for k in ("panel", "E_ratio", "pair_size", "slip_limit", "method", "step", "rho",
                                           "status", "outer")}, flush=True)
    header = list(rows[0])
    write_table("dd_stability", header, [[r[k] for k in header] for r in rows])
    chart(rows)
    return rows


@pytest.mark.bench
def test_dd_stability():
    rows = main()
    assert all(r["status"] == "converged" for r in rows if r["method"] == "newton")
    # auto's choice matches the chart: the seed's step only where it converges
    for r in rows:
        if r["method"] == "auto" and r["step"] == "seed":
            assert r["status"] == "converged"


def chart(rows):
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    marks = {"converged": ("o", "tab:green"), "diverged": ("x", "tab:red"), "stagnated": ("s", "tab:orange"),
             "budget exhausted": ("s", "tab:orange"), "local solve failed": ("^", "tab:purple"),
             "setup failed": ("^", "black")}
    shift = {"seed": -0.12, "newton": 0.12}
    for ax, panel, xkey, xlabel in ((axes[0], "a", "pair_size", "pair thickness δ/H (solver.dd.pair_size)"),
                                    (axes[1], "b", "slip_limit", "Tresca slip limit g [Pa] (0 = frictionless)")):
        xs = sorted({r[xkey] for r in rows if r["panel"] == panel})
        for r in rows:
            if r["panel"] != panel:
                continue
            x0, y = xs.index(r[xkey]), np.log10(r["E_ratio"])
            if r["method"] == "auto":             # ρ and the pick: a ring around the chosen step
                ax.scatter(x0 + shift[r["step"]], y, marker="o", s=260, facecolors="none", edgecolors="black")
                ax.annotate(f"ρ≈{r['rho']:.2g}", (x0, y), textcoords="offset points", xytext=(0, -16), ha="center",
                            fontsize=7)
                continue
            x = x0 + shift[r["method"]]
            m, c = marks[r["status"]]
            if r["method"] == "seed" or m == "x":
                ax.scatter(x, y, marker=m, s=90, color=c)
            else:
                ax.scatter(x, y, marker=m, s=90, facecolors="none", edgecolors=c)
            ax.annotate(str(r["outer"]), (x, y), textcoords="offset points", xytext=(0, 8), ha="center", fontsize=7)
        ax.set_xticks(range(len(xs)), [f"{x:g}" for x in xs])
        ax.set_xlabel(xlabel)
        ax.set_ylabel("log10 E_pad / E_base (pad = one side of the contact)")
        ax.set_title(f"({panel}) " + ("frictionless" if panel == "a" else "δ/H = 0.3"))
        ax.grid(alpha=0.3)
    handles = [plt.Line2D([], [], marker=m, color=c, ls="", label=s) for s, (m, c) in marks.items()
               if s in {r["status"] for r in rows}]
    handles += [plt.Line2D([], [], marker="o", color="gray", ls="", label="left/filled: seed's step, ω = 1"),
                plt.Line2D([], [], marker="o", mfc="none", color="gray", ls="", label="right/open: interface Newton"),
                plt.Line2D([], [], marker="o", mfc="none", color="black", ms=12, ls="", label="ring: step auto's pick")]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=8)
    fig.suptitle("DD outer iteration: status (numbers: outer steps), ρ(S0⁻¹ dS_con) estimated at U⁰; "
                 "8 subdomains, tol 1e-8")
    fig.tight_layout(rect=(0, 0.08, 1, 0.95))
    save_figure(fig, "dd_stability")


if __name__ == "__main__":
    main()
