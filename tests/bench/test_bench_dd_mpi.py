"""DD over MPI ranks (`python tests/bench/dd_bench.py`): one large DD solve on 1 and 2 ranks (per-rank
timings, speed-up, bitwise identity) and a study on 1 and 2 ranks (evaluation-level speed-up).
Writes results/bench/dd_mpi_solve.json and dd_mpi_study.json. Run by `make bench`."""
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


@pytest.mark.bench
def test_dd_solve_on_two_ranks():
    out = _bench("speedup", "studies/tunnel-fault.yaml", "--mesh-scale", "0.4", "--repeat", "2",
                 "--out", str(OUT / "dd_mpi_solve.json"))
    assert "bitwise identical (u, lam_n, lam_t, PCG1 residuals, ‖ΔU‖ history): True" in out


@pytest.mark.bench
def test_dd_study_on_two_ranks():
    """A whole `dd` study (the tunnel, 12 subdomains): each rank solves its share of every batch
    (issue 12: ≥ 1.6× on 2 ranks)."""
    out = _bench("study-speedup", "studies/tunnel-fault.yaml", "--method", "dd", "--budget", "80",
                 "--out", str(OUT / "dd_mpi_study.json"))
    assert "bitwise identical (x, phi, worst_value, worst_x): True" in out
    speedup = float(out.split("speed-up of the study, 2 vs 1 rank(s): ")[1].split()[0])
    assert speedup >= 1.6, out
