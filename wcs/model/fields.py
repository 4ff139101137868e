"""The solution fields of one evaluation (the fields a results file holds): triangles with
stress (xx, yy, zz, xy) in 2D, tetrahedra with (xx, yy, zz, yz, xz, xy) in 3D; and how far they
leave small-strain theory (`small_strain_*`, wcs/model/validity.py).

They are held as a `Data`: named variables over named dimensions, coordinates and attributes —
what an xarray.Dataset would hold, without xarray (and pandas, 40 MB and half a second of a
solve): `wcs.results.netcdf` writes it as NetCDF-4, `to_xarray()` gives the Dataset where one
is wanted (`Evaluation.fields`, the Python API's)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from . import validity
from ..fem import stress
from ..geometry import tet

if TYPE_CHECKING:
    import xarray as xr


class Variable:
    """One variable: its dimensions (a name for one), its values (an array with one axis per
    dimension) and its attributes, as xarray.Variable holds them."""

    def __init__(self, dims, values, attrs: dict | None = None):
        self.dims = (dims,) if isinstance(dims, str) else tuple(dims)
        self.values, self.attrs = np.asarray(values), dict(attrs or {})
        if self.values.ndim != len(self.dims):
            raise ValueError(f"{self.values.ndim}-dimensional values for the dimensions {self.dims}")

    @property
    def shape(self) -> tuple:
        return self.values.shape

    @property
    def dtype(self) -> np.dtype:
        return self.values.dtype


def as_variable(v) -> Variable:
    """A Variable from itself or a tuple (dims, values[, attrs])."""
    return v if isinstance(v, Variable) else Variable(*v)


def dimension_sizes(variables: dict) -> dict:
    """The length of each dimension of the variables {name: (anything with `dims` and `values`)},
    in the order the variables meet them (ValueError where two variables disagree)."""
    out = {}
    for name, v in variables.items():
        for d, n in zip(v.dims, np.shape(v.values)):
            if out.setdefault(d, n) != n:
                raise ValueError(f"dimension {d!r} of {name!r} has length {n}, elsewhere {out[d]}")
    return out


class Data:
    """Data variables and coordinates (name -> Variable) and attributes: the content of a
    NetCDF file. Variables are given as Variables or (dims, values[, attrs]) tuples; a
    coordinate also as the values of a dimension of its own name. `ds[name]` is a data variable
    or a coordinate, `name in ds` whether it has one."""

    def __init__(self, data_vars: dict | None = None, coords: dict | None = None, attrs: dict | None = None):
        self.data_vars = {k: as_variable(v) for k, v in (data_vars or {}).items()}
        self.coords = {}
        self.attrs = dict(attrs or {})
        for k, v in (coords or {}).items():
            self.set_coord(k, v)

    def set_coord(self, name: str, v) -> None:
        """A coordinate: a Variable, a (dims, values[, attrs]) tuple, or the values of the dimension `name`."""
        self.coords[name] = as_variable(v) if isinstance(v, (Variable, tuple)) else Variable((name,), v)

    def __getitem__(self, name: str) -> Variable:
        return self.data_vars[name] if name in self.data_vars else self.coords[name]

    def __setitem__(self, name: str, v) -> None:
        self.data_vars[name] = as_variable(v)

    def __contains__(self, name: str) -> bool:
        return name in self.data_vars or name in self.coords

    @property
    def variables(self) -> dict:
        """Every variable, the data variables first, then the coordinates."""
        return {**self.data_vars, **self.coords}

    @property
    def sizes(self) -> dict:
        """The length of each dimension (`dimension_sizes`)."""
        return dimension_sizes(self.variables)

    def copy(self) -> Data:
        """A new Data of the same variables (new mappings, the variables shared)."""
        out = Data(attrs=self.attrs)
        out.data_vars, out.coords = dict(self.data_vars), dict(self.coords)
        return out

    def to_xarray(self) -> xr.Dataset:
        """The same as an xarray.Dataset (xarray loaded here)."""
        import xarray as xr

        def var(v):
            return xr.Variable(v.dims, v.values, v.attrs)
        return xr.Dataset({k: var(v) for k, v in self.data_vars.items()},
                          coords={k: var(v) for k, v in self.coords.items()}, attrs=self.attrs)


def fields_dataset(model, state) -> Data:
    mesh = model.smesh.mesh
    s = state.stress
    d = model.dim
    law = tet if d == 3 else stress
    principal, shear_intensity, von_mises = law.principal, law.shear_intensity, law.von_mises
    cells = "tetrahedron" if d == 3 else "triangle"
    data = {
        "coords": (("node", "dim"), mesh.p.T.copy(), {"units": "m", "long_name": "node coordinates"}),
        "cells": (("cell", "vertex"), mesh.t.T.astype(np.int64), {"long_name": f"{cells} vertices (0-based)"}),
        "cell_body": (("cell",), model.smesh.cell_body.astype(np.int32), {"long_name": "body index"}),
        "cell_region": (("cell",), model.smesh.cell_region.astype(np.int32), {"long_name": "region index"}),
        "displacement": (("node", "dim"), state.u.reshape(-1, d), {"units": "m", "long_name": "displacement"}),
        "stress": (("cell", "component"), s.T.copy(), {"units": "Pa", "long_name": "Cauchy stress"}),
        "von_mises": (("cell",), von_mises(s), {"units": "Pa", "long_name": "von Mises stress"}),
        "principal_stress": (("cell", "principal"), principal(s),
                             {"units": "Pa", "long_name": ("principal stresses, largest first" if d == 3 else
                                                           "in-plane principal stresses, largest first")}),
        "shear_stress_intensity": (("cell",), shear_intensity(s),
                                   {"units": "Pa^2", "long_name": "shear stress intensity I2^2"}),
    }
    data.update(validity.variables(mesh.p.T, mesh.t.T, model.smesh.cell_body, state.u.reshape(-1, d)))
    if state.T is not None:
        data["temperature"] = (("node",), state.T, {"units": "K", "long_name": "temperature"})
    if state.contact is not None:
        data.update(state.contact.fields())
    return Data(data, coords={"dim": ["x", "y", "z"][:d], "component": list(law.COMPONENTS),
                              "principal": list(range(1, d + 1)),
                              "body": model.smesh.bodies,
                              "region": [r for _, r in model.smesh.regions]})
