"""DD over MPI ranks (`python tests/bench/dd_bench.py`): one large DD solve on 1 and 2 ranks (per-rank
timings, speed-up, bitwise identity) and a `dd` study on 1 and 2 ranks (evaluations spread over them).
Writes results/bench/dd_mpi_solve_*.json and dd_mpi_study.json. Run by `make bench`.

Measured (one BLAS thread per rank, the 2 shared cores with another job on about one of them,
so these are lower bounds; before → after this branch, same conditions): Hertz (1.05e5) 0.63× →
1.92× on the same data, 1.42× on new data (the pair's Schur factor, a third of the assembly,
on one rank); tunnel ×0.55 (4.2e4) 0.49× → 1.25× and 1.60×; tunnel ×0.4 (1e5) 0.60× and 0.84×
while the other job held a core (each rank's own work took 70–90 % of the serial time of all
units). A whole `dd` study of the tunnel (22 evaluations): 0.50× with every DD solve spread over
the ranks → 1.50× with the evaluations spread."""
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "results" / "bench"
DD_BENCH = Path(__file__).resolve().parent / "dd_bench.py"


def _bench(*args, timeout=3600):
    p = subprocess.run([sys.executable, str(DD_BENCH), *args], cwd=ROOT, capture_output=True, text=True,
                       timeout=timeout)
    print(p.stdout)
    assert p.returncode == 0, p.stdout + p.stderr
    return p.stdout


@pytest.mark.parametrize("study, scale", [("studies/validation/hertz.yaml", "0.53"), ("studies/tunnel-fault.yaml", "0.4")],
                         ids=["hertz", "tunnel"])
@pytest.mark.parametrize("data", ["same", "new"])
@pytest.mark.bench
def test_dd_solve_on_two_ranks(study, scale, data):
    """One DD solve (about 1e5 unknowns, 12 subdomains, tolerance 1e-6) on 2 ranks against 1, the
    best of 4 repeats after the first (issue 12: ≥ 1.6×); `new`: new material data each time."""
    name = Path(study).stem
    out = _bench("speedup", study, "--mesh-scale", scale, "--repeat", "5", "--tolerance", "1e-6",
                 *(["--new-data"] if data == "new" else []), "--out", str(OUT / f"dd_mpi_solve_{name}_{data}.json"))
    assert "bitwise identical (u, lam_n, lam_t, PCG1 residuals, ‖ΔU‖ / Newton residual history): True" in out
    speedup = float(out.split("one DD solve: ")[1].split()[0])
    assert speedup >= 1.6, out


@pytest.mark.bench
def test_dd_study_on_two_ranks():
    """A whole `dd` study (the tunnel, 12 subdomains): each rank solves its share of every batch
    (issue 12: ≥ 1.6× on 2 ranks)."""
    out = _bench("study-speedup", "studies/tunnel-fault.yaml", "--method", "dd", "--budget", "80",
                 "--out", str(OUT / "dd_mpi_study.json"))
    assert "bitwise identical (x, phi, worst_value, worst_x): True" in out
    speedup = float(out.split("speed-up of the study, 2 vs 1 rank(s): ")[1].split()[0])
    assert speedup >= 1.6, out
