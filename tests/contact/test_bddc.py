"""BDDC (`wcs.contact.bddc`): subdomain matrices assembled over each part's cells, transformed by
a step's elimination, precondition CG to the direct solve's answer."""
import numpy as np
import pytest
import scipy.sparse as sp
import skfem as fem
from scipy.sparse.linalg import spsolve
from skfem.models.elasticity import lame_parameters, linear_elasticity

from wcs.contact.bddc import Bddc, bisection, local_step, subdomain_dofs
from wcs.contact.iterative import _basis, _eliminated
from wcs.fem.rigid import rigid_modes

pytest.importorskip("dolfinx_solver")


def _block(dim, cells):
    """An elastic unit square/cube clamped at x = 0: its basis, K and form."""
    axes = [np.linspace(0.0, 1.0, cells + 1)] * dim
    mesh = fem.MeshTri.init_tensor(*axes) if dim == 2 else fem.MeshTet.init_tensor(*axes)
    element = fem.ElementVector(fem.ElementTriP1() if dim == 2 else fem.ElementTetP1())
    basis = fem.Basis(mesh, element)
    form = linear_elasticity(*lame_parameters(1.0, 0.3))
    return basis, form.assemble(basis).tocsr(), form


def _parts(basis, form, parts):
    """Each part's dofs and its own matrix, assembled over its cells only."""
    mesh = basis.mesh
    part = bisection(mesh.p[:, mesh.t].mean(axis=1), parts)
    dofs = subdomain_dofs(basis.element_dofs, part)
    mats = [form.assemble(fem.Basis(mesh, basis.elem, elements=np.flatnonzero(part == s))).tocsr()[d][:, d]
            for s, d in enumerate(dofs)]
    return dofs, mats


def _scatter(n, dofs, local):
    return sum(sp.csr_matrix(sp.coo_matrix((L.tocoo().data, (d[L.tocoo().row], d[L.tocoo().col])), shape=(n, n)))
               for d, L in zip(dofs, local))


def _check(basis, K, form, C, rows_b, parts):
    """The step u = Z x + u_b with C u = rows_b (one pivot per row, its own dof), solved by
    BDDC and directly; the subdomains' parts sum to the step's operator."""
    n = K.shape[0]
    P = np.asarray(C.tocsr().indices[C.tocsr().indptr[:-1]])     # each row's first dof
    Binv = sp.diags(1.0 / np.asarray(C.tocsr()[np.arange(C.shape[0]), P]).ravel())
    Z, ub = _basis(C.tocsr(), np.arange(C.shape[0]), P, Binv, rows_b)
    A = _eliminated(Z, K, K, P)
    f = basis.doflocs.sum(axis=0) - 1.0
    b = Z.T @ (f - K @ ub)
    dofs, mats = _parts(basis, form, parts)
    local = [local_step(L, d, Z, P) for d, L in zip(dofs, mats)]
    assert abs(_scatter(n, dofs, local) - A).max() <= 1e-12 * abs(A).max()
    dim = basis.mesh.dim()
    nodes = np.arange(basis.mesh.nvertices)
    R = rigid_modes(basis.mesh.p, nodes, len(nodes))
    x, its, ok = Bddc(dofs, local, R, block=dim).solve(A, b, 1e-10)
    direct = spsolve(A.tocsc(), b)
    assert ok
    assert np.linalg.norm(x - direct) <= 1e-7 * np.linalg.norm(direct)
    return its


def _clamped(basis):
    """Rows u_i = 0 at the dofs on x = 0 (the glued/supported step)."""
    D = basis.get_dofs(lambda x: np.isclose(x[0], 0.0)).flatten()
    n = basis.N
    return sp.csr_matrix((np.ones(len(D)), (np.arange(len(D)), D)), shape=(len(D), n))


@pytest.mark.parametrize("dim, cells, parts", [(2, 16, 8), (3, 6, 4)])
def test_bddc_glued_step_agrees_with_direct(dim, cells, parts):
    basis, K, form = _block(dim, cells)
    its = _check(basis, K, form, _clamped(basis), np.zeros(_clamped(basis).shape[0]), parts)
    assert its < 40


def test_bddc_contact_step_agrees_with_direct():
    """Closed node-to-obstacle rows on x = 1 (u·(1, 1, 0)/√2 = gap: one node's two dofs) on top
    of the clamp: the elimination ties each node's dofs, the subdomains' parts stay exact."""
    basis, K, form = _block(3, 6, )
    clamp = _clamped(basis)
    top = basis.nodal_dofs[:, np.flatnonzero(np.isclose(basis.mesh.p[0], 1.0))]
    m = top.shape[1]
    rows = sp.csr_matrix((np.full(2 * m, 2 ** -0.5), (np.repeat(np.arange(m), 2), top[:2].T.ravel())),
                         shape=(m, basis.N))
    C = sp.vstack([clamp, rows]).tocsr()
    gap = np.r_[np.zeros(clamp.shape[0]), np.full(m, -0.01)]
    assert _check(basis, K, form, C, gap, 4) < 40


def test_bddc_refuses_an_elimination_across_subdomains():
    basis, K, form = _block(2, 8)
    dofs, mats = _parts(basis, form, 2)
    a, b = np.setdiff1d(dofs[0], dofs[1])[0], np.setdiff1d(dofs[1], dofs[0])[0]
    Z = sp.eye(basis.N, format="lil")
    Z[a, a], Z[a, b] = 0.0, 1.0             # u_a = u_b: a's part of the other subdomain
    with pytest.raises(ValueError, match="another subdomain"):
        local_step(mats[0], dofs[0], Z.tocsr(), np.array([a]))
