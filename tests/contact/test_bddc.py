"""BDDC (`wcs.contact.bddc`): subdomain matrices assembled over each part's cells (the model's
cell matrices), transformed by a step's elimination, precondition CG to the direct solve's answer."""
import numpy as np
import pytest
import scipy.sparse as sp
import skfem as fem
from scipy.sparse.linalg import spsolve

from wcs.contact.bddc import Bddc, bisection, subdomain_stiffness, transformed
from wcs.fem.affine import CellAffineOperator, elastic_cells
from wcs.contact.iterative import _basis, _eliminated
from wcs.fem.rigid import rigid_modes

pytest.importorskip("dolfinx_solver")


LAME = np.array([[0.6, 0.4], [1.2, 0.8]])       # (λ, μ) of two regions: the cells' halves x < 0.5, x > 0.5


def _block(dim, cells):
    """An elastic unit square/cube of two materials: its basis, K (the model's assembly:
    `CellAffineOperator`) and the pieces to assemble a part of it."""
    axes = [np.linspace(0.0, 1.0, cells + 1)] * dim
    mesh = fem.MeshTri.init_tensor(*axes) if dim == 2 else fem.MeshTet.init_tensor(*axes)
    element = fem.ElementVector(fem.ElementTriP1() if dim == 2 else fem.ElementTetP1())
    group = (mesh.p[0, mesh.t].mean(axis=0) > 0.5).astype(int)
    op = CellAffineOperator(mesh.t, mesh.nvertices, elastic_cells(mesh.p, mesh.t), group)
    return fem.Basis(mesh, element), op(LAME), op


def _parts(basis, op, parts):
    """Each part's dofs and its own matrix, assembled over its cells only."""
    mesh = basis.mesh
    part = bisection(mesh.p[:, mesh.t].mean(axis=1), parts)
    return zip(*[subdomain_stiffness(mesh.t, op.local, op.group, LAME, np.flatnonzero(part == s))
                 for s in range(parts)])


def _scatter(n, dofs, local):
    return sum(sp.csr_matrix(sp.coo_matrix((L.tocoo().data, (d[L.tocoo().row], d[L.tocoo().col])), shape=(n, n)))
               for d, L in zip(dofs, local))


def _check(basis, K, op, C, rows_b, parts):
    """The step u = Z x + u_b with C u = rows_b (one pivot per row, its own dof), solved by
    BDDC and directly; the subdomains' parts sum to the step's operator."""
    n = K.shape[0]
    P = np.asarray(C.tocsr().indices[C.tocsr().indptr[:-1]])     # each row's first dof
    Binv = sp.diags(1.0 / np.asarray(C.tocsr()[np.arange(C.shape[0]), P]).ravel())
    Z, ub = _basis(C.tocsr(), np.arange(C.shape[0]), P, Binv, rows_b)
    A = _eliminated(Z, K, K, P)
    f = basis.doflocs.sum(axis=0) - 1.0
    b = Z.T @ (f - K @ ub)
    dofs, local = zip(*[transformed(d, L, Z, P) for d, L in zip(*_parts(basis, op, parts))])
    assert abs(_scatter(n, dofs, local) - A).max() <= 1e-12 * abs(A).max()
    dim = basis.mesh.dim()
    nodes = np.arange(basis.mesh.nvertices)
    R = rigid_modes(basis.mesh.p, nodes, len(nodes))
    solver = Bddc(dofs, local, np.arange(n) % dim, R)
    x, its, ok = solver.solve(A, b, 1e-10)
    direct = spsolve(A.tocsc(), b)
    assert ok
    assert np.linalg.norm(x - direct) <= 1e-7 * np.linalg.norm(direct)
    return its, solver.faces


def _clamped(basis):
    """Rows u_i = 0 at the dofs on x = 0 (the glued/supported step)."""
    D = basis.get_dofs(lambda x: np.isclose(x[0], 0.0)).flatten()
    n = basis.N
    return sp.csr_matrix((np.ones(len(D)), (np.arange(len(D)), D)), shape=(len(D), n))


