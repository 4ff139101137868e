"""`mpiexec -n 2 wcs run`: the same results file as the serial run, bit for bit."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

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
