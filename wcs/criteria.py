"""Criterion functionals Φ1–Φ6 [68, (4.29)–(4.34)]: each a maximum over regions of
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
from .scene.selectors import (Selection, boundary_facets, dist_segment, distance_function, facet_lengths,
                              facet_normals, select_region)

CORNER = np.cos(np.radians(30.0))   # boundary edges nearest X_r turning by more: a corner, n(X_r) undefined

UNITS = {"mean_temperature": "K", "mean_normal_displacement": "m",
         "shear_stress_intensity": "Pa^2", "von_mises": "Pa", "contact_pressure": "Pa"}


@dataclass
class Criterion:
    name: str
    kind: str
    rois: list[str]
    selections: list[Selection]
    functionals: list[np.ndarray] | None     # linear kinds: one ℓ_r per region of interest
    measures: np.ndarray                      # meas G_r (contact_pressure: of its contact rows)
    contact_masks: list[np.ndarray] | None = None   # contact_pressure: contact rows next to G_r

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
        if spec["kind"] == "contact_pressure":             # only the contact rows next to G_r matter
            sels = [_roi_selection(smesh, r, rois[r], f"scene.regions_of_interest.{r}")
                    if "boundary" in rois[r] else Selection("cells", np.zeros(0, dtype=np.int64))
                    for r in spec["regions"]]
            masks = [_contact_rows_in(smesh, scene, zone, r, s, f"scene.regions_of_interest.{r}")
                     for r, s in zip(spec["regions"], sels)]
            measures = np.array([zone.weight[m].sum() for m in masks])
            out.append(Criterion(spec["name"], spec["kind"], list(spec["regions"]), sels, None, measures, masks))
            continue
        sels = [_roi_selection(smesh, r, rois[r], f"scene.regions_of_interest.{r}") for r in spec["regions"]]
        functionals, measures = None, np.array([_measure(smesh.mesh, s) for s in sels])
        if spec["kind"] == "mean_temperature":
            functionals = [_mean_weights(smesh.mesh, s) for s in sels]
        elif spec["kind"] == "mean_normal_displacement":
            functionals = []
            for r, s in zip(spec["regions"], sels):
                d = _direction(smesh, spec, s, path, r)
                nodal = _mean_weights(smesh.mesh, s)
                ell = np.zeros(2 * nodal.size)
                ell[0::2], ell[1::2] = nodal * d[0], nodal * d[1]
                functionals.append(ell)
        out.append(Criterion(spec["name"], spec["kind"], list(spec["regions"]), sels, functionals, measures))
    return out


def embedded_rois(study_criteria: list[dict]) -> list[str]:
    """The regions of interest whose cells a criterion integrates over (every kind but the
    contact pressure, which takes the contact rows next to G_r): the mesh embeds them."""
    return sorted({r for c in study_criteria if c["kind"] != "contact_pressure" for r in c["regions"]})


def _roi_selection(smesh, name: str, spec: dict, path: str) -> Selection:
    """G_r as mesh entities: the cells of a box / disc / polygon embedded in the mesh (exactly
    G_r, the disc as the mesh's polygon), else `select_region` (boundary facets; on a mesh file
    the cells cut exactly by a box or polygon)."""
    if name not in smesh.roi_cells:
        return select_region(smesh, spec, path)
    sel = Selection("cells", smesh.roi_cells[name])
    if len(sel) == 0:
        where = f" of body {spec['body']!r}" if spec.get("body") is not None else ""
        raise StudyError(f"the region of interest covers no part of the scene{where}", path=path)
    return sel


def _measure(mesh, sel: Selection) -> float:
    if sel.kind == "cells":
        return float(sel.cell_moments(mesh).sum())
    return float(facet_lengths(mesh, sel.index).sum())


def cell_weights(model, sel: Selection) -> tuple[np.ndarray, np.ndarray]:
    """(cells, meas(G ∩ T)) of the cells a cell-wise mean over G_r runs over; a boundary
    region of interest: the cells along its facets, whole."""
    if sel.kind == "facets":
        cells = np.unique(model.smesh.mesh.f2t[0, sel.index])
        return cells, model.cell_area[cells]
    if sel.moments is None:
        return sel.index, model.cell_area[sel.index]
    return sel.index, sel.moments.sum(axis=0)


def _mean_weights(mesh, sel: Selection) -> np.ndarray:
    """Nodal weights ℓ with ℓ · v = (meas G)⁻¹ ∫_G v for a P1 field v (exact)."""
    w = np.zeros(mesh.p.shape[1])
    if sel.kind == "cells":
        m = sel.cell_moments(mesh)
        for k in range(3):
            np.add.at(w, mesh.t[k, sel.index], m[k])
        return w / m.sum()
    L = facet_lengths(mesh, sel.index)
    for k in range(2):
        np.add.at(w, mesh.facets[k, sel.index], L / 2.0)
    return w / L.sum()


def _direction(smesh, spec: dict, sel: Selection, path: str, roi: str) -> np.ndarray:
    """The fixed direction n(X_r): given, the outward normal of the boundary of the region's
    body at `point` X_r (X_r must lie on it, up to half an edge; at a node between edges that
    turn by at most 30° their length-weighted mean normal, at a sharper corner refused), or the
    mean outward normal of a boundary region of interest."""
    mesh = smesh.mesh
    if spec.get("direction") is not None:
        d = np.asarray(spec["direction"], float)
        return d / np.linalg.norm(d)
    if spec.get("point") is not None:
        X = np.asarray(spec["point"], float)
        facets = boundary_facets(mesh)
        owners = smesh.cell_body[sel.index] if sel.kind == "cells" else smesh.cell_body[mesh.f2t[0, sel.index]]
        facets = facets[np.isin(smesh.cell_body[mesh.f2t[0, facets]], owners)]   # the ROI's own body
        a, b = mesh.p[:, mesh.facets[0, facets]], mesh.p[:, mesh.facets[1, facets]]
        e = b - a
        s = np.clip(((X[:, None] - a) * e).sum(axis=0) / (e * e).sum(axis=0), 0.0, 1.0)
        dist = np.hypot(*(X[:, None] - a - s * e))
        L = np.hypot(*e)
        k = int(np.argmin(dist))
        bodies = ", ".join(smesh.bodies[i] for i in np.unique(owners))
        if dist[k] > 0.5 * L[k]:
            raise StudyError(f"point {X.tolist()} is not on the boundary of body {bodies} (region "
                             f"'{roi}'): the nearest boundary edge is {dist[k]:.6g} away; X_r must lie "
                             "on the boundary", path=f"{path}.point")
        tied = dist <= dist[k] + 1e-3 * L[k]
        n = facet_normals(mesh, facets[tied])
        if np.min(n @ n.T) < CORNER:
            raise StudyError(f"point {X.tolist()} is equally near boundary edges of body {bodies} "
                             f"whose outward normals differ by more than 30° (a corner, or the two "
                             "sides of an interface): n(X_r) is not defined there; move the point "
                             "or give `direction`",
                             path=f"{path}.point")
        m = (n * L[tied][:, None]).sum(axis=0)
        return m / np.linalg.norm(m)
    if sel.kind == "facets":
        n = (facet_normals(mesh, sel.index) * facet_lengths(mesh, sel.index)[:, None]).sum(axis=0)
        return n / np.linalg.norm(n)
    raise StudyError(f"a mean normal displacement over an area (region '{roi}') needs `point` (X_r) "
                     "or `direction`", path=path)


def _cell_mean(model, sel: Selection, density: np.ndarray) -> float:
    cells, a = cell_weights(model, sel)
    return float(a @ density[cells] / a.sum())


def _contact_rows_in(smesh, scene: dict, zone, roi: str, sel: Selection, path: str) -> np.ndarray:
    """Contact rows (slave nodes) next to G_r: the slave node x or its master projection
    x + gap·n lies in G_r, so a region on either side of a contact, open or closed, matching
    or not, catches the same rows. A boundary G_r is its facets; an area one its shape."""
    normal = np.concatenate([p.normal for p in zone.pairs])
    pts = np.vstack([zone.coords, zone.coords + zone.gap[:, None] * normal])
    if sel.kind == "facets":
        mesh = smesh.mesh
        a, b = mesh.p[:, mesh.facets[0, sel.index]].T, mesh.p[:, mesh.facets[1, sel.index]].T
        dist = np.min([dist_segment(pts[:, 0], pts[:, 1], a[i], b[i]) for i in range(len(a))], axis=0)
    else:
        spec = {k: v for k, v in scene["regions_of_interest"][roi].items() if k != "body"}
        dist = distance_function(spec, path)(pts[:, 0], pts[:, 1])
    scale = max(np.ptp(pts, axis=0).max(), 1e-300)
    near = dist <= 1e-6 * scale + 1e-3 * np.tile(zone.weight, 2)
    mask = near[:zone.gap.size] | near[zone.gap.size:]
    if not mask.any():
        raise StudyError(f"region of interest '{roi}' holds no contact node nor its master "
                         "projection: a contact pressure criterion needs a region next to a contact",
                         path=path)
    return mask


def _contact_mean(state, mask: np.ndarray) -> float:
    """Mean contact pressure over the contact nodes in G_r: transmitted force / length."""
    c = state.contact
    return float(c.force_n[mask].sum() / c.weight[mask].sum())
