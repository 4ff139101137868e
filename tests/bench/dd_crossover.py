"""One DD solve against a warm monolithic evaluation on new material data (every modulus × 1.01,
1.02, 1.03, best of three), serial, at growing mesh sizes: where the DD would start to pay.

    python tests/bench/dd_crossover.py tunnel-fault.yaml 0.33 0.23 0.16
    python tests/bench/dd_crossover.py validation/hertz.yaml 0.53 0.37 0.26

It prints one line a size (unknowns, contact nodes, the best seconds of each, their ratio) and
writes no table. The ratio fell as the mesh grew, on both scenes: `wcs.choose.DD_MIN_UNKNOWNS`
(where `auto` starts to pick the DD) rests on it, and its comment holds the ratios measured.
"""
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from dd_bench import _scale_mesh  # noqa: E402
from dd_common import build  # noqa: E402
from wcs.dd import solver as dds  # noqa: E402
from wcs.linalg import configure_threads  # noqa: E402


def ratio(name: str, scale: float) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        study, model = build(name, Path(tmp), lambda doc: _scale_mesh(doc, scale))
    options = {"tolerance": 1e-6, "max_iterations": 200, "dd": {"subdomains": 12}}
    nominal = model.coefficients(study.scene)

    def dd(c):
        _, Kr, rhs, u0 = model.reduced_system(c, None)
        return dds.solve_dd(model, study.scene, Kr, rhs, u0, options, coefficients=c)

    dd(nominal), model.solve(nominal)                          # warm both
    t_dd, t_mono = [], []
    for k in range(1, 4):
        c = dataclasses.replace(nominal, lam=(1 + 0.01 * k) * nominal.lam, mu=(1 + 0.01 * k) * nominal.mu)
        t = time.perf_counter()
        res = dd(c)
        t_dd.append(time.perf_counter() - t)
        t = time.perf_counter()
        model.solve(c)
        t_mono.append(time.perf_counter() - t)
    return (f"{name} ×{scale}: {model.Bn_r.shape[1]} unknowns, {model.zone.gap.size} contact nodes: DD "
            f"{min(t_dd):.3f} s, monolithic {min(t_mono):.3f} s, ratio {min(t_dd) / min(t_mono):.2f} "
            f"({res.status.value})")


if __name__ == "__main__":
    configure_threads()
    for s in sys.argv[2:]:
        print(ratio(sys.argv[1], float(s)), flush=True)
