"""Results files: provenance attributes, the nominal-solve file (and its ParaView files, `wcs.results.paraview`).

NetCDF attributes hold strings and numbers only (no bool/dict/None).

A file is encoded in memory and written with one plain write + rename
(`wcs.results.store.write_atomic`): a full disk or a removed folder is an ordinary
`WriteError` and the previous file stays whole, never a fault inside HDF5.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import datetime as _dt
import subprocess
from pathlib import Path

import numpy as np

from .. import linalg
from ..version import __version__
from ..contact.methods import krylov_counts
from ..model import validity
from ..model.dynamic_numbers import DYNAMIC_UNITS
from ..model.fields import Data
from ..status import Status, flag_attrs
from ..study.fuzzy import alpha_cut
from .dynamics import dynamic_results

if TYPE_CHECKING:
    import xarray as xr


def git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent,
                             capture_output=True, text=True, timeout=5)
        return out.stdout.strip() if out.returncode == 0 else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def provenance(study, evaluator, layout: tuple[int, int] = (1, 1)) -> dict:
    """The results file's attributes of the study, the code and the machine; layout: (MPI ranks,
    ranks each solve spanned) of the run (a solve: each rank alone)."""
    mesh = evaluator.smesh.mesh
    return {
        "Conventions": "CF-1.10",
        "title": f"wcs study {study.name}",
        "study": study.name,
        "study_yaml": study.text,
        "study_sha256": study.sha256,
        "wcs_version": __version__,
        "git_commit": git_commit(),
        "seed": study.search.sample.seed,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "solver": (f"{study.solver.method} (contact: PETSc CG + GAMG; direct solves: {linalg.direct_backend_used()})"
                   if evaluator.model.solver_method == "iterative" else f"{study.solver.method} ({linalg.backend()})"),
        "solver_choice": f"{evaluator.model.solver_method}: {evaluator.model.solver_reason}",   # auto's reason, the estimate
        "ranks": layout[0],                     # MPI ranks of the run
        "ranks_per_evaluation": layout[1],      # ranks each solve spanned (the ranks: that many groups)
        **({"dimension": 3} if study.scene.dimension == 3 else {"plane": study.scene.plane}),
        "mesh_nodes": int(mesh.p.shape[1]),
        "mesh_cells": int(mesh.t.shape[1]),
        "warnings": "\n".join(getattr(study, "warnings", None) or []),   # what `wcs check` warns of, one a line
    }


def open_results(path: str | Path) -> xr.Dataset:
    """The results file at `path`, opened (a context manager); xarray (with pandas, 43 MB)
    loads here, where a results file is read, not at the commands' import."""
    import xarray as xr
    return xr.open_dataset(path, engine="h5netcdf")


def scalars(values: dict) -> xr.Dataset:
    """A dataset of scalar variables {name: ((), value, attrs)} (xarray loaded here)."""
    import xarray as xr
    return xr.Dataset(values)


def parameter_variables(study) -> dict:
    params = study.parameters
    names = list(params.names)
    return {
        "param_lower": (("param",), np.asarray(params.lower, float), {"long_name": "lower bound of the box"}),
        "param_upper": (("param",), np.asarray(params.upper, float), {"long_name": "upper bound of the box"}),
    }, {"param": names}


ITERATIONS = ("outer iterations of the contact solve, per solver.method: monolithic and iterative their semismooth "
              "Newton steps (Coulomb: over all the Tresca problems of the fixed point), dd its successive "
              "approximations or interface Newton steps, qp 0 (the QP solver's own are not counted); where "
              "monolithic polished or replaced the answer (the message says so), monolithic's; 1 for a model "
              "without contact (one direct sparse solve); 0 for a failed evaluation")
KRYLOV_ITERATIONS = ("Krylov iterations of the contact solve in all: solver.method iterative the CG iterations "
                     "(GAMG-preconditioned) of all its Newton steps; 0 where no Krylov method solved it (monolithic, "
                     "qp, no contact: direct factorizations); -1 where not counted (dd: its PCG counts are in "
                     "`message`; a failed evaluation)")
