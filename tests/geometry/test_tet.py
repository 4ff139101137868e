"""Linear tetrahedra: closed-form cell matrices against scikit-fem, the affine operator with
3×3 blocks, strains/stresses/invariants, rigid modes, and a manufactured solution in 3D.

P1 theory on a cube under a smooth body force: L2 error O(h²), energy error O(h); the
observed rates over the last halving are asserted within 0.15 of them.
"""
import numpy as np
import pytest
from skfem import Basis, BilinearForm, ElementTetP1, ElementVector, FacetBasis, Functional, LinearForm, MeshTet, asm
from skfem.helpers import dot

from tests.support.reference_forms import conduction, div_div, strain_strain
from wcs import linalg
from wcs.dd.kernels import rigid_basis
from wcs.geometry import tet
from wcs.fem.affine import CellAffineOperator, conduction_cell_matrices, elastic_cell_matrices
from wcs.fem.constraints import Constraint, eliminate

PI = np.pi
LAM, MU = 3.0, 1.5
VECTOR = ElementVector(ElementTetP1())


def distorted_cube(n, seed=0, amount=0.25):
    """A tensor tet mesh of the unit cube with interior nodes moved by up to `amount`·h:
    no two cells alike, so cancellations of a regular mesh hide nothing."""
    m = MeshTet.init_tensor(*(np.linspace(0, 1, n + 1),) * 3)
    p = m.p.copy()
    interior = np.setdiff1d(np.arange(m.nvertices), m.boundary_nodes())
    p[:, interior] += amount / n * np.random.default_rng(seed).uniform(-1, 1, (3, interior.size))
    return MeshTet(p, m.t)


def relative(A, B):
    return abs(A - B).max() / abs(B).max()


def test_gradients_and_volumes_of_one_tetrahedron():
    p = np.array([[0.0, 2.0, 0.0, 0.0], [0.0, 0.0, 3.0, 0.0], [0.0, 0.0, 0.0, 4.0]])
    g, vol = tet.gradient_operator(p, np.array([[0], [1], [2], [3]]))
    # N_1 = x/2, N_2 = y/3, N_3 = z/4, N_0 = 1 − N_1 − N_2 − N_3; |T| = 2·3·4/6
    expect = np.array([[-1 / 2, -1 / 3, -1 / 4], [1 / 2, 0, 0], [0, 1 / 3, 0], [0, 0, 1 / 4]])
    assert np.allclose(g[0], expect, rtol=0, atol=1e-15)
    assert vol[0] == pytest.approx(4.0, rel=1e-15)
    flipped = tet.gradient_operator(p, np.array([[0], [2], [1], [3]]))   # negative orientation
    assert np.allclose(flipped[0][0], expect[[0, 2, 1, 3]], rtol=0, atol=1e-15)
    assert tet.volumes(p, np.array([[0], [2], [1], [3]]))[0] == pytest.approx(4.0, rel=1e-15)


def test_volumes_sum_to_the_cube():
    m = distorted_cube(3)
    assert tet.volumes(m.p, m.t).sum() == pytest.approx(1.0, rel=1e-13)


def test_cell_matrices_match_scikit_fem_assembly():
    """The closed-form pieces through CellAffineOperator (3×3 node blocks, two regions) against
    scikit-fem's ElementTetP1 / ElementVector quadrature, to 1e-12 relative."""
    m = distorted_cube(3)
    region = (m.p[0, m.t].mean(axis=0) > 0.5).astype(int)
    vb, sb = Basis(m, VECTOR), Basis(m, ElementTetP1())
    c = np.where(region == 1, 4.0, 1.0)                       # cell-wise factor of region 1
    op = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), region)
    assert op.block == 3 and op.shape == (3 * m.nvertices,) * 2
    for piece, form in enumerate((div_div, strain_strain)):
        coeff = np.zeros((2, 2))
        coeff[:, piece] = (1.0, 4.0)
        ref = asm(BilinearForm(lambda u, v, w: form.form(u, v, w) * w.c), vb, c=c[:, None])
        assert relative(op(coeff).toarray(), ref.toarray()) < 1e-12
    H = CellAffineOperator(m.t, m.nvertices, conduction_cell_matrices(m.p, m.t), region)
    ref = asm(BilinearForm(lambda u, v, w: conduction.form(u, v, w) * w.c), sb, c=c[:, None])
    assert relative(H([[1.0], [4.0]]).toarray(), ref.toarray()) < 1e-12
    # sensitivities: the derivative of aᵀK(c)b in each coefficient (K affine in c)
    rng = np.random.default_rng(1)
    a, b = rng.standard_normal(op.shape[0]), rng.standard_normal(op.shape[0])
    coeff = np.array([[LAM, MU], [2 * LAM, 3 * MU]])
    assert np.allclose((op.sensitivities(a, b) * coeff).sum(), a @ op(coeff) @ b, rtol=1e-12)


