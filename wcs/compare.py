"""`wcs compare A.nc B.nc [--rtol R]`: do two results files of one study hold the same answer?

Exit 0 when both files are of the same study (`study_sha256`) and `x`, `phi`, `status` and
every `worst_*` / `best_*` variable agree; 4 when they differ, with a table of what differs
(variable, index, both values); 2 when a file is unreadable or of another study (StudyError).

Agreement is exact (NaN equals NaN) or, with `rtol` R > 0, |a − b| ≤ R·max(|a|, |b|) for
floating-point values; integers and text always compare exactly. Attributes other than the
study hash (creation time, commit, solver wording) are not compared: the command is for
reproducibility across versions, machines and MPI rank counts.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from .errors import StudyError

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
    """The variables `compare` looks at in a results file, in this order."""
    return [*CORE, *sorted(v for v in ds.data_vars if str(v).startswith(("worst_", "best_")))]


def _label(var: xr.DataArray, index: tuple) -> str:
    """`criterion=heave, param=materials.steel.E` for one element (coordinate labels where there are)."""
    parts = []
    for dim, i in zip(var.dims, index):
        c = var.coords.get(dim)
        parts.append(f"{dim}={c.values[i] if c is not None else i}")
    return ", ".join(parts)


def _show(v) -> str:
    return repr(float(v)) if isinstance(v, (float, np.floating)) else str(v)


def differences(a: xr.Dataset, b: xr.Dataset, rtol: float = 0.0) -> list[tuple[str, str, str, str]]:
    """(variable, index, value in A, value in B) of every element that differs; a variable in
    one file only, or of another shape, is one row."""
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
                close = x == y if rtol == 0 else np.abs(x - y) <= rtol * np.maximum(np.abs(x), np.abs(y))
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
    if not args.rtol >= 0:
        raise StudyError(f"--rtol must be >= 0, got {args.rtol}", path="--rtol")
    a, b = open_pair(args.a, args.b)
    rows = differences(a, b, args.rtol)
    what = "exactly" if args.rtol == 0 else f"within rtol {args.rtol:g}"
    if not rows:
        if not args.quiet:
            print(f"{args.a} and {args.b} agree {what} in {', '.join(compared(a))}")
        return 0
    variables = sorted({r[0] for r in rows})
    print(f"{args.a} and {args.b} differ ({what}): {len(rows)} value(s) in {', '.join(variables)}")
    print(table(rows, Path(args.a).name, Path(args.b).name))
    return 4