KRYLOV_STEP_MAX = ("the most Krylov iterations of one outer step (iterative: one Newton step's CG iterations; "
                   "their mean is krylov_iterations / iterations); 0 and -1 as krylov_iterations")


def solve_dataset(study, evaluator, ev, layout: tuple[int, int] = (1, 1)) -> Data:
    """The file of `wcs solve`: the fields of one evaluation, its data set and criteria."""
    ds = ev.field_data.copy()
    pvars, pcoords = parameter_variables(study)
    for k, v in pvars.items():
        ds[k] = v
    for k, v in pcoords.items():
        ds.set_coord(k, v)
    ds["x"] = (("param",), ev.x, {"long_name": "the evaluated data set"})
    names = [c.name for c in evaluator.criteria]
    ds.set_coord("criterion", names)
    ds["phi"] = (("criterion",), np.array([ev.phi[n] for n in names], float),
                 {"long_name": "criterion values",
                  "units": ", ".join(f"{c.name}: {c.units}" for c in evaluator.criteria)})
    ds["status"] = ((), np.int32(ev.status), flag_attrs())
    ds["iterations"] = ((), np.int32(ev.iterations), {"long_name": ITERATIONS})
    total, most = krylov_counts(ev.krylov_steps)
    ds["krylov_iterations"] = ((), np.int32(total), {"long_name": KRYLOV_ITERATIONS})
    ds["krylov_step_max"] = ((), np.int32(most), {"long_name": KRYLOV_STEP_MAX})
    if ev.krylov_steps:
        ds["krylov_steps"] = (("outer_step",), np.asarray(ev.krylov_steps, np.int32),
                              {"long_name": "Krylov (CG) iterations of each outer (Newton) step, in order"})
    ds["wall_time"] = ((), float(ev.wall_time), {"units": "s"})
    units = ", ".join(f"{c.name}: {c.units}" for c in evaluator.criteria)
    ds["limit"] = (("criterion",), np.array([float(study.limits.get(n, np.nan)) for n in names]),
                   {"long_name": "limit of each criterion (NaN where none)", "units": units})
    if study.lower_limits:
        ds["limit_lower"] = (("criterion",), np.array([float(study.lower_limits.get(n, np.nan)) for n in names]),
                             {"long_name": "lower limit of each criterion (NaN where none)", "units": units})
    ds.attrs.update(provenance(study, evaluator, layout))
    ds.attrs["small_strain"] = "\n".join(validity.warnings(ds))
    return ds


def release_heap() -> None:
    """Return the C heap's free pages to the OS (glibc's `malloc_trim`; without glibc nothing):
    the arrays a solve freed stay resident in the heap otherwise (tens of MB on a 3D model), and
    what the results phase adds would stack on them."""
    import ctypes
    try:
        trim = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):
        return
    trim(0)


def write_netcdf(ds, path: str | Path) -> Path:
    """NetCDF-4 file of `ds` (a `Data` or an xarray.Dataset: `wcs.results.netcdf`) at `path`,
    whole or not at all (WriteError on an I/O fault)."""
    from .netcdf import encode
    from .store import WriteError, uninterrupted, write_atomic
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise WriteError(f"cannot create the folder of {path}: {e.strerror or e}") from None
    with uninterrupted():                           # a Ctrl-C waits for the end of the encoding
        data = encode(ds)                           # bytes in memory: HDF5 never meets the disk's faults
        write_atomic(path, lambda fh: fh.write(data))
    return path


# ---------------------------------------------------------------- the results file of a run or sweep

# units of each addressable number (study.py `_ADDRESSES`), by the last key of its path
_PARAM_UNITS = {
    "E": "Pa", "nu": "1", "lambda": "Pa", "mu": "Pa", "conductivity": "W m-1 K-1", "expansion": "K-1",
    "density_weight": "N m-3", "pressure": "Pa", "traction": "Pa", "u": "m", "normal": "m",
    "slip_limit": "Pa", "coefficient": "1", "reference": "K", "temperature": "K", "sources": "W m-3",
}
_BODY_FORCE_UNITS = "N m-3"

