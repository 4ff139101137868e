"""FEM layer against manufactured solutions on a two-region mesh.

Coefficients jump across x = 1/2 by a factor s: with u = φ/s_j and φ = 0 on
the interface, u is continuous and the flux/traction σ_0(φ)·n is too, so one
body force f = −div σ_0(φ) (resp. source −Δφ) serves both regions. P1 theory:
L2 error O(h²), energy error O(h); observed rates are asserted within 0.15.
"""
import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, Functional, LinearForm, MeshTri, asm
from skfem.helpers import dot

from tests.support.reference_forms import conduction, div_div, strain_strain
from wcs import linalg
from wcs.fem import forms
from wcs.fem.affine import CellAffineOperator, conduction_cell_matrices, elastic_cell_matrices
from wcs.fem.constraints import Constraint, eliminate

PI = np.pi
LAM, MU = 2.0, 1.0
SCALE = (1.0, 4.0)   # coefficient factor left / right of x = 1/2


def two_region(n):
    m = MeshTri.init_tensor(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    region = (m.p[0, m.t].mean(axis=0) > 0.5).astype(int)
    return m, region


def scale_of(x):
    return np.where(x > 0.5, SCALE[1], SCALE[0])


def elastic_exact(x, y):
    a = np.sin(2 * PI * x) * np.sin(PI * y) / scale_of(x)
    return np.array([a, a])


def elastic_grad(x, y):
    s = scale_of(x)
    ax = 2 * PI * np.cos(2 * PI * x) * np.sin(PI * y) / s
    ay = PI * np.sin(2 * PI * x) * np.cos(PI * y) / s
    return np.array([[ax, ay], [ax, ay]])


def elastic_force(x, y):
    s2x, c2x, sy, cy = np.sin(2 * PI * x), np.cos(2 * PI * x), np.sin(PI * y), np.cos(PI * y)
    grad_div = np.array([-4 * PI**2 * s2x * sy + 2 * PI**2 * c2x * cy,
                         2 * PI**2 * c2x * cy - PI**2 * s2x * sy])
    lap = -5 * PI**2 * s2x * sy
    return -((LAM + MU) * grad_div + MU * np.array([lap, lap]))


def solve_elastic(n):
    m, region = two_region(n)
    K = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), region)(
        [[SCALE[0] * LAM, SCALE[0] * MU], [SCALE[1] * LAM, SCALE[1] * MU]])
    b = Basis(m, forms.VECTOR, intorder=4)
    f = asm(LinearForm(lambda v, w: dot(elastic_force(*w.x), v)), b)
    nodes = m.boundary_nodes()
    cons = [Constraint(nodes, np.tile([1.0, 0.0], (nodes.size, 1)), 0),
            Constraint(nodes, np.tile([0.0, 1.0], (nodes.size, 1)), 0)]
    el = eliminate(m.p.shape[1], 2, cons, 1)
    w = linalg.solve(el.T.T @ K @ el.T, el.T.T @ f)
    uh = b.interpolate(el.expand(w, np.zeros(1)))
    l2 = np.sqrt(Functional(lambda w: dot(w["uh"] - elastic_exact(*w.x), w["uh"] - elastic_exact(*w.x))).assemble(b, uh=uh))
    def energy_density(w):
        e = w["uh"].grad - elastic_grad(*w.x)
        s = scale_of(w.x[0])
        es = 0.5 * (e + np.swapaxes(e, 0, 1))
        tr = es[0, 0] + es[1, 1]
        return s * (LAM * tr**2 + 2 * MU * (es * es).sum(axis=(0, 1)))
    en = np.sqrt(Functional(energy_density).assemble(b, uh=uh))
    return 1.0 / n, l2, en


def heat_exact(x, y):
    return np.sin(2 * PI * x) * np.sin(PI * y) / scale_of(x)


def heat_grad(x, y):
    s = scale_of(x)
    return np.array([2 * PI * np.cos(2 * PI * x) * np.sin(PI * y), PI * np.sin(2 * PI * x) * np.cos(PI * y)]) / s


