"""`wcs compare A.nc B.nc [--rtol R] [--atol A]`: do two results files of one study hold the same answer?

Exit 0 when both files are of the same study (`study_sha256`) and `x`, `phi`, `status` and
every `worst_*` / `best_*` variable agree; 4 when they differ, with a table of what differs
(variable, index, both values); 2 when a file is unreadable or of another study (StudyError).

With neither option the comparison is bitwise (NaN equals NaN; the contract, §6: the command
checks reproducibility). With a tolerance, floating-point values agree when
|a − b| ≤ A + R·max(|a|, |b|); integers and text always compare exactly. Given `--rtol` alone,
A is a floor per quantity (`floors`): FLOOR of the largest magnitude of that quantity in either
file, so a closed gap of 1e-14 m against 0 (round-off of a difference of positions, 100 %
relatively) is no difference while a real one is; R defaults to 0. Attributes other than the
study hash (creation time, commit, solver wording) are not compared: the command is for
reproducibility across versions, machines and MPI rank counts.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from ..errors import StudyError

FLOOR = 1e-12   # the default absolute floor, relative to the largest magnitude of the quantity: ~1e4
                # ulps, above the round-off of sums and differences of near-equal numbers (a closed
                # gap is a difference of positions: ~1e-16 of the model's extent)
POSITIONS = "contact_gap"   # differences of positions: their round-off scales with the coordinates
CORE = ("x", "phi", "status")      # always compared; then every worst_* / best_* variable
SHOWN = 20                         # rows of the table of differences


def _open(path: str) -> xr.Dataset:
    p = Path(path)
    if p.exists() and not (p.is_file() or p.is_dir()):    # a FIFO would block, a device never end
        raise StudyError("not a regular file, not a results file", file=str(path))
    try:
        ds = xr.load_dataset(path, engine="h5netcdf")
    except (OSError, ValueError) as e:
        raise StudyError(f"cannot read the results file ({' '.join(str(e).split())})", file=str(path)) from None   # HDF5 breaks lines
    missing = [v for v in CORE if v not in ds]
    if "study_sha256" not in ds.attrs or missing:
        raise StudyError("not a results file of `wcs run` or `wcs sweep` (no "
                         f"{', '.join(missing) if missing else 'study_sha256 attribute'})", file=str(path))
    return ds


def compared(ds: xr.Dataset) -> list[str]:
    """The variables `compare` looks at in a results file, in this order (a dynamic study's
    criteria at every time level, `phi_history`, after `phi`)."""
    history = ["phi_history"] if "phi_history" in ds else []
    return [*CORE, *history, *sorted(v for v in ds.data_vars if str(v).startswith(("worst_", "best_")))]


def _label(var: xr.DataArray, index: tuple) -> str:
    """`criterion=heave, param=materials.steel.E` for one element (coordinate labels where there are)."""
    parts = []
    for dim, i in zip(var.dims, index):
        c = var.coords.get(dim)
        parts.append(f"{dim}={c.values[i] if c is not None else i}")
    return ", ".join(parts)


def _show(v) -> str:
    return repr(float(v)) if isinstance(v, (float, np.floating)) else str(v)


def _quantities(var: xr.DataArray) -> tuple[int | None, list[str]]:
    """Which physical quantity each element of a compared variable is: (axis, keys along it), or
    (None, [key]) for the whole variable. A parameter's values (dim `param`) are each their own
    quantity; a gap is a difference of positions; a criterion-wise variable (units "name: unit,
    ...") takes each criterion's units; else the variable's units (a unitless variable: itself)."""
    if str(var.name).endswith(POSITIONS):
        return None, ["positions"]
    if "param" in var.dims:
        return var.dims.index("param"), [f"param {p}" for p in var["param"].values]
    units = str(var.attrs.get("units", ""))
    if "criterion" in var.dims and ": " in units:
        by = dict(part.rsplit(": ", 1) for part in units.split(", "))
        return var.dims.index("criterion"), [f"units {by.get(str(c), '?')}" for c in var["criterion"].values]
    return None, [f"units {units}" if units else f"variable {var.name}"]


def _magnitudes(ds: xr.Dataset, name: str) -> dict[str, float]:
    """Largest finite |value| of each quantity of one variable (NaN and ±inf ignored)."""
    var = ds[name]
    axis, keys = _quantities(var)
    x = np.abs(var.values.astype(float))
    x[~np.isfinite(x)] = 0.0
    parts = [x] if axis is None else [np.take(x, j, axis=axis) for j in range(len(keys))]
    return {k: float(np.max(v, initial=0.0)) for k, v in zip(keys, parts)}


def floors(a: xr.Dataset, b: xr.Dataset) -> dict[str, float]:
    """The default absolute tolerance of each quantity: FLOOR × its scale, the largest magnitude
    of that quantity among the compared variables of both files; the gaps' scale includes the node
    coordinates (a gap is a difference of positions), a parameter's its box."""
    scale: dict[str, float] = {}
    for ds in (a, b):
        for name in compared(ds):
            if ds[name].dtype.kind == "f":
                for k, m in _magnitudes(ds, name).items():
                    scale[k] = max(scale.get(k, 0.0), m)
        for name in ("coords", "contact_coords"):
            if name in ds:
                scale["positions"] = max(scale.get("positions", 0.0), float(np.abs(ds[name].values).max(initial=0.0)))
        if "param_lower" in ds and "param_upper" in ds:
            for p, lo, hi in zip(ds["param"].values, ds["param_lower"].values, ds["param_upper"].values):
                scale[f"param {p}"] = max(scale.get(f"param {p}", 0.0), abs(lo), abs(hi))
    return {k: FLOOR * v for k, v in scale.items()}


def _atol(var: xr.DataArray, atol: float | dict) -> np.ndarray | float:
    """The absolute tolerance of each element: `atol`, or by quantity from a `floors` table."""
    if not isinstance(atol, dict):
        return atol
    axis, keys = _quantities(var)
    if axis is None:
        return atol.get(keys[0], 0.0)
    shape = [1] * var.ndim
    shape[axis] = len(keys)
    return np.array([atol.get(k, 0.0) for k in keys]).reshape(shape)


def differences(a: xr.Dataset, b: xr.Dataset, rtol: float = 0.0,
                atol: float | dict = 0.0) -> list[tuple[str, str, str, str]]:
    """(variable, index, value in A, value in B) of every element that differs beyond
    |a − b| ≤ atol + rtol·max(|a|, |b|) (atol: one number, or a `floors` table by quantity); a
    variable in one file only, or of another shape, is one row."""
    rows = []
    names = compared(a) + [v for v in compared(b) if v not in compared(a)]
    for name in names:
        if name not in a or name not in b:
            rows.append((name, "-", "present" if name in a else "absent", "present" if name in b else "absent"))
            continue
        va, vb = a[name], b[name]
        if va.shape != vb.shape or va.dims != vb.dims:
            rows.append((name, "shape", f"{dict(va.sizes)}", f"{dict(vb.sizes)}"))
            continue
        x, y = va.values, vb.values
        if x.dtype.kind == "f" and y.dtype.kind == "f":
            both_nan = np.isnan(x) & np.isnan(y)
            with np.errstate(invalid="ignore"):
                tol = _atol(va, atol) + rtol * np.maximum(np.abs(x), np.abs(y))
                close = (x == y) | (np.abs(x - y) <= tol)
            same = close | both_nan
        else:
            same = np.asarray(x == y)
        for index in map(tuple, np.argwhere(~same)):
            rows.append((name, _label(va, index), _show(x[index]), _show(y[index])))
    return rows


def table(rows: list[tuple[str, str, str, str]], a: str, b: str) -> str:
    """The first SHOWN differences as an aligned text table."""
    head = [("variable", "index", a, b)] + rows[:SHOWN]
    widths = [max(len(r[k]) for r in head) for k in range(4)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in head]
    if len(rows) > SHOWN:
        lines.append(f"... and {len(rows) - SHOWN} more")
    return "\n".join(lines)


def open_pair(path_a: str, path_b: str) -> tuple[xr.Dataset, xr.Dataset]:
    """Both results files, read whole (StudyError: unreadable, or of two different studies)."""
    a, b = _open(path_a), _open(path_b)
    sa, sb = a.attrs["study_sha256"], b.attrs["study_sha256"]
    if sa != sb:
        raise StudyError(f"the files are of different studies (study_sha256 {str(sa)[:12]}... in {path_a}, "
                         f"{str(sb)[:12]}... here)", file=str(path_b))
    return a, b


def cmd_compare(args) -> int:
    atol, rtol = getattr(args, "atol", None), getattr(args, "rtol", None)
    for name, v in (("--rtol", rtol), ("--atol", atol)):
        if v is not None and not 0 <= v < np.inf:
            raise StudyError(f"{name} must be a finite number >= 0, got {v}", path=name)
    a, b = open_pair(args.a, args.b)
    if rtol is None and atol is None:           # bitwise
        rtol, atol = 0.0, 0.0
    rtol = rtol or 0.0
    rows = differences(a, b, rtol, floors(a, b) if atol is None else atol)
    if atol is None:
        what = f"within rtol {rtol:g} and the default floors ({FLOOR:g} of each quantity's scale)"
    else:
        what = "exactly" if rtol == 0 and atol == 0 else f"within rtol {rtol:g} and atol {atol:g}"
    if not rows:
        if not args.quiet:
            print(f"{args.a} and {args.b} agree {what} in {', '.join(compared(a))}")
        return 0
    variables = sorted({r[0] for r in rows})
    print(f"{args.a} and {args.b} differ ({what}): {len(rows)} value(s) in {', '.join(variables)}")
    print(table(rows, Path(args.a).name, Path(args.b).name))
    if what == "exactly" and not differences(a, b, 0.0, floors(a, b)):
        print(f"note: every difference is below the default floors ({FLOOR:g} of each quantity's scale): "
              "round-off, which `--rtol 0` (a tolerance with the floors) accepts")
    return 4