CERTIFICATES = "corner-kkt: KKT sign pattern holds at a vertex; local-kkt: KKT conditions hold at a " \
               "local maximum; heuristic: best value found, no optimality proof; grid: maximum over a sweep grid; " \
               "not-searched: the criterion's sense does not ask for this end; none: no successful evaluation " \
               "(for best_*: the same of the minimum, with the KKT signs of -Phi)"


def parameter_units(path: str) -> str:
    """Units of an addressable number (its dotted path, `[i]` of a profile ignored)."""
    from ..study.paths import _address
    pattern = _address(path.split("[")[0])
    if pattern is None:
        return "1"
    if pattern.startswith("body_forces"):
        return _BODY_FORCE_UNITS
    if pattern in DYNAMIC_UNITS:
        return DYNAMIC_UNITS[pattern]
    field = [k for k in pattern.split(".") if not k.startswith("<")][-1]
    return _PARAM_UNITS.get(field, "1")


def status_attrs() -> dict:
    return {"long_name": "evaluation status (0 solved)", **flag_attrs(),
            "codes": "; ".join(f"{s.value}: {s.description}" for s in Status)}


def _criterion_units(evaluator) -> dict:
    return {c.name: getattr(c, "units", "1") for c in evaluator.criteria}


# fields stored per criterion (leading `criterion` dim) and fields stored once (geometry)
_GEOMETRY = ("coords", "cells", "cell_body", "cell_region", "contact_coords", "contact_pair")


def worst_field_variables(criteria: list[str], fields: dict) -> dict:
    """`worst_<field>` (criterion, ...) for every solution field, plus the mesh variables once.

    `fields`: criterion -> the fields of its worst case (`Data`; None where no data set was solved).
    """
    import xarray as xr
    template = next((f for f in fields.values() if f is not None), None)
    if template is None:
        return {}
    out = {}
    for name in _GEOMETRY:
        if name in template:
            v = template[name]
            out[name] = xr.Variable(v.dims, v.values, v.attrs)
    for name, v in template.data_vars.items():
        if name in _GEOMETRY:
            continue
        stack = []
        for c in criteria:
            f = fields.get(c)
            stack.append(f[name].values if f is not None and name in f else np.full(v.shape, np.nan))
        attrs = dict(v.attrs)
        attrs["long_name"] = f"{attrs.get('long_name', name)} in the worst case of each criterion"
        out[f"worst_{name}"] = xr.Variable(("criterion",) + v.dims, np.stack(stack).astype(v.dtype), attrs)
    return out


