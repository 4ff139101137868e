r"""The mass and viscous matrices of the P1 model (`wcs.model.Model`), on the stiffness's pattern.

Mass (consistent): M_ab,ij = ρ ∫_T N_a N_b δ_ij = ρ |T| (1 + δ_ab) / ((d + 1)(d + 2)) δ_ij, the
exact integral of the product of two P1 shape functions on a simplex of dimension d — the
(ρ u'', v) of [101, (9)]. The schemes need no lumping: each level solves with
M/Δt² + … (`wcs.dynamics.schemes`), as [101, (10)] writes it.

Viscosity: c⁽¹⁾ of τ = c⁽⁰⁾e(u) + c⁽¹⁾e(u') [101, (1)], isotropic with Lamé constants
(λ₁, μ₁): the viscous matrix is the stiffness operator at (λ₁, μ₁), a⁽¹⁾ of [101, (9)]. With
`ratio: η`, c⁽¹⁾ = η c⁽⁰⁾ (λ₁, μ₁) = η (λ, μ); with `{E, nu}`, (λ₁, μ₁) of those moduli [Pa s]
by the same formulas as the elastic ones (plane stress: λ₁* = 2λ₁μ₁/(λ₁ + 2μ₁)).
"""
from __future__ import annotations

import numpy as np

from wcs.fem.affine import CellAffineOperator, gradients
from wcs.model.materials import plane_lame


def mass_cell_matrices(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(1, ncells, n, n, d, d): |T| (1 + δ_ab) / ((d + 1)(d + 2)) δ_ij, the consistent P1 mass
    of unit density, by node pair (a, b) and components (i, j)."""
    _, measure = gradients(p, t)
    d, n = p.shape[0], t.shape[0]
    pair = (np.ones((n, n)) + np.eye(n)) / ((d + 1) * (d + 2))
    local = measure[:, None, None, None, None] * pair[None, :, :, None, None] * np.eye(d)[None, None, None]
    return local[None]


def mass_operator(model) -> CellAffineOperator:
    """M(ρ) = Σ_regions ρ_j M_j on the model's mesh (ρ per region)."""
    mesh = model.smesh.mesh
    return CellAffineOperator(mesh.t, model.nnodes, mass_cell_matrices(mesh.p, mesh.t), model.smesh.cell_region)


def viscous_lame(viscosity, lam: float, mu: float, plane: str | None) -> tuple[float, float]:
    """(λ₁, μ₁) of a material's viscosity (None: no viscosity) given its elastic (λ, μ) as
    they enter the stiffness (plane stress: λ*); plane None: 3D."""
    if viscosity is None:
        return 0.0, 0.0
    if viscosity.ratio is not None:
        return viscosity.ratio * lam, viscosity.ratio * mu
    return plane_lame({"E": viscosity.E, "nu": viscosity.nu}, plane or "strain")
