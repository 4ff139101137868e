"""Read a results file (`param`, `x`, `phi`, `status`, `worst_*`, …; see wcs.results.dataset) into one
plain structure for the report.

Accepts the file of `wcs run` and `wcs sweep` (evaluations along `eval`, worst-case
fields under a `worst_` prefix with a leading `criterion` dimension) and the file of
`wcs solve` (one evaluation, its fields unprefixed). Every optional piece (thermal,
contact, worst-case fields, limits, failures, provenance) may be absent.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from ..model.criteria import KINDS
from ..errors import StudyError
from ..results.dataset import widest
from ..results.drivers import IDLE
from ..status import Status
from ..model.validity import warnings as validity_warnings
from ..results.verdict import Verdict, failures, verdict
from . import timeline
from .timeline import Histories

KIND_UNITS = {k: v.units for k, v in KINDS.items()}
KIND_LABEL = {k: v.label for k, v in KINDS.items()}
FIELD_NAMES = ("displacement", "stress", "von_mises", "principal_stress", "shear_stress_intensity",
               "temperature", "contact_coords", "contact_pair", "contact_pressure", "contact_gap",
               "contact_slip", "contact_shear")


@dataclass
class Criterion:
    name: str
    kind: str          # "" when unknown
    units: str
    regions: list[str]
    limit: float       # NaN: none
    worst: float       # NaN: every evaluation failed
    worst_x: np.ndarray
    certificate: str
    worst_eval: int | None = None   # index into the evaluations, when found
    certificate_note: str = ""
    best: float = float("nan")      # the minimum found (NaN: not searched, or every evaluation failed)
    best_certificate: str = "not-searched"
    limit_lower: float = float("nan")   # NaN: none

    @property
    def searched_min(self) -> bool:
        return self.best_certificate != "not-searched"

    @property
    def searched_max(self) -> bool:
        return self.certificate != "not-searched"


@dataclass
class Levels:
    """A fuzzy study's ranges: per α-level (ascending) and criterion, NaN where not searched."""
    alpha: np.ndarray          # (level,)
    worst: np.ndarray          # (level, criterion)
    best: np.ndarray           # (level, criterion)


@dataclass
class Mesh:
    coords: np.ndarray     # (node, dim)
    cells: np.ndarray      # (cell, dim + 1): triangles in 2D, tetrahedra in 3D
    cell_body: np.ndarray | None
    cell_region: np.ndarray | None
    bodies: list[str]
    regions: list[str]

    @property
    def dim(self) -> int:
        return self.cells.shape[1] - 1


@dataclass
class Contact:
    pair: str
    coords: np.ndarray      # (n, 2) ordered along the contact
    arc: np.ndarray         # (n,) arc length [m]
    order: np.ndarray       # indices into the contact nodes of the file


@dataclass
class Fields:
    """The solution fields of one case (plain arrays; absent ones are None)."""
    displacement: np.ndarray | None = None
    stress: np.ndarray | None = None
    von_mises: np.ndarray | None = None
    principal_stress: np.ndarray | None = None
    shear_stress_intensity: np.ndarray | None = None
    temperature: np.ndarray | None = None
    contact: dict = field(default_factory=dict)   # name -> (contact_node,) array
    contact_coords: np.ndarray | None = None
    contact_pair: np.ndarray | None = None
    contact_tangents: np.ndarray | None = None    # 3D: (contact_node, tangent, 3) the directions of slip/shear


