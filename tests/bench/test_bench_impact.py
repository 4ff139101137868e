"""Speed against accuracy of the time-stepping schemes, and where each fails (the charts):
the cylinder impact of `tests/dynamics/test_impact.py` over the mesh size h at the contact and the
time step Δt, per scheme — the errors of the contact time and the peak force against Hertz's
impact theory, the energy kept at the end (after the rebound), against the CPU and wall time of
the run; a level that fails is a row with its message. Writes results/bench/impact_schemes.csv
and impact_schemes.png: error against CPU time (contact time, peak force, energy) and the
stability chart (h against Δt per scheme, each run marked solved or failed); and
results/bench/impact_orders.csv: the observed orders in Δt and h with their Richardson limits.

The scene (a steel cylinder on a 5 cm aluminium block) is where Hertz's quasi-static theory holds
(little of the energy left in vibration; on the former 10 cm steel block that vibration set a floor
under the peak force's error): `tests/dynamics/test_impact.py` says how much.

The sphere (quarter model, graded mesh: size h in a 3 mm ball around the first contact point, growing
by `GRADING` per unit distance): results/bench/sphere_impact.csv, the contact time and the peak force
against `hertz_sphere` over h, with Hertz's impact on each mesh's own static law (`sphere_quasi_static`)
beside them, and sphere_impact_orders.csv, their observed orders in h.
"""
import time

import numpy as np
import pytest

from common import save_figure, write_table
from tests.dynamics.test_impact import GRADING, hertz, hertz_sphere, impact, sphere_impact, sphere_quasi_static
from wcs.errors import SolveError

pytestmark = pytest.mark.bench

MESHES = (4e-4, 2e-4, 1e-4)                 # h at the contact [m] (b_max = 1.13 mm)
STEPS = (8e-6, 4e-6, 2e-6, 1e-6, 5e-7)      # Δt [s] (t_c = 174 µs: 22 to 348 steps in contact)
SCHEMES = ("seed", "stabilized")
HEADER = ["scheme", "h", "dt", "t_c error", "peak force error", "energy change", "status", "cpu seconds",
          "wall seconds"]


def run(scheme: str, h: float, dt: float) -> list:
    """One row of the table: the errors against Hertz, or the failure's message."""
    tc_ref, q_ref = hertz()
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        tc, q, kept, _ = impact(h, dt, scheme)
        row = [scheme, h, dt, round(tc / tc_ref - 1, 6), round(q / q_ref - 1, 6), float(f"{kept - 1:.3e}"), "solved"]
    except SolveError as e:
        row = [scheme, h, dt, "", "", "", f"failed: {e}"]
    return row + [round(time.process_time() - c0, 2), round(time.perf_counter() - t0, 2)]


def test_impact_schemes_speed_against_accuracy():
    rows = []
    for scheme in SCHEMES:
        for h in MESHES:
            for dt in STEPS:
                rows.append(run(scheme, h, dt))
                print(rows[-1], flush=True)
    path = write_table("impact_schemes", HEADER, rows)
    print(path.read_text())
    print(write_table("impact_orders", ["scheme", "refined", "at", "quantity", "last three", "observed order",
                                        "Richardson limit"], orders(rows)).read_text())
    _plot(rows)
    solved = [r for r in rows if r[6] == "solved"]
    assert len(solved) == len(rows), [r for r in rows if r[6] != "solved"]
    fine = [r for r in solved if r[2] <= 2e-6]
    assert all(abs(r[3]) < 0.02 for r in fine), fine      # t_c to the step's ±Δt/t_c (1.15 % at 2 µs)


SPHERE_MESHES = (1e-3, 5e-4, 2.5e-4, 1.25e-4)   # h at the contact [m] (a_max = 2.44 mm)
SPHERE_STEP = 2e-6                         # Δt [s] (t_c = 354 µs: 177 levels in contact)
SPHERE_HEADER = ["scheme", "h", "grading", "dt", "cells", "t_c error", "peak force error", "quasi-static t_c error",
                 "quasi-static peak force error", "energy change", "status", "cpu seconds", "wall seconds"]


def sphere_run(scheme: str, h: float, dt: float) -> list:
    """One row of the sphere's table: the errors against Hertz and those of Hertz's impact on the
    mesh's own static law, or the failure's message."""
    tc_ref, F_ref = hertz_sphere()
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        r = sphere_impact(h, dt, scheme)
        tc_qs, F_qs, _ = sphere_quasi_static(h)
        status = "solved" if r["one contact"] else "solved: not one contact"
        row = [scheme, h, GRADING, dt, r["cells"], round(r["t_c"] / tc_ref - 1, 5), round(r["F_max"] / F_ref - 1, 5),
               round(tc_qs / tc_ref - 1, 5), round(F_qs / F_ref - 1, 5), float(f"{r['energy'] - 1:.3e}"), status]
    except SolveError as e:
        row = [scheme, h, GRADING, dt, "", "", "", "", "", "", f"failed: {e}"]
    return row + [round(time.process_time() - c0, 2), round(time.perf_counter() - t0, 2)]


