"""wcs/results/netcdf.py writes what xarray's `to_netcdf(engine="h5netcdf")` writes: for the
solve files of shipped and validation studies (2D, 3D, thermal, contact, mortar, dynamic) and
the results files of runs (failed evaluations, worst-case fields, drivers, mesh check; fuzzy
levels and both ends; a dynamic run's histories), the
file reads back identical with xarray (values, dtypes, attributes, coordinates, strings, NaN)
and holds the same HDF5 datasets (dtype, shape, fill value, every attribute but the object
references of the dimension scales)."""
import io
from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray as xr

import wcs
from tests.dynamics.test_run import tiny
from tests.support.bad_studies import write_study
from wcs.app.runner import CheckedRunner
from wcs.app.dynamics import history_dataset
from wcs.dynamics.history import DynamicEvaluator, simulate
from wcs.model.evaluation import Evaluator
from wcs.model.fields import Data
from wcs.results.dataset import run_dataset, solve_dataset, write_netcdf
from wcs.results.netcdf import encode
from wcs.study.source import _read_yaml

ROOT = Path(__file__).resolve().parents[2]
REFERENCES = ("DIMENSION_LIST", "REFERENCE_LIST")      # HDF5 object references: compared as dims by xarray


def reference(ds) -> bytes:
    """What xarray writes for the same content."""
    return bytes((ds.to_xarray() if isinstance(ds, Data) else ds).to_netcdf(engine="h5netcdf"))


