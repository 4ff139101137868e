"""Criterion functionals Φ1–Φ6 [68, (4.29)–(4.34)]: each a maximum over regions of
interest G_r of a mean over G_r.

`KINDS` is the one registry of criterion kinds: a `Kind` holds everything the code
knows of a kind (its value on a region, its partial derivatives for the adjoint,
units, label, the scene block it needs, the options it takes, where it reads its
regions). The schema, the adjoint and the report read it; a new kind is one entry.

Linear criteria (temperature, normal displacement) keep their functional as
a vector ℓ_r (Φ_r = ℓ_r · field), which is also the adjoint load of the
criterion. Stress criteria average a cell density ψ(τ) over G_r; contact
criteria a nodal quantity along the contact (Φ6: the mean of the interpolated pressure
over Γc ∩ G_r, again a vector ℓ_r, on λ_n).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .contact.zone import slave_segments
from .errors import StudyError
from .fem.stress import principal, shear_intensity, von_mises
from .scene.selectors import (Selection, boundary_facets, dist_segments, distance_function, facet_lengths,
                              facet_normals, select_region)

CORNER = np.cos(np.radians(30.0))   # boundary edges nearest X_r turning by more: a corner, n(X_r) undefined
REL_TOL = 1e-7       # "within reach" for the non-smoothness flags, relative


@dataclass
class Partials:
    """Explicit partial derivatives of one criterion at a solution."""
    u: np.ndarray | None = None          # ∂Φ/∂u (full dofs)
    theta: np.ndarray | None = None      # ∂Φ/∂θ (heat nodes)
    lam_n: np.ndarray | None = None      # ∂Φ/∂λ_n (contact nodes)
    coef: dict | None = None             # field -> ∂Φ/∂c (explicit dependence, e.g. of stresses)


@dataclass(frozen=True)
class Kind:
    """One criterion kind. `value(criterion, model, state, r)` is Φ_r; `partials(...)` its
    explicit partials at region r and whether Φ_r is not differentiable within reach."""
    label: str
    units: str
    value: Callable
    partials: Callable
    reads: str = "cells"                 # "cells": G_r embedded in the mesh; "contact": the contact rows next to G_r
    functional: Callable | None = None   # (smesh, spec, selection, path, roi) -> ℓ_r of a linear kind
    contact_functional: Callable | None = None   # (smesh, scene, zone, roi, selection, path) -> (ℓ_r on λ_n, meas)
    needs: str | None = None             # the scene block the kind needs: "thermal", "contacts"
    options: tuple[str, ...] = ()        # criterion keys beyond name, kind, regions


@dataclass
class Criterion:
    name: str
    kind: str
    rois: list[str]
    selections: list[Selection]
    functionals: list[np.ndarray] | None     # linear kinds: one ℓ_r per region of interest
    measures: np.ndarray                      # meas G_r (contact kinds: of Γc ∩ G_r, slip: of its rows)
    contact_masks: list[np.ndarray] | None = None   # contact kinds: contact rows next to G_r

    @property
    def units(self) -> str:
        return KINDS[self.kind].units

    def region_values(self, model, state) -> np.ndarray:
        value = KINDS[self.kind].value
        return np.array([value(self, model, state, r) for r in range(len(self.rois))])

    def value(self, model, state) -> float:
        return float(np.max(self.region_values(model, state)))


def build_criteria(study_criteria, scene, smesh, zone=None) -> list[Criterion]:
    """The study's criteria (validated specs: name, kind, regions, options) on the mesh."""
    rois = scene.regions_of_interest
    out = []
    for k, spec in enumerate(study_criteria):
        path, kind = f"criteria.{k}", KINDS[spec.kind]
        if kind.reads == "contact":             # only the contact rows next to G_r matter
            sels = [_roi_selection(smesh, r, rois[r], f"scene.regions_of_interest.{r}")
                    if rois[r].boundary is not None else Selection("cells", np.zeros(0, dtype=np.int64))
                    for r in spec.regions]
            masks = [_contact_rows_in(smesh, scene, zone, r, s, f"scene.regions_of_interest.{r}")
                     for r, s in zip(spec.regions, sels)]
            measures = np.array([zone.weight[m].sum() for m in masks])
            functionals = None
            if kind.contact_functional is not None:
                lm = [kind.contact_functional(smesh, scene, zone, r, s, f"scene.regions_of_interest.{r}")
                      for r, s in zip(spec.regions, sels)]
                functionals, measures = [ell for ell, _ in lm], np.array([m for _, m in lm])
            out.append(Criterion(spec.name, spec.kind, list(spec.regions), sels, functionals, measures,
                                 masks))
            continue
        sels = [_roi_selection(smesh, r, rois[r], f"scene.regions_of_interest.{r}") for r in spec.regions]
        functionals = None if kind.functional is None else \
            [kind.functional(smesh, spec, s, path, r) for r, s in zip(spec.regions, sels)]
        measures = np.array([_measure(smesh.mesh, s) for s in sels])
        out.append(Criterion(spec.name, spec.kind, list(spec.regions), sels, functionals, measures))
    return out


