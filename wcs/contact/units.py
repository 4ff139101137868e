r"""The contact factorization of a stiffness made of units that no entry couples.

A unit is a set of reduced DOFs closed under K's couplings: a connected component of K's
graph, or several that share a material (their moduli always move together). Then
K = blockdiag_u(K_u), and K_u = Σ_j λ_j Kλ_j + μ_j Kμ_j is homogeneous of degree one in
its moduli (in 2D too: plane stress's λ* = 2λμ/(λ + 2μ) is): when they are s_u times those
of a direction c*_u, K_u = s_u K*_u. Each K*_u (regularized on its pinned DOFs) is factored
with the contact rows restricted to the unit, C_u = C[:, unit], which gives
W*_u = C_u K*_u⁻¹ C_uᵀ (`factor_regularized`), and

    K⁻¹ b = (K*_u⁻¹ b_u / s_u)_u,      W = C K⁻¹ Cᵀ = Σ_u W*_u / s_u,

since K⁻¹ is block diagonal too. Data sets that move each unit's moduli by a factor of its
own (the Young's moduli of several bodies) share every factorization; one that turns the
moduli of one unit (a Poisson ratio) refactors that unit alone."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from wcs.contact.solver import ContactFactor, factor_regularized
from wcs.linalg import Factor


@dataclass(frozen=True)
class Units:
    """The units of a reduced stiffness: each one's DOFs (ascending) and mesh regions."""
    dofs: tuple
    regions: tuple


def stiffness_units(pattern: sp.csr_matrix, region_dofs: list[np.ndarray], region_material: list[str]) -> Units:
    """The units of the reduced stiffness with sparsity `pattern`: the
    connected components of its graph, merged where two hold regions of one material; a unit's
    DOFs ascending, units by their first DOF, a unit's regions ascending. `region_dofs[j]`: the
    reduced DOFs region j's cells act on (a region acting on none joins no unit)."""
    n = pattern.shape[0]
    ncomp, label = connected_components(pattern, directed=False)
    materials = sorted(set(region_material))
    edges = [(c, ncomp + materials.index(region_material[j]))
             for j, dofs in enumerate(region_dofs) for c in np.unique(label[dofs])]
    a, b = np.array(edges, dtype=int).reshape(-1, 2).T
    size = ncomp + len(materials)
    graph = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(size, size))
    _, group = connected_components(graph, directed=False)
    of_dof = group[label]
    values, first = np.unique(of_dof, return_index=True)
    groups = values[np.argsort(first)]
    dofs = [np.flatnonzero(of_dof == g) for g in groups]
    regions = [[j for j, d in enumerate(region_dofs) if d.size and of_dof[d[0]] == g] for g in groups]
    assert sum(d.size for d in dofs) == n
    return Units(tuple(dofs), tuple(regions))


@dataclass(frozen=True)
class UnitSolve:
    """Solves with blockdiag(s_u K*_u) from the factors of the K*_u (a `linalg.Factor`)."""
    factors: tuple[Factor, ...]
    dofs: tuple
    scales: np.ndarray

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=float)
        if len(self.dofs) == 1:
            return self.factors[0].solve(b) / self.scales[0]
        x = np.empty(b.shape)
        for f, d, s in zip(self.factors, self.dofs, self.scales):
            x[d] = f.solve(b[d]) / s
        return x


@dataclass(frozen=True)
class ScaledUnits:
    """What `solve_contact(..., factored=)` and the adjoint use: `factor.solve` with K and W."""
    factor: Factor
    W: np.ndarray


class UnitFactors:
    """One contact factor per unit, each refactored in place (its analysis kept) when the
    block it is asked for is not the one it holds (`ContactFactor.holds`).

    dofs: the units' DOFs; C: the contact rows (all units'); pinned: the DOFs of the whole
    on which the blocks are regularized (`regularize`); bordered: W*_u from the factor of
    K*_u bordered by C_u (3D), else from the Schur complement on C_u's DOFs (2D: fewer, and
    faster so, `factor_regularized`)."""

    def __init__(self, dofs: tuple, C: sp.csr_matrix, pinned: np.ndarray, bordered: bool = True):
        self.dofs = dofs
        self.bordered = bordered
        self.borders = [C] if len(dofs) == 1 else [C[:, d].tocsr() for d in dofs]
        self.pinned = [np.searchsorted(d, pinned[np.isin(pinned, d)]) for d in dofs]
        self.parts: list[ContactFactor | None] = [None] * len(dofs)

    def of(self, blocks: list[sp.csr_matrix], scales) -> ScaledUnits:
        """The operators of blockdiag(s_u K*_u) for the regularized blocks K*_u (`blocks`) and
        the scales s_u."""
        scales = np.asarray(scales, dtype=float)
        for i, K in enumerate(blocks):
            self.parts[i] = factor_regularized(K, self.borders[i], self.pinned[i], self.parts[i], self.bordered)
        W = self.parts[0].W / scales[0]
        for part, s in zip(self.parts[1:], scales[1:]):
            W += part.W / s
        return ScaledUnits(UnitSolve(tuple(p.factor for p in self.parts), self.dofs, scales), W)
