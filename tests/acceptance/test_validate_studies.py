"""`make validate`: every study in studies/ (and studies/validation/) runs end to end.

Each study is run by `wcs run` at a small budget (BUDGET solves, the mesh as in the
file) from a copy of its file; the run must solve every evaluation (status 0), write a
results file with every variable wcs.results.dataset.run_dataset writes, and `wcs report` must make an
HTML page with all its sections. The tunnel study must show the seed's qualitative
picture: the fault slips, and stresses concentrate at the tunnel wall
(studies/figures.py computes the numbers and draws results/tunnel-*.png).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from wcs.cli import main

ROOT = Path(__file__).resolve().parents[2]
ALL_STUDIES = sorted((ROOT / "studies").glob("*.yaml")) + sorted((ROOT / "studies" / "validation").glob("*.yaml"))
DYNAMIC = [p for p in ALL_STUDIES if "dynamics" in (yaml.safe_load(p.read_text()) or {})]   # `wcs solve` runs them
STUDIES = [p for p in ALL_STUDIES if p not in DYNAMIC or "uncertain" in yaml.safe_load(p.read_text())]   # `wcs run`
BUDGET = 10
# the fine 3D tunnel's cold nominal solve is minutes (4.5 min of CPU on a loaded machine): 3 solves keep it in the timeout
BUDGETS = {"tunnel-fault-3d-fine": 3}

RUN_VARS = ("param", "param_lower", "param_upper", "x", "phi", "status", "stage", "wall_time",
            "iterations", "worst_value", "worst_x", "limit")
RUN_ATTRS = ("study", "study_yaml", "study_sha256", "wcs_version", "seed", "created", "solver",
             "mesh_nodes", "mesh_cells")
FIELD_VARS = ("coords", "cells", "worst_displacement", "worst_stress", "worst_von_mises",
              "worst_principal_stress", "worst_shear_stress_intensity")
CONTACT_VARS = ("contact_coords", "contact_pair", "worst_contact_pressure", "worst_contact_gap",
                "worst_contact_slip", "worst_contact_shear")


def _id(path: Path) -> str:
    return f"{path.parent.name}/{path.stem}" if path.parent.name == "validation" else path.stem


def small_copy(path: Path, folder: Path, budget: int = BUDGET) -> Path:
    """The study with search.budget = budget, written into `folder`; files the study names
    relative to itself (meshes/) stay reachable through a link, material libraries are
    found among the shipped ones as for any study."""
    doc = yaml.safe_load(path.read_text())
    doc.setdefault("search", {})
    doc["search"] = {**(doc["search"] or {}), "budget": budget}
    folder.mkdir(parents=True, exist_ok=True)
    for sub in path.parent.iterdir():
        if sub.is_dir() and not (folder / sub.name).exists():
            (folder / sub.name).symlink_to(sub, target_is_directory=True)
    for lib in path.parent.glob("materials*.yaml"):
        (folder / lib.name).write_text(lib.read_text())
    out = folder / path.name
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


_RUNS: dict[Path, tuple[Path, dict]] = {}


@pytest.fixture(scope="module")
def run_study(tmp_path_factory):
    """Run (once per module) a study at the small budget -> (results file, study doc)."""
    def run(path: Path):
        if path not in _RUNS:
            folder = tmp_path_factory.mktemp(path.stem)
            study = small_copy(path, folder, BUDGETS.get(path.stem, BUDGET))
            nc = folder / f"{path.stem}.nc"
            assert main(["run", str(study), "-o", str(nc), "--quiet"]) == 0, path.name
            _RUNS[path] = (nc, yaml.safe_load(study.read_text()))
        return _RUNS[path]
    return run


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("path", STUDIES, ids=[_id(p) for p in STUDIES])
def test_study_runs_and_reports(path, run_study, tmp_path):
    from tests.report.test_report import check_page

    nc, doc = run_study(path)
    with xr.open_dataset(nc, engine="h5netcdf") as ds:
        ds = ds.load()
    missing = [v for v in RUN_VARS if v not in ds.variables]
    assert not missing, f"results file lacks {missing}"
    missing = [a for a in RUN_ATTRS if a not in ds.attrs]
    assert not missing, f"results file lacks attributes {missing}"
    n = ds.sizes["eval"]
    assert 1 <= n <= BUDGET
    bad = {int(i): str(m) for i, m in zip(np.flatnonzero(ds["status"].values), ds["message"].values[ds["status"].values != 0])} \
        if "message" in ds else np.flatnonzero(ds["status"].values).tolist()
    assert not bad, f"failed evaluations: {bad}"
    assert np.isfinite(ds["phi"].values).all()
    assert np.isfinite(ds["worst_value"].values).all()
    for j, c in enumerate(map(str, ds["criterion"].values)):
        assert ds["worst_value"].values[j] == pytest.approx(np.max(ds["phi"].values[:, j])), c
    missing = [v for v in FIELD_VARS if v not in ds.variables]
    assert not missing, f"results file lacks the worst-case fields {missing}"
    scene = doc["scene"] if isinstance(doc["scene"], dict) else {}
    if scene.get("contacts"):
        missing = [v for v in CONTACT_VARS if v not in ds.variables]
        assert not missing, f"results file lacks the contact fields {missing}"
    if scene.get("thermal"):
        assert "worst_temperature" in ds.variables
    html = tmp_path / f"{path.stem}.html"
    assert main(["report", str(nc), "-o", str(html), "--quiet"]) == 0
    page = check_page(html.read_text())
    for c in map(str, ds["criterion"].values):
        verdict = page.limit_row(c)["verdict"]["text"]
        assert verdict.removesuffix(" (mesh share unknown)") in ("PASS", "FAIL", "no limit"), (c, verdict)
    if path.stem in ("tunnel-fault-3d", "knee-replacement-3d"):    # the assessor turns the model in Chromium
        from tests.report.test_report_3d import drive_view
        drive_view(html, tmp_path)


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("path", DYNAMIC, ids=[_id(p) for p in DYNAMIC])
def test_dynamic_study_solves(path, tmp_path):
    """A dynamic study runs its levels by `wcs solve`: the history of every criterion at every
    level, finite, and the ParaView series."""
    nc = tmp_path / f"{path.stem}.nc"
    assert main(["solve", str(path), "-o", str(nc), "--quiet"]) == 0, path.name
    with xr.open_dataset(nc, engine="h5netcdf") as ds:
        assert ds["phi_history"].dims == ("criterion", "time")
        assert np.isfinite(ds["phi_history"].values).all()
    assert nc.with_suffix(".pvd").is_file()


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_tunnel_shows_the_seed_picture(run_study, tmp_path):
    """The fault slips (slip > 0 on both parts, a slip zone over most of each) and the
    stresses concentrate at the tunnel wall: the shear stress intensity next to the
    tunnel (r < 8 m) is several times its mean elsewhere, and the largest von Mises
    stress away from the outer boundary is at the wall."""
    sys.path.insert(0, str(ROOT / "studies"))
    import figures

    nc, _ = run_study(ROOT / "studies" / "tunnel-fault.yaml")
    with xr.open_dataset(nc, engine="h5netcdf") as ds:
        ds = ds.load()
    for crit in map(str, ds["criterion"].values):
        p = figures.picture(ds, crit)
        for part in ("fault_west", "fault_east"):
            assert p[f"max_slip_{part}"] > 5e-3, (crit, part, p)          # centimetres, as the seed's Fig. 4
            assert p[f"slipping_share_{part}"] > 0.5, (crit, part, p)
            assert p[f"max_pressure_{part}"] > 0.0
        assert p["I2_ratio"] > 3.0, (crit, p)
        assert p["max_von_mises_inner_r"] < figures.NEAR, (crit, p)
        assert p["max_von_mises_near"] > p["max_von_mises_inner_elsewhere"], (crit, p)
    slip_png = figures.slip_figure(ds, tmp_path / "tunnel-slip.png")
    stress_png, _ = figures.stress_figure(ds, tmp_path / "tunnel-stress.png")
    for png in (slip_png, stress_png):
        assert png.stat().st_size > 20_000