def embedded_rois(study_criteria) -> list[str]:
    """The regions of interest whose cells a criterion integrates over (every kind but the
    contact ones, which take the contact rows next to G_r): the mesh embeds them."""
    return sorted({r for c in study_criteria if KINDS[c.kind].reads == "cells" for r in c.regions})


def _roi_selection(smesh, name: str, spec, path: str) -> Selection:
    """G_r as mesh entities: the cells of a box / disc / polygon embedded in the mesh (exactly
    G_r, the disc as the mesh's polygon), else `select_region` (boundary facets; on a mesh file
    the cells cut exactly by a box or polygon)."""
    if name not in smesh.roi_cells:
        return select_region(smesh, spec, path)
    sel = Selection("cells", smesh.roi_cells[name])
    if len(sel) == 0:
        where = f" of body {spec.body!r}" if spec.body is not None else ""
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


def _direction(smesh, spec, sel: Selection, path: str, roi: str) -> np.ndarray:
    """The fixed direction n(X_r): given, the outward normal of the boundary of the region's
    body at `point` X_r (X_r must lie on it, up to half an edge; at a node between edges that
    turn by at most 30° their length-weighted mean normal, at a sharper corner refused), or the
    mean outward normal of a boundary region of interest."""
    mesh = smesh.mesh
    if spec.direction is not None:
        d = np.asarray(spec.direction, float)
        return d / np.linalg.norm(d)
    if spec.point is not None:
        X = np.asarray(spec.point, float)
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


def _contact_rows_in(smesh, scene, zone, roi: str, sel: Selection, path: str) -> np.ndarray:
    """Contact rows (slave nodes) next to G_r: the slave node x or its master projection
    x + gap·n lies in G_r, so a region on either side of a contact, open or closed, matching
    or not, catches the same rows. A boundary G_r is its facets; an area one its shape."""
    normal = np.concatenate([p.normal for p in zone.pairs])
    pts = np.vstack([zone.coords, zone.coords + zone.gap[:, None] * normal])
    if sel.kind == "facets":
        mesh = smesh.mesh
        a, b = mesh.p[:, mesh.facets[0, sel.index]].T, mesh.p[:, mesh.facets[1, sel.index]].T
        dist = dist_segments(pts[:, 0], pts[:, 1], a, b)
    else:
        dist = distance_function(scene.regions_of_interest[roi], path)(pts[:, 0], pts[:, 1])
    scale = max(np.ptp(pts, axis=0).max(), 1e-300)
    near = dist <= 1e-6 * scale + 1e-3 * np.tile(zone.weight, 2)
    mask = near[:zone.gap.size] | near[zone.gap.size:]
    if not mask.any():
        raise StudyError(f"region of interest '{roi}' holds no contact node nor its master "
                         "projection: a contact pressure criterion needs a region next to a contact",
                         path=path)
    return mask


