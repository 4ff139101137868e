"""PARDISO and SuperLU factorizations agree: solve, multi-RHS, refactor, inverse block (Schur complement)."""
import numpy as np
import pytest
import scipy.sparse as sp

from wcs import linalg

pytestmark = pytest.mark.skipif(linalg._pardiso() is None, reason="PARDISO not available")


def laplacian_2d(k, shift=0.0):
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(k, k))
    return (sp.kronsum(T, T) + shift * sp.eye(k * k)).tocsr()


@pytest.mark.parametrize("spd", [True, False])
def test_backends_agree(spd):
    rng = np.random.default_rng(1)
    A = laplacian_2d(15)
    if not spd:  # add a skew part: nonsymmetric, same pattern
        A = (A + 0.3 * (sp.triu(A, 1) - sp.tril(A, -1))).tocsr()
    n = A.shape[0]
    S = rng.choice(n, 12, replace=False)
    B = rng.standard_normal((n, 4))
    D = sp.diags(1.0 + rng.random(n))
    A2 = (D @ A @ D).tocsr()  # new values, same pattern (and SPD when A is)
    # cond(A) ~ 1e2 here: agreement to 1e-10 relative leaves a wide margin over round-off
    for M in (A, A2):
        X = np.linalg.solve(M.toarray(), B)
        Z = np.linalg.inv(M.toarray())[np.ix_(S, S)]
        if M is A:
            fs = [linalg.factorize(A, kind, spd=spd, block=S) for kind in ("pardiso", "superlu")]
        else:
            fs = [f.refactor(A2) for f in fs]
        for f in fs:
            np.testing.assert_allclose(f.solve(B), X, rtol=0, atol=1e-10 * np.abs(X).max())
            np.testing.assert_allclose(f.solve(B[:, 0]), X[:, 0], rtol=0, atol=1e-10 * np.abs(X).max())
            np.testing.assert_allclose(f.inverse_block(), Z, rtol=0, atol=1e-10 * np.abs(Z).max())