def run_dataset(study, evaluator, records: list[dict], *, worst: dict, certificate: dict,
                notes: dict | None = None, worst_fields: dict | None = None, attrs: dict | None = None,
                sweep_paths: list[str] | None = None, provenance_attrs: dict | None = None,
                extremes: list | None = None) -> xr.Dataset:
    """The results file of `wcs run` / `wcs sweep`: `param` with its box `param_lower`/`param_upper`;
    per evaluation `x` (eval, param), `phi` (eval, criterion), `status`, `stage`, `wall_time`,
    `iterations`; per criterion `worst_value`, `worst_x`, `limit`; the study text in the attributes
    and the worst-case fields under a `worst_` prefix.

    records: one dict per evaluation, in order, with x, phi (array in criterion order), status,
    message, stage, iterations, wall_time, grad ((criterion, param) array or None), nonsmooth,
    and for sweeps `sweep` (values of the swept paths).
    worst: criterion -> (value, x, eval index); certificate: criterion -> string.
    extremes: every end of every range (`wcs.search.ranges.Extreme`; `range_variables`): the
    minima as best_*, and a fuzzy study's worst_*/best_* per α-level.
    """
    import xarray as xr
    names = list(study.parameters.names)
    lower = np.asarray(study.parameters.lower, float)
    upper = np.asarray(study.parameters.upper, float)
    crit = [c.name for c in evaluator.criteria]
    units = _criterion_units(evaluator)
    n, p, k = len(records), len(names), len(crit)

    def col(key, dtype, shape=()):
        if n == 0:
            return np.zeros((0,) + shape, dtype=dtype)
        return np.array([r[key] for r in records], dtype=dtype).reshape((n,) + shape)

    def counted(key):       # a record without Krylov counts (made by hand, an old store): not counted
        return np.array([r.get(key, -1) for r in records], dtype=np.int32)

    grad = np.full((n, k, p), np.nan)
    for i, r in enumerate(records):
        if r.get("grad") is not None:
            grad[i] = r["grad"]
    nan = float("nan")
    limits = np.array([float(study.limits.get(c, nan)) for c in crit])
    wv = np.array([worst[c][0] if c in worst else nan for c in crit], float)
    wx = np.stack([worst[c][1] if c in worst else np.full(p, nan) for c in crit]) if k else np.zeros((0, p))
    we = np.array([worst[c][2] if c in worst else -1 for c in crit], dtype=np.int32)
    unit_text = ", ".join(f"{c}: {units[c]}" for c in crit)

    data = {
        "param_lower": (("param",), lower, {"long_name": "lower bound of the box U_ad"}),
        "param_upper": (("param",), upper, {"long_name": "upper bound of the box U_ad"}),
        "param_units": (("param",), np.array([parameter_units(s) for s in names], dtype=object),
                        {"long_name": "units of each parameter"}),
        "x": (("eval", "param"), col("x", float, (p,)),
              {"long_name": "evaluated data set, in evaluation order (physical units, see param_units)",
               "valid_min": float(lower.min()) if p else 0.0, "valid_max": float(upper.max()) if p else 0.0,
               "ancillary_variables": "param_lower param_upper param_units",
               "comment": "valid_min/valid_max span all parameters; the box of each parameter is "
                          "param_lower/param_upper"}),
        "phi": (("eval", "criterion"), col("phi", float, (k,)),
                {"long_name": "criterion values (NaN where the evaluation failed)", "units": unit_text}),
        "status": (("eval",), col("status", np.int32), status_attrs()),
        "message": (("eval",), np.array([str(r["message"]) for r in records], dtype=object),
                    {"long_name": "solver message of the evaluation"}),
        "stage": (("eval",), np.array([str(r["stage"]) for r in records], dtype=object),
                  {"long_name": "search stage that asked for the evaluation"}),
        "wall_time": (("eval",), col("wall_time", float), {"long_name": "wall time of the evaluation", "units": "s"}),
        "iterations": (("eval",), col("iterations", np.int32), {"long_name": ITERATIONS}),
        "krylov_iterations": (("eval",), counted("krylov_iterations"), {"long_name": KRYLOV_ITERATIONS}),
        "krylov_step_max": (("eval",), counted("krylov_step_max"), {"long_name": KRYLOV_STEP_MAX}),
        "grad": (("eval", "criterion", "param"), grad,
                 {"long_name": "gradient dPhi/dx of each criterion (adjoint, on the active set of the evaluation); "
                               "NaN where not computed", "units": "criterion units per parameter units"}),
        "nonsmooth": (("eval",), col("nonsmooth", np.int8),
                      {"long_name": "the active set (or the max over regions) changes within reach of the data set",
                       "flag_values": np.array([0, 1], dtype=np.int8), "flag_meanings": "smooth nonsmooth"}),
        "worst_value": (("criterion",), wv, {"long_name": "maximum of each criterion found", "units": unit_text}),
        "worst_x": (("criterion", "param"), wx, {"long_name": "data set attaining worst_value"}),
        "worst_eval": (("criterion",), we, {"long_name": "index (eval) of the evaluation attaining worst_value; "
                                                         "-1 if none succeeded"}),
        "limit": (("criterion",), limits, {"long_name": "limit of each criterion (NaN where none)", "units": unit_text}),
        "margin": (("criterion",), limits - wv, {"long_name": "limit - worst_value (negative: limit broken)",
                                                  "units": unit_text}),
        "certificate": (("criterion",), np.array([certificate.get(c, "heuristic") for c in crit], dtype=object),
                        {"long_name": "how the worst value is certified", "flag_meanings_text": CERTIFICATES}),
        "certificate_note": (("criterion",), np.array([(notes or {}).get(c, "") for c in crit], dtype=object),
                             {"long_name": "search notes per criterion"}),
    }
    coords = {"param": np.array(names, dtype=object), "criterion": np.array(crit, dtype=object),
              "eval": np.arange(n, dtype=np.int32)}
    if sweep_paths is not None:
        data["sweep_value"] = (("eval", "sweep_path"), col("sweep", float, (len(sweep_paths),)),
                               {"long_name": "value of each swept path"})
        coords["sweep_path"] = np.array(sweep_paths, dtype=object)
    ds = xr.Dataset(data, coords=coords)
    ds["param"].attrs["long_name"] = "dotted path of each uncertain number"
    ds["criterion"].attrs["long_name"] = "criterion name (all maximised)"
    ds["eval"].attrs["long_name"] = "evaluation index, in evaluation order"
    for name, v in worst_field_variables(crit, worst_fields or {}).items():
        ds[name] = v
    if worst_fields:
        template = next((f for f in worst_fields.values() if f is not None), None)
        if template is not None:
            ds = ds.assign_coords({c: template[c].values for c in template.coords if c not in ds.coords})
    ds.attrs.update(provenance_attrs or provenance(study, evaluator))
    ds.attrs.update(attrs or {})
    ds.attrs["small_strain"] = "\n".join(validity.warnings(ds))   # the worst cases' fields leave the model's validity
    if extremes:
        ds = ds.assign_coords(range_coords(study)).assign(range_variables(study, crit, extremes, unit_text))
    if getattr(study, "dynamics", None) is not None:
        ds = dynamic_results(ds, study, records)
    return ds


