"""solver.method iterative (`wcs.contact.iterative`): the same discrete problem as the condensed
semismooth Newton of `wcs.contact.solver`, solved by a primal active set with CG + GAMG.

Tolerance 1e-7 relative: both methods satisfy the same KKT system, the direct one to
round-off, the iterative one to the final CG residual 1e-12 of the right-hand side; measured
agreement is 1e-11–1e-13, so 1e-7 leaves four orders of margin while a wrong active node
moves the multipliers by ≥ 1e-3. Tractions are compared as the model reports them
(`Model.contact_state`, the canonical split of tied rows: a tangent parallel to its normal
carries no force of its own, and the two methods split such a pair differently).
"""
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import yaml

from tests.contact.test_solver import args, two_blocks
from tests.contact.test_patch_3d import floating, shear_patch
from tests.contact.test_solver_3d_inclined_fault import tunnel_fault_3d
from tests.fem.test_glue_3d import plane, stack
from wcs.contact import solver as cs
from wcs.contact.iterative import solve_contact_iterative
from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs.status import Status
from wcs import load_study

ROOT = Path(__file__).resolve().parents[2]
VALIDATION = ROOT / "studies" / "validation"
AGREE = 1e-7


def rel(a, b):
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300)


def study(path, method="monolithic", **mesh):
    d = yaml.safe_load(yaml.safe_dump(path)) if isinstance(path, dict) else yaml.safe_load(Path(path).read_text())
    d["scene"].setdefault("mesh", {}).update(mesh)
    d["solver"] = {**d.get("solver", {}), "method": method}
    return d


def both(path, tol=1e-10, rtol=1e-12, tol_fp=1e-8, **mesh):
    """The model of a study and its nominal contact problem solved by both methods (the contact,
    Krylov and fixed-point tolerances)."""
    M = Evaluator(load_study(study(path, **mesh))).model
    c = M.nominal
    T = M._heat(c, False)[0] if M.thermal else None
    _, Kr, rhs, u0 = M.reduced_system(c, T)
    z = M.zone
    P = dict(K=Kr, f=rhs, Bn=M.Bn_r, Bt=M.Bt_r, d=z.gap - z.Bn @ u0, w=z.weight, g=c.slip,
             F=c.coulomb if c.coulomb.any() else None, R=M.R_r)
    direct = cs.solve_contact(**P, tol=tol, tol_fp=tol_fp)
    iterative = solve_contact_iterative(**P, tol=tol, tol_fp=tol_fp, near_nullspace=M.near_nullspace, rtol=rtol)
    return M, direct, iterative


def assert_agree(M, direct, iterative):
    assert direct.status == 0, direct.message
    assert iterative.status == 0, iterative.message
    assert rel(iterative.u, direct.u) <= AGREE
    states = [M.contact_state(r.lam_n, r.lam_t, M.elim.T @ r.u, r.active) for r in (direct, iterative)]
    assert rel(states[1].force_n, states[0].force_n) <= AGREE
    assert rel(states[1].force_t, states[0].force_t) <= AGREE
    assert iterative.iterations >= 1 and iterative.krylov_iterations >= iterative.iterations


@pytest.mark.parametrize("g", [None, 0.004])
def test_2d_blocks_frictionless_and_tresca_agree_with_the_direct_method(g):
    P = two_blocks(20)
    m = P["Bn"].shape[0]
    gw = None if g is None else np.full(m, g)
    direct = cs.solve_contact(*args(P), g=gw, tol=1e-10)
    iterative = solve_contact_iterative(*args(P), g=gw, tol=1e-10, rtol=1e-12)
    assert direct.status == 0 and iterative.status == 0, iterative.message
    assert rel(iterative.u, direct.u) <= AGREE
    assert rel(iterative.lam_n, direct.lam_n) <= AGREE
    if g is not None:       # partial slip: 17 stuck, 4 slipping nodes
        assert rel(iterative.lam_t, direct.lam_t) <= AGREE
        assert np.array_equal(iterative.active, direct.active) and (direct.active == cs.SLIP).sum() >= 2