@dataclass
class Results:
    kind: str                      # "run", "sweep" or "solve"
    study: str
    attrs: dict
    study_yaml: str
    study_doc: dict                # the study's first YAML document (may be {})
    scene: dict                    # the scene (may be {})
    params: list[str]
    lower: np.ndarray
    upper: np.ndarray
    x: np.ndarray                  # (eval, param)
    phi: np.ndarray                # (eval, criterion)
    status: np.ndarray             # (eval,) int
    stage: list[str]
    wall_time: np.ndarray
    iterations: np.ndarray
    status_meanings: dict
    criteria: list[Criterion]
    mesh: Mesh | None
    worst_fields: list[Fields | None]   # one per criterion
    iterations_doc: str = ""
    param_units: list[str] | None = None    # from the file, when it records them
    messages: list[str] | None = None       # per evaluation, when recorded
    incomplete: str = ""                    # why the run is not finished ("" when it is)
    source: str = ""                        # the file it was read from
    warnings: list[str] = field(default_factory=list)   # the study's warnings (`wcs check`)
    levels: Levels | None = None            # a fuzzy study's ranges per α-level
    after_search: xr.Dataset | None = None  # drivers* and mesh_check* (`after_search`), when recorded
    verdict: Verdict | None = None          # the study's verdict (`wcs.results.verdict`), as the terminal gives it
    small_strain: tuple[float, float] | None = None   # max |u| / body size, max |∇u| of the solved fields
    validity: list[str] = field(default_factory=list)  # where they leave the model's validity (`wcs.model.validity`)
    failed_where: list[str] = field(default_factory=list)   # each kind of failure, where in U_ad (`wcs.results.verdict`)
    histories: Histories | None = None      # a dynamic study's criteria against time (`wcs.report.timeline`)

    @property
    def n_eval(self) -> int:
        return self.x.shape[0]

    @property
    def failed(self) -> np.ndarray:
        return self.status != 0


def _text(v) -> str:
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    return str(v)


def _attr_scalar(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray) and v.size == 1:
        return v.reshape(()).item()
    return v


def split_yaml(text: str) -> tuple[dict, dict]:
    """The study document and the files pulled in ({relative name: document})."""
    import yaml
    parts = text.split("\n---\n")
    try:
        first = yaml.safe_load(parts[0]) or {}
    except yaml.YAMLError:
        first = {}
    extra = {}
    for part in parts[1:]:
        head = part.lstrip().splitlines()[0] if part.strip() else ""
        name = head[1:].strip() if head.startswith("#") else ""
        try:
            extra[name] = yaml.safe_load(part)
        except yaml.YAMLError:
            pass
    return (first if isinstance(first, dict) else {}), extra


def _scene(doc: dict, extra: dict) -> dict:
    scene = doc.get("scene")
    if isinstance(scene, dict):
        return scene
    if isinstance(scene, str):
        base = Path(scene).name
        for name, d in extra.items():
            if isinstance(d, dict) and (name == scene or Path(name).name == base):
                return d.get("scene", d) if isinstance(d.get("scene", d), dict) else {}
    return {}


def status_meanings(var: xr.DataArray | None) -> dict:
    out = {s.value: s.description for s in Status}
    if var is None:
        return out
    values = var.attrs.get("flag_values")
    meanings = var.attrs.get("flag_meanings")
    if values is not None and meanings is not None:
        words = _text(meanings).split()
        values = np.atleast_1d(np.asarray(values)).tolist()
        if len(words) == len(values):
            out.update({int(v): w.replace("_", " ") for v, w in zip(values, words)})
    return out


def order_along(points: np.ndarray) -> np.ndarray:
    """An order of points along an open curve: start at an end, walk to the nearest neighbour."""
    n = len(points)
    if n <= 2:
        return np.arange(n)
    c = points.mean(axis=0)
    d2c = np.linalg.norm(points - c, axis=1)
    start = int(np.argmax(d2c))
    # the end of the curve: farthest from the point farthest from the centroid
    start = int(np.argmax(np.linalg.norm(points - points[start], axis=1)))
    seen = np.zeros(n, bool)
    order = [start]
    seen[start] = True
    for _ in range(n - 1):
        d = np.linalg.norm(points - points[order[-1]], axis=1)
        d[seen] = np.inf
        k = int(np.argmin(d))
        order.append(k)
        seen[k] = True
    return np.array(order)


