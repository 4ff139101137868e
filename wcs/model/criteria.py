"""Criterion functionals Φ1–Φ6 [68, (4.29)–(4.34)]: each a maximum over regions of
interest G_r of a mean over G_r — and beyond the seed, `contact_pressure_peak`: the largest
nodal contact pressure in G_r (`in_words` says which reduction a criterion is).

`KINDS` is the one registry of criterion kinds: a `Kind` holds everything the code
knows of a kind (its value on a region, its partial derivatives for the adjoint,
units, label, the scene block it needs, the options it takes, where it reads its
regions). The schema, the adjoint and the report read it; a new kind is one entry. The
regions of interest on the mesh (selections, mean weights, directions, contact rows and
pressure functionals) are `wcs.model.regions`.

Linear criteria (temperature, normal displacement) keep their functional as
a vector ℓ_r (Φ_r = ℓ_r · field), which is also the adjoint load of the
criterion. Stress criteria average a cell density ψ(τ) over G_r; contact
criteria a nodal quantity along the contact (Φ6: the mean of the interpolated pressure
over Γc ∩ G_r, again a vector ℓ_r, on λ_n).

The mesh gives the dimension: triangles (areas, edges, stresses xx yy zz xy) or tetrahedra
(volumes, triangular faces with the normal from the face, stresses xx yy zz yz xz xy, two
tangent components of the slip per contact node).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..fem import stress
from ..geometry import tet
from ..scene.selectors import Selection
from .regions import (_cell_mean, _contact_rows_in, _direction, _mean_weights, _measure, _pressure_functional,
                      _roi_selection, cell_weights)
REL_TOL = 1e-7       # "within reach" for the non-smoothness flags, relative


@dataclass
class Partials:
    """Explicit partial derivatives of one criterion at a solution."""
    u: np.ndarray | None = None          # ∂Φ/∂u (full dofs)
    theta: np.ndarray | None = None      # ∂Φ/∂θ (heat nodes)
    lam_n: np.ndarray | None = None      # ∂Φ/∂λ_n (contact nodes)
    lam_t: np.ndarray | None = None      # ∂Φ/∂λ_t (tangent rows, stacked as Bt)
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


# ---------------------------------------------------------------- the kinds

def _normal_functional(smesh, spec, sel: Selection, path: str, roi: str) -> np.ndarray:
    """ℓ_r with ℓ_r · u = mean over G_r of u · n(X_r)."""
    d = _direction(smesh, spec, sel, path, roi)
    nodal = _mean_weights(smesh.mesh, sel)
    ell = np.zeros(d.size * nodal.size)
    for i in range(d.size):
        ell[i::d.size] = nodal * d[i]
    return ell


def _stress_partials(model, state, sel: Selection, dpsi: np.ndarray) -> Partials:
    """Partials of Φ = Σ_c a_c ψ(τ_c) / Σ a_c given ∂ψ/∂τ per cell (4 or 6, nc);
    τ = D(λ, μ) e − β ΔT m."""
    sm, mesh = model.smesh, model.smesh.mesh
    cells, a = cell_weights(model, sel)
    weight = np.zeros(mesh.t.shape[1])
    weight[cells] = a / a.sum()
    d = dpsi * weight                                          # ∂Φ/∂τ per cell
    c = state.coefficients
    reg = sm.cell_region
    lam, mu, beta = c.lam[reg], c.mu[reg], c.beta[reg]
    if mesh.p.shape[0] == 3:                                   # τ_ii = λ tr e + 2μ e_ii − βΔT, τ_ij = μ γ_ij
        strain = (model.G @ state.u).reshape(6, -1)
        trace_load = d[0] + d[1] + d[2]
        de = np.vstack([lam * trace_load + 2 * mu * d[:3], mu * d[3:]])
        dlam = trace_load * strain[:3].sum(axis=0)
        dmu = 2 * (strain[:3] * d[:3]).sum(axis=0) + (strain[3:] * d[3:]).sum(axis=0)
    else:
        exx, eyy, gxy = (model.G @ state.u).reshape(3, -1)
        dz = d[2] if model.plane == "strain" else np.zeros_like(d[2])
        trace_load = d[0] + d[1] + dz                          # ∂Φ/∂(λ tr − βΔT) along m
        de = np.array([(lam + 2 * mu) * d[0] + lam * (d[1] + dz),
                       lam * (d[0] + dz) + (lam + 2 * mu) * d[1],
                       mu * d[3]])
        dlam, dmu = trace_load * (exx + eyy), 2 * exx * d[0] + 2 * eyy * d[1] + gxy * d[3]
    nr = len(model.region_cells)
    per_region = lambda v: np.bincount(reg, weights=v, minlength=nr)   # noqa: E731
    dT = (np.zeros(reg.size) if state.T is None
          else state.T[mesh.t].mean(axis=0) - c.reference)
    coef = {"lam": per_region(dlam),
            "mu": per_region(dmu),
            "beta": per_region(-dT * trace_load),
            "reference": np.array([np.sum(beta * trace_load)])}
    theta = None
    if state.T is not None:
        nodal = np.zeros(mesh.p.shape[1])
        nv = mesh.t.shape[0]
        for k in range(nv):
            np.add.at(nodal, mesh.t[k], -beta * trace_load / nv)
        theta = model.P.T @ nodal
    return Partials(u=model.G.T @ de.ravel(), theta=theta, coef=coef)


def _invariants(s: np.ndarray):
    """The stress module of the components s: `wcs.fem.stress` (4: xx yy zz xy) or
    `wcs.geometry.tet` (6: xx yy zz yz xz xy)."""
    return tet if len(s) == 6 else stress


def _shear_intensity(s: np.ndarray) -> np.ndarray:
    return _invariants(s).shear_intensity(s)


def _von_mises(s: np.ndarray) -> np.ndarray:
    return _invariants(s).von_mises(s)


def _dI2(s: np.ndarray) -> np.ndarray:
    """∂I₂²/∂τ (4 or 6, nc), each shear component counted twice (τ_xy = τ_yx)."""
    xx, yy, zz = s[:3]
    dI = (2.0 / 3.0) * np.vstack([[2 * xx - yy - zz, 2 * yy - xx - zz, 2 * zz - xx - yy], 3 * s[3:]])
    dI[3:] *= 2.0                                             # ∂I₂²/∂τ_xy = 4 τ_xy
    return dI


def _dvon_mises(s: np.ndarray) -> np.ndarray:
    """∂σ_vM/∂τ = (3/4) ∂I₂²/∂τ / σ_vM (σ_vM = √(3/2 I₂²)); 0 where σ_vM = 0."""
    vm = np.sqrt(1.5 * _shear_intensity(s))
    return _dI2(s) * np.where(vm > 0, 0.75 / np.where(vm > 0, vm, 1.0), 0.0)


def _principal_max(s: np.ndarray) -> np.ndarray:
    """σ₁, the largest principal stress (in 2D the in-plane one: the field `principal_stress`,
    first column)."""
    return _invariants(s).principal(s)[:, 0]


def _dprincipal_max(s: np.ndarray) -> np.ndarray:
    """∂σ₁/∂τ. 2D: σ₁ = (τxx+τyy)/2 + r, r = √(((τxx−τyy)/2)² + τxy²); at r = 0 (σ₁ = σ₂,
    a kink) the mean of the one-sided derivatives, (½, ½, 0, 0). 3D: σ₁ = vᵀτv with v the
    unit eigenvector of σ₁, ∂σ₁/∂τ = v vᵀ (a shear component twice); where σ₁ is a multiple
    eigenvalue (a kink, `_principal_kink`) the mean of the tied eigenvectors' projectors."""
    if len(s) == 6:
        w, V = np.linalg.eigh(tet.tensor(s))                  # ascending
        tied = (w[:, 2:] - w) <= REL_TOL * np.abs(s).max(axis=0)[:, None]
        P = np.einsum("cik,cjk,ck->cij", V, V, tied) / tied.sum(axis=1)[:, None, None]
        return np.array([P[:, 0, 0], P[:, 1, 1], P[:, 2, 2], 2 * P[:, 1, 2], 2 * P[:, 0, 2], 2 * P[:, 0, 1]])
    xx, yy, _, xy = s
    r = np.sqrt((0.5 * (xx - yy)) ** 2 + xy**2)
    q = np.where(r > 0, 1.0 / np.where(r > 0, r, 1.0), 0.0)
    return np.array([0.5 + 0.25 * (xx - yy) * q, 0.5 - 0.25 * (xx - yy) * q, np.zeros_like(r), xy * q])


