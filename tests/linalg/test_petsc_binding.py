"""PETSc's answers do not depend on whether, or when, MKL is loaded (`wcs.linalg.petsc`).

Each order runs in its own process (a library's symbol bindings last the process): a GAMG +
CG solve of a 2D Laplacian (GAMG's set-up calls LAPACK, CG's dot products and norms BLAS), a
dense PETSc matrix times a vector (BLAS dgemv) and a dot product, their bits hashed. The
control imports petsc4py directly after MKL has run a PARDISO factor: its BLAS and LAPACK
are then MKL's, and its bits differ, so the probe does see which library computed."""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}

PROBE = r'''
import hashlib, sys
import numpy as np
import scipy.sparse as sp
from wcs import linalg

def mkl():                                  # MKL loaded and called: its BLAS in the global scope
    linalg.factorize(sp.eye(3, format="csr"), "pardiso", spd=True).solve(np.ones(3))

order = sys.argv[1]
if order in ("mkl-first", "control"):
    mkl()
if order == "control":
    import dolfinx_solver  # noqa: F401
    from petsc4py import PETSc
else:
    PETSc = linalg.petsc()
if order == "mkl-late":                     # after PETSc's libraries, before their first call
    mkl()
assert ("pypardiso" in sys.modules) == (order != "no-mkl")
n = 40
T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
A = (sp.kron(T, sp.eye(n)) + sp.kron(sp.eye(n), T)).tocsr()
b = np.random.default_rng(0).standard_normal(n * n)
M = PETSc.Mat().createAIJ(A.shape, csr=(A.indptr, A.indices, A.data))
ksp = PETSc.KSP().create()
ksp.setOperators(M)
ksp.setType("cg")
ksp.getPC().setType("gamg")
ksp.setTolerances(rtol=1e-10)
x, r = M.createVecs()
r.setArray(b)
ksp.solve(r, x)
assert ksp.getConvergedReason() > 0
D = PETSc.Mat().createDense((60, 60), array=np.random.default_rng(1).standard_normal((60, 60)))
D.assemble()
v, y = D.createVecs()
v.setArray(b[:60])
D.mult(v, y)
print(hashlib.sha256(x.getArray().tobytes() + y.getArray().tobytes()).hexdigest(), r.dot(x).hex())
'''


def probe(order: str) -> str:
    out = subprocess.run([sys.executable, "-c", PROBE, order], capture_output=True, text=True, check=True, env=ENV)
    return out.stdout.strip()


def test_petsc_answers_do_not_depend_on_mkl_being_loaded():
    alone = probe("no-mkl")
    assert probe("mkl-first") == alone
    assert probe("mkl-late") == alone
    assert probe("control") != alone, "the probe no longer tells MKL's BLAS from OpenBLAS's"


def test_petsc_loaded_before_says_its_bindings_are_not_wcs_own():
    """petsc4py imported directly first: `petsc()` cannot bind its libraries any more, and warns."""
    code = ("import warnings, dolfinx_solver\nfrom petsc4py import PETSc\nfrom wcs import linalg\n"
            "with warnings.catch_warnings(record=True) as w:\n    warnings.simplefilter('always')\n"
            "    assert linalg.petsc() is PETSc\nprint([str(x.message) for x in w if x.category is RuntimeWarning])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=ENV).stdout
    assert "was loaded before wcs.linalg.petsc()" in out, out


SINGLETON = r'''
import os, sys
from wcs import linalg
PETSc = linalg.petsc()
from mpi4py import MPI
print(MPI.COMM_WORLD.size, "UCX_TLS" in os.environ, os.environ.get("UCX_TLS"))
'''


def test_a_singleton_starts_mpi_with_ucx_loopback_alone_and_passes_no_variable_on():
    """A process no launcher started starts MPI with UCX_TLS=self (`linalg.bootstrap_mpi`) and
    unsets it again: a child it launches (mpiexec) gets the environment it had; a user's own
    UCX_TLS is left as it is."""
    env = {k: v for k, v in ENV.items() if k != "UCX_TLS"}
    out = subprocess.run([sys.executable, "-c", SINGLETON], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["1", "False", "None"], out.stderr
    out = subprocess.run([sys.executable, "-c", SINGLETON], env={**env, "UCX_TLS": "self,tcp"}, capture_output=True,
                         text=True, check=True)
    assert out.stdout.split() == ["1", "True", "self,tcp"], out.stderr
