"""The solution fields of one evaluation as an xarray.Dataset (the fields a results file holds):
triangles with stress (xx, yy, zz, xy) in 2D, tetrahedra with (xx, yy, zz, yz, xz, xy) in 3D;
and how far they leave small-strain theory (`small_strain_*`, wcs/model/validity.py)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from . import validity
from ..fem import stress
from ..geometry import tet

if TYPE_CHECKING:
    import xarray as xr


def fields_dataset(model, state) -> xr.Dataset:
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
    import xarray as xr
    ds = xr.Dataset(data, coords={"dim": ["x", "y", "z"][:d], "component": list(law.COMPONENTS),
                                  "principal": list(range(1, d + 1)),
                                  "body": model.smesh.bodies,
                                  "region": [r for _, r in model.smesh.regions]})
    return ds
