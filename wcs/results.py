"""Results files: provenance attributes, the nominal-solve file, and the .vtu for ParaView.

NetCDF attributes hold strings and numbers only (no bool/dict/None).
"""
from __future__ import annotations

import datetime as _dt
import subprocess
from pathlib import Path

import numpy as np
import xarray as xr

from . import __version__, linalg


def git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent,
                             capture_output=True, text=True, timeout=5)
        return out.stdout.strip() if out.returncode == 0 else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def provenance(study, evaluator) -> dict:
    mesh = evaluator.smesh.mesh
    return {
        "Conventions": "CF-1.10",
        "title": f"wcs study {study.name}",
        "study": study.name,
        "study_yaml": study.text,
        "study_sha256": study.sha256,
        "wcs_version": __version__,
        "git_commit": git_commit(),
        "seed": int(study.search.get("sample", {}).get("seed", 0)),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "solver": f"{study.solver.get('method', 'auto')} ({linalg.backend()})",
        "plane": study.scene.get("plane", "strain"),
        "mesh_nodes": int(mesh.p.shape[1]),
        "mesh_cells": int(mesh.t.shape[1]),
    }


def parameter_variables(study) -> dict:
    params = study.parameters
    names = list(params.names)
    return {
        "param_lower": (("param",), np.asarray(params.lower, float), {"long_name": "lower bound of the box"}),
        "param_upper": (("param",), np.asarray(params.upper, float), {"long_name": "upper bound of the box"}),
    }, {"param": names}


def solve_dataset(study, evaluator, ev) -> xr.Dataset:
    """The file of `wcs solve`: the fields of one evaluation, its data set and criteria."""
    from .evaluation import STATUS
    ds = ev.fields.copy()
    pvars, pcoords = parameter_variables(study)
    for k, v in pvars.items():
        ds[k] = xr.Variable(*v)
    ds = ds.assign_coords(pcoords)
    ds["x"] = xr.Variable(("param",), ev.x, {"long_name": "the evaluated data set"})
    names = [c.name for c in evaluator.criteria]
    ds = ds.assign_coords(criterion=names)
    ds["phi"] = xr.Variable(("criterion",), np.array([ev.phi[n] for n in names], float),
                            {"long_name": "criterion values",
                             "units": ", ".join(f"{c.name}: {c.units}" for c in evaluator.criteria)})
    ds["status"] = xr.Variable((), np.int32(ev.status), {
        "flag_values": np.array(sorted(STATUS), dtype=np.int32),
        "flag_meanings": " ".join(v.replace(" ", "_").replace(":", "").replace(",", "") for _, v in sorted(STATUS.items())),
    })
    ds["iterations"] = xr.Variable((), np.int32(ev.iterations))
    ds["wall_time"] = xr.Variable((), float(ev.wall_time), {"units": "s"})
    ds.attrs.update(provenance(study, evaluator))
    return ds


def write_netcdf(ds: xr.Dataset, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    ds.to_netcdf(tmp, engine="h5netcdf")
    tmp.replace(path)                    # never leave a half-written file under the real name
    return path


def write_vtu(ds: xr.Dataset, path: str | Path) -> Path:
    import meshio
    p = ds["coords"].values
    points = np.column_stack([p, np.zeros(len(p))])
    u = ds["displacement"].values
    point_data = {"displacement": np.column_stack([u, np.zeros(len(u))])}
    if "temperature" in ds:
        point_data["temperature"] = ds["temperature"].values
    s = ds["stress"].values
    cell_data = {
        "stress_xx": [s[:, 0]], "stress_yy": [s[:, 1]], "stress_zz": [s[:, 2]], "stress_xy": [s[:, 3]],
        "von_mises": [ds["von_mises"].values],
        "shear_stress_intensity": [ds["shear_stress_intensity"].values],
        "principal_1": [ds["principal_stress"].values[:, 0]],
        "principal_2": [ds["principal_stress"].values[:, 1]],
        "body": [ds["cell_body"].values], "region": [ds["cell_region"].values],
    }
    mesh = meshio.Mesh(points, [("triangle", ds["cells"].values)], point_data=point_data, cell_data=cell_data)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mesh.write(path)
    return path
