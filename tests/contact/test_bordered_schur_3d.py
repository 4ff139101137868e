"""The 3D contact solve with W from the bordered matrix [[K⁺⁻¹, Cᵀ], [C, 0]] (Schur complement
on the contact rows) gives the answers of the dense path W = C_S (K⁺)_SS C_Sᵀ, which 2D keeps."""

import numpy as np
import pytest
import scipy.sparse as sp

from wcs import linalg
from wcs.contact import solver as cs
from wcs.status import Status
from tests.contact.test_solver_3d import args, pad_on_base


def C_of(P):
    return sp.vstack([P["Bn"], P["Bt"]]).tocsr()


@pytest.mark.parametrize("floating", [False, True])
def test_bordered_delassus_equals_the_dense_inverse_block_one(floating):
    """W and the solves with K⁺ agree to round-off (cond(K⁺) ~ 1e4 here: 1e-11 relative leaves a
    wide margin), also after a refactor on new values (a stiffer base: same pattern)."""
    P = pad_on_base(floating=floating, load=(0.001, 0.0, -0.01))
    C = C_of(P)
    a = cs.factor_contact(P["K"], C, P["R"], None)
    b = cs.factor_contact(P["K"], C, P["R"], None, bordered=False)
    assert cs._bordered(a.factor) and not cs._bordered(b.factor)
    for K in (P["K"], (P["K"] + sp.diags(np.linspace(0.0, 0.1, P["K"].shape[0]))).tocsr()):
        a, b = cs.factor_contact(K, C, P["R"], a), cs.factor_contact(K, C, P["R"], b, bordered=False)
        np.testing.assert_allclose(a.W, b.W, rtol=0, atol=1e-11 * np.abs(b.W).max())
        x, y = a.factor.solve(P["f"]), b.factor.solve(P["f"])
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-11 * np.abs(y).max())
    assert a.holds(cs.regularize(K, a.pinned), C[:, a.S])


@pytest.mark.parametrize("case", ["tresca twisted", "tresca floating", "frictionless"])
def test_bordered_and_dense_contact_solves_agree(case):
    """Same status, same active sets, |Δu| ≤ 1e-9 |u| (the solver's tolerance 1e-10 on scaled
    forces; the two W differ by round-off). The twisted pad slips on discs in varying directions
    (the disc rows of the Newton system), the floating one carries the rigid modes."""
    if case == "tresca floating":
        P = pad_on_base(floating=True, load=(0.002, -0.001, -0.01))
    else:
        P = pad_on_base(twist=0.02)
    m = len(P["w"])
    g = None if case == "frictionless" else np.full(m, 0.004)
    dense = cs.factor_contact(P["K"], C_of(P), P["R"], None, bordered=False)
    r_dense = cs.solve_contact(*args(P), g=g, R=P["R"], factor=dense)
    r = cs.solve_contact(*args(P), g=g, R=P["R"])
    assert cs._bordered(r.factor.factor) and not cs._bordered(r_dense.factor.factor)
    assert r.status == r_dense.status == Status.SOLVED
    np.testing.assert_array_equal(r.active, r_dense.active)
    if case != "frictionless":
        assert {cs.STICK, cs.SLIP} <= set(r.active) or set(r.active) == {cs.SLIP}
    assert np.linalg.norm(r.u - r_dense.u) <= 1e-9 * np.linalg.norm(r_dense.u)


def test_bordered_factor_needs_a_symmetric_matrix():
    with pytest.raises(ValueError, match="symmetric"):
        linalg.factorize(sp.eye(4, format="csr"), "pardiso", border=sp.eye(1, 4, format="csr"))


@pytest.mark.parametrize("case", ["tresca twisted", "tresca floating", "frictionless"])
def test_the_symmetric_disc_frame_step_follows_the_lu_iterates(case, monkeypatch):
    """The 3D Newton step in the slip frame (Cholesky) and the unsymmetric form (LU, refined)
    solve the same equations: the same iterates, so the same iteration count, active sets and
    status, |Δu| ≤ 1e-9 |u|."""
    if case == "tresca floating":
        P = pad_on_base(floating=True, load=(0.002, -0.001, -0.01))
    else:
        P = pad_on_base(twist=0.02)
    g = None if case == "frictionless" else np.full(len(P["w"]), 0.004)
    calls = []
    step = cs._disc_frame_step
    monkeypatch.setattr(cs, "_disc_frame_step", lambda *a: calls.append(1) or step(*a))
    r = cs.solve_contact(*args(P), g=g, R=P["R"])
    assert calls and r.status == Status.SOLVED
    monkeypatch.setattr(cs, "_disc_frame_step", lambda *a: None)
    r_lu = cs.solve_contact(*args(P), g=g, R=P["R"])
    assert r_lu.status == Status.SOLVED and r.iterations == r_lu.iterations
    np.testing.assert_array_equal(r.active, r_lu.active)
    assert np.linalg.norm(r.u - r_lu.u) <= 1e-9 * np.linalg.norm(r_lu.u)