@pytest.mark.parametrize("dim, cells, parts, faces", [(2, 16, 8, 0), (3, 6, 8, 0), (3, 6, 4, 1)])
def test_bddc_glued_step_agrees_with_direct(dim, cells, parts, faces):
    """Four columns of the cube (parts 4) float without a primal vertex: the faces' change of
    basis is taken (`Bddc`); eight octants have vertices and do without."""
    basis, K, op = _block(dim, cells)
    its, took = _check(basis, K, op, _clamped(basis), np.zeros(_clamped(basis).shape[0]), parts)
    assert took == faces
    assert its < 30


def test_bddc_contact_step_agrees_with_direct():
    """Closed node-to-obstacle rows on x = 1 (u·(1, 1, 0)/√2 = gap: one node's two dofs) on top
    of the clamp: the elimination ties each node's dofs, the subdomains' parts stay exact."""
    basis, K, op = _block(3, 6)
    clamp = _clamped(basis)
    top = basis.nodal_dofs[:, np.flatnonzero(np.isclose(basis.mesh.p[0], 1.0))]
    m = top.shape[1]
    rows = sp.csr_matrix((np.full(2 * m, 2 ** -0.5), (np.repeat(np.arange(m), 2), top[:2].T.ravel())),
                         shape=(m, basis.N))
    C = sp.vstack([clamp, rows]).tocsr()
    gap = np.r_[np.zeros(clamp.shape[0]), np.full(m, -0.01)]
    assert _check(basis, K, op, C, gap, 8)[0] < 30


def test_bddc_parts_sum_to_the_model_stiffness():
    """Σ_s of the parts' own matrices is the model's K (`CellAffineOperator`), to round-off."""
    basis, K, op = _block(3, 4)
    assert abs(_scatter(K.shape[0], *_parts(basis, op, 5)) - K).max() <= 1e-13 * abs(K).max()


def test_bddc_elimination_across_subdomains_stays_exact():
    """A row of the elimination that ties a dof to another part's (a glued slave to its master
    across the cut) adds that unknown to the part: the parts still sum to Tᵀ K T + diag(K)_P."""
    basis, K, op = _block(2, 8)
    dofs, mats = _parts(basis, op, 2)
    a, b = np.setdiff1d(dofs[0], dofs[1])[0], np.setdiff1d(dofs[1], dofs[0])[0]
    Z = sp.eye(basis.N, format="lil")
    Z[a, a], Z[a, b] = 0.0, 1.0             # u_a = u_b: a follows the other part's b
    Z = Z.tocsr()
    P = np.array([a])
    local, parts = zip(*[transformed(d, L, Z, P) for d, L in zip(dofs, mats)])
    assert b in local[0]
    A = _eliminated(Z, K, K, P)
    assert abs(_scatter(K.shape[0], local, parts) - A).max() <= 1e-12 * abs(A).max()


def _evaluate(source, preconditioner):
    """The nominal evaluation (criteria and gradients) of a study with the iterative method and
    this preconditioner (None: the monolithic method), CG to 1e-12."""
    from tests.contact.test_iterative import study
    from wcs.model.evaluation import Evaluator
    from wcs import load_study
    d = study(source, "monolithic" if preconditioner is None else "iterative")
    if preconditioner is not None:
        d["solver"]["iterative"] = {"preconditioner": preconditioner, "tolerance": 1e-12}
    ev = Evaluator(load_study(d))
    return ev.evaluate(ev.study.nominal(), gradients=True)


def _floating():
    from tests.contact.test_patch_3d import floating
    return floating({"slip_limit": 3.0e5})


@pytest.mark.parametrize("source", [pytest.param("tresca-shear-patch-3d.yaml", marks=pytest.mark.slow),
                                    "floating", "contact-patch.yaml"])