def uniform_value(values: np.ndarray) -> float | None:
    """The value of a field that is uniform up to its solve's round-off (its spread at most IDLE
    times its largest magnitude, eps times a condition number of 1e6–1e8, `wcs.results.drivers`),
    their mean; None where it varies or has no finite value. A colour scale over such a field
    spans the round-off and draws noise."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size == 0 or np.ptp(v) > IDLE * float(np.max(np.abs(v))):
        return None
    return float(np.mean(v))


def _get(ds: xr.Dataset, name: str):
    return ds[name] if name in ds.variables else None


def load(path: str | Path) -> Results:
    """Open a results file; StudyError (exit 2) when it is missing or not a wcs results file."""
    path = Path(path)
    if not path.exists():
        raise StudyError(f"{path}: no such results file")
    if path.is_dir():
        raise StudyError(f"{path}: is a directory, not a results file")
    if not path.is_file():                   # a FIFO or a device: reading would wait or never end
        raise StudyError(f"{path}: not a regular file (a FIFO, a device or a socket), not a results file")
    try:
        ds = xr.open_dataset(path, engine="h5netcdf")
    except Exception:  # noqa: BLE001 - try the other engine before giving up
        try:
            ds = xr.open_dataset(path)
        except Exception as e:  # noqa: BLE001
            first = str(e).splitlines()[0] if str(e) else type(e).__name__
            raise StudyError(f"{path}: not a NetCDF results file ({first})") from None
    with ds:
        ds.load()
    res = from_dataset(ds, str(path))
    if res.incomplete:           # the store and the lock beside the file tell how far the run got
        from ..results.store import incomplete_run
        res.incomplete = incomplete_run(path, res.n_eval, _text(res.attrs.get("study_file", "STUDY.yaml")))
    return res


def _upper_limit(limit):
    """The upper limit of a study file's `limits.<c>`: a number, or `upper` of {lower, upper} (NaN: none)."""
    return limit.get("upper", np.nan) if isinstance(limit, dict) else limit