def test_rows_with_no_unknown_of_their_own_are_refused_not_solved():
    """Two contact nodes on the same pair of DOFs (a row repeated): neither has an unknown of
    its own to eliminate; the iterative method says so (status OTHER_FAILURE, no answer)."""
    P = two_blocks(10)
    Bn, Bt = (sp.vstack([B, B[:1]]).tocsr() for B in (P["Bn"], P["Bt"]))
    res = solve_contact_iterative(P["K"], P["f"], Bn, Bt, np.r_[P["d"], 0.0], np.r_[P["w"], P["w"][0]],
                                  tol=1e-10, rtol=1e-12)
    assert res.status == Status.OTHER_FAILURE and res.u is None
    assert "no unknown of its own" in res.message


def test_the_3d_block_patch_agrees_with_the_direct_method():
    """Node-to-node, frictionless, the block floating along z and held by the contact."""
    assert_agree(*both(VALIDATION / "block-on-block-3d.yaml"))


def test_the_3d_tresca_shear_patch_agrees_with_the_direct_method():
    """Every node slipping on its disc: the linearised disc projection (the springs across the slip)."""
    M, direct, iterative = both(VALIDATION / "tresca-shear-patch-3d.yaml")
    assert_agree(M, direct, iterative)
    assert (iterative.active == cs.SLIP).all()


def test_the_coulomb_fixed_point_settles_at_the_default_tolerances():
    """The 3D shear patch with Coulomb friction, every node slipping on its disc, at the study
    defaults (contact, fixed point and Krylov tolerances 1e-8). Steps solved for u itself carried
    an error of 1e-8 ‖u‖ however small the change, and the fixed point stalled at ‖Δp‖ ~ 5e-8 ‖p‖
    (FIXED_POINT_NOT_CONVERGED); solved for the correction, it settles. Agreement to
    1e-6: both answers are the fixed point's to 1e-8, whose contraction (Δp falls 25× a step)
    leaves them within a few 1e-8 of it."""
    d = shear_patch(coefficient=0.3)
    d["uncertain"] = {"contacts.interface.friction.coefficient": [0.25, 0.35]}
    M, direct, iterative = both(d, tol=1e-8, rtol=1e-8, tol_fp=1e-8)
    assert direct.status == 0 and iterative.status == 0, iterative.message
    assert (iterative.active == cs.SLIP).all() and iterative.fixed_point_iterations >= 5
    assert rel(iterative.u, direct.u) <= 1e-6
    assert rel(iterative.lam_n, direct.lam_n) <= 1e-6 and rel(iterative.lam_t, direct.lam_t) <= 1e-6


@pytest.mark.slow
def test_a_3d_dual_mortar_patch_agrees_with_the_direct_method():
    assert_agree(*both(VALIDATION / "mortar-patch-3d.yaml"))


@pytest.mark.slow
def test_the_2d_tunnel_agrees_with_the_direct_method():
    """Tresca with open, stuck and slipping fault nodes; fault nodes on rollers on both sides
    (tied rows: a tangent dependent on its normal carries no multiplier of its own)."""
    assert_agree(*both(ROOT / "studies" / "tunnel-fault.yaml"))


def glued_contact() -> dict:
    """A pad pressed on a block glued (nonmatching, mortar) on a base: glue eliminated in K, mortar contact."""
    d = stack(0.25, 0.125)
    sc = d["scene"]
    sc["bodies"]["pad"] = {"regions": [{"material": "soft", "shape": {"box": [0, 0, 0.25, 1, 1, 0.5]}}],
                           "mesh": {"size": 0.25}}
    sc["boundaries"].update(top=plane([0, 0, 0.5], [0, 0, 1]), block_top=plane([0, 0, 0.25], [0, 0, 1], "block"),
                            pad_bottom=plane([0, 0, 0.25], [0, 0, 1], "pad"))
    sc["contacts"] = {"c": {"slave": "pad_bottom", "master": "block_top"}}
    return d


