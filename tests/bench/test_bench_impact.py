"""Speed against accuracy of the time-stepping schemes (issue 29's chart): the cylinder impact of
`tests/dynamics/test_impact.py` over the mesh size h and the time step Δt, per scheme — the
errors of the contact time and the peak force against Hertz's impact theory, the energy kept at
the end, and the wall time; a level that fails is a row with its message (where each scheme
stops: the stability chart). Writes results/bench/impact_schemes.csv and impact_schemes.png.
"""
import time

import numpy as np
import pytest

from common import save_figure, write_table
from tests.dynamics.test_impact import hertz, impact
from wcs.errors import SolveError

pytestmark = pytest.mark.bench

MESHES = (4e-4, 2e-4, 1e-4)          # h at the contact [m] (b_max = 0.93 mm)
STEPS = (2e-6, 1e-6, 5e-7)           # Δt [s] (t_c = 133 µs)


def test_impact_schemes_speed_against_accuracy():
    tc_ref, q_ref = hertz()
    rows = []
    for scheme in ("seed", "stabilized"):
        for h in MESHES:
            for dt in STEPS:
                t0 = time.perf_counter()
                try:
                    tc, q, kept, _ = impact(h, dt, scheme)
                    row = [scheme, h, dt, tc / tc_ref - 1, q / q_ref - 1, kept - 1, "solved"]
                except SolveError as e:
                    row = [scheme, h, dt, "", "", "", f"failed: {e}"]
                rows.append(row + [round(time.perf_counter() - t0, 2)])
                print(rows[-1], flush=True)
    path = write_table("impact_schemes", ["scheme", "h", "dt", "t_c error", "peak force error",
                                          "energy change", "status", "seconds"], rows)
    print(path.read_text())
    _plot(rows)
    seed = [r for r in rows if r[0] == "seed"]
    assert all(r[6] == "solved" and abs(r[3]) < 0.01 for r in seed), seed


def _plot(rows):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for scheme, marker in (("seed", "o"), ("stabilized", "s")):
        for h, colour in zip(MESHES, ("tab:blue", "tab:orange", "tab:green")):
            ok = [r for r in rows if r[0] == scheme and r[1] == h and r[6] == "solved"]
            failed = [r for r in rows if r[0] == scheme and r[1] == h and r[6] != "solved"]
            for ax, k in zip(axes, (3, 4)):
                ax.loglog([r[7] for r in ok], [max(abs(r[k]), 1e-5) for r in ok], marker=marker, color=colour,
                          label=f"{scheme}, h = {h * 1e3:g} mm")
                ax.plot([r[7] for r in failed], np.full(len(failed), 1.0), "x", color=colour)
    for ax, what in zip(axes, ("|contact time error|", "|peak force error|")):
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel(what)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("Cylinder impact against Hertz: error against cost over h and Δt (x at 1: a level failed)")
    save_figure(fig, "impact_schemes")