def _principal_kink(s: np.ndarray) -> np.ndarray:
    """Cells where σ₁ ≈ σ₂ (relative to the cell's stress): σ₁ is not differentiable there."""
    if len(s) == 6:
        p = tet.principal(s)
        return p[:, 0] - p[:, 1] <= REL_TOL * np.abs(s).max(axis=0)
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


def node_norm(v: np.ndarray, m: int) -> np.ndarray:
    """(m,) the norm of each contact node's tangent components (rows j·m + i; one in 2D: its
    absolute value)."""
    return np.abs(v) if v.size == m else np.linalg.norm(v.reshape(-1, m), axis=0)


def _slip_mean(crit, model, state, r) -> float:
    """Mean |relative tangential displacement| over the contact nodes next to G_r: Σ w|s| / Σ w
    (3D: |s| the length of the node's two-component slip)."""
    mask, c = crit.contact_masks[r], state.contact
    return float(c.weight[mask] @ node_norm(c.slip, mask.size)[mask] / c.weight[mask].sum())


def _slip_partials(crit, model, state, r):
    """∂Φ/∂u = Btᵀ (w ν) / Σ w over the rows next to G_r (s = Bt u, ν = s/|s|: sign(s) in 2D).
    |s| has a kink at s = 0, which matters only where s can cross 0: a stuck node keeps s fixed
    on its active set (and a stick/slip switch is flagged with the active set), and a node whose
    reduced tangential rows vanish or are round-off (`Model.held`: held by supports on both
    sides) has s fixed by them; any other node in G_r with s ≈ 0 makes the point non-smooth."""
    mask, c = crit.contact_masks[r], state.contact
    m = mask.size
    k = c.slip.size // m
    norm = node_norm(c.slip, m)
    w = np.where(mask, c.weight, 0.0)
    nu = np.divide(c.slip, np.tile(norm, k), out=np.zeros_like(c.slip), where=np.tile(norm > 0, k))
    dslip = np.tile(w, k) * nu / w.sum()
    stuck = state.raw.free[m:2 * m] if state.raw is not None else np.zeros(m, dtype=bool)
    scale = max(np.abs(c.slip).max(), np.abs(state.u).max(), 1e-300)
    moves = (~model.held[m:]).reshape(k, m).any(axis=0)
    kink = mask & ~stuck & moves & (norm <= REL_TOL * scale)
    return Partials(u=model.zone.Bt.T @ dslip), bool(kink.any())