# ---------------------------------------------------------------- both ends, α-levels

def range_coords(study) -> dict:
    """The `level` coordinate of a fuzzy study (ascending α), else none."""
    import xarray as xr
    if study.levels is None:
        return {}
    return {"level": xr.Variable(("level",), np.array(study.levels, float),
                                 {"long_name": "membership level alpha of the fuzzy admissible set"})}


def range_variables(study, crit: list[str], extremes: list, unit_text: str) -> dict:
    """The ends of the ranges (`Extreme`s): best_value, best_x, best_eval, best_certificate,
    best_certificate_note (criterion) and the lower limits `limit_lower`, `margin_lower`
    (best − lower limit) when some criterion asks for its minimum; in a fuzzy study both ends
    per α-level (leading `level` dimension, replacing the crisp worst_*, certificate and
    margin) and each level's α-cut `level_lower`, `level_upper` (level, param)."""
    import xarray as xr
    names = list(study.parameters.names)
    levels = [None] if study.levels is None else list(study.levels)
    dims = ("criterion",) if study.levels is None else ("level", "criterion")
    shape = (len(levels), len(crit))
    by = {(e.level, e.criterion, e.sense): e for e in extremes}

    def table(sense):
        value, x = np.full(shape, np.nan), np.full(shape + (len(names),), np.nan)
        row, cert, note = np.full(shape, -1, np.int32), np.full(shape, "not-searched", object), np.full(shape, "", object)
        for i, level in enumerate(levels):
            for j, c in enumerate(crit):
                e = by.get((level, c, sense))
                if e is not None:
                    value[i, j], x[i, j], row[i, j], cert[i, j], note[i, j] = e.value, e.x, e.eval, e.certificate, e.note
        squeeze = (lambda a: a[0]) if study.levels is None else (lambda a: a)
        return [squeeze(a) for a in (value, x, row, cert, note)]

    out = {}
    limit = np.array([float(study.limits.get(c, np.nan)) for c in crit])
    lower = np.array([float(study.lower_limits.get(c, np.nan)) for c in crit])
    where = " at each level" if study.levels is not None else ""
    if study.levels is not None:
        wv, wx, we, wc, wn = table("max")
        out.update({
            "worst_value": (dims, wv, {"long_name": f"maximum of each criterion found{where}", "units": unit_text}),
            "worst_x": (dims + ("param",), wx, {"long_name": "data set attaining worst_value"}),
            "worst_eval": (dims, we, {"long_name": "index (eval) of the evaluation attaining worst_value; -1 if none"}),
            "margin": (dims, limit - wv, {"long_name": "limit - worst_value (negative: limit broken)", "units": unit_text}),
            "certificate": (dims, wc, {"long_name": "how the worst value is certified", "flag_meanings_text": CERTIFICATES}),
            "certificate_note": (dims, wn, {"long_name": "search notes per criterion"}),
        })
        cuts = [alpha_cut(study, a) for a in levels]
        out["level_lower"] = (("level", "param"), np.array([lo for lo, _ in cuts]).reshape(len(levels), len(names)),
                              {"long_name": "lower bound of the alpha-cut of each parameter"})
        out["level_upper"] = (("level", "param"), np.array([hi for _, hi in cuts]).reshape(len(levels), len(names)),
                              {"long_name": "upper bound of the alpha-cut of each parameter"})
    if any(e.sense == "min" for e in extremes):
        bv, bx, be, bc, bn = table("min")
        out.update({
            "best_value": (dims, bv, {"long_name": f"minimum of each criterion found{where} (NaN where its sense "
                                                   "does not ask for it)", "units": unit_text}),
            "best_x": (dims + ("param",), bx, {"long_name": "data set attaining best_value"}),
            "best_eval": (dims, be, {"long_name": "index (eval) of the evaluation attaining best_value; -1 if none"}),
            "best_certificate": (dims, bc, {"long_name": "how the minimum is certified", "flag_meanings_text": CERTIFICATES}),
            "best_certificate_note": (dims, bn, {"long_name": "search notes of the minimum per criterion"}),
            "limit_lower": (("criterion",), lower, {"long_name": "lower limit of each criterion (NaN where none)",
                                                    "units": unit_text}),
            "margin_lower": (dims, bv - lower, {"long_name": "best_value - limit_lower (negative: lower limit broken)",
                                                "units": unit_text}),
        })
    return {k: xr.Variable(*v) for k, v in out.items()}