@pytest.mark.parametrize("ascending", [True, False])
def test_schur_block_in_block_order_and_symmetric_to_the_bit(ascending):
    """schur(): A_SS − A_SI A_II⁻¹ A_IS in the block's order (an ascending block without a gather,
    `copy=False` PARDISO's own buffer); on the Cholesky path symmetric to the bit
    (`symmetric_schur`: the DD takes its units' Σ unsymmetrised), also after a refactor."""
    rng = np.random.default_rng(2)
    A = laplacian_2d(15, 0.1)
    D = sp.diags(1.0 + rng.random(A.shape[0]))
    S = rng.choice(A.shape[0], 20, replace=False)
    S = np.sort(S) if ascending else S
    f = linalg.factorize(A, "pardiso", spd=True, block=S)
    assert f.symmetric_schur
    for M in (A, (D @ A @ D).tocsr()):
        f = f if M is A else f.refactor(M)
        Md = M.toarray()
        I = np.setdiff1d(np.arange(M.shape[0]), S)
        ref = Md[np.ix_(S, S)] - Md[np.ix_(S, I)] @ np.linalg.solve(Md[np.ix_(I, I)], Md[np.ix_(I, S)])
        sigma = f.schur()
        np.testing.assert_allclose(sigma, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
        assert np.array_equal(sigma, sigma.T)
        if ascending:
            assert np.array_equal(f.schur(copy=False), sigma)


def test_refactor_with_new_pattern_reanalyses():
    A, A3 = laplacian_2d(8), laplacian_2d(8, 1.0) + sp.eye(64, k=5)
    f = linalg.factorize(A, "pardiso").refactor(A3.tocsr())
    b = np.ones(64)
    np.testing.assert_allclose(f.solve(b), np.linalg.solve(A3.toarray(), b), atol=1e-12)


def test_not_positive_definite_raises():
    with pytest.raises(linalg.FactorizationError):
        linalg.factorize(-laplacian_2d(5), "pardiso", spd=True)


@pytest.mark.parametrize("kind", ["pardiso", "superlu"])
def test_bordered_factor_gives_C_A_inverse_Ct_and_solves_with_A(kind):
    """factorize(A, spd=True, border=C): delassus() = C A⁻¹ Cᵀ and solve() with A itself, also
    after a refactor with new values and with a border that makes [[A, Cᵀ], [C, 0]] singular
    (a zero row and a repeated one: C A⁻¹ Cᵀ is then singular, its Schur pivots perturbed)."""
    rng = np.random.default_rng(3)
    A = laplacian_2d(15, 0.1)
    n = A.shape[0]
    C = sp.random(20, n, density=0.02, random_state=4, format="csr")
    C = sp.vstack([C, sp.csr_matrix((1, n)), C[:1]]).tocsr()
    B = rng.standard_normal((n, 3))
    D = sp.diags(1.0 + rng.random(n))
    f = linalg.factorize(A, kind, spd=True, border=C)
    for M in (A, (D @ A @ D).tocsr()):
        if M is not A:
            f.refactor(M)
        X = np.linalg.solve(M.toarray(), B)
        W = C @ np.linalg.solve(M.toarray(), C.T.toarray())
        # cond(M) ~ 1e3: 1e-10 relative is far above round-off and far below any wrong block
        np.testing.assert_allclose(f.delassus(), W, rtol=0, atol=1e-10 * np.abs(W).max())
        np.testing.assert_allclose(f.solve(B), X, rtol=0, atol=1e-10 * np.abs(X).max())
        np.testing.assert_allclose(f.solve(B[:, 1]), X[:, 1], rtol=0, atol=1e-10 * np.abs(X).max())
    C2 = (2.0 * C).tocsr()                                  # a new border on the same pattern
    f.refactor(A, border=C2)
    W2 = C2 @ np.linalg.solve(A.toarray(), C2.T.toarray())
    np.testing.assert_allclose(f.delassus(), W2, rtol=0, atol=1e-10 * np.abs(W2).max())


def test_an_empty_schur_block_is_not_asked_of_pardiso():
    """A unit without interface unknowns has an empty block: PARDISO asked for a 0 × 0 Schur
    complement wrote past its buffer and the process aborted at the next collection (a DD with
    thousands of subdomains). Run apart: on failure the interpreter dies, not the test session."""
    import os
    import subprocess
    import sys
    code = """if True:
        import gc
        import numpy as np
        import scipy.sparse as sp
        from wcs import linalg
        T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(6, 6))
        A = (sp.kronsum(T, T) + 0.1 * sp.eye(36)).tocsr()
        b = np.arange(36.0)
        for _ in range(50):
            f = linalg.factorize(A, "pardiso", spd=True, block=np.zeros(0, dtype=int))
            f.refactor((2 * A).tocsr())
            assert f.schur().shape == (0, 0)
            assert np.allclose(f.solve(b), np.linalg.solve(2 * A.toarray(), b), rtol=1e-12, atol=0)
            del f
            gc.collect()
        print("ok")
    """
    from pathlib import Path
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert (run.returncode, run.stdout) == (0, "ok\n"), run.stderr[-2000:]


@pytest.mark.skipif(linalg.backend() != "pardiso", reason="PARDISO is the x86_64 backend")
def test_pardiso_error_codes_are_translated(monkeypatch):
    """PARDISO's error −2 is "not enough memory", not a singular matrix: the message says so and
    names the way out (a 3D patch at a 0.01 contact face failed as 'singular')."""
    A = sp.identity(4, format="csr")
    F = linalg.PardisoFactor(A, spd=True)

    def out_of_memory(*args):
        args[-1]._obj.value = -2          # the `error` output argument, passed by reference

    monkeypatch.setattr(F, "_lib", out_of_memory)
    with pytest.raises(linalg.FactorizationError, match="error -2 .not enough memory.*iterative"):
        F.refactor(A)