def test_rigid_modes_are_the_null_space():
    """The six rigid motions (translations and rotations) give zero stiffness and zero strain,
    and are the whole null space of the floating body's stiffness."""
    m = distorted_cube(2)
    K = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), np.zeros(m.nelements, int))([[LAM, MU]])
    R = rigid_basis(m.p, np.arange(m.nvertices), 3)
    assert R.shape == (3 * m.nvertices, 6)
    assert abs(K @ R).max() < 1e-12 * abs(K).max()
    assert abs(tet.strain_operator(m.p, m.t) @ R).max() < 1e-12
    eig = np.linalg.eigvalsh(K.toarray())
    assert np.sum(eig < 1e-10 * eig[-1]) == 6 and eig[6] > 1e-4 * eig[-1]


A = np.array([[0.3, -0.2, 0.5], [0.1, 0.4, -0.6], [-0.7, 0.25, 0.2]])   # a linear field u = A x + b
B = np.array([0.1, -0.2, 0.3])


def test_linear_field_strain_and_stress_are_exact():
    """G u of a linear field is its constant strain; the stress, I₂², von Mises and principal
    stresses are those of the tensor σ = λ tr(e) I + 2μ e − βΔT I, computed by hand."""
    m = distorted_cube(2)
    u = (A @ m.p + B[:, None]).T.ravel()
    e = tet.strain_operator(m.p, m.t) @ u
    nc = m.nelements
    sym = 0.5 * (A + A.T)
    want = [sym[0, 0], sym[1, 1], sym[2, 2], 2 * sym[1, 2], 2 * sym[0, 2], 2 * sym[0, 1]]
    assert np.allclose(e.reshape(6, nc), np.array(want)[:, None], rtol=0, atol=1e-13)
    beta, dT = 0.7, 2.0
    ones = np.ones(nc)
    s = tet.stresses(e.reshape(6, nc), LAM * ones, MU * ones, beta * ones, dT * ones)
    sigma = LAM * np.trace(sym) * np.eye(3) + 2 * MU * sym - beta * dT * np.eye(3)
    assert np.allclose(tet.tensor(s), sigma, rtol=0, atol=1e-12)
    dev = sigma - np.trace(sigma) / 3 * np.eye(3)
    assert np.allclose(tet.shear_intensity(s), np.sum(dev * dev), rtol=1e-12)
    assert np.allclose(tet.von_mises(s), np.sqrt(1.5 * np.sum(dev * dev)), rtol=1e-12)
    assert np.allclose(tet.principal(s), np.sort(np.linalg.eigvalsh(sigma))[::-1], rtol=0, atol=1e-12)


def test_invariants_of_known_tensors():
    s = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]])
    # uniaxial σ_xx = 1: von Mises 1; pure shear τ_yz = 1: von Mises √3, principal (1, 0, −1)
    assert np.allclose(tet.von_mises(s), [1.0, np.sqrt(3.0)], rtol=1e-15)
    assert np.allclose(tet.principal(s), [[1, 0, 0], [1, 0, -1]], rtol=0, atol=1e-15)


def test_patch_linear_displacement_reproduced():
    """Patch test: the linear field prescribed on the boundary of a distorted mesh (no body
    force) is reproduced at every interior node to round-off."""
    m = distorted_cube(3, seed=2, amount=0.35)
    K = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), np.zeros(m.nelements, int))([[LAM, MU]])
    exact = (A @ m.p + B[:, None]).T.ravel()
    bnd = m.boundary_nodes()
    fixed = (3 * bnd[:, None] + np.arange(3)).ravel()
    free = np.setdiff1d(np.arange(3 * m.nvertices), fixed)
    u = exact.copy()
    u[free] = linalg.solve(K[free][:, free], -K[free][:, fixed] @ exact[fixed])
    assert abs(u - exact).max() < 1e-12


def test_traction_patch_floating_body():
    """Traction patch: the tractions σ·n of a uniform stress on the whole boundary of a floating
    distorted cube (a self-equilibrated load) give back the linear field of that stress, up to a
    rigid motion: the solution orthogonal to the six rigid modes is the exact field's projection."""
    m = distorted_cube(3, seed=3, amount=0.3)
    K = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), np.zeros(m.nelements, int))([[LAM, MU]])
    sym = 0.5 * (A + A.T)
    sigma = LAM * np.trace(sym) * np.eye(3) + 2 * MU * sym
    fb = FacetBasis(m, VECTOR, facets=m.boundary_facets())
    f = asm(LinearForm(lambda v, w: dot(np.einsum("ij,j...->i...", sigma, w.n), v)), fb)
    R = rigid_basis(m.p, np.arange(m.nvertices), 3)
    assert abs(R.T @ f).max() < 1e-13                                  # equilibrated
    scale = abs(K).max()
    u = np.linalg.solve(K.toarray() + scale * (R @ R.T), f)           # Rᵀu = 0 since Rᵀf = 0
    exact = (A @ m.p + B[:, None]).T.ravel()
    exact -= R @ np.linalg.lstsq(R, exact, rcond=None)[0]
    assert abs(u - exact).max() < 1e-11 * abs(exact).max()


