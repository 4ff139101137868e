"""`mpiexec -n 2 wcs run`: the same results file as the serial run, bit for bit."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from tests.support.processes import wait_until

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "studies" / "validation" / "stacked-layers.yaml"
BIN = Path(sys.executable).parent


def serial_and_two_ranks(folder: Path) -> tuple[xr.Dataset, xr.Dataset]:
    """`wcs run study.yaml` in `folder`, serially and under `mpiexec -n 2` (this checkout's wcs
    on every rank): the two results files, both runs having exited 0."""
    mpiexec = BIN / "mpiexec"
    if not mpiexec.exists():
        pytest.fail("mpiexec is missing from the environment (the mpich wheel provides it)")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_"))}
    env["PYTHONPATH"] = str(ROOT)
    run = lambda *cmd: subprocess.run([*cmd], cwd=folder, env=env, capture_output=True, text=True, timeout=600)  # noqa: E731
    serial = run(str(BIN / "wcs"), "run", "study.yaml", "-o", "serial.nc", "--quiet")
    assert serial.returncode == 0, serial.stderr
    parallel = run(str(mpiexec), "-n", "2", str(BIN / "wcs"), "run", "study.yaml", "-o", "mpi.nc", "--quiet")
    assert parallel.returncode == 0, parallel.stderr + parallel.stdout
    return (xr.open_dataset(folder / "serial.nc", engine="h5netcdf"),
            xr.open_dataset(folder / "mpi.nc", engine="h5netcdf"))


def test_two_ranks_give_the_serial_results_bitwise(tmp_path):
    shutil.copy(STUDY, tmp_path / "study.yaml")
    a, b = serial_and_two_ranks(tmp_path)
    assert a.sizes["eval"] == b.sizes["eval"] >= 10
    for v in ("x", "phi", "grad", "status", "worst_value", "worst_x", "worst_displacement",
              "worst_stress", "worst_contact_pressure"):
        assert np.array_equal(a[v].values, b[v].values, equal_nan=True), v


def test_dd_study_on_two_ranks_matches_serial(tmp_path):
    """solver.method dd under mpiexec: each rank solves its share of a batch by a serial DD."""
    import yaml
    doc = yaml.safe_load((STUDY.parent / "contact-patch.yaml").read_text())
    doc["solver"] = {"method": "dd", "dd": {"subdomains": 6}}
    doc["search"] = {"method": "auto", "budget": 8}
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(doc))
    a, b = serial_and_two_ranks(tmp_path)
    assert "dd" in a.attrs["solver"]
    for v in ("x", "phi", "status", "worst_value", "worst_x", "worst_displacement"):
        assert np.array_equal(a[v].values, b[v].values, equal_nan=True), v



KILLED_RUN = """
import os
import signal
import sys

sys.path.insert(0, {root!r})
import wcs.app.runner
from wcs.search import Batch, Worst


def one_batch(problem, config, rng):
    # the centre, then one batch of 12 samples: the kill lands inside it
    lo, hi = problem.lower, problem.upper
    seen = list((yield Batch((0.5 * (lo + hi))[None, :], "centre", True)))
    seen += (yield Batch(lo + (hi - lo) * rng.random((12, len(lo))), "sample", False))
    best = {{c: max(seen, key=lambda o: o.phi[c]) for c in problem.criteria}}
    return Worst(x={{c: o.x for c, o in best.items()}}, value={{c: o.phi[c] for c, o in best.items()}},
                 certificate={{c: "heuristic" for c in best}})


wcs.app.runner.get_strategy = lambda name: one_batch
evaluate, samples = wcs.app.runner.Runner.evaluate, []
hang = int(os.environ.get("HANG_AT_SAMPLE", "0"))


def held(self, point, gradients, stage):
    # HANG_AT_SAMPLE=n: this rank stops at its n-th sample (it has solved n - 1 of them), saying so
    samples.extend([stage] if stage == "sample" else [])
    if hang and len(samples) >= hang:
        open(f"held.{{os.getpid()}}", "w").close()
        signal.pause()                      # until the test kills it
    return evaluate(self, point, gradients, stage)


wcs.app.runner.Runner.evaluate = held
from wcs.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_run_killed_mid_batch_on_two_ranks_keeps_what_it_solved_and_resumes_bitwise(tmp_path):
    """Under mpiexec -n 2 each rank stores an evaluation as soon as it is solved, not at the
    batch's gather: each rank held at its 4th sample of a batch of 12 (3 solved), the store holds
    the centre and those 6; killed there (SIGKILL to the launcher and both ranks), `--resume` on
    two ranks solves only the other 6 and writes the uninterrupted run's file (x, phi, grad,
    status, the worst cases and their fields) bit for bit."""
    import signal

    from wcs.results.store import store_path
    mpiexec = BIN / "mpiexec"
    if not mpiexec.exists():
        pytest.fail("mpiexec is missing from the environment (the mpich wheel provides it)")
    shutil.copy(STUDY.parent / "tresca-pad.yaml", tmp_path / "study.yaml")
    script = tmp_path / "killed_run.py"
    script.write_text(KILLED_RUN.format(root=str(ROOT)))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_"))}
    env["PYTHONPATH"] = str(ROOT)

    def launch(out, *more, hang=0):
        return subprocess.Popen([str(mpiexec), "-n", "2", sys.executable, str(script), "run", "study.yaml", "-o", out,
                                 "--quiet", *more], cwd=tmp_path, env={**env, "HANG_AT_SAMPLE": str(hang)},
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)

    def finish(proc):
        out, err = proc.communicate(timeout=600)
        assert proc.returncode == 0, err + out

    finish(launch("clean.nc"))
    out = tmp_path / "killed.nc"
    proc = launch("killed.nc", hang=4)
    wait_until(proc, lambda: len(list(tmp_path.glob("held.*"))) >= 2, seconds=600, poll=0.05)
    os.killpg(proc.pid, signal.SIGKILL)       # mpiexec and both ranks (one session), in the middle of the batch
    said = proc.communicate()
    assert len(list(tmp_path.glob("held.*"))) == 2, said
    assert len(list(store_path(out).glob("*.npz"))) == 7
    finish(launch("killed.nc", "--resume"))
    clean = xr.open_dataset(tmp_path / "clean.nc", engine="h5netcdf")
    resumed = xr.open_dataset(out, engine="h5netcdf")
    assert clean.sizes["eval"] == resumed.sizes["eval"] == 13 and resumed.attrs["complete"] == "yes"
    assert resumed.attrs["answered_from_store"] == 7 and resumed.attrs["solves_this_session"] == 6
    worst = [v for v in clean.data_vars if v.startswith("worst_")]
    assert "worst_contact_pressure" in worst and "worst_displacement" in worst
    for v in ("x", "phi", "grad", "status", *worst):
        assert np.array_equal(clean[v].values, resumed[v].values, equal_nan=True), v