def _crossings(spec, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(s, K) parameters t ∈ [0, 1] where the edges a + t (b − a) cross the boundary of a box,
    disc or polygon (NaN: none); between two of them an edge is wholly inside or outside."""
    d = b - a
    if spec.disc is not None:
        c, r = np.asarray(spec.disc.center, float), float(spec.disc.radius)
        e = a - c
        qa, qb, qc = (d * d).sum(axis=1), 2 * (d * e).sum(axis=1), (e * e).sum(axis=1) - r * r
        disc = qb * qb - 4 * qa * qc
        root = np.sqrt(np.where(disc > 0, disc, np.nan))
        t = np.stack([(-qb - root) / (2 * qa), (-qb + root) / (2 * qa)], axis=1)
    else:
        if spec.box is not None:
            x0, y0, x1, y1 = map(float, spec.box)
            pts = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        else:
            pts = np.asarray(spec.polygon, float)
        c, e = np.roll(pts, 1, axis=0), pts - np.roll(pts, 1, axis=0)       # the polygon's edges c + u e
        det = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
        w = c[None] - a[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[..., 0] * e[None, :, 1] - w[..., 1] * e[None, :, 0]) / det
            u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / det
        t = np.where((u >= 0) & (u <= 1), t, np.nan)                       # parallel edges: NaN
    return np.where((t > 0) & (t < 1), t, np.nan)


def _pressure_functional(smesh, scene, zone, roi: str, sel: Selection, path: str):
    """(ℓ_r, meas Γc ∩ G_r) with ℓ_r · λ_n = (meas Γc ∩ G_r)⁻¹ ∫_{Γc ∩ G_r} p_h ds, Φ6 [68, (4.34)]:
    p_h the piecewise linear interpolant along the slave side of the nodal pressures
    p_i = λ_i / w_i (w_i: the row's weight, node-to-node or mortar), integrated exactly.
    A point of a slave edge lies in G_r when it or its master projection does (the projection
    of x_i is x_i + gap_i n_i, interpolated along the edge), so a region on either side of a
    contact, open or closed, catches the same part of it. Each edge is cut where it or its
    projection crosses the boundary of G_r (a boundary G_r: at its facets' ends), and each piece
    is in or out by its midpoint: in G_r up to 1e-6 of the contact's extent (round-off), next
    to a boundary G_r up to a tenth of the edge more (the chord between two projections on a
    curved master side leaves it by about L²/8R)."""
    seg = slave_segments(zone, scene, smesh)
    normal = np.concatenate([p.normal for p in zone.pairs])
    ends = [(zone.coords[seg[:, 0]], zone.coords[seg[:, 1]]),
            (zone.coords[seg[:, 0]] + (zone.gap[:, None] * normal)[seg[:, 0]],
             zone.coords[seg[:, 1]] + (zone.gap[:, None] * normal)[seg[:, 1]])]
    length = np.hypot(*(ends[0][1] - ends[0][0]).T)
    tol = 1e-6 * max(np.ptp(np.vstack([zone.coords, ends[1][0], ends[1][1]]), axis=0).max(), 1e-300)
    if sel.kind == "facets":
        mesh = smesh.mesh
        fa, fb = mesh.p[:, mesh.facets[0, sel.index]].T, mesh.p[:, mesh.facets[1, sel.index]].T
        corners, tol = np.vstack([fa, fb]), tol + 0.1 * length[:, None]

        def dist(x, y):
            return dist_segments(x, y, fa, fb)

        def cuts(a, b):                         # where the facets' ends project on the edge
            d = b - a
            return ((corners[None] - a[:, None]) * d[:, None]).sum(axis=2) / (d * d).sum(axis=1)[:, None]
    else:
        spec = scene.regions_of_interest[roi]
        dist = distance_function(spec, path)

        def cuts(a, b):
            return _crossings(spec, a, b)
    t = np.hstack([np.zeros((len(seg), 1)), np.ones((len(seg), 1))] + [cuts(a, b) for a, b in ends])
    t = np.sort(np.where((t >= 0) & (t <= 1), t, np.nan), axis=1)           # NaN last
    t0, t1 = t[:, :-1], t[:, 1:]
    mid = np.nan_to_num(0.5 * (t0 + t1))
    inside = np.zeros(mid.shape, dtype=bool)
    real = ~np.isnan(t1)                        # the pieces (the NaN-padded ones have no length)
    e, tol = np.nonzero(real)[0], np.broadcast_to(tol, mid.shape)[real]
    for a, b in ends:
        x = a[e] + mid[real][:, None] * (b - a)[e]
        inside[real] |= dist(x[:, 0], x[:, 1]) <= tol
    piece = np.where(inside, np.nan_to_num(t1 - t0), 0.0) * length[:, None]
    meas = float(piece.sum())
    if meas <= 0:
        raise StudyError(f"region of interest '{roi}' covers no length of a contact's slave side "
                         "(nor of its master projection): a contact pressure criterion needs one",
                         path=path)
    ell = np.zeros(zone.gap.size)
    np.add.at(ell, seg[:, 0], (piece * (1 - mid)).sum(axis=1))
    np.add.at(ell, seg[:, 1], (piece * mid).sum(axis=1))
    return ell / zone.weight / meas, meas


# ---------------------------------------------------------------- the kinds

def _normal_functional(smesh, spec, sel: Selection, path: str, roi: str) -> np.ndarray:
    """ℓ_r with ℓ_r · u = mean over G_r of u · n(X_r)."""
    d = _direction(smesh, spec, sel, path, roi)
    nodal = _mean_weights(smesh.mesh, sel)
    ell = np.zeros(2 * nodal.size)
    ell[0::2], ell[1::2] = nodal * d[0], nodal * d[1]
    return ell


def _stress_partials(model, state, sel: Selection, dpsi: np.ndarray) -> Partials:
    """Partials of Φ = Σ_c a_c ψ(τ_c) / Σ a_c given ∂ψ/∂τ per cell (4, nc); τ = D(λ, μ) e − β ΔT m."""
    sm, mesh = model.smesh, model.smesh.mesh
    cells, a = cell_weights(model, sel)
    weight = np.zeros(mesh.t.shape[1])
    weight[cells] = a / a.sum()
    d = dpsi * weight                                          # ∂Φ/∂τ per cell, (4, nc)
    c = state.coefficients
    reg = sm.cell_region
    lam, mu, beta = c.lam[reg], c.mu[reg], c.beta[reg]
    strain = (model.G @ state.u).reshape(3, -1)
    exx, eyy, gxy = strain
    dz = d[2] if model.plane == "strain" else np.zeros_like(d[2])
    trace_load = d[0] + d[1] + dz                              # ∂Φ/∂(λ tr − βΔT) along m
    de = np.array([(lam + 2 * mu) * d[0] + lam * (d[1] + dz),
                   lam * (d[0] + dz) + (lam + 2 * mu) * d[1],
                   mu * d[3]])
    nr = len(model.region_cells)
    per_region = lambda v: np.bincount(reg, weights=v, minlength=nr)   # noqa: E731
    dT = (np.zeros(reg.size) if state.T is None
          else state.T[mesh.t].mean(axis=0) - c.reference)
    coef = {"lam": per_region(trace_load * (exx + eyy)),
            "mu": per_region(2 * exx * d[0] + 2 * eyy * d[1] + gxy * d[3]),
            "beta": per_region(-dT * trace_load),
            "reference": np.array([np.sum(beta * trace_load)])}
    theta = None
    if state.T is not None:
        nodal = np.zeros(mesh.p.shape[1])
        for k in range(3):
            np.add.at(nodal, mesh.t[k], -beta * trace_load / 3.0)
        theta = model.P.T @ nodal
    return Partials(u=model.G.T @ de.ravel(), theta=theta, coef=coef)


def _dI2(s: np.ndarray) -> np.ndarray:
    """∂I₂²/∂τ (4, nc), τ_xy counted twice (τ_xy = τ_yx)."""
    xx, yy, zz, xy = s
    dI = (2.0 / 3.0) * np.array([2 * xx - yy - zz, 2 * yy - xx - zz, 2 * zz - xx - yy, 3 * xy])
    dI[3] *= 2.0                                              # ∂I₂²/∂τ_xy = 4 τ_xy
    return dI


def _dvon_mises(s: np.ndarray) -> np.ndarray:
    """∂σ_vM/∂τ = (3/4) ∂I₂²/∂τ / σ_vM (σ_vM = √(3/2 I₂²)); 0 where σ_vM = 0."""
    vm = np.sqrt(1.5 * shear_intensity(s))
    return _dI2(s) * np.where(vm > 0, 0.75 / np.where(vm > 0, vm, 1.0), 0.0)


def _principal_max(s: np.ndarray) -> np.ndarray:
    """σ₁, the largest in-plane principal stress (the field `principal_stress`, first column)."""
    return principal(s)[:, 0]


def _dprincipal_max(s: np.ndarray) -> np.ndarray:
    """∂σ₁/∂τ with σ₁ = (τxx+τyy)/2 + r, r = √(((τxx−τyy)/2)² + τxy²); at r = 0 (σ₁ = σ₂,
    a kink) the mean of the one-sided derivatives, (½, ½, 0, 0)."""
    xx, yy, _, xy = s
    r = np.sqrt((0.5 * (xx - yy)) ** 2 + xy**2)
    q = np.where(r > 0, 1.0 / np.where(r > 0, r, 1.0), 0.0)
    return np.array([0.5 + 0.25 * (xx - yy) * q, 0.5 - 0.25 * (xx - yy) * q, np.zeros_like(r), xy * q])


def _principal_kink(s: np.ndarray) -> np.ndarray:
    """Cells where σ₁ ≈ σ₂ (relative to the cell's stress): σ₁ is not differentiable there."""
    xx, yy, _, xy = s
    return np.sqrt((0.5 * (xx - yy)) ** 2 + xy**2) <= REL_TOL * np.abs(s).max(axis=0)


def _area_kind(label: str, units: str, density: Callable, ddensity: Callable,
               kink: Callable | None = None) -> Kind:
    """A mean over G_r of a cell density ψ(τ) (as Φ5): value and partials from ψ and ∂ψ/∂τ;
    `kink(τ)`: the cells where ψ is not differentiable."""
    def partials(crit, model, state, r):
        sel = crit.selections[r]
        nonsmooth = kink is not None and bool(kink(state.stress)[cell_weights(model, sel)[0]].any())
        return _stress_partials(model, state, sel, ddensity(state.stress)), nonsmooth
    return Kind(label, units, partials=partials,
                value=lambda crit, model, state, r: _cell_mean(model, crit.selections[r], density(state.stress)))


def _slip_mean(crit, model, state, r) -> float:
    """Mean |relative tangential displacement| over the contact nodes next to G_r: Σ w|s| / Σ w."""
    mask, c = crit.contact_masks[r], state.contact
    return float(c.weight[mask] @ np.abs(c.slip[mask]) / c.weight[mask].sum())


def _slip_partials(crit, model, state, r):
    """∂Φ/∂u = Btᵀ (w sign(s)) / Σ w over the rows next to G_r (s = Bt u). |s| has a kink at
    s = 0, which matters only where s can cross 0: a stuck node keeps s fixed on its active
    set (and a stick/slip switch is flagged with the active set), and a node whose reduced
    tangential row vanishes (held by supports on both sides) has s fixed by them; any other
    node in G_r with s ≈ 0 makes the point non-smooth."""
    mask, c = crit.contact_masks[r], state.contact
    w = np.where(mask, c.weight, 0.0)
    dslip = w * np.sign(c.slip) / w.sum()
    m = c.slip.size
    stuck = state.raw.free[m:] if state.raw is not None else np.zeros(m, dtype=bool)
    scale = max(np.abs(c.slip).max(), np.abs(state.u).max(), 1e-300)
    moves = np.asarray(abs(model.Bt_r.copy()).sum(axis=1)).ravel() > 0   # abs() sorts its operand in place
    kink = mask & ~stuck & moves & (np.abs(c.slip) <= REL_TOL * scale)
    return Partials(u=model.zone.Bt.T @ dslip), bool(kink.any())


KINDS: dict[str, Kind] = {
    "mean_temperature": Kind(
        "mean temperature (Φ1/Φ2)", "K",
        value=lambda crit, model, state, r: crit.functionals[r] @ state.T,
        partials=lambda crit, model, state, r: (Partials(theta=model.P.T @ crit.functionals[r]), False),
        functional=lambda smesh, spec, sel, path, roi: _mean_weights(smesh.mesh, sel), needs="thermal"),
    "mean_normal_displacement": Kind(
        "mean normal displacement (Φ3/Φ4)", "m",
        value=lambda crit, model, state, r: crit.functionals[r] @ state.u,
        partials=lambda crit, model, state, r: (Partials(u=crit.functionals[r].copy()), False),
        functional=_normal_functional, options=("point", "direction")),
    "shear_stress_intensity": _area_kind("shear stress intensity I₂² (Φ5)", "Pa^2", shear_intensity, _dI2),
    "contact_pressure": Kind(
        "contact pressure (Φ6)", "Pa",
        value=lambda crit, model, state, r: crit.functionals[r] @ state.contact.force_n,
        partials=lambda crit, model, state, r: (Partials(lam_n=crit.functionals[r].copy()), False),
        contact_functional=_pressure_functional, reads="contact", needs="contacts"),
    "von_mises": _area_kind("von Mises stress", "Pa", von_mises, _dvon_mises),
    "principal_stress": _area_kind("largest principal stress σ₁ (in-plane)", "Pa", _principal_max,
                                   _dprincipal_max, _principal_kink),
    "contact_slip": Kind("mean contact slip |relative tangential displacement|", "m",
                         value=_slip_mean, partials=_slip_partials, reads="contact", needs="contacts"),
}