def same_value(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.dtype == b.dtype and a.shape == b.shape and (
            np.array_equal(a, b, equal_nan=True) if a.dtype.kind in "iuf" else np.array_equal(a, b))
    return type(a) is type(b) and (a == b or (a != a and b != b))


def hdf5_content(data: bytes) -> dict:
    """{name: (dtype, shape, fill value, attributes)} of every dataset, and the file's attributes."""
    out = {}
    with h5py.File(io.BytesIO(data), "r") as f:
        out["/"] = {k: v for k, v in f.attrs.items()}
        for name, d in f.items():
            out[name] = (d.dtype, d.shape, d.fillvalue, {k: v for k, v in d.attrs.items() if k not in REFERENCES})
    return out


def assert_same_file(ours: bytes, theirs: bytes):
    a, b = hdf5_content(ours), hdf5_content(theirs)
    assert a.keys() == b.keys()
    for name in a:
        if name == "/":
            assert a[name].keys() == b[name].keys()
            assert all(same_value(a[name][k], b[name][k]) for k in a[name]), name
            continue
        (dt, shape, fill, attrs), (dt2, shape2, fill2, attrs2) = a[name], b[name]
        assert (dt, shape) == (dt2, shape2), name
        assert same_value(fill, fill2), name
        assert attrs.keys() == attrs2.keys(), name
        assert all(same_value(attrs[k], attrs2[k]) for k in attrs), name
    with xr.open_dataset(io.BytesIO(ours), engine="h5netcdf") as x, \
            xr.open_dataset(io.BytesIO(theirs), engine="h5netcdf") as y:
        xr.testing.assert_identical(x.load(), y.load())
        for name in x.variables:
            assert x[name].dtype == y[name].dtype, name


SOLVES = ["studies/heated-plate.yaml",                         # 2D, thermal
          "studies/validation/contact-patch.yaml",             # 2D contact
          "studies/validation/mortar-patch.yaml",              # mortar
          "studies/validation/tresca-shear-patch-3d.yaml"]     # 3D contact, Tresca


@pytest.mark.parametrize("path", SOLVES)
def test_solve_file_is_what_xarray_writes(path, tmp_path):
    study = wcs.load_study(ROOT / path)
    ev = Evaluator(study)
    res = ev.evaluate(study.nominal())
    assert res.status == 0
    assert isinstance(res.fields, xr.Dataset)                 # the Python API's fields (docs/study-format.md §3)
    ds = solve_dataset(study, ev, res)
    out = write_netcdf(ds, tmp_path / "solve.nc")
    assert_same_file(out.read_bytes(), reference(ds))
    with xr.open_dataset(out, engine="h5netcdf") as back:
        assert list(back["dim"].values) == ["x", "y", "z"][:study.scene.dimension]
        assert list(back["criterion"].values) == [c.name for c in study.criteria]
        assert np.array_equal(back["displacement"].values, res.fields["displacement"].values)


def test_dynamic_solve_file_is_what_xarray_writes():
    study = wcs.load_study(ROOT / "studies/validation/two-bars-impact.yaml")
    ev = DynamicEvaluator(study)
    x, others = study.data_set(study.nominal())
    ds = history_dataset(study, ev, simulate(ev, x, others), x, others, 1.0)
    assert ds["displacement"].dims == ("output_time", "node", "dim") and "time" in ds.coords
    assert_same_file(encode(ds), reference(ds))


def test_run_file_is_what_xarray_writes(tmp_path):
    """A whole run (its worst-case fields, drivers, nominal case and mesh check), and a run file
    with a failed evaluation and a criterion without worst-case fields."""
    study = wcs.load_study(ROOT / "studies/validation/cooled-layer.yaml")
    ds = CheckedRunner(study, tmp_path / "run.nc", False, None, kind="run", where=(None, "-o")).run()
    assert "mesh_check_value" in ds and "worst_displacement" in ds
    assert_same_file(encode(ds), reference(ds))

    study = wcs.load_study(ROOT / "studies/heated-plate.yaml")
    ev = Evaluator(study)
    res = ev.evaluate(study.nominal())
    rec = {"x": res.x, "phi": np.array(list(res.phi.values())), "status": 0, "message": "solved",
           "stage": "centre", "iterations": 3, "wall_time": 0.1, "grad": None, "nonsmooth": 0}
    failed = {**rec, "status": 1, "phi": np.full(len(res.phi), np.nan), "message": "did not converge"}
    worst = {c: (res.phi[c], res.x, 0) for c in res.phi}
    names = list(res.phi)
    ds = run_dataset(study, ev, [rec, failed], worst=worst, certificate={names[0]: "corner-kkt"},
                     worst_fields={names[0]: res.fields, names[1]: None})
    assert np.isnan(ds["worst_displacement"].values[1]).all()
    assert_same_file(encode(ds), reference(ds))


def test_fuzzy_and_dynamic_run_files_are_what_xarray_writes(tmp_path):
    """A fuzzy run of both ends (the `level` coordinate, best_* and α-cuts) and a dynamic run
    (the `time` coordinate, histories, worst-case fields over the output times)."""
    doc = _read_yaml(ROOT / "studies/validation/cooled-layer.yaml")[0]
    doc["uncertain"]["materials.polymer.nu"] = {"support": [0.05, 0.45], "core": [0.25, 0.35]}
    doc["fuzzy"] = {"levels": [0.0, 1.0]}
    doc["criteria"][0]["sense"] = "both"
    doc["search"] = {"method": "auto", "budget": 30}
    ds = wcs.run(wcs.load_study(doc, base_dir=ROOT / "studies/validation"), output=False)
    assert "level" in ds.coords and "best_value" in ds
    assert_same_file(encode(ds), reference(ds))

    study = wcs.load_study(write_study(tiny(budget=2), tmp_path, "dynamic.yaml"))
    ds = wcs.run(study, output=False)
    assert "time" in ds.coords and "worst_displacement" in ds
    assert_same_file(encode(ds), reference(ds))


def test_non_dimension_coordinates_are_named_as_xarray_names_them():
    ds = Data({"a": (("n",), np.arange(3.0)), "s": ((), 2)},
              coords={"n": [1, 2, 3], "label": (("n",), np.array(["x", "yy", "z"], dtype=object)),
                      "t0": ((), 0.5), "alone": (("m",), [1.0, 2.0])})
    ours = encode(ds)
    assert_same_file(ours, reference(ds))
    with h5py.File(io.BytesIO(ours), "r") as f:
        assert f["a"].attrs["coordinates"] == "label t0" and f["s"].attrs["coordinates"] == "t0"
        assert f.attrs["coordinates"] == "alone"


@pytest.mark.parametrize("values", [np.array([True, False]), np.array([b"a", b"b"]),
                                    np.array(["a", 1], dtype=object)])
def test_what_is_not_written_is_refused(values):
    with pytest.raises(TypeError, match="variable 'v'"):
        encode(Data({"v": (("n",), values)}))
