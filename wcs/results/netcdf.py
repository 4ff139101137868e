"""NetCDF-4 in memory, written by h5netcdf's own API (h5py beneath it; no xarray, no pandas).

`encode(ds)` takes a `wcs.model.fields.Data` or an xarray.Dataset (anything with `variables`,
`coords` and `attrs`, each variable with `dims`, `values` and `attrs`) and gives the bytes that
xarray's `ds.to_netcdf(engine="h5netcdf")` writes for the same content — the file reads back
identical with `xarray.open_dataset` (tests/results/test_netcdf.py): the CF encoding xarray
applies, as far as results files use it:

- a float variable without a `_FillValue` gets NaN as its fill value (xarray's default);
- strings (unicode or object arrays of str) are variable-length UTF-8 strings;
- a coordinate that is not a dimension of its own name is listed in the `coordinates`
  attribute of each variable over its dimensions (CF), or in the file's `coordinates` when
  no variable is;
- integer and float variables as they are; any other kind (bool, bytes, dates, objects that
  are not str) raises TypeError, never a silent conversion.

Global attributes first, then the dimensions in the order the variables meet them, then the
variables in their order: as xarray does.
"""
from __future__ import annotations

import io

import numpy as np

from ..model.fields import dimension_sizes


def _strings(name: str, values: np.ndarray) -> np.ndarray:
    """An object array of str (TypeError for anything else in an object array)."""
    out = values.astype(object)
    if not all(isinstance(s, str) for s in out.flat):
        raise TypeError(f"variable {name!r}: an object array holds values that are not strings")
    return out


def _coordinates(variables: dict, coords) -> tuple[dict, str]:
    """{variable: its `coordinates` attribute} and the file's (CF, as xarray names them)."""
    non_dim = {k for k in coords if variables[k].dims != (k,)}
    for k in non_dim:
        if " " in k:
            raise ValueError(f"coordinate {k!r}: a space in its name cannot be listed as a coordinate")
    per_var, written = {}, set()
    for name, v in variables.items():
        if name in non_dim or name in v.dims:
            continue
        mine = sorted(c for c in non_dim if set(variables[c].dims) <= set(v.dims))
        if mine and "coordinates" not in v.attrs:
            per_var[name] = " ".join(mine)
        written.update(per_var.get(name, v.attrs.get("coordinates", "")).split())
    return per_var, " ".join(sorted(non_dim - written))


def encode(ds) -> memoryview:
    """The NetCDF-4 file of `ds` as bytes (a memoryview of its buffer)."""
    import h5netcdf
    import h5py
    variables = dict(ds.variables)
    per_var, global_coords = _coordinates(variables, ds.coords)
    attrs = dict(ds.attrs)
    if global_coords:
        if "coordinates" in attrs:
            raise ValueError(f"coordinates {global_coords} belong to no variable and the file already has "
                             f"a 'coordinates' attribute")
        attrs["coordinates"] = global_coords
    sizes = dimension_sizes(variables)
    buf = io.BytesIO()
    with h5netcdf.File(buf, "w") as f:
        for k, a in attrs.items():
            f.attrs[k] = a
        for d, n in sizes.items():
            f.dimensions[d] = n
        for name, v in variables.items():
            values = np.asarray(v.values)
            var_attrs = dict(v.attrs)
            if name in per_var:
                var_attrs["coordinates"] = per_var[name]
            fill = var_attrs.pop("_FillValue", None)
            if values.dtype.kind in "UO":
                values, dtype = _strings(name, values), h5py.string_dtype()
            elif values.dtype.kind in "iuf":
                dtype = values.dtype
                if dtype.kind == "f" and fill is None:
                    fill = dtype.type(np.nan)
            else:
                raise TypeError(f"variable {name!r}: values of dtype {values.dtype} are not written "
                                f"(integers, floats and strings are)")
            var = f.create_variable(name, dimensions=v.dims, dtype=dtype, fillvalue=fill, data=values)
            for k, a in var_attrs.items():
                var.attrs[k] = a
    return buf.getbuffer()
