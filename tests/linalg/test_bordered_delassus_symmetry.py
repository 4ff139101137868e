"""The bordered factor's Delassus operator is used unsymmetrized (`PardisoFactor.delassus`): PARDISO's
Schur complement of the symmetric bordered matrix [[A, Cᵀ], [C, 0]] must come back symmetric to
the bit, also with a regularized (pinned) A and rows of C that act on round-off only."""
import numpy as np
import scipy.sparse as sp

from wcs import linalg


def test_the_bordered_schur_complement_is_symmetric_to_the_bit():
    rng = np.random.default_rng(3)
    n, r = 2000, 300
    A = sp.random(n, n, density=0.003, random_state=rng)
    K = (A @ A.T + 4.0 * sp.eye(n)).tocsr()
    C = sp.random(r, n, density=0.01, random_state=rng).tolil()
    C[5] = 1e-17 * C[6]                                  # a row of round-off (a roller-held tangent)
    W = linalg.factorize(K, spd=True, border=C.tocsr()).delassus()
    assert np.array_equal(W, W.T)
    Wd = C.toarray() @ np.linalg.solve(K.toarray(), C.toarray().T)
    np.testing.assert_allclose(W, Wd, rtol=0, atol=1e-10 * np.abs(Wd).max())