def exact_u(x):
    """u = c φ, φ = sin πx sin πy sin πz (zero on the cube's boundary)."""
    return C[:, None, None] * (np.sin(PI * x[0]) * np.sin(PI * x[1]) * np.sin(PI * x[2]))[None]


C = np.array([1.0, -0.5, 0.75])


def exact_grad(x):
    s, c = np.sin(PI * x), np.cos(PI * x)
    dphi = PI * np.array([c[0] * s[1] * s[2], s[0] * c[1] * s[2], s[0] * s[1] * c[2]])
    return C[:, None, None, None] * dphi[None]


def body_force(x):
    """f = −div σ(u) = −(λ + μ) ∇(div u) − μ Δu, with ∇(div u) = Hess(φ) c, Δu = −3π² φ c."""
    s, c = np.sin(PI * x), np.cos(PI * x)
    phi = s[0] * s[1] * s[2]
    hess = np.empty((3, 3) + phi.shape)
    for i in range(3):
        for j in range(3):
            if i == j:
                hess[i, j] = -PI**2 * phi
            else:
                k = 3 - i - j
                hess[i, j] = PI**2 * c[i] * c[j] * s[k]
    return -(LAM + MU) * np.einsum("ij...,j->i...", hess, C) + 3 * PI**2 * MU * C[:, None, None] * phi


def solve_cube(n):
    m = MeshTet.init_tensor(*(np.linspace(0, 1, n + 1),) * 3)
    K = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), np.zeros(m.nelements, int))([[LAM, MU]])
    b = Basis(m, VECTOR, intorder=4)
    f = asm(LinearForm(lambda v, w: dot(body_force(w.x), v)), b)
    nodes = m.boundary_nodes()
    cons = [Constraint(nodes, np.tile(np.eye(3)[k], (nodes.size, 1)), 0) for k in range(3)]
    el = eliminate(m.nvertices, 3, cons, 1)
    uh = b.interpolate(el.expand(linalg.solve(el.T.T @ K @ el.T, el.T.T @ f), np.zeros(1)))
    err = lambda w: w["uh"] - exact_u(w.x)
    l2 = np.sqrt(Functional(lambda w: dot(err(w), err(w))).assemble(b, uh=uh))

    def energy_density(w):
        e = w["uh"].grad - exact_grad(w.x)
        es = 0.5 * (e + np.swapaxes(e, 0, 1))
        return LAM * np.einsum("ii...", es) ** 2 + 2 * MU * (es * es).sum(axis=(0, 1))
    return 1.0 / n, l2, np.sqrt(Functional(energy_density).assemble(b, uh=uh))


def test_manufactured_convergence_rates_3d():
    h, l2, en = np.array([solve_cube(n) for n in (4, 8, 16)]).T
    r_l2 = np.diff(np.log(l2)) / np.diff(np.log(h))
    r_en = np.diff(np.log(en)) / np.diff(np.log(h))
    assert abs(r_l2[-1] - 2.0) < 0.15, r_l2
    assert abs(r_en[-1] - 1.0) < 0.15, r_en


@pytest.mark.parametrize("cells", [tet.CELLS, 7])
def test_the_strain_operator_from_the_gradients_gives_the_matrix_products_bits(cells, monkeypatch):
    """G u and Gᵀ e applied from the cells' gradients (what the model keeps instead of G's matrix,
    432 bytes a cell) are bitwise the CSR products: node numbers shuffled and each cell's nodes in
    random order, so that the sorted order of a row's dofs is not the cell's; G u made `CELLS`
    cells at a time (7: many blocks) too."""
    monkeypatch.setattr(tet, "CELLS", cells)
    rng = np.random.default_rng(5)
    m = distorted_cube(4)
    new = rng.permutation(m.nvertices)
    p = np.empty_like(m.p)
    p[:, new] = m.p
    t = rng.permuted(new[m.t], axis=0)
    G = tet.strain_operator(p, t)
    S = tet.StrainOperator(t, tet.gradient_operator(p, t)[0], p.shape[1])
    assert S.shape == G.shape and S.T.shape == G.T.shape
    u, e = rng.standard_normal(G.shape[1]), rng.standard_normal(G.shape[0])
    assert np.array_equal(S @ u, G @ u)
    assert np.array_equal(S.T @ e, G.T @ e)