def test_a_glued_stack_under_a_mortar_contact_agrees_with_the_direct_method():
    M, direct, iterative = both(glued_contact())
    assert len(M.glue) == 1 and M.zone.discretization == ["mortar"]
    assert_agree(M, direct, iterative)


@pytest.mark.parametrize("friction", [{"slip_limit": 3.0e5}, {"coefficient": 0.3}], ids=["tresca", "coulomb"])
def test_a_block_held_only_by_contact_and_friction_agrees_with_the_direct_method(friction):
    """All six rigid motions of the block free (R given): the glued start holds them, and the
    stuck nodes keep holding them; partial slip on discs; Coulomb: the fixed point over Tresca."""
    M, direct, iterative = both(floating(friction))
    assert [r.shape[1] for _, r in M.floating] == [6]
    assert_agree(M, direct, iterative)
    assert (iterative.active == cs.SLIP).any() and (iterative.active == cs.STICK).any()
    if "coefficient" in friction:
        assert iterative.fixed_point_iterations >= 2


def test_a_3d_tunnel_slice_on_rollers_agrees_with_the_direct_method():
    """Tresca on a fault whose nodes are on rollers front and back: one tangent of such a node is
    held by the supports (a row of round-off), the other slips or sticks alone; a node's state
    and its slip force are those of its acting tangent (the first tangent held: it cycled)."""
    M, direct, iterative = both(tunnel_fault_3d())
    assert_agree(M, direct, iterative)
    assert np.array_equal(iterative.active, direct.active)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["hertz-3d.yaml", "hertz-mortar.yaml"])
def test_hertz_3d_and_2d_mortar_agree_with_the_direct_method(name):
    """3D Hertz (dual mortar, 274 rows, 18 Newton steps from the glued start) and 2D Hertz by mortar."""
    assert_agree(*both(VALIDATION / name))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["tunnel-fault-3d.yaml", "tunnel-fault-oblique-3d.yaml"])
def test_the_shipped_3d_tunnels_agree_with_the_direct_method(name):
    """Tresca on the 3D fault (529 nodes: open, stuck, slipping on discs; rollers front and back)."""
    assert_agree(*both(ROOT / "studies" / name))


def test_the_study_runs_with_method_iterative_and_reports_the_monolithic_answer():
    path = VALIDATION / "tresca-shear-patch-3d.yaml"
    results = []
    for method in ("monolithic", "iterative"):
        ev = Evaluator(load_study(study(path, method)))
        results.append(ev.evaluate(ev.study.nominal()))
    assert results[1].status == 0, results[1].message
    assert results[1].phi.keys() == results[0].phi.keys()
    for name, value in results[0].phi.items():
        np.testing.assert_allclose(results[1].phi[name], value, rtol=AGREE)
    assert "iterative" in results[1].message and "CG iterations" in results[1].message


def test_other_data_start_from_the_nominal_answer_and_gradients_are_those_of_the_direct_method():
    """A data set other than the nominal one starts from the anchor (the nominal answer, solved
    cold once) as the monolithic method does, and needs fewer Newton steps and CG iterations than
    from the glued start (measured 2 steps and 28 iterations against 5 and 51); the gradient solve is the iterative one too (its adjoint by
    CG on the final active set, `IterativeAdjoint`: no polish by monolithic)."""
    path = VALIDATION / "tresca-shear-patch-3d.yaml"
    x = [3.2e5, 1.1e-3]
    ref = Evaluator(load_study(study(path, "monolithic")))
    ev = Evaluator(load_study(study(path, "iterative")))
    warm, direct = ev.evaluate(x, gradients=False), ref.evaluate(x, gradients=True)
    M, c = ev.model, ev.map.coefficients(x)
    _, Kr, rhs, u0 = M.reduced_system(c, None)
    cold = solve_contact_iterative(Kr, rhs, M.Bn_r, M.Bt_r, M.zone.gap - M.zone.Bn @ u0, M.zone.weight, g=c.slip,
                                   R=M.R_r, tol=1e-8, rtol=1e-8, near_nullspace=M.near_nullspace)
    assert M._cache.anchor is not None and cold.status == 0
    assert warm.state.raw.iterations < cold.iterations and warm.state.raw.krylov_iterations < cold.krylov_iterations
    for name, value in direct.phi.items():
        assert warm.phi[name] == pytest.approx(value, rel=AGREE)
    adjoint = ev.evaluate(x, gradients=True)
    assert "iterative" in adjoint.message and "polished" not in adjoint.message, adjoint.message
    for name, g in direct.grad.items():     # a zero derivative (pressure by the shear) is round-off of |Φ| / |x|
        assert np.all(np.abs(adjoint.grad[name] - g) <= AGREE * (np.abs(g) + abs(direct.phi[name]) / np.abs(x)))