def test_sphere_impact_on_graded_meshes():
    """The stabilized scheme over SPHERE_MESHES and the seed scheme at the finest, Δt = SPHERE_STEP:
    at the finest mesh the contact time and the peak force within 3 % of Hertz (issue 29)."""
    rows = [sphere_run("stabilized", h, SPHERE_STEP) for h in SPHERE_MESHES]
    rows.append(sphere_run("seed", SPHERE_MESHES[-1], SPHERE_STEP))
    print(write_table("sphere_impact", SPHERE_HEADER, rows).read_text())
    solved = [r for r in rows if r[10] == "solved"]
    stabilized = [r for r in solved if r[0] == "stabilized"]
    out = []
    for i in range(len(stabilized) - 2):               # each three successive meshes
        for k, quantity in ((5, "t_c error"), (6, "peak force error"), (7, "quasi-static t_c error")):
            e = [r[k] for r in stabilized[i:i + 3]]
            out.append(["stabilized", "h", f"h = {stabilized[i + 2][1]:g}, dt = {SPHERE_STEP:g}", quantity,
                        " ".join(f"{x:.4g}" for x in e), *observed(*e)])
    print(write_table("sphere_impact_orders", ["scheme", "refined", "at", "quantity", "last three", "observed order",
                                               "Richardson limit"], out).read_text())
    assert len(solved) == len(rows), [r for r in rows if r[10] != "solved"]
    finest = [r for r in rows if r[1] == SPHERE_MESHES[-1]]
    assert all(abs(r[5]) < 0.03 and abs(r[6]) < 0.03 for r in finest), finest


def observed(e1: float, e2: float, e3: float) -> tuple:
    """(p, the limit) of three errors as the step halves: p = log2(|e1 − e2| / |e2 − e3|), the
    limit e3 + (e3 − e2)/(2^p − 1) (Richardson); ("", "") where the changes alternate in sign or
    do not shrink (no asymptotic range: the error does not converge monotonically there)."""
    d1, d2 = e1 - e2, e2 - e3
    if d1 * d2 <= 0 or abs(d2) >= abs(d1):
        return "", ""
    p = float(np.log2(d1 / d2))
    return round(p, 2), float(f"{e3 + (e3 - e2) / (2.0 ** p - 1.0):.4g}")


def orders(rows) -> list:
    """The observed orders of the peak force and energy errors: in Δt (the three smallest steps)
    on each mesh, and in h (the three meshes) at the smallest step."""
    solved = {(r[0], r[1], r[2]): r for r in rows if r[6] == "solved"}
    out = []
    for scheme in SCHEMES:
        lines = [("dt", f"h = {h:g}", [(scheme, h, dt) for dt in STEPS[-3:]]) for h in MESHES]
        lines.append(("h", f"dt = {STEPS[-1]:g}", [(scheme, h, STEPS[-1]) for h in MESHES]))
        for refined, at, keys in lines:
            if not all(k in solved for k in keys):
                continue
            for k, quantity in ((4, "peak force error"), (5, "energy change")):
                e = [solved[key][k] for key in keys]
                p, limit = observed(*e)
                out.append([scheme, refined, at, quantity, " ".join(f"{x:.4g}" for x in e), p, limit])
    return out


def _plot(rows):
    import matplotlib
    import matplotlib.ticker
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    colours = dict(zip(MESHES, ("tab:blue", "tab:orange", "tab:green")))
    for scheme, marker, style in (("seed", "o", "-"), ("stabilized", "s", "--")):
        for h in MESHES:
            ok = [r for r in rows if r[0] == scheme and r[1] == h and r[6] == "solved"]
            for ax, k in zip((axes[0, 0], axes[0, 1], axes[1, 0]), (3, 4, 5)):
                ax.loglog([r[7] for r in ok], [max(abs(r[k]), 1e-6) for r in ok], style, marker=marker,
                          color=colours[h], label=f"{scheme}, h = {h * 1e3:g} mm")
    for ax, what in zip((axes[0, 0], axes[0, 1], axes[1, 0]),
                        ("|contact time error|", "|peak force error|", "|energy change| after the rebound")):
        ax.set_xlabel("CPU time [s] (along a line: Δt halves)")
        ax.set_ylabel(what)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    ax = axes[1, 1]
    for scheme, shift, marker in (("seed", 0.93, "o"), ("stabilized", 1.07, "s")):
        for ok, face in ((True, "tab:green"), (False, "tab:red")):
            pts = [r for r in rows if r[0] == scheme and (r[6] == "solved") == ok]
            ax.scatter([r[1] * 1e3 * shift for r in pts], [r[2] * 1e6 for r in pts], marker=marker, color=face,
                       label=f"{scheme}: {'solved' if ok else 'failed'} ({len(pts)})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("h at the contact [mm]")
    ax.set_ylabel("Δt [µs]")
    ax.set_title("stability: where each scheme fails", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("Cylinder impact against Hertz: error against cost over h and Δt")
    fig.tight_layout()
    save_figure(fig, "impact_schemes")
