"""The results-file helpers of wcs/results/dataset.py: units, status flags, the run layout, NetCDF round trip."""
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import wcs
from wcs.model.evaluation import Evaluator
from wcs.results.dataset import parameter_units, run_dataset, status_attrs, worst_field_variables, write_netcdf
from wcs.status import Status

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("path,units", [
    ("materials.steel.E", "Pa"), ("materials.steel.nu", "1"), ("materials.steel.expansion", "K-1"),
    ("loads.top.traction.1", "Pa"), ("body_forces.base.1", "N m-3"), ("supports.left.u.0", "m"),
    ("contacts.interface.friction.slip_limit[3]", "Pa"), ("thermal.temperature.top", "K"),
    ("thermal.sources.pad", "W m-3"), ("materials.rock.conductivity", "W m-1 K-1"),
])
def test_parameter_units(path, units):
    assert parameter_units(path) == units


def test_status_flags_are_cf():
    a = status_attrs()
    assert list(a["flag_values"]) == list(range(len(Status)))
    words = a["flag_meanings"].split()
    assert len(words) == len(Status) and words[0] == "solved"
    assert all(w.replace("_", "").isalnum() for w in words)


@pytest.fixture(scope="module")
def heated():
    study = wcs.load_study(ROOT / "studies" / "heated-plate.yaml")
    ev = Evaluator(study)
    return study, ev, ev.evaluate(study.nominal())


def _record(res, stage="sample"):
    return {"x": res.x, "phi": np.array(list(res.phi.values())), "status": 0, "message": "solved",
            "stage": stage, "iterations": 0, "wall_time": 0.1, "grad": None, "nonsmooth": 0}


def test_empty_run_round_trips(heated, tmp_path):
    study, ev, _ = heated
    ds = run_dataset(study, ev, [], worst={}, certificate={})
    assert ds.sizes["eval"] == 0 and ds["x"].shape == (0, 5)
    assert np.isnan(ds["worst_value"]).all() and (ds["worst_eval"] == -1).all()
    write_netcdf(ds, tmp_path / "empty.nc")
    back = xr.open_dataset(tmp_path / "empty.nc", engine="h5netcdf")
    assert back.sizes["eval"] == 0 and back.attrs["study_sha256"] == study.sha256


def test_run_dataset_round_trip(heated, tmp_path):
    study, ev, res = heated
    recs = [_record(res, "centre"), _record(res)]
    recs[1]["status"], recs[1]["phi"] = 3, np.full(3, np.nan)
    worst = {c: (res.phi[c], res.x, 0) for c in res.phi}
    fields = {"heave": res.fields, "shear": res.fields, "temperature": None}
    ds = run_dataset(study, ev, recs, worst=worst, certificate={"heave": "corner-kkt"}, worst_fields=fields)
    write_netcdf(ds, tmp_path / "r.nc")
    back = xr.open_dataset(tmp_path / "r.nc", engine="h5netcdf")
    assert list(back["stage"].values) == ["centre", "sample"] and list(back["status"].values) == [0, 3]
    assert list(back["certificate"].values) == ["corner-kkt", "heuristic", "heuristic"]
    assert back["worst_displacement"].dims == ("criterion", "node", "dim")
    assert np.array_equal(back["worst_displacement"].values[0], res.fields["displacement"].values)
    assert np.isnan(back["worst_temperature"].values[2]).all()
    assert back["margin"].sel(criterion="heave") == pytest.approx(1e-4 - res.phi["heave"])
    assert "coords" in back and "worst_coords" not in back and "worst_cells" not in back


def test_worst_fields_none_without_data(heated):
    assert worst_field_variables(["a"], {"a": None}) == {}