def test_bddc_study_agrees_with_direct_and_amg(source, monkeypatch):
    """`solver.iterative.preconditioner: bddc` end to end: a 3D block held by contact alone
    (Tresca, disc springs across the slip: each spring row to its subdomain; its steps pin the
    free rigid modes' unknowns), a 2D patch and the 3D shear patch (slow: 14 s); the answer and the adjoint
    gradients those of the monolithic method and of GAMG to 1e-7 (the KKT system is the same,
    CG's residual 1e-12: both iterative answers agree with the direct one to 1e-11). The set-up
    is kept across Newton steps (`Krylov`'s rule): fewer set-ups than steps, the adjoint's one
    aside."""
    from tests.contact.test_iterative import VALIDATION, rel
    from wcs.contact.iterative import Krylov
    path = _floating() if source == "floating" else VALIDATION / source
    direct, amg = (_evaluate(path, p) for p in (None, "amg"))
    built, build = [], Krylov._build

    def counted(self, *args):
        built.append(self.parts is not None)
        return build(self, *args)
    monkeypatch.setattr(Krylov, "_build", counted)
    bddc = _evaluate(path, "bddc")
    assert bddc.status == 0, bddc.message
    raw = bddc.state.raw
    steps = len(built) - 1           # set-ups of the Newton steps (the adjoint's one aside)
    assert all(built) and (steps < raw.iterations if raw.iterations > 1 else steps == 1)
    assert raw.timings["bddc_setup"] > 0 and "gamg_setup" not in raw.timings
    for other in (direct, amg):
        assert rel(raw.u, other.state.raw.u) <= 1e-7
        for name, value in other.phi.items():
            assert bddc.phi[name] == pytest.approx(value, rel=1e-7, abs=1e-7 * max(map(abs, other.phi.values())))
    for name, g in amg.grad.items():
        if g is not None:
            assert np.linalg.norm(bddc.grad[name] - g) <= 1e-7 * max(np.linalg.norm(g), abs(amg.phi[name]))


def test_bddc_is_refused_in_a_dynamic_study_and_taken_on_a_group():
    """In a dynamic study (a time level's operator holds the mass, the subdomain matrices the
    stiffness only) bddc is exit 2 naming the key, never a silent GAMG; on a group of ranks it
    is taken (each rank its share of the subdomains)."""
    from tests.contact.test_iterative import VALIDATION, study
    from wcs.errors import StudyError
    from wcs.model.evaluation import Evaluator
    from wcs import load_study
    d = study(VALIDATION / "two-bars-impact.yaml", "iterative")
    d["solver"]["iterative"] = {"preconditioner": "bddc"}
    with pytest.raises(StudyError, match="dynamic study") as info:
        Evaluator(load_study(d))
    assert info.value.path == "solver.iterative.preconditioner"
    d = study(VALIDATION / "block-on-block-3d.yaml", "iterative")
    d["solver"].update(ranks_per_evaluation=2, iterative={"preconditioner": "bddc"})
    assert Evaluator(load_study(d)).model.options.iterative.preconditioner == "bddc"


def test_auto_chooses_amg_and_check_says_why():
    """`preconditioner: auto` on one process and on a group of ranks: amg, by BDDC's measured
    set-up cost on one rank and on two (`wcs.choose.BDDC_SETUP_RATIO`, `BDDC_SETUP_RATIO_RANKS`,
    bench_bddc_*.csv); `wcs check`'s plan says so, and where the study chose bddc, that the
    evaluation's estimate is made for amg."""
    from tests.contact.test_iterative import VALIDATION, study
    from wcs.choose import BDDC_SETUP_RATIO, BDDC_SETUP_RATIO_RANKS, PreconditionerFacts, preconditioner
    from wcs.cli import plan
    from wcs.model.evaluation import Evaluator
    from wcs import load_study
    for ranks, where, ratio in ((1, "one process", BDDC_SETUP_RATIO), (4, "4 ranks: on 2 ranks", BDDC_SETUP_RATIO_RANKS)):
        which, why = preconditioner(PreconditionerFacts(10 ** 6, ranks))
        assert which == "amg" and why.startswith(where) and f"took {ratio:g}x GAMG's CPU time" in why
    ev = Evaluator(load_study(study(VALIDATION / "block-on-block-3d.yaml", "iterative")))
    line = next(x for x in plan(ev.study, ev) if "solver:" in x)
    assert "preconditioner: auto -> amg (one process" in line and "bench_bddc_*.csv" in line
    d = study(VALIDATION / "block-on-block-3d.yaml", "iterative")
    d["solver"]["ranks_per_evaluation"] = 2
    ev = Evaluator(load_study(d))
    line = next(x for x in plan(ev.study, ev) if "solver:" in x)
    assert f"preconditioner: auto -> amg (2 ranks: on 2 ranks, each its share of the subdomains, BDDC's set-up took " \
           f"{BDDC_SETUP_RATIO_RANKS:g}x" in line
    d = study(VALIDATION / "block-on-block-3d.yaml", "iterative")
    d["solver"]["iterative"] = {"preconditioner": "bddc"}
    ev = Evaluator(load_study(d))
    line = next(x for x in plan(ev.study, ev) if "solver:" in x)
    assert "preconditioner: bddc (chosen in the study; the evaluation's estimate is the method's with amg" in line