def solve_heat(n):
    m, region = two_region(n)
    H = CellAffineOperator(m.t, m.nvertices, conduction_cell_matrices(m.p, m.t), region)(list(SCALE))
    b = Basis(m, forms.SCALAR, intorder=4)
    q = asm(LinearForm(lambda v, w: 5 * PI**2 * np.sin(2 * PI * w.x[0]) * np.sin(PI * w.x[1]) * v), b)
    nodes = m.boundary_nodes()
    el = eliminate(m.p.shape[1], 1, [Constraint(nodes, np.ones((nodes.size, 1)), 0)], 1)
    Th = b.interpolate(el.expand(linalg.solve(el.T.T @ H @ el.T, el.T.T @ q), np.zeros(1)))
    l2 = np.sqrt(Functional(lambda w: (w["Th"] - heat_exact(*w.x)) ** 2).assemble(b, Th=Th))
    en = np.sqrt(Functional(lambda w: scale_of(w.x[0]) * dot(w["Th"].grad - heat_grad(*w.x),
                                                               w["Th"].grad - heat_grad(*w.x))).assemble(b, Th=Th))
    return 1.0 / n, l2, en


def rates(results):
    h, l2, en = np.array(results).T
    return np.diff(np.log(l2)) / np.diff(np.log(h)), np.diff(np.log(en)) / np.diff(np.log(h))


@pytest.mark.parametrize("solver", [solve_elastic, solve_heat], ids=["elasticity", "heat"])
def test_manufactured_convergence_rates(solver):
    r_l2, r_en = rates([solver(n) for n in (8, 16, 32, 64)])
    # asymptotic rates over the last two halvings (4 refinements in all)
    assert abs(r_l2[-1] - 2.0) < 0.15, r_l2
    assert abs(r_en[-1] - 1.0) < 0.15, r_en
    assert np.all(r_l2 > 1.7) and np.all(r_en > 0.85)


def test_cell_matrices_match_scikit_fem_assembly():
    """The closed-form P1 cell matrices against scikit-fem's quadrature of the weak forms,
    region by region; one pattern for every data set (the analysis is reused)."""
    m, region = two_region(6)
    def piece(form, element, j):
        return asm(form, Basis(m, element, elements=np.flatnonzero(region == j), intorder=1))
    Kl0, Km0, Kl1, Km1 = (piece(f, forms.VECTOR, j) for j in (0, 1) for f in (div_div, strain_strain))
    op = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), region)
    direct = 1.5 * Kl0 + 0.7 * Km0 + 3.0 * Kl1 + 2.0 * Km1
    assert abs(op([[1.5, 0.7], [3.0, 2.0]]) - direct).max() < 1e-12 * abs(direct).max()
    assert op([[1.5, 0.7], [3.0, 2.0]]).nnz == op([[1, 1], [1, 1]]).nnz == op([[0, 1], [0, 1]]).nnz
    H = CellAffineOperator(m.t, m.nvertices, conduction_cell_matrices(m.p, m.t), region)([[2.0], [5.0]])
    Hd = 2.0 * piece(conduction, forms.SCALAR, 0) + 5.0 * piece(conduction, forms.SCALAR, 1)
    assert abs(H - Hd).max() < 1e-12 * abs(Hd).max()


def test_roller_elimination_on_inclined_direction():
    # a node constrained by u·n = c keeps exactly its tangential freedom
    n = np.array([[0.6, 0.8]])
    el = eliminate(2, 2, [Constraint(np.array([0]), n, 0)], 1)
    u = el.expand(np.array([2.0, 5.0, 7.0]), np.array([0.3]))
    assert np.isclose(u[:2] @ n[0], 0.3)
    assert el.T.shape == (4, 3)
    assert np.allclose((el.T.T @ el.T).toarray(), np.eye(3))


def test_reduction_keeps_one_pattern_whatever_the_data():
    """Tᵀ K T by a sparse product drops entries that vanish for some data; the reduction
    keeps the structural pattern, so the factorization's ordering never changes."""
    from wcs.fem.constraints import Reduction
    m, region = two_region(6)
    op = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), region)
    nodes = m.boundary_nodes()
    n = np.tile([0.6, 0.8], (nodes.size, 1))
    el = eliminate(m.p.shape[1], 2, [Constraint(nodes[:5], n[:5], 0)], 1)
    red = Reduction(op([[1.0, 1.0], [1.0, 1.0]]), el.T)
    for coeffs in ([[2.0, 1.0], [3.0, 0.5]], [[0.0, 1.0], [0.0, 1.0]]):
        K = op(coeffs)
        Kr = red(K)
        direct = el.T.T @ K @ el.T
        assert abs(Kr - direct).max() <= 1e-12 * abs(direct).max()
        assert np.array_equal(Kr.indptr, red.pattern.indptr) and np.array_equal(Kr.indices, red.pattern.indices)