def test_without_petsc_the_study_is_refused_with_the_way_out(monkeypatch):
    monkeypatch.setitem(sys.modules, "dolfinx_solver", None)       # import dolfinx_solver raises ImportError
    with pytest.raises(StudyError, match="dolfinx-solver-real") as info:
        Evaluator(load_study(study(VALIDATION / "block-on-block-3d.yaml", "iterative")))
    assert info.value.path == "solver.method"


def test_a_warm_start_from_its_own_answer_ends_at_once_on_discs():
    """Started from its own answer (the anchor of every other data set), the method takes it up,
    displacement and multipliers: one Newton step. From u = 0 with the warm multipliers every
    slipping node sat on the rim of its disc, where the linearised projection degenerates, and CG
    failed (2000 iterations) on the shipped 3D tunnel's second solve."""
    M, direct, cold = both(VALIDATION / "tresca-shear-patch-3d.yaml")
    c = M.nominal
    _, Kr, rhs, u0 = M.reduced_system(c, None)
    z = M.zone
    warm = solve_contact_iterative(Kr, rhs, M.Bn_r, M.Bt_r, z.gap - z.Bn @ u0, z.weight, g=c.slip, tol=1e-10,
                                   near_nullspace=M.near_nullspace, rtol=1e-8, warm=cold)
    assert warm.status == 0, warm.message
    assert warm.iterations <= 1 and rel(warm.u, direct.u) <= AGREE


def test_the_results_file_names_the_iterative_solver(tmp_path):
    """The results file's `solver` says what solved the contact (PETSc's CG + GAMG), not only the
    direct backend the heat step would use ("iterative (pardiso)" before)."""
    import xarray as xr

    from wcs.cli import main
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(study(VALIDATION / "tresca-shear-patch-3d.yaml", "iterative")), encoding="utf-8")
    assert main(["solve", str(path), "-o", str(tmp_path / "out.nc"), "-q"]) == 0
    with xr.open_dataset(tmp_path / "out.nc") as ds:
        assert ds.attrs["solver"].startswith("iterative (contact: PETSc CG + GAMG")


def test_a_step_that_leaves_a_floating_pad_free_is_taken_in_the_complement_of_its_free_motions():
    """The floating Tresca pad started from a warm active set with every node open (its tangents
    stuck): the first step's rows hold only the pad's slide, its lift and tilt are free. The step is
    taken in the complement of the free rigid motions (the unbalanced load projected out, the free
    amplitude kept) and Newton goes on to the direct answer (refused as a singular step before)."""
    M, direct, _ = both(VALIDATION / "tresca-pad.yaml")
    c, z = M.nominal, M.zone
    _, Kr, rhs, u0 = M.reduced_system(c, None)
    m = z.weight.size
    warm = cs.ContactResult(None, np.zeros(m), np.zeros(m), Status.SOLVED, "", active=np.full(m, cs.OPEN))
    res = solve_contact_iterative(Kr, rhs, M.Bn_r, M.Bt_r, z.gap - z.Bn @ u0, z.weight, g=c.slip, R=M.R_r, tol=1e-10,
                                  near_nullspace=M.near_nullspace, rtol=1e-12, warm=warm)
    assert res.status == 0, res.message
    assert rel(res.u, direct.u) <= AGREE
    assert rel(res.lam_n, direct.lam_n) <= AGREE and rel(res.lam_t, direct.lam_t) <= AGREE