def _pressure_partials(ell: np.ndarray, model, state) -> Partials:
    """∂(ℓ · λn)/∂λ of the solver's multipliers through the reported λn (`wcs.contact.zone.
    canonical_split`'s jacobian): a tied node's canonical λn + κ λt, a dependent node's least
    |λt| split, 0 on a held normal or a tied node pulled apart. Each is a function of the
    combination that acts, so its derivative holds whichever split the solver's path found."""
    jac = state.contact.jacobian
    if jac is None:
        return Partials(lam_n=ell.copy())
    dn, dt = jac
    lam_t = np.tile(ell, dt.size // ell.size) * dt
    return Partials(lam_n=ell * dn, lam_t=lam_t if lam_t.any() else None)


def _peak_pressure(crit, model, state, r) -> float:
    """The largest nodal contact pressure λ_i / w_i over the contact rows next to G_r."""
    return float(state.contact.pressure[crit.contact_masks[r]].max())


def _peak_partials(crit, model, state, r):
    """∂Φ/∂λ of the maximising row k's pressure λ_k / w_k (as Φ6's, `_pressure_partials`). The
    maximum is differentiable where k is the only maximiser; another row in reach of it (within
    REL_TOL of the peak, as the other kinds' ties) makes the point non-smooth, unless the peak is
    0: then every row in G_r is open or unloaded and the active set decides."""
    mask, p = crit.contact_masks[r], state.contact.pressure
    rows = np.flatnonzero(mask)
    k = rows[int(np.argmax(p[rows]))]
    ell = np.zeros(p.size)
    ell[k] = 1.0 / state.contact.weight[k]
    tied = bool((p[rows] >= p[k] - REL_TOL * abs(p[k])).sum() > 1 and p[k] > 0)
    return _pressure_partials(ell, model, state), tied


def in_words(kind: str, regions: list[str]) -> str:
    """What a criterion is, in words: its kind's reduction over its region of interest, or the
    largest over several regions of the reduction over each ([68, (4.29)–(4.34)])."""
    label = KINDS[kind].label if kind in KINDS else (kind or "criterion")
    if not regions:
        return label
    if len(regions) == 1:
        return f"{label} over {regions[0]}"
    return f"the largest over {', '.join(regions)} of the {label} over each"


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
    "shear_stress_intensity": _area_kind("mean shear stress intensity I₂² (Φ5)", "Pa^2", _shear_intensity, _dI2),
    "contact_pressure": Kind(
        "mean contact pressure (Φ6)", "Pa",
        value=lambda crit, model, state, r: crit.functionals[r] @ state.contact.force_n,
        partials=lambda crit, model, state, r: (_pressure_partials(crit.functionals[r], model, state), False),
        contact_functional=_pressure_functional, reads="contact", needs="contacts"),
    "von_mises": _area_kind("mean von Mises stress", "Pa", _von_mises, _dvon_mises),
    "principal_stress": _area_kind("mean largest principal stress σ₁ (in-plane in 2D)", "Pa", _principal_max,
                                   _dprincipal_max, _principal_kink),
    "contact_slip": Kind("mean contact slip |relative tangential displacement|", "m",
                         value=_slip_mean, partials=_slip_partials, reads="contact", needs="contacts"),
    "contact_pressure_peak": Kind("largest nodal contact pressure", "Pa", value=_peak_pressure,
                                  partials=_peak_partials, reads="contact", needs="contacts"),
}