def test_bddc_step_parts_with_springs_and_pins_sum_to_the_step():
    """A step's parts (`step_parts`) with disc springs Qᵀ diag(s) Q whose rows span two
    subdomains and pinned unknowns sum to the operator `_Stepper` solves:
    Zᵀ (K + Qᵀ diag(s) Q) Z + diag(K)_P, plus its own diagonal on the pinned unknowns."""
    from wcs.contact.bddc import step_parts
    from wcs.contact.iterative import _pinned
    basis, K, op = _block(3, 4)
    C = _clamped(basis)
    P = np.asarray(C.indices[C.indptr[:-1]])
    Z, _ = _basis(C, np.arange(C.shape[0]), P, sp.eye(C.shape[0], format="csr"), np.zeros(C.shape[0]))
    dofs, mats = _parts(basis, op, 4)
    n = K.shape[0]
    x = basis.mesh.p
    right = basis.nodal_dofs[:, np.flatnonzero(np.isclose(x[0], 1.0))]
    inner = basis.nodal_dofs[:, np.flatnonzero(np.isclose(x[0], 0.25))]      # the same (y, z), another part
    m = right.shape[1]
    Q = sp.csr_matrix((np.tile([0.6, 0.8, -1.0], m), (np.repeat(np.arange(m), 3),
                       np.column_stack([right[1:].T, inner[1]]).ravel())), shape=(m, n))
    s = np.linspace(1.0, 2.0, Q.shape[0])
    pin = right[0, :3]
    A = _pinned(lambda lo, hi: _eliminated(Z, (K + Q.T @ sp.diags(s) @ Q).tocsr(), K, P), pin)(0, n)
    local_dofs, local = step_parts(dofs, mats, Z, P, (Q, s), pin)
    plain = [transformed(d, L, Z, P)[0] for d, L in zip(dofs, mats)]
    assert any(len(a) > len(b) for a, b in zip(local_dofs, plain))     # a spring row joined another part's unknowns
    assert abs(_scatter(n, local_dofs, local) - A).max() <= 1e-12 * abs(A).max()


def _failed_set_up(comm=None):
    """A solve whose subdomain matrices are zero (spanning `comm`, each rank its share of the two
    subdomains; None: this process alone): (ok, its, failure, builds, ksp is None)."""
    from wcs.contact.bddc import Parts
    from wcs.contact.iterative import Krylov
    from wcs.group import share, spanning
    basis, K, op = _block(2, 4)
    C = _clamped(basis)
    P = np.asarray(C.indices[C.indptr[:-1]])
    Z, _ = _basis(C, np.arange(C.shape[0]), P, sp.eye(C.shape[0], format="csr"), np.zeros(C.shape[0]))
    dofs, mats = _parts(basis, op, 2)
    with spanning(comm):
        owned = range(*share(2))
        parts = Parts(dofs, tuple(0.0 * mats[j] for j in owned), np.arange(K.shape[0]) % 2, None, owned)
        solver = Krylov(parts=parts)
        A = _eliminated(Z, K, K, P)
        x, its, ok = solver.solve(A, np.ones(K.shape[0]), 1e-8, (Z, P, None, None))
        out = (ok, its, solver.failure, solver.builds, solver.ksp is None)
        solver.close()
    return out


def test_a_failed_bddc_set_up_is_a_failed_solve_that_says_why():
    """Subdomain matrices that cannot be factored (here zero: both set-ups, with and without the
    faces' change of basis, fail) give a failed solve with the reason, never an exception or a
    preconditioner of another kind."""
    ok, its, failure, builds, empty = _failed_set_up()
    assert not ok and its == 0 and "BDDC's set-up failed" in failure
    assert builds == 0 and empty


def test_a_failed_bddc_set_up_on_two_ranks_fails_on_both(spread_runs):
    """On a group the ranks agree on the failed set-up (the worst rank's reason): each records
    the failed solve and its reason, none waits for another."""
    for ok, its, failure, builds, empty in spread_runs["failed"]:
        assert not ok and its == 0 and "BDDC's set-up failed" in failure
        assert builds == 0 and empty