def test_an_answer_that_leaves_a_floating_pad_free_is_not_unique_as_by_the_direct_method():
    """A frictionless pad pressed straight down: its slide moves no closed node. Every Newton step
    leaves it free (taken in its complement); the answer is NOT_UNIQUE with the free motion, as
    the direct method says (the iterative method refused the first step before)."""
    d = yaml.safe_load((VALIDATION / "tresca-pad.yaml").read_text())
    del d["scene"]["contacts"]["interface"]["friction"]
    d["scene"]["loads"]["pad_top"]["traction"][0] = 0.0
    d["uncertain"] = {"loads.pad_top.traction.1": [-2e6, -0.5e6]}
    _, direct, iterative = both(d)
    assert direct.status == iterative.status == Status.NOT_UNIQUE, iterative.message
    assert iterative.u is None and np.allclose(iterative.alpha, direct.alpha)


def test_a_newton_step_without_disc_springs_works_on_k_itself_not_a_copy(monkeypatch):
    """Frictionless 3D: no tangent slips on a disc, so every step's matrix K + Σ springs is K
    itself (the stepper built K + 0, a second copy of K — 1 GB at 1e6 unknowns — each step)."""
    from wcs.contact import iterative
    seen, made = [], iterative._eliminated
    monkeypatch.setattr(iterative, "_eliminated", lambda Z, Kt, K, P, *a: seen.append(Kt is K) or made(Z, Kt, K, P, *a))
    M = Evaluator(load_study(study(VALIDATION / "block-on-block-3d.yaml"))).model
    c = M.nominal
    _, Kr, rhs, u0 = M.reduced_system(c, None)
    z = M.zone
    res = solve_contact_iterative(Kr, rhs, M.Bn_r, M.Bt_r, z.gap - z.Bn @ u0, z.weight, g=c.slip, R=M.R_r,
                                  tol=1e-10, near_nullspace=M.near_nullspace, rtol=1e-12)
    assert res.status == 0, res.message
    assert len(seen) == res.iterations >= 1 and all(seen)


def test_petsc_holds_a_steps_matrix_in_its_own_arrays_not_a_copy():
    """On one process the PETSc matrix of a step is the rows' CSR arrays themselves (a copy beside
    them doubled the largest matrix of the solve): a change to them is seen by PETSc."""
    from wcs import linalg
    PETSc = linalg.petsc()
    from wcs.contact.distributed import Layout, RowBlocks
    A = (sp.random(40, 40, density=0.1, random_state=1, format="csr") + 4 * sp.eye(40)).tocsr()
    A = (A + A.T).tocsr()
    A.sort_indices()
    M = Layout(None, 40, PETSc).matrix(RowBlocks(40, lambda lo, hi: A), PETSc)     # one rank: all rows
    i, j = 3, A.indices[A.indptr[3]]
    assert M.getValue(i, j) == A[i, j]
    A.data[A.indptr[3]] = 123.0
    assert M.getValue(i, j) == 123.0
    M.destroy()