def widest(ds: xr.Dataset) -> xr.Dataset:
    """A fuzzy study's results at its widest level (the smallest α: the support when α = 0 is a
    level), the per-criterion layout of a crisp study; a crisp study's results unchanged."""
    return ds.isel(level=int(np.argmin(ds["level"].values))) if "level" in ds.dims else ds


def write_solution(study, evaluator, evaluation, out: str | Path, layout: tuple[int, int] = (1, 1),
                   **attrs) -> tuple[Path, Path]:
    """The files of one solved scenario: OUT.nc (fields, data set, criteria) and the ParaView
    multiblock OUT.vtm (the volume OUT.vtu, the contact surface OUT-contact.vtu: `wcs.results.paraview`);
    layout: (MPI ranks, ranks the solve spanned), as `provenance`."""
    from ..contact.zone import slave_segments
    from .paraview import write_paraview
    ds = solve_dataset(study, evaluator, evaluation, layout)
    ds.attrs.update({k: str(v) for k, v in attrs.items()})
    release_heap()                  # before h5py's libraries load: the peak is the max over the phases
    out = write_netcdf(ds, out)
    zone = evaluator.model.zone
    facets = None if zone is None else slave_segments(zone, study.scene, evaluator.smesh)
    return out, write_paraview(ds, out, zone, facets)