def test_reduction_with_rows_of_several_entries():
    """T rows tying a dof to several columns (mortar gluing) and zero data: M maps K's values to
    Tᵀ K T's on the structural pattern (a product of the patterns), its rows in CSR order with
    each row's terms by increasing entry of K (the order its product sums them in)."""
    from wcs.fem.constraints import Reduction
    rng = np.random.default_rng(3)
    K = sp.random(60, 60, density=0.1, random_state=4, format="csr") + sp.eye(60, format="csr")
    K = (K + K.T).tocsr()
    T = sp.random(60, 45, density=0.05, random_state=5, format="csr") + sp.eye(60, 45, format="csr")
    T = T.tocsr()
    assert np.diff(T.indptr).max() > 2
    red = Reduction(K, T)
    K.data = rng.normal(size=K.nnz)
    Kr = red(K)
    direct = (T.T @ K @ T).toarray()
    assert abs(Kr.toarray() - direct).max() <= 1e-13 * abs(direct).max()
    ones = abs(T).T @ sp.csr_matrix((np.ones(K.nnz), K.indices, K.indptr), shape=K.shape) @ abs(T)
    assert np.array_equal(red.pattern.indptr, ones.indptr) and red.pattern.nnz == ones.nnz
    assert red.M.has_canonical_format


def _whole_map(K, T):
    """The map of K's values to Tᵀ K T's on the pattern as ONE sparse matrix, built from the terms
    T_ki K_kl T_lj enumerated entry by entry: row (i, j) holds the weights T_ki T_lj at the columns
    e = (k, l), by increasing e (the order its product sums them in)."""
    K, T = sp.csr_matrix(K), sp.csr_matrix(T)
    K.sort_indices()
    T.sort_indices()
    terms = {}
    rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
    for e, (k, l) in enumerate(zip(rows, K.indices)):
        for a in range(T.indptr[k], T.indptr[k + 1]):
            for b in range(T.indptr[l], T.indptr[l + 1]):
                terms.setdefault((T.indices[a], T.indices[b]), []).append((e, T.data[a] * T.data[b]))
    keys = sorted(terms)
    r = np.repeat(np.arange(len(keys)), [len(terms[key]) for key in keys])
    e, w = np.array([t for key in keys for t in terms[key]]).T
    return sp.csr_matrix((w, (r, e.astype(int))), shape=(len(keys), K.nnz)), keys


def test_reduction_gives_the_whole_maps_bits_holding_a_gather_for_its_unit_rows():
    """Kr.data of the reduction is bitwise the product of the whole map (`_whole_map`) with K's
    values, −0 included (M's row sums 0 + 1·(−0) = +0), though it holds that map only on the rows
    of several terms or a weight other than 1 (supports: T's rows of a roller; gluing) and a
    4-byte index of K's entry for every other row; K of another structure is refused."""
    from wcs.fem.constraints import Reduction
    m, region = two_region(6)
    op = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), region)
    nodes = m.boundary_nodes()
    el = eliminate(m.p.shape[1], 2, [Constraint(nodes[:5], np.tile([0.6, 0.8], (5, 1)), 0),
                                      Constraint(nodes[5:9], np.tile([1.0, 0.0], (4, 1)), 0)], 1)
    K = op([[2.0, 1.0], [3.0, 0.5]])
    red = Reduction(K, el.T)
    whole, keys = _whole_map(K, el.T)
    n = el.T.shape[1]
    assert [(i, j) for i in range(n) for j in red.indices[red.indptr[i]:red.indptr[i + 1]]] == keys
    assert 0 < red.rest.size < 0.5 * red.nnz and red.source.dtype == np.int32
    rng = np.random.default_rng(7)
    K.data = rng.normal(size=K.nnz) * 1e9
    K.data[rng.random(K.nnz) < 0.2] = -0.0
    Kr = red(K)
    assert np.array_equal(Kr.data.view(np.int64), (whole @ K.data).view(np.int64))
    assert np.signbit(whole @ K.data).sum() < np.signbit(K.data).sum()        # −0 met and made +0
    other = K.copy()
    other.indices = other.indices.copy()
    row0 = other.indices[:other.indptr[1]]
    other.indices[0] = np.setdiff1d(np.arange(K.shape[1]), row0)[-1]     # same counts, another column
    with pytest.raises(ValueError):
        red(other)