def from_dataset(ds: xr.Dataset, where: str = "results") -> Results:
    missing = [v for v in ("phi", "param") if v not in ds.variables]
    if missing:
        raise StudyError(f"{where}: not a wcs results file (no {', '.join(missing)}; "
                         f"expected the layout written by wcs run, sweep or solve)")
    levels = _levels(ds)
    ds = widest(ds)                          # a fuzzy study reads as its widest level, plus `levels`
    attrs = {k: _attr_scalar(v) for k, v in ds.attrs.items()}
    study_yaml = _text(attrs.get("study_yaml", ""))
    doc, extra = split_yaml(study_yaml) if study_yaml else ({}, {})
    scene = _scene(doc, extra)

    params = [_text(p) for p in ds["param"].values.tolist()]
    nparam = len(params)
    lower = ds["param_lower"].values.astype(float) if "param_lower" in ds else np.full(nparam, np.nan)
    upper = ds["param_upper"].values.astype(float) if "param_upper" in ds else np.full(nparam, np.nan)

    names = [_text(c) for c in ds["criterion"].values.tolist()] if "criterion" in ds.coords else \
        [f"criterion {i}" for i in range(ds["phi"].shape[-1])]
    ncrit = len(names)
    phi_var = ds["phi"]
    is_run = "eval" in phi_var.dims
    if is_run:
        phi = phi_var.transpose("eval", ...).values.astype(float).reshape(-1, ncrit)
        n = phi.shape[0]
        x = ds["x"].transpose("eval", "param").values.astype(float) if "x" in ds else np.full((n, nparam), np.nan)
        status = ds["status"].values.astype(int).reshape(n) if "status" in ds else np.zeros(n, int)
        stage = [_text(s) for s in ds["stage"].values.tolist()] if "stage" in ds else ["—"] * n
        wall = ds["wall_time"].values.astype(float).reshape(n) if "wall_time" in ds else np.full(n, np.nan)
        iters = ds["iterations"].values.astype(float).reshape(n) if "iterations" in ds else np.full(n, np.nan)
    else:
        phi = phi_var.values.astype(float).reshape(1, ncrit)
        x = ds["x"].values.astype(float).reshape(1, nparam) if "x" in ds else np.full((1, nparam), np.nan)
        status = np.array([int(ds["status"].values)]) if "status" in ds else np.zeros(1, int)
        stage = ["nominal solve"]
        wall = np.array([float(ds["wall_time"].values)]) if "wall_time" in ds else np.full(1, np.nan)
        iters = np.array([float(ds["iterations"].values)]) if "iterations" in ds else np.full(1, np.nan)
    kind = "solve" if not is_run else ("sweep" if stage and all(s == "sweep" for s in stage) else "run")
    if is_run and _text(attrs.get("kind", "")) in ("run", "sweep"):
        kind = _text(attrs["kind"])

    # criteria: kind and units from the file, else from the study text
    specs = {c.get("name"): c for c in doc.get("criteria", []) if isinstance(c, dict)}
    yaml_limits = doc.get("limits") or {}
    unit_attr = {}
    for piece in _text(phi_var.attrs.get("units", "")).split(","):
        if ":" in piece:
            k, v = piece.split(":", 1)
            unit_attr[k.strip()] = v.strip()
    kinds_var = _get(ds, "criterion_kind")
    units_var = _get(ds, "criterion_units")
    limit = ds["limit"].values.astype(float) if "limit" in ds else \
        np.array([float(_upper_limit(yaml_limits.get(n, np.nan))) for n in names])
    ok = status == 0
    if "worst_value" in ds:
        worst = ds["worst_value"].values.astype(float).reshape(ncrit)
    else:
        worst = np.array([np.nanmax(phi[ok, j]) if np.isfinite(phi[ok, j]).any() else np.nan
                          for j in range(ncrit)])
    cert_var = _get(ds, "certificate")
    criteria = []
    for j, name in enumerate(names):
        spec = specs.get(name, {})
        kind_j = _text(kinds_var.values[j]) if kinds_var is not None else spec.get("kind", "")
        units = _text(units_var.values[j]) if units_var is not None else \
            unit_attr.get(name) or KIND_UNITS.get(kind_j, "")
        col = np.where(ok, phi[:, j], np.nan)
        worst_eval = None
        if is_run and "worst_eval" in ds and "criterion" in ds["worst_eval"].dims:
            w = int(ds["worst_eval"].values[j])
            worst_eval = w if 0 <= w < len(col) else None
        elif np.isfinite(worst[j]) and np.isfinite(col).any():
            hit = np.flatnonzero(col == worst[j])
            worst_eval = int(hit[0]) if hit.size else int(np.nanargmax(col))
        if "worst_x" in ds:
            wx = ds["worst_x"].transpose("criterion", "param").values.astype(float)[j]
        elif worst_eval is not None:
            wx = x[worst_eval]
        else:
            wx = np.full(nparam, np.nan)
        if cert_var is not None:
            cert = _text(cert_var.values[j]) if cert_var.ndim else _text(cert_var.values)
        else:
            cert = {"solve": "none (a single solve)", "sweep": "none (a grid sweep)"}.get(kind, "—")
        note = _text(ds["certificate_note"].values[j]) if "certificate_note" in ds and \
            "criterion" in ds["certificate_note"].dims else ""
        criteria.append(Criterion(name, kind_j, units, list(spec.get("regions", [])), float(limit[j]),
                                  float(worst[j]), wx, cert, worst_eval, note))
        if "best_value" in ds:
            criteria[-1].best = float(ds["best_value"].values[j])
            criteria[-1].best_certificate = _text(ds["best_certificate"].values[j])
            criteria[-1].limit_lower = float(ds["limit_lower"].values[j])

    mesh = None
    if "coords" in ds and "cells" in ds:
        bodies = [_text(b) for b in ds["body"].values.tolist()] if "body" in ds.coords else []
        regions = [_text(r) for r in ds["region"].values.tolist()] if "region" in ds.coords else []
        coords, cells = ds["coords"].values.astype(float), ds["cells"].values.astype(np.int64)
        mesh = Mesh(coords[:, :cells.shape[1] - 1], cells,
                    ds["cell_body"].values.astype(int) if "cell_body" in ds else None,
                    ds["cell_region"].values.astype(int) if "cell_region" in ds else None,
                    bodies, regions)

    histories = timeline.read(ds, [c.worst_eval for c in criteria])
    worst_fields: list[Fields | None] = []
    for j, name in enumerate(names):
        at = timeline.output_index(histories, j) if histories is not None and "output_time" in ds.dims else None
        worst_fields.append(_fields(ds, j, name, prefixed=is_run, at=at))

    return Results(kind=kind, study=_text(attrs.get("study", doc.get("study", "unnamed study"))),
                   attrs=attrs, study_yaml=study_yaml, study_doc=doc, scene=scene, params=params,
                   lower=lower, upper=upper, x=x, phi=phi, status=status, stage=stage,
                   wall_time=wall, iterations=iters, status_meanings=status_meanings(_get(ds, "status")),
                   criteria=criteria, mesh=mesh, worst_fields=worst_fields,
                   iterations_doc=_text(ds["iterations"].attrs.get("long_name", "")) if "iterations" in ds else "",
                   param_units=[_text(u) for u in ds["param_units"].values.tolist()] if "param_units" in ds else None,
                   messages=[_text(m) for m in ds["message"].values.tolist()]
                   if is_run and "message" in ds and ds["message"].dims == ("eval",) else None,
                   incomplete="the run stopped before the end (complete: no)"
                   if _text(attrs.get("complete", "yes")) == "no" else "",
                   warnings=[w for w in _text(attrs.get("warnings", "")).splitlines() if w.strip()],
                   source=where, levels=levels, after_search=after_search(ds), small_strain=_small_strain(ds),
                   validity=validity_warnings(ds), failed_where=failures(ds), histories=histories,
                   verdict=verdict(ds if "limit" in ds or not ncrit else ds.assign(limit=("criterion", limit))))


