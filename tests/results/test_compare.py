"""`wcs compare A.nc B.nc [--rtol R] [--atol A]`: 0 equal, 4 different (with a table), 2 unreadable /
another study."""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from wcs.cli import main

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "studies" / "validation" / "stacked-layers.yaml"
BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two serial runs of one study (a tiny mesh, ~1 s each), with the mesh check skipped."""
    d = tmp_path_factory.mktemp("compare")
    shutil.copy(STUDY, d / "study.yaml")
    for name in ("a.nc", "b.nc"):
        assert main(["run", str(d / "study.yaml"), "-o", str(d / name), "--quiet", "--no-mesh-check"]) == 0
    return d


def _edited(src: Path, dst: Path, edit) -> Path:
    ds = xr.load_dataset(src, engine="h5netcdf")
    edit(ds)
    ds.to_netcdf(dst, engine="h5netcdf")
    return dst


def test_two_runs_of_one_study_agree(runs, capsys):
    assert main(["compare", str(runs / "a.nc"), str(runs / "b.nc"), "--atol", "0"]) == 0     # bitwise
    out = capsys.readouterr().out
    assert "agree exactly" in out and "worst_value" in out and "phi" in out
    assert main(["compare", str(runs / "a.nc"), str(runs / "b.nc")]) == 0       # no option: bitwise too
    assert "agree exactly" in capsys.readouterr().out
    assert main(["compare", str(runs / "a.nc"), str(runs / "b.nc"), "--rtol", "0"]) == 0
    assert "agree within rtol 0 and the default floors" in capsys.readouterr().out


def test_one_changed_evaluation_is_named(runs, capsys):
    ds = xr.load_dataset(runs / "a.nc", engine="h5netcdf")
    crit = str(ds["criterion"].values[0])
    old = float(ds["phi"].values[3, 0])

    def edit(ds):
        ds["phi"].values[3, 0] = np.nextafter(old, np.inf)       # the smallest change there is
    b = _edited(runs / "a.nc", runs / "one-changed.nc", edit)
    assert main(["compare", str(runs / "a.nc"), str(b), "--atol", "0"]) == 4
    out = capsys.readouterr().out
    assert "1 value(s) in phi" in out
    row = [line for line in out.splitlines() if line.startswith("phi ")]
    assert len(row) == 1 and f"eval=3, criterion={crit}" in row[0]
    assert repr(old) in row[0] and repr(float(np.nextafter(old, np.inf))) in row[0]
    # within a relative tolerance, or the default floors, the one-ulp change is no difference; a 1e-6 change is
    assert main(["compare", str(runs / "a.nc"), str(b), "--rtol", "1e-12", "--atol", "0"]) == 0
    assert main(["compare", str(runs / "a.nc"), str(b), "--rtol", "0"]) == 0
    assert main(["compare", str(runs / "a.nc"), str(b)]) == 4          # no option: bitwise

    def bigger(ds):
        ds["worst_value"].values[0] *= 1 + 1e-6
    c = _edited(runs / "a.nc", runs / "worst-changed.nc", bigger)
    assert main(["compare", str(runs / "a.nc"), str(c), "--rtol", "1e-9"]) == 4
    assert "worst_value" in capsys.readouterr().out


def test_a_missing_nan_or_extra_variable_is_a_difference(runs, capsys):
    def nan_status(ds):
        ds["phi"].values[0, 0] = np.nan
        ds["best_value"] = ds["worst_value"]
    b = _edited(runs / "a.nc", runs / "nan.nc", nan_status)
    assert main(["compare", str(runs / "a.nc"), str(b)]) == 4
    out = capsys.readouterr().out
    assert re.search(r"^best_value\s+-\s+absent\s+present$", out, re.M)
    assert re.search(r"^phi\s+eval=0, criterion=\S+\s+\S+\s+nan$", out, re.M)


def test_unreadable_or_another_study_is_exit_2(runs, capsys):
    bad = runs / "bad.nc"
    bad.write_text("not netcdf")
    assert main(["compare", str(runs / "a.nc"), str(bad)]) == 2
    assert "bad.nc" in capsys.readouterr().err
    assert main(["compare", str(runs / "a.nc"), str(runs / "missing.nc")]) == 2

    def other(ds):
        ds.attrs["study_sha256"] = "0" * 64
    b = _edited(runs / "a.nc", runs / "other.nc", other)
    assert main(["compare", str(runs / "a.nc"), str(b)]) == 2
    assert "different studies" in capsys.readouterr().err


def test_one_and_two_mpi_ranks_agree(runs):
    mpiexec = BIN / "mpiexec"
    if not mpiexec.exists():
        pytest.fail("mpiexec is missing from the environment (the mpich wheel provides it)")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_"))}
    env["PYTHONPATH"] = str(ROOT)                  # this tree's wcs, whatever the venv installed
    cmd = [str(mpiexec), "-n", "2", sys.executable, "-m", "wcs.cli", "run", "study.yaml", "-o", "mpi.nc",
           "--quiet", "--no-mesh-check"]
    p = subprocess.run(cmd, cwd=runs, env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr + p.stdout
    assert main(["compare", str(runs / "a.nc"), str(runs / "mpi.nc"), "--atol", "0"]) == 0     # bitwise


def test_round_off_in_gaps_is_no_difference_with_a_tolerance_and_a_real_one_is(runs, capsys):
    """Closed gaps are differences of positions: round-off of about 100 ulps of the model's extent
    (1e-14 m on a 120 m tunnel) differ by ~100 % relatively, so even `--rtol 1e-3`
    exited 4; the default floor (1e-12 of the gaps' scale, the coordinates') takes them as
    equal under any `--rtol` (0 included), while a change of 1e-6 of the extent in one gap still counts;
    no option, or `--atol 0`, compares bitwise (contract §6) and says the differences are below them.
    Slips are relative displacements: 100 ulps of the displacements' scale is round-off there."""
    ds = xr.load_dataset(runs / "a.nc", engine="h5netcdf")
    extent = float(np.abs(ds["coords"].values).max())
    noise = 100 * np.finfo(float).eps * extent
    gap = ds["worst_contact_gap"].values
    closed = np.abs(gap) < noise
    assert closed.sum() >= 5                       # the study has closed gaps: round-off about zero

    slip = ds["worst_contact_slip"].values
    assert (slip == 0).any()                       # a node at zero slip: any change is 100 % there
    slip_noise = 100 * np.finfo(float).eps * np.abs(ds["worst_displacement"].values).max()

    def round_off(ds):
        g = ds["worst_contact_gap"].values
        g[closed] += noise * np.where(np.arange(closed.sum()) % 2, 1.0, -1.0)
        ds["worst_contact_slip"].values[...] += slip_noise             # slips: round-off of the displacements
    b = _edited(runs / "a.nc", runs / "gap-round-off.nc", round_off)
    assert main(["compare", str(runs / "a.nc"), str(b), "--rtol", "0"]) == 0          # the floors alone
    assert "default floors" in capsys.readouterr().out
    assert main(["compare", str(runs / "a.nc"), str(b), "--rtol", "1e-3"]) == 0
    assert main(["compare", str(runs / "a.nc"), str(b), "--rtol", "1e-3", "--atol", "0"]) == 4
    assert main(["compare", str(runs / "a.nc"), str(b)]) == 4                         # bitwise (contract §6)
    assert main(["compare", str(runs / "a.nc"), str(b), "--atol", "0"]) == 4          # bitwise
    assert "note: every difference is below the default floors" in capsys.readouterr().out

    def real(ds):
        round_off(ds)
        ds["worst_contact_gap"].values[np.flatnonzero(closed.ravel())[0] // gap.shape[-1],
                                       np.flatnonzero(closed.ravel())[0] % gap.shape[-1]] += 1e-6 * extent
    c = _edited(runs / "a.nc", runs / "gap-real.nc", real)
    assert main(["compare", str(runs / "a.nc"), str(c), "--rtol", "0"]) == 4
    out = capsys.readouterr().out
    assert "1 value(s) in worst_contact_gap" in out
    assert main(["compare", str(runs / "a.nc"), str(c), "--rtol", "1e-3"]) == 4
    assert main(["compare", str(runs / "a.nc"), str(c), "--atol", "0"]) == 4
    assert "note: every difference" not in capsys.readouterr().out     # a real one among them


def test_atol_is_an_absolute_tolerance_on_every_float(runs, capsys):
    ds = xr.load_dataset(runs / "a.nc", engine="h5netcdf")
    w = float(ds["worst_value"].values[0])

    def shifted(ds):
        ds["worst_value"].values[0] = w + 1e-3 * abs(w)
    b = _edited(runs / "a.nc", runs / "atol.nc", shifted)
    assert main(["compare", str(runs / "a.nc"), str(b), "--atol", f"{2e-3 * abs(w)!r}"]) == 0
    assert main(["compare", str(runs / "a.nc"), str(b), "--atol", f"{0.5e-3 * abs(w)!r}"]) == 4
    capsys.readouterr()
    for bad in ("-1", "nan", "inf"):
        assert main(["compare", str(runs / "a.nc"), str(b), "--atol", bad]) == 2
        assert "--atol must be a finite number >= 0" in capsys.readouterr().err