@pytest.mark.parametrize("permuted", [False, True])
def test_reduction_places_the_unit_entries_in_any_column_order(permuted, monkeypatch):
    """The entries of K whose rows of T are unit rows of their own columns are placed by their
    keys alone, in K's order where T's columns follow the dofs (`eliminate`'s numbering) and
    sorted where they do not (columns permuted): the whole map's pattern and bits either way,
    with chunks of 64 entries of K (keys ordered across chunks)."""
    from wcs.fem import constraints
    monkeypatch.setattr(constraints, "PRODUCTS_CHUNK", 64)
    m, region = two_region(6)
    op = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), region)
    nodes = m.boundary_nodes()
    T = eliminate(m.p.shape[1], 2, [Constraint(nodes[:5], np.tile([0.6, 0.8], (5, 1)), 0)], 1).T
    if permuted:
        T = sp.csr_matrix(T[:, np.random.default_rng(2).permutation(T.shape[1])])
    K = op([[2.0, 1.0], [3.0, 0.5]])
    red = constraints.Reduction(K, T)
    whole, keys = _whole_map(K, T)
    assert [(i, j) for i in range(T.shape[1]) for j in red.indices[red.indptr[i]:red.indptr[i + 1]]] == keys
    assert red.rest.size < 0.1 * red.nnz
    K.data = np.random.default_rng(5).normal(size=K.nnz)
    assert np.array_equal(red(K).data.view(np.int64), (whole @ K.data).view(np.int64))


@pytest.mark.parametrize("dim", [2, 3])
def test_cell_matrices_made_chunk_by_chunk_give_the_held_ones_bits(dim, monkeypatch):
    """The model's operators make their cell matrices chunk by chunk from the cells' gradients
    (`elastic_cells`, `conduction_cells`: 104 bytes a tetrahedron held, not 2.3 kB): K(c), K(c) x
    and the sensitivities are bitwise those of the held matrices, with chunks of 7 cells (the
    terms of an entry summed in the same cell order across chunks)."""
    from skfem import MeshTet
    from wcs.fem import affine
    monkeypatch.setattr(affine, "CHUNK", 7)
    rng = np.random.default_rng(3)
    m = MeshTet().refined(2) if dim == 3 else MeshTri().refined(3)
    p = m.p + 0.02 * rng.standard_normal(m.p.shape)
    region = rng.integers(0, 3, m.t.shape[1])
    for held, made in ((elastic_cell_matrices, affine.elastic_cells), (conduction_cell_matrices, affine.conduction_cells)):
        A = CellAffineOperator(m.t, p.shape[1], held(p, m.t), region)
        B = CellAffineOperator(m.t, p.shape[1], made(p, m.t), region)
        c = rng.uniform(1.0, 3.0e9, (3, A.npieces))
        KA, KB = A(c), B(c)
        assert np.array_equal(KA.indptr, KB.indptr) and np.array_equal(KA.indices, KB.indices)
        assert np.array_equal(KA.data, KB.data)
        x, y = rng.standard_normal((2, A.shape[0]))
        x[rng.random(x.size) < 0.7] = 0.0
        assert np.array_equal(A.apply(c, x), B.apply(c, x))
        assert np.array_equal(A.sensitivities(x, y), B.sensitivities(x, y))


def test_every_reduced_stiffness_shares_the_patterns_index_arrays():
    """Kr of every data set is its values over one read-only copy of the pattern's indices (each
    Kr had its own: 0.33 GB at 1e6 unknowns for every reduced matrix alive); an in-place change
    of the structure is refused, not spread to the other data sets' Kr."""
    from wcs.fem.constraints import Reduction
    m, region = two_region(6)
    op = CellAffineOperator(m.t, m.nvertices, elastic_cell_matrices(m.p, m.t), region)
    nodes = m.boundary_nodes()
    el = eliminate(m.p.shape[1], 2, [Constraint(nodes[:5], np.tile([0.6, 0.8], (5, 1)), 0)], 1)
    red = Reduction(op([[1.0, 1.0], [1.0, 1.0]]), el.T)
    A, B = red(op([[2.0, 1.0], [3.0, 0.5]])), red(op([[1.0, 4.0], [1.0, 2.0]]))
    for Kr in (A, B):
        assert np.shares_memory(Kr.indices, red.pattern.indices) and np.shares_memory(Kr.indptr, red.pattern.indptr)
    assert abs(B - el.T.T @ op([[1.0, 4.0], [1.0, 2.0]]) @ el.T).max() <= 1e-12 * abs(B).max()
    with pytest.raises(ValueError):
        A.indices[0] = 1
