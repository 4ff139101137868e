"""Fingerprint of every shipped study: what a redesign must leave bitwise unchanged.

    python tests/bench/fingerprint.py record FILE.npz     # run every study, store the numbers
    python tests/bench/fingerprint.py compare FILE.npz    # run again, list what differs (exit 4)

Each study of studies/ and studies/validation/ is run with `wcs run` at the budget
`make validate` uses (tests/acceptance/test_validate_studies.py: BUDGET), from a copy of its file;
the fingerprint is the results file's `x`, `phi`, `status`, `worst_value` and
`worst_x`, compared to the last bit (NaN equal to NaN).
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))        # the checkout this script lives in, not whichever wcs is installed

from tests.acceptance.test_validate_studies import BUDGET, STUDIES, _id, small_copy  # noqa: E402

from wcs.cli import main  # noqa: E402

VARIABLES = ("x", "phi", "status", "worst_value", "worst_x")


def fingerprint() -> dict[str, np.ndarray]:
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for path in STUDIES:
            folder = Path(tmp) / path.stem
            study = small_copy(path, folder, BUDGET)
            nc = folder / f"{path.stem}.nc"
            rc = main(["run", str(study), "-o", str(nc), "--quiet", "--no-mesh-check"])
            print(f"{_id(path)}: exit {rc}", flush=True)
            with xr.open_dataset(nc) as ds:
                for v in VARIABLES:
                    if v in ds:
                        out[f"{_id(path)}:{v}"] = ds[v].values.copy()
    return out


def differences(old: dict, new: dict) -> list[str]:
    rows = []
    for key in sorted(set(old) | set(new)):
        if key not in old or key not in new:
            rows.append(f"{key}: only in the {'new' if key in new else 'recorded'} run")
            continue
        a, b = np.asarray(old[key]), np.asarray(new[key])
        if a.shape != b.shape:
            rows.append(f"{key}: shape {a.shape} -> {b.shape}")
        elif not np.array_equal(a, b, equal_nan=a.dtype.kind == "f"):
            with np.errstate(invalid="ignore", divide="ignore"):
                rel = np.nanmax(np.abs(a - b) / np.maximum(np.abs(a), 1e-300)) if a.dtype.kind == "f" else None
            rows.append(f"{key}: differs" + (f" (largest relative difference {rel:.3g})" if rel is not None else ""))
    return rows


def cli(argv: list[str]) -> int:
    if len(argv) != 2 or argv[0] not in ("record", "compare"):
        print(__doc__)
        return 2
    verb, file = argv
    new = fingerprint()
    if verb == "record":
        np.savez(file, **new)
        print(f"recorded {len(new)} arrays of {len(STUDIES)} studies in {file}")
        return 0
    with np.load(file, allow_pickle=False) as f:
        old = {k: f[k] for k in f.files}
    rows = differences(old, new)
    print("\n".join(rows) if rows else f"bitwise identical: {len(new)} arrays of {len(STUDIES)} studies")
    return 4 if rows else 0


if __name__ == "__main__":
    sys.exit(cli(sys.argv[1:]))
