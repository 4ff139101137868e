"""When the iterative method keeps its GAMG hierarchy (`wcs.contact.iterative.Krylov`): while the
operator is, up to one scalar, the one it was built for in all but `REBUILD_ROWS` rows — within
one contact solve's Newton steps and, from the nominal answer's solve, across data sets whose
moduli all scale by one factor (K = s·K*)."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import yaml

import wcs.contact.iterative as iterative
from wcs.contact.iterative import Krylov
from wcs.model.evaluation import Evaluator
from wcs import load_study
from tests.contact.test_iterative import VALIDATION

RTOL = 1e-10


def laplacian(n: int, cut: bool = False) -> sp.csr_matrix:
    """The 5-point Laplacian on an n × n grid (Dirichlet all round); cut: the couplings across
    the grid's middle column line taken out (two halves, as a contact that opens)."""
    T = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    if cut:
        T = T.tolil()
        h = n // 2
        T[h - 1, h] = T[h, h - 1] = 0.0
        T[h - 1, h - 1] = T[h, h] = 1.0
    I = sp.identity(n)
    return (sp.kron(T, I) + sp.kron(I, sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]))).tocsr()


def solved(A, b, krylov=None):
    k = Krylov() if krylov is None else krylov
    x, its, ok = k.solve(A, b, RTOL)
    assert ok
    assert np.linalg.norm(b - A @ x) <= RTOL * np.linalg.norm(b) * 1.0001
    return x, its


def test_a_hierarchy_is_rebuilt_once_its_solves_cost_more_than_a_set_up_and_a_converged_solve_is_kept():
    """Kept for a changed operator (the grid cut in two, as a contact that opens), the hierarchy
    costs each solve iterations beyond its fresh rate; once they add up to more than
    REBUILD_ITERATIONS (about a GAMG set-up) the next solve gets a fresh one, which then takes
    what a new solver takes. No converged answer is thrown away and solved again (on main a
    slow solve was repeated with a fresh hierarchy: 130 + 36 CG iterations on the 2D tunnel)."""
    n = 40
    A0, A1 = laplacian(n), laplacian(n, cut=True)
    b = np.random.default_rng(1).standard_normal(n * n)
    fresh_x, fresh_its = solved(A1, b)
    k = Krylov()
    _, its0 = solved(A0, b, k)
    counts = []
    while k.builds == 1:
        x, its = solved(A1, b, k)
        counts.append(its)
    extra = [c - its0 for c in counts[:-1]]
    assert len(extra) >= 1 and sum(extra[:-1]) <= Krylov.REBUILD_ITERATIONS < sum(extra)
    assert counts[-1] == fresh_its and k.builds == 2
    np.testing.assert_allclose(x, fresh_x, rtol=0, atol=1e-12 * np.abs(fresh_x).max())


def test_a_scaled_operator_or_a_few_changed_rows_keep_the_hierarchy():
    """GAMG of s·A is GAMG of A over s, and CG's iterates are the same for a preconditioner times
    a constant: 3·A keeps the hierarchy and takes A's iterations, in the same solver and in one
    that inherits it (`kept`, as a data set from the nominal answer's); a change in ≤ REBUILD_ROWS
    rows keeps it, in more it is rebuilt for the inheriting solver (the answer is the solve's
    to its tolerance either way: `solved`)."""
    n = 40
    A0 = laplacian(n)
    b = np.random.default_rng(2).standard_normal(n * n)
    k = Krylov()
    x0, its0 = solved(A0, b, k)
    x3, its3 = solved(3.0 * A0, b, k)
    assert k.builds == 1 and its3 == its0
    np.testing.assert_allclose(3.0 * x3, x0, rtol=0, atol=1e-8 * np.abs(x0).max())
    few = A0 + sp.csr_matrix((np.ones(Krylov.REBUILD_ROWS), (np.arange(Krylov.REBUILD_ROWS),) * 2), shape=A0.shape)
    for A, built in ((2.5 * A0, 0), (few, 0), (laplacian(n, cut=True), 1)):
        heir = Krylov(kept=k)
        x, its = solved(A, b, heir)
        assert heir.builds == built
        np.testing.assert_allclose(x, spla.spsolve(A.tocsc(), b), rtol=0, atol=1e-7 * np.abs(x).max())
        heir.close()
    assert k.ksp is not None        # an heir does not free what it inherited


@pytest.fixture
def builds(monkeypatch):
    """The GAMG hierarchies built, in order."""
    made = []
    build = Krylov._build

    def counted(self, *args):
        made.append(1)
        return build(self, *args)
    monkeypatch.setattr(Krylov, "_build", counted)
    return made


