"""Load and coupling forms, written as the math reads (P1 triangles or tetrahedra, scikit-fem).

Each form is one parameter-free piece; the data (β, loads, sources) multiply
the assembled pieces later. The stiffness and conduction operators are in
`affine.py` (cell matrices in closed form, verified against scikit-fem).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from skfem import (Basis, BilinearForm, ElementTetP1, ElementTriP1, ElementVector, FacetBasis, LinearForm,
                   MeshTet, asm)
from skfem.helpers import div, dot

SCALAR = ElementTriP1()
VECTOR = ElementVector(ElementTriP1())
SCALAR3 = ElementTetP1()
VECTOR3 = ElementVector(ElementTetP1())


def _elements(mesh):
    """(scalar, vector) P1 elements of the mesh: triangles, or tetrahedra on a MeshTet."""
    return (SCALAR3, VECTOR3) if isinstance(mesh, MeshTet) else (SCALAR, VECTOR)


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


def release_mapping(mesh) -> None:
    """Drop the affine mapping scikit-fem caches on the mesh when a first basis is made: every
    cell's A, A⁻¹, b, det A and every facet's B, c, det B (350 bytes a tetrahedron: 75 MB at
    1.4e5 unknowns), which the forms need only while they assemble; a later basis makes it again."""
    mesh.__dict__.pop("_cached_mapping", None)


def region_basis(mesh, element, cells: np.ndarray, intorder: int = 2) -> Basis:
    """The basis on the cells given; without the global dof locations scikit-fem maps for every
    cell of the mesh (288 bytes a tetrahedron), which no form here reads."""
    return Basis(mesh, element, elements=cells, intorder=intorder, disable_doflocs=True)


def facet_basis(mesh, element, facets: np.ndarray, intorder: int = 2) -> FacetBasis:
    """The basis on the facets given, without the global dof locations (`region_basis`)."""
    return FacetBasis(mesh, element, facets=facets, intorder=intorder, disable_doflocs=True)


def coupling_piece(mesh, cells: np.ndarray) -> sp.csr_matrix:
    """(d nnodes × nnodes): f_th = β B (T − T0) on the region."""
    scalar, vector = _elements(mesh)
    return asm(thermal_coupling, region_basis(mesh, scalar, cells), region_basis(mesh, vector, cells)).tocsr()


def source_vector(mesh, cells: np.ndarray) -> np.ndarray:
    """∫_region s dx: the load of a unit heat source W."""
    return asm(unit_scalar, region_basis(mesh, _elements(mesh)[0], cells))


def body_force_vectors(mesh, cells: np.ndarray) -> np.ndarray:
    """(d, ndof): ∫_region e_i · v dx for i = x, y (, z)."""
    b = region_basis(mesh, _elements(mesh)[1], cells)
    return np.array([asm(component_form(i), b) for i in range(mesh.dim())])


def pressure_vector(mesh, facets: np.ndarray) -> np.ndarray:
    return asm(outward_pressure, facet_basis(mesh, _elements(mesh)[1], facets))


def traction_vectors(mesh, facets: np.ndarray) -> np.ndarray:
    """(d, ndof): ∫_facets e_i · v ds for i = x, y (, z)."""
    b = facet_basis(mesh, _elements(mesh)[1], facets)
    return np.array([asm(component_form(i), b) for i in range(mesh.dim())])
