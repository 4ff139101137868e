"""The seismic tunnel study as a user runs it (`studies/tunnel-fault-seismic.yaml`), at a
coarse time step and a short end time: a run killed midway and resumed, and a run on two MPI
ranks, give the serial run's bits; the search as the study file sets it (auto, without adjoint
gradients through time)."""
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from tests.support.bad_studies import write_study
from wcs.cli import main
from wcs.results.store import store_path
from tests.support.processes import wait_for_records

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
COMPARED = ("x", "phi", "phi_history", "status", "stage", "worst_value", "worst_x", "worst_displacement",
            "worst_contact_pressure")
BUDGET = 14


def short_seismic() -> dict:
    """The study file with 20 levels of 0.01 s (the wavelet's first half, to 0.2 s) and a budget
    of 14 evaluations (auto: its first sample, then restarts)."""
    doc = yaml.safe_load((ROOT / "studies" / "tunnel-fault-seismic.yaml").read_text())
    doc["dynamics"].update({"end_time": 0.2, "time_step": 0.01, "output_every": 5})
    doc.pop("include", None)
    doc["search"] = {"method": "auto", "budget": BUDGET}
    return doc


def _run(args, cwd, env=None, **kw):
    return subprocess.Popen([str(BIN / "wcs"), *args], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def _env():
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_"))}
    env["PYTHONPATH"] = str(ROOT)
    return env


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    folder = tmp_path_factory.mktemp("seismic")
    path = write_study(short_seismic(), folder, "seismic.yaml")
    out = folder / "serial.nc"
    assert main(["run", str(path), "-o", str(out), "--quiet", "--no-mesh-check"]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        return path, ds.load()


def _same(a: xr.Dataset, b: xr.Dataset):
    for v in COMPARED:
        assert np.array_equal(a[v].values, b[v].values), v


@pytest.mark.slow
def test_the_short_seismic_run_searches_its_four_numbers(serial):
    _, ds = serial
    assert ds.sizes["eval"] <= BUDGET and (ds["status"].values == 0).all()
    assert ds.sizes["param"] == 4 and ds.sizes["time"] == 21
    assert ds.attrs["gradients"].startswith("adjoint through time")


@pytest.mark.slow
def test_a_killed_seismic_run_resumes_to_the_serial_bits(serial, tmp_path):
    path, ds = serial
    shutil.copy(path, tmp_path / "seismic.yaml")
    out = tmp_path / "killed.nc"
    proc = _run(["run", "seismic.yaml", "-o", out.name, "--quiet", "--no-mesh-check"], tmp_path, _env())
    store = store_path(out)
    wait_for_records(proc, out, 4, seconds=600)
    assert proc.poll() is None, proc.communicate()
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    stored = len(list(store.glob("*.npz")))
    assert 4 <= stored < ds.sizes["eval"]
    assert main(["run", str(tmp_path / "seismic.yaml"), "-o", str(out), "--resume", "--quiet", "--no-mesh-check"]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as r:
        assert r.attrs["answered_from_store"] == stored and r.attrs["complete"] == "yes"
        _same(r, ds)


@pytest.mark.slow
def test_two_ranks_give_the_serial_seismic_run_bitwise(serial, tmp_path):
    mpiexec = BIN / "mpiexec"
    if not mpiexec.exists():
        pytest.fail("mpiexec is missing from the environment (the mpich wheel provides it)")
    path, ds = serial
    shutil.copy(path, tmp_path / "seismic.yaml")
    run = subprocess.run([str(mpiexec), "-n", "2", str(BIN / "wcs"), "run", "seismic.yaml", "-o", "mpi.nc",
                          "--quiet", "--no-mesh-check"], cwd=tmp_path, env=_env(), capture_output=True, text=True,
                         timeout=900)
    assert run.returncode == 0, run.stderr + run.stdout
    with xr.open_dataset(tmp_path / "mpi.nc", engine="h5netcdf") as m:
        _same(m, ds)