def test_the_step_after_the_glued_start_gets_a_fresh_hierarchy_before_its_one_solve(monkeypatch):
    """A cold solve's first step glues every contact row (closed and stuck): its hierarchy's
    aggregates span the contact surface. Kept for step 2, where the rubber pad of the Tresca pad
    opens and slips, it cost 337 CG iterations (20 for the glued step) on main, which then
    solved the step again with a fresh one; now step 2 builds a fresh hierarchy and solves once."""
    events = []
    step, solve, build = iterative._Stepper.solve, Krylov.solve, Krylov._build

    def record(name, f):
        def wrapped(self, *args):
            events.append(name)
            return f(self, *args)
        return wrapped
    monkeypatch.setattr(iterative._Stepper, "solve", record("step", step))
    monkeypatch.setattr(Krylov, "solve", record("solve", solve))
    monkeypatch.setattr(Krylov, "_build", record("build", build))
    d = yaml.safe_load((VALIDATION / "tresca-pad.yaml").read_text())
    ref = Evaluator(load_study(d))
    d["solver"] = {"method": "iterative"}
    ev = Evaluator(load_study(d))
    got, want = ev.evaluate(ev.study.nominal(), gradients=False), ref.evaluate(ref.study.nominal(), gradients=False)
    assert got.status == 0
    starts = [i for i, e in enumerate(events) if e == "step"]
    assert len(starts) >= 3 and events[starts[1]:starts[2]] == ["step", "solve", "build"], events[:starts[2]]
    for name, value in want.phi.items():
        assert got.phi[name] == pytest.approx(value, rel=1e-7)


def patch(method):
    d = yaml.safe_load((VALIDATION / "block-on-block-3d.yaml").read_text())
    d["uncertain"] = {"materials.stiff.E": [1.0e10, 3.0e10], "materials.soft.E": [2.5e9, 7.5e9],
                      "loads.block_top.pressure": [1.0e6, 3.0e6]}
    d["solver"] = {"method": method}
    return load_study(d)


def test_data_sets_whose_moduli_all_scale_by_one_factor_keep_the_nominal_hierarchy(builds):
    """From the nominal answer (E = 2e10 and 5e9): both Young's moduli × 1.5 and a new load is
    K = 1.5 K* — no hierarchy built, the nominal solve's is kept; a new E of one material
    only is not a scaling — a fresh one. Every answer agrees with the direct method."""
    ev, ref = Evaluator(patch("iterative")), Evaluator(patch("monolithic"))
    nominal = [2.0e10, 5.0e9, 2.0e6]
    ev.evaluate(nominal, gradients=False)
    assert len(builds) >= 1
    for x, built in (([3.0e10, 7.5e9, 2.6e6], False), ([3.0e10, 5.0e9, 2.6e6], True)):
        del builds[:]
        got, want = ev.evaluate(x, gradients=False), ref.evaluate(x, gradients=False)
        assert got.status == 0 and (len(builds) > 0) == built, (x, builds)
        for name, value in want.phi.items():
            assert got.phi[name] == pytest.approx(value, rel=1e-7)
    kept = iterative._ANCHOR[ev.model][1]
    assert kept.builds >= 1
    pc, level = kept.fine                   # between solves the hierarchy holds no operator of K's size
    held, _ = pc.getMGSmoother(level).getOperators()
    assert kept.P is None and held.getInfo()["nz_used"] == held.getSize()[0]


def test_a_solve_lets_go_of_what_its_operator_replaces_before_building_it(monkeypatch):
    """Each operator is a matrix of K's size: when a kept hierarchy's next operator is built, the
    last solve's operator is already freed (the KSP and the hierarchy's finest level hold a
    diagonal in its place, PETSc no reference to it), and when the hierarchy is to be rebuilt,
    it is gone too — so no operator but the one being built is alive (two had been: the kept
    hierarchy's and the step's)."""
    from wcs.contact.distributed import Layout
    n = 30
    A0, A1 = laplacian(n), laplacian(n, cut=True)
    b = np.random.default_rng(2).standard_normal(n * n)
    k = Krylov()
    seen, made = [], []
    build = Layout.matrix

    def matrix(layout, A, PETSc):
        if k.ksp is None:
            seen.append("none")
        else:
            op, pre = k.ksp.getOperators()
            pc, level = k.fine
            fine, _ = pc.getMGSmoother(level).getOperators()
            seen.append("a diagonal" if op.handle == pre.handle == fine.handle and op.getInfo()["nz_used"] == n * n
                        else "an operator")
        assert [M.getRefCount() for M in made] == [1] * len(made)     # PETSc holds none of the earlier ones
        made.append(build(layout, A, PETSc))
        return made[-1]

    monkeypatch.setattr(Layout, "matrix", matrix)
    solved(A0, b, k)
    while k.builds == 1:            # kept solves of the changed operator, until the rebuild
        solved(A1, b, k)
    assert seen[0] == "none" and seen[-1] == "none"     # before the rebuild's operator: nothing kept
    assert seen[1:-1] and set(seen[1:-1]) == {"a diagonal"}
    k.close()
    assert [M.getRefCount() for M in made] == [1] * len(made)
