"""Criterion functionals Φ1–Φ6 (physics.md §6): each a maximum over regions of
interest G_r of a mean over G_r.

Linear criteria (temperature, normal displacement) keep their functional as
a vector ℓ_r (Φ_r = ℓ_r · field), which is also the adjoint load of the
criterion. Quadratic ones (shear stress intensity) average a cell field.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import StudyError
from .fem.stress import shear_intensity, von_mises
from .scene.selectors import Selection, distance_function, facet_lengths, facet_normals, select_region

UNITS = {"mean_temperature": "K", "mean_normal_displacement": "m",
         "shear_stress_intensity": "Pa^2", "von_mises": "Pa", "contact_pressure": "Pa"}


@dataclass
class Criterion:
    name: str
    kind: str
    rois: list[str]
    selections: list[Selection]
    functionals: list[np.ndarray] | None     # linear kinds: one ℓ_r per region of interest
    measures: np.ndarray                      # meas G_r
    contact_masks: list[np.ndarray] | None = None   # contact_pressure: contact nodes inside G_r

    @property
    def units(self) -> str:
        return UNITS[self.kind]

    def region_values(self, model, state) -> np.ndarray:
        if self.kind == "mean_temperature":
            return np.array([l @ state.T for l in self.functionals])
        if self.kind == "mean_normal_displacement":
            return np.array([l @ state.u for l in self.functionals])
        if self.kind in ("shear_stress_intensity", "von_mises"):
            density = shear_intensity(state.stress) if self.kind == "shear_stress_intensity" else von_mises(state.stress)
            return np.array([_cell_mean(model, sel, density) for sel in self.selections])
        if self.kind == "contact_pressure":
            return np.array([_contact_mean(state, mask) for mask in self.contact_masks])
        raise ValueError(self.kind)

    def value(self, model, state) -> float:
        return float(np.max(self.region_values(model, state)))


def build_criteria(study_criteria: list[dict], scene: dict, smesh, zone=None) -> list[Criterion]:
    rois = scene.get("regions_of_interest") or {}
    out = []
    for k, spec in enumerate(study_criteria):
        path = f"criteria.{k}"
        contact = spec["kind"] == "contact_pressure"        # only the contact nodes in G_r matter
        sels = [select_region(smesh, rois[r], f"scene.regions_of_interest.{r}", allow_empty=contact)
                for r in spec["regions"]]
        functionals, measures = None, np.array([_measure(smesh.mesh, s) for s in sels])
        if spec["kind"] == "mean_temperature":
            functionals = [_mean_weights(smesh.mesh, s) for s in sels]
        elif spec["kind"] == "mean_normal_displacement":
            functionals = []
            for r, s in zip(spec["regions"], sels):
                d = _direction(smesh, spec, s, f"{path} ({r})")
                nodal = _mean_weights(smesh.mesh, s)
                ell = np.zeros(2 * nodal.size)
                ell[0::2], ell[1::2] = nodal * d[0], nodal * d[1]
                functionals.append(ell)
        masks = None
        if spec["kind"] == "contact_pressure":
            masks = [_contact_nodes_in(scene, zone, r, f"scene.regions_of_interest.{r}") for r in spec["regions"]]
        out.append(Criterion(spec["name"], spec["kind"], list(spec["regions"]), sels, functionals, measures, masks))
    return out


def _measure(mesh, sel: Selection) -> float:
    if sel.kind == "cells":
        return float(_areas(mesh, sel.index).sum())
    return float(facet_lengths(mesh, sel.index).sum())


def _areas(mesh, cells):
    p, t = mesh.p, mesh.t[:, cells]
    d1, d2 = p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]
    return 0.5 * np.abs(d1[0] * d2[1] - d1[1] * d2[0])


def _mean_weights(mesh, sel: Selection) -> np.ndarray:
    """Nodal weights ℓ with ℓ · v = (meas G)⁻¹ ∫_G v for a P1 field v (exact)."""
    w = np.zeros(mesh.p.shape[1])
    if sel.kind == "cells":
        a = _areas(mesh, sel.index)
        for k in range(3):
            np.add.at(w, mesh.t[k, sel.index], a / 3.0)
        return w / a.sum()
    L = facet_lengths(mesh, sel.index)
    for k in range(2):
        np.add.at(w, mesh.facets[k, sel.index], L / 2.0)
    return w / L.sum()


def _direction(smesh, spec: dict, sel: Selection, path: str) -> np.ndarray:
    """The fixed direction n(X_r): given, the outward normal at the boundary point nearest
    `point`, or the mean outward normal of a boundary region of interest."""
    mesh = smesh.mesh
    if spec.get("direction") is not None:
        d = np.asarray(spec["direction"], float)
        return d / np.linalg.norm(d)
    if spec.get("point") is not None:
        X = np.asarray(spec["point"], float)
        facets = np.flatnonzero(mesh.f2t[1] == -1)
        owners = smesh.cell_body[sel.index] if sel.kind == "cells" else smesh.cell_body[mesh.f2t[0, sel.index]]
        facets = facets[np.isin(smesh.cell_body[mesh.f2t[0, facets]], owners)]   # the ROI's own body
        mid = mesh.p[:, mesh.facets[:, facets]].mean(axis=1)
        nearest = facets[np.argmin(np.hypot(mid[0] - X[0], mid[1] - X[1]))]
        return facet_normals(mesh, np.array([nearest]))[0]
    if sel.kind == "facets":
        n = (facet_normals(mesh, sel.index) * facet_lengths(mesh, sel.index)[:, None]).sum(axis=0)
        return n / np.linalg.norm(n)
    raise StudyError("a mean normal displacement over an area needs `point` (X_r) or `direction`",
                     path=path)


def _cell_mean(model, sel: Selection, density: np.ndarray) -> float:
    cells = sel.index if sel.kind == "cells" else np.unique(model.smesh.mesh.f2t[0, sel.index])
    a = model.cell_area[cells]
    return float(a @ density[cells] / a.sum())


def _contact_nodes_in(scene: dict, zone, roi: str, path: str) -> np.ndarray:
    """Contact (slave) nodes lying in a region of interest, tested on the ROI's geometry:
    a ROI on either side of the contact catches the same nodes, matching or not."""
    spec = dict(scene["regions_of_interest"][roi])
    spec.pop("body", None)
    if "boundary" in spec:
        spec = {k: v for k, v in scene["boundaries"][spec["boundary"]].items() if k != "body"}
    x, y = zone.coords.T
    scale = max(np.ptp(zone.coords, axis=0).max(), 1e-300)
    mask = distance_function(spec, path)(x, y) <= 1e-6 * scale + 1e-3 * zone.weight
    if not mask.any():
        raise StudyError(f"region of interest '{roi}' holds no contact node: a contact pressure "
                         "criterion needs a region next to a contact", path=path)
    return mask


def _contact_mean(state, mask: np.ndarray) -> float:
    """Mean contact pressure over the contact nodes in G_r: transmitted force / length."""
    c = state.contact
    return float(c.force_n[mask].sum() / c.weight[mask].sum())