def test_a_nodes_one_active_row_pivots_on_its_largest_entry_without_a_qr(monkeypatch):
    """A node with one active row (a frictionless contact node: its normal row) pivots on the
    unknown of its largest entry, the first of equal ones, as the two pivoted QRs of the general
    case choose, with the same bits; and no QR is taken for it (11,820 nodes at the patch's face
    0.01: the QRs were the largest part of the Newton steps after CG and GAMG)."""
    import scipy.linalg as sla
    from wcs.contact.iterative import DEPENDENT, _Rows
    rng = np.random.default_rng(3)
    m, k = 40, 2
    B = rng.standard_normal((m, 1 + k, 3))
    B[::4, :, 1] = -B[::4, :, 0]                         # ties: the first of equal magnitudes
    B[1::4, 0, 0] = 0.0
    rows = np.repeat(np.arange(m)[None, :] + m * np.arange(1 + k)[:, None], 3, axis=1).ravel()
    cols = np.tile(3 * np.repeat(np.arange(m), 3) + np.tile(np.arange(3), m), 1 + k)
    C = sp.csr_matrix((B.transpose(1, 0, 2).ravel(), (rows, cols)), shape=((1 + k) * m, 3 * m))

    def by_qr(b, own, node_rows):                        # the general case's two pivoted QRs
        _, r, piv = sla.qr(b.T, mode="economic", pivoting=True)
        assert abs(r[0, 0]) > DEPENDENT * abs(r[0, 0])
        chosen = np.sort(sla.qr(b, mode="economic", pivoting=True)[2][:1])
        return node_rows, own[chosen], np.linalg.inv(b[:, chosen])
    expected = {(i, j): by_qr(B[i, j][None], 3 * i + np.arange(3), np.array([i + m * j]))
                for i in range(m) for j in range(1 + k)}
    monkeypatch.setattr(sla, "qr", lambda *a, **kw: pytest.fail("a QR for one active row"))
    R = _Rows(C, m, k)
    for (i, j), want in expected.items():
        got = R.pivots(i, np.arange(1 + k) == j)
        assert all(np.array_equal(g, w) for g, w in zip(got, want)), (i, j)


@pytest.mark.parametrize("ranks", [1, 3])
def test_the_eliminated_operator_is_z_transpose_kt_z_built_without_products_of_k_size(ranks):
    """`_eliminated` (Kt without the pivots' rows and columns plus a correction near them,
    spliced row by row) equals the product Zᵀ Kt Z + diag(K)_P it stands for, entry by entry
    to round-off, on each rank's rows: a 3D elastic block (K from scikit-fem), contact-like
    rows of four unknowns each (their pivots' inverse blocks dense), disc springs in Kt, and
    chunks of a few rows so that the copy crosses its chunk borders."""
    import skfem as fem
    from skfem.models.elasticity import linear_elasticity
    from wcs.contact.iterative import _basis, _block_diagonal, _eliminated, _spliced
    mesh = fem.MeshTet.init_tensor(*[np.linspace(0.0, 1.0, 5)] * 3)
    basis = fem.Basis(mesh, fem.ElementVector(fem.ElementTetP1()))
    K = fem.asm(linear_elasticity(1.0, 0.7), basis).tocsr()
    n = K.shape[0]
    rng = np.random.default_rng(3)
    top = basis.get_dofs(lambda x: np.isclose(x[2], 1.0)).nodal["u^3"]
    far = basis.get_dofs(lambda x: np.isclose(x[2], 0.0)).nodal["u^1"]
    rows = len(top)
    cols = np.column_stack([top, far[rng.integers(0, len(far), rows)], rng.integers(0, n, (rows, 2))])
    C = sp.csr_matrix((rng.uniform(0.5, 1.5, cols.size), (np.repeat(np.arange(rows), 4), cols.ravel())), shape=(rows, n))
    P = top                                                     # each row's pivot: its top dof
    Binv = _block_diagonal([np.array([[1.0 / C[i, P[i]]]]) for i in range(rows)])
    Z, _ = _basis(C, np.arange(rows), P, Binv, np.zeros(rows))
    Q = sp.csr_matrix(rng.uniform(-1, 1, (6, n)) * (rng.uniform(0, 1, (6, n)) < 0.02))
    Kt = (K + Q.T @ sp.diags(rng.uniform(1.0, 2.0, 6)) @ Q).tocsr()
    full = (Z.T @ Kt @ Z + sp.csr_matrix((K.diagonal()[P], (P, P)), shape=(n, n))).tocsr()
    edges = np.linspace(0, n, ranks + 1).astype(int)
    for lo, hi in zip(edges[:-1], edges[1:]):
        A = _eliminated(Z, Kt, K, P, lo, hi)
        assert A.shape == (hi - lo, n) and A.has_sorted_indices
        assert abs(A - full[lo:hi]).max() <= 1e-13 * abs(full).max()
        assert np.array_equal(np.diff(A.indptr)[np.isin(np.arange(lo, hi), P)], np.ones(np.sum((P >= lo) & (P < hi))))
    pivot = np.zeros(n, dtype=bool)
    pivot[P] = True
    touched = np.array([0, 7, n - 1])
    T = sp.csr_matrix(np.eye(n)[touched] * 5.0)
    A = _spliced(Kt, 0, n, pivot, touched, T, chunk=5)          # the copy across chunks of 5 rows
    kept = sp.diags((~pivot).astype(float)) @ Kt @ sp.diags((~pivot).astype(float))
    kept = sp.lil_matrix(kept)
    kept[touched] = T.toarray()
    assert abs(A - kept.tocsr()).max() == 0.0


