"""scikit-fem's weak forms of the model's affine pieces (the λ-piece div u div v, the μ-piece
2 e(u):e(v), conduction ∇t·∇s): the independent reference that wcs's closed-form P1 cell
matrices (triangles and tetrahedra) are checked against."""
from skfem import BilinearForm
from skfem.helpers import ddot, div, dot, grad, sym_grad


@BilinearForm
def div_div(u, v, w):
    return div(u) * div(v)


@BilinearForm
def strain_strain(u, v, w):
    return 2.0 * ddot(sym_grad(u), sym_grad(v))


@BilinearForm
def conduction(t, s, w):
    return dot(grad(t), grad(s))