def _small_strain(ds: xr.Dataset) -> tuple[float, float] | None:
    """The largest displacement-to-size ratio and displacement gradient of the file's solved
    fields (a solve's, or a run's nominal case and every criterion's worst case); None when the file has none."""
    r, g = ([np.ravel(ds[f"{prefix}small_strain_{m}"].values).astype(float) for prefix in ("", "nominal_", "worst_")
             if f"{prefix}small_strain_{m}" in ds] for m in ("displacement", "gradient"))
    if not g or not np.isfinite(np.concatenate(g)).any():
        return None
    return float(np.nanmax(np.concatenate(r))), float(np.nanmax(np.concatenate(g)))


def _levels(ds: xr.Dataset) -> Levels | None:
    """The per-level ranges of a fuzzy study's results (None: a crisp study)."""
    if "level" not in ds.dims:
        return None
    worst = ds["worst_value"].transpose("level", "criterion").values.astype(float)
    best = ds["best_value"].transpose("level", "criterion").values.astype(float) if "best_value" in ds \
        else np.full_like(worst, np.nan)
    return Levels(ds["level"].values.astype(float), worst, best)


def after_search(ds: xr.Dataset) -> xr.Dataset | None:
    """What `wcs run` adds after the search (`wcs/results/drivers.py`, `wcs/results/meshcheck.py`): the drivers*
    and mesh_check* variables with the `mesh_check` attribute; None when the file has neither."""
    names = [v for v in ds.data_vars if str(v).startswith(("drivers", "mesh_check_"))]
    if not names and "mesh_check" not in ds.attrs:
        return None
    out = ds[names]
    out.attrs = {"mesh_check": _text(ds.attrs.get("mesh_check", ""))}
    return out


def _fields(ds: xr.Dataset, j: int, name: str, prefixed: bool, at: int | None = None) -> Fields | None:
    """The fields at the worst case of criterion j: `worst_<f>` (criterion, ...) in a run
    file, the unprefixed fields of a solve file (the same case for every criterion); a dynamic
    study's at its output time `at` (`output_time`)."""
    def when(v):
        return v.isel(output_time=at) if at is not None and "output_time" in v.dims else v

    def pick(f):
        v = _get(ds, f"worst_{f}")
        if v is not None:
            return when(v.isel(criterion=j) if "criterion" in v.dims else v).values
        if prefixed and f not in ("contact_coords", "contact_pair", "contact_tangents"):
            return None       # a run file without worst-case fields
        v = _get(ds, f)       # a solve file; or contact geometry stored once
        return None if v is None or "eval" in v.dims else when(v).values
    out = Fields()
    found = False
    for f in ("displacement", "stress", "von_mises", "principal_stress", "shear_stress_intensity", "temperature"):
        v = pick(f)
        if v is not None:
            setattr(out, f, np.asarray(v, float))
            found = True
    cc = pick("contact_coords")
    cp = pick("contact_pair")
    if cc is not None and cp is not None:
        out.contact_coords = np.asarray(cc, float)
        out.contact_pair = np.array([_text(p) for p in np.asarray(cp).tolist()])
        ct = pick("contact_tangents")
        out.contact_tangents = None if ct is None else np.asarray(ct, float)
        for f in ("contact_pressure", "contact_gap", "contact_slip", "contact_shear"):
            v = pick(f)
            if v is not None:
                out.contact[f] = np.asarray(v, float)
        found = True
    if not found:
        return None
    if out.displacement is not None and not np.isfinite(out.displacement).any():
        return None            # a placeholder for a criterion whose every evaluation failed
    return out
