"""`pip install .` (not editable) into a fresh venv, then `wcs run` from outside the clone of
a study that names a shipped material library and includes a shipped preset
(`include: configs/search-quick.yaml`): both come from the installed package (configs/).

The fresh venv has no packages of its own but wcs: a .pth file lends it the test
interpreter's site-packages for the dependencies and pip (pip still fetches the build
backend, setuptools, from the configured index for its isolated build). A .pth line only appends a folder to sys.path (the test venv's own .pth files,
e.g. an editable wcs, are not run), and the venv's site-packages comes first, so `import wcs`
is the installed copy; the test checks that it is.
"""
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

import wcs

REPO = Path(__file__).resolve().parents[2]
BUDGET = 6


def _not_copied(folder, names) -> list[str]:
    """What the copy leaves out: the clone's own runs (its top-level results/, not the package
    wcs/results/), git, venvs and build leftovers."""
    skip = {".git", ".venv", "build", "__pycache__", ".pytest_cache"} | ({"results"} if Path(folder) == REPO else set())
    return [n for n in names if n in skip or n.endswith(".egg-info")]


def _run(*args, cwd):
    done = subprocess.run([str(a) for a in args], cwd=cwd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{args}\n{done.stdout}\n{done.stderr}"
    return done.stdout


@pytest.mark.slow
def test_installed_wcs_runs_a_study_with_a_shipped_library(tmp_path):
    src = tmp_path / "src"                       # pip builds in-tree: build a copy, not the clone
    shutil.copytree(REPO, src, ignore=_not_copied)
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", venv], check=True)
    python = venv / "bin" / "python"
    site = Path(_run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])", cwd=tmp_path).strip())
    (site / "shared-deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    # a plain `pip install .` (its build backend fetched into an isolated build env) with the
    # dependencies already present; --ignore-installed: never touch the lent site-packages' wcs
    _run(python, "-m", "pip", "install", "--no-deps", "--ignore-installed", "--quiet", src, cwd=tmp_path)

    outside = tmp_path / "elsewhere"             # no source tree, no material library
    outside.mkdir()
    doc = yaml.safe_load((REPO / "studies" / "heated-plate.yaml").read_text())
    doc["scene"]["materials"] = "materials-basic.yaml"
    doc["scene"]["mesh"] = {"size": 0.125}
    doc["search"] = {"method": "sample", "sample": {"n": BUDGET}, "budget": BUDGET}
    (outside / "plate.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))

    where = _run(python, "-c", "import wcs; print(wcs.__file__)", cwd=outside).strip()
    assert Path(where).is_relative_to(site), where
    _run(venv / "bin" / "wcs", "run", "--quiet", "plate.yaml", "-o", "plate.nc", cwd=outside)

    with xr.open_dataset(outside / "plate.nc") as ds:
        assert ds.sizes["eval"] == BUDGET
        assert (ds["status"].values == 0).all()
        assert "aluminium:" in ds.attrs["study_yaml"]      # the library's text is recorded
        assert "# shipped library search-quick.yaml\n" in ds.attrs["study_yaml"]   # and the preset's
        x = ds["x"].values[0]
        phi = dict(zip(ds["criterion"].values.tolist(), ds["phi"].values[0]))
    # the same study loaded here (the clone's wcs) gives the same numbers at the same data
    ev = wcs.load_study(outside / "plate.yaml").evaluate(x)
    assert set(ev.phi) == set(phi) and len(phi) == 3
    for name, value in phi.items():             # same code, same mesh: round-off at most
        np.testing.assert_allclose(ev.phi[name], value, rtol=1e-10, err_msg=name)