def test_the_node_blocks_operator_is_the_eliminated_one_at_its_nodes_places():
    """With `NodeBlocks` the step's operator is the reduced one with each unknown's row and
    column moved to its place (home) in the mesh's node-major numbering and the scale alone on
    the places of no unknown, on each rank's rows (whole nodes); the 3D patch's model places its
    unknowns in increasing order, a node's at its own three places."""
    from skfem.models.elasticity import linear_elasticity
    import skfem as fem
    from wcs.contact.iterative import NodeBlocks, _basis, _block_diagonal, _eliminated, node_blocks
    mesh = fem.MeshTet.init_tensor(*[np.linspace(0.0, 1.0, 4)] * 3)
    basis = fem.Basis(mesh, fem.ElementVector(fem.ElementTetP1()))
    full = fem.asm(linear_elasticity(1.0, 0.7), basis).tocsr()
    rng = np.random.default_rng(5)
    home = np.sort(rng.choice(full.shape[0], full.shape[0] - 7, replace=False))       # 7 components dropped
    K = full[home][:, home].tocsr()
    n = K.shape[0]
    top = np.flatnonzero(np.isin(home, basis.get_dofs(lambda x: np.isclose(x[2], 1.0)).nodal["u^3"]))
    C = sp.csr_matrix((np.ones(len(top)), (np.arange(len(top)), top)), shape=(len(top), n)) + \
        sp.csr_matrix((np.full(len(top), 0.5), (np.arange(len(top)), (top + 5) % n)), shape=(len(top), n))
    P = top
    Binv = _block_diagonal([np.array([[1.0 / C[i, P[i]]]]) for i in range(len(top))])
    Z, _ = _basis(C.tocsr(), np.arange(len(top)), P, Binv, np.zeros(len(top)))
    blocks = NodeBlocks(home, full.shape[0], 3, 2.5)
    A = _eliminated(Z, K, K, P)
    E = sp.csr_matrix((np.ones(n), (home, np.arange(n))), shape=(blocks.size, n))
    pad = np.ones(blocks.size)
    pad[home] = 0.0
    want = (E @ A @ E.T + sp.diags(2.5 * pad)).tocsr()
    for lo, hi in ((0, blocks.size), (0, 27), (27, blocks.size)):       # whole nodes: 9 and the rest
        got = _eliminated(Z, K, K, P, lo, hi, blocks)
        assert got.shape == (hi - lo, blocks.size) and got.has_sorted_indices
        assert abs(got - want[lo:hi]).max() <= 1e-14 * abs(want).max()
    np.testing.assert_array_equal(blocks.embed(np.arange(n, dtype=float))[home], np.arange(n))
    model = Evaluator(load_study(study(VALIDATION / "block-on-block-3d.yaml", "iterative"))).model
    b = node_blocks(model, model.stiffness(model.nominal))
    T = model.elim.T.tocsc()
    assert b.size == 3 * model.nnodes and np.all(np.diff(b.home) > 0)
    assert np.all(b.home // 3 == np.asarray(abs(T).argmax(axis=0)).ravel() // 3)