@pytest.fixture(scope="module")
def spread_runs(tmp_path_factory) -> dict:
    """`spread` under mpiexec -n 2: what rank 0 saved."""
    import json
    import sys
    from tests.app.test_ranks_per_evaluation import mpiexec
    out = tmp_path_factory.mktemp("bddc") / "spread.json"
    done = mpiexec(2, sys.executable, __file__, out, timeout=600)
    assert done.returncode == 0, done.stderr + done.stdout
    return json.loads(out.read_text())


@pytest.mark.parametrize("name", ["floating", "patch"])
def test_bddc_on_two_ranks_agrees_with_one_rank_and_direct(spread_runs, name):
    """BDDC with the subdomains shared over a group of 2 ranks (a distributed MATIS) is the
    same preconditioner as on one rank (the same cut, `parts_of`): the same CG iterations to
    ±2 (round-off), the answer within 1e-10 of the one-rank answer (CG's residual 1e-12 on
    both: the two differ by rounding only), within 1e-8 of the monolithic method's (the KKT
    system is the same; 1e-12 of CG's residual is amplified by the operator's condition); the
    same layout gives the same bits."""
    a, b, one, direct = (spread_runs[f"{name}_{r}"] for r in ("a", "b", "one", "direct"))
    for r in (a, one, direct):
        assert r["status"] == 0, r["message"]
    assert a["bddc"] and one["bddc"] and abs(a["krylov"] - one["krylov"]) <= 2
    assert a == b
    u = np.array(a["u"])
    for other, tol in ((one, 1e-10), (direct, 1e-8)):
        assert np.linalg.norm(u - other["u"]) <= tol * np.linalg.norm(other["u"])
        scale = max(map(abs, other["phi"].values()))
        for c, v in other["phi"].items():
            assert a["phi"][c] == pytest.approx(v, rel=tol, abs=tol * scale)
    assert not np.array_equal(u, one["u"])          # two layouts, two roundings: a real comparison
    for c, g in one["grad"].items():
        assert np.linalg.norm(np.subtract(a["grad"][c], g)) <= 1e-10 * max(np.linalg.norm(g), abs(one["phi"][c]))


def spread(out: str) -> None:
    """Under mpiexec -n 2 (one group of 2 ranks): the nominal evaluation (criteria, gradients,
    displacement, CG iterations) of the floating Tresca block and of the 3D shear patch with
    bddc, CG to 1e-12, each twice on the group (`solver.ranks_per_evaluation: 2`, each rank its
    share of the subdomains) and once on each rank alone (k = 1); rank 0 saves them to `out`."""
    import json
    from tests.contact.test_iterative import VALIDATION, study
    from wcs.app.parallel import world
    from wcs.group import spanning
    from wcs.model.evaluation import Evaluator
    from wcs import load_study
    comm, saved = world(), {}
    for name, source in (("floating", _floating()), ("patch", VALIDATION / "tresca-shear-patch-3d.yaml")):
        for run, k in (("a", 2), ("b", 2), ("one", 1), ("direct", 1)):
            d = study(source, "monolithic" if run == "direct" else "iterative")
            if run != "direct":
                d["solver"].update(ranks_per_evaluation=k, iterative={"preconditioner": "bddc", "tolerance": 1e-12})
            ev = Evaluator(load_study(d))
            with spanning(comm if k == 2 else None):
                r = ev.evaluate(ev.study.nominal(), gradients=True)
            saved[f"{name}_{run}"] = {"status": int(r.status), "message": r.message, "phi": r.phi,
                                      "grad": {c: np.asarray(g).tolist() for c, g in r.grad.items() if g is not None},
                                      "u": r.state.raw.u.tolist(), "krylov": int(getattr(r.state.raw, "krylov_iterations", 0)),
                                      "bddc": r.state.raw.timings.get("bddc_setup", 0.0) > 0}
    failed = comm.gather(_failed_set_up(comm))
    if comm.rank == 0:
        Path(out).write_text(json.dumps({**saved, "failed": failed}))


if __name__ == "__main__":
    import sys
    from pathlib import Path
    spread(sys.argv[1])
