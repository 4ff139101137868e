"""Load and coupling forms, written as the math reads (P1 triangles, scikit-fem).

Each form is one parameter-free piece; the data (β, loads, sources) multiply
the assembled pieces later. The stiffness and conduction operators are in
`affine.py` (cell matrices in closed form, verified against scikit-fem).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from skfem import Basis, BilinearForm, ElementTriP1, ElementVector, FacetBasis, LinearForm, asm
from skfem.helpers import div, dot

SCALAR = ElementTriP1()
VECTOR = ElementVector(ElementTriP1())


@BilinearForm
def thermal_coupling(theta, v, w):
    """β-piece of the thermal load: θ div v (θ = T − T0, scalar trial)."""
    return theta * div(v)


@LinearForm
def unit_scalar(s, w):
    return s


@LinearForm
def outward_pressure(v, w):
    """A unit pressure pushes against the outward normal: −n · v."""
    return -dot(w.n, v)


def component_form(i: int) -> LinearForm:
    @LinearForm
    def form(v, w):
        return v[i]
    return form


def region_basis(mesh, element, cells: np.ndarray, intorder: int = 2) -> Basis:
    return Basis(mesh, element, elements=cells, intorder=intorder)


def facet_basis(mesh, element, facets: np.ndarray, intorder: int = 2) -> FacetBasis:
    return FacetBasis(mesh, element, facets=facets, intorder=intorder)


def coupling_piece(mesh, cells: np.ndarray) -> sp.csr_matrix:
    """(2 nnodes × nnodes): f_th = β B (T − T0) on the region."""
    return asm(thermal_coupling, region_basis(mesh, SCALAR, cells), region_basis(mesh, VECTOR, cells)).tocsr()


def source_vector(mesh, cells: np.ndarray) -> np.ndarray:
    """∫_region s dx: the load of a unit heat source W."""
    return asm(unit_scalar, region_basis(mesh, SCALAR, cells))


def body_force_vectors(mesh, cells: np.ndarray) -> np.ndarray:
    """(2, ndof): ∫_region e_i · v dx for i = x, y."""
    b = region_basis(mesh, VECTOR, cells)
    return np.array([asm(component_form(i), b) for i in range(2)])


def pressure_vector(mesh, facets: np.ndarray) -> np.ndarray:
    return asm(outward_pressure, facet_basis(mesh, VECTOR, facets))


def traction_vectors(mesh, facets: np.ndarray) -> np.ndarray:
    b = facet_basis(mesh, VECTOR, facets)
    return np.array([asm(component_form(i), b) for i in range(2)])
