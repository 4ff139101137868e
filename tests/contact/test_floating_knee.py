"""The knee's femur, held only by its two condyle contacts under Coulomb friction (a floating body).

In 2D its sideways position is held by the few nodes that stick at the bottom of the dishes
(the answer: 2 of 140 contact nodes). Full semismooth Newton steps cycled there: a step with
every closed node slipping puts the femur's sideways balance on the normals' small lateral
components alone and slides it by ±1–2 mm (10⁴ times the answer's 2e-7 m), which turns every
slip the other way, period 2. From a repeated pattern on, the steps are shortened (Armijo) in
both methods, and the iterative method's steps on a floating body in 2D always are (solved to
its final tolerance: its loose steps wandered over ever new patterns); both end at the answer,
the direct method without its dual QP.
"""
from pathlib import Path

import numpy as np
import pytest

from tests.contact.test_iterative import AGREE, rel, study
from wcs import load_study
from wcs.contact import solver as cs
from wcs.contact.iterative import solve_contact_iterative
from wcs.model.evaluation import Evaluator
from wcs.status import Status

ROOT = Path(__file__).resolve().parents[2]
KNEE = ROOT / "studies" / "knee-replacement.yaml"


def problem(ev, x):
    """The contact problem of data set x (as `tests.contact.test_iterative.both` builds it)."""
    M = ev.model
    c = ev.map.coefficients(ev.study.data_set(x)[0])
    _, Kr, rhs, u0 = M.reduced_system(c, None)
    z = M.zone
    return dict(K=Kr, f=rhs, Bn=M.Bn_r, Bt=M.Bt_r, d=z.gap - z.Bn @ u0, w=z.weight, g=c.slip,
                F=c.coulomb if c.coulomb.any() else None, R=M.R_r)


def corners(study_, n):
    """n corners of the box, alternating lower and upper ends by parameter (reproducible)."""
    lo = np.array([e.lower for e in study_.uncertain])
    hi = np.array([e.upper for e in study_.uncertain])
    flips = np.random.default_rng(7).integers(0, 2, (n, len(lo))).astype(bool)
    return [np.where(f, hi, lo) for f in flips]


@pytest.fixture(scope="module")
def knee2d():
    return Evaluator(load_study(study(KNEE), base_dir=KNEE.parent))


def test_the_direct_method_solves_the_2d_knee_without_its_dual_qp(knee2d, monkeypatch):
    """Nominal and four corners of the box, each cold (from the glued start): every Tresca
    problem of the Coulomb fixed point ends by Newton, and the answer passes the certificate
    (`conditions_violated`: non-penetration, λn ≥ 0, |λt| ≤ F λn to 1e-6) at a settled fixed point."""
    def refused(*args, **kw):
        raise AssertionError("the dual QP was called")
    monkeypatch.setattr(cs, "_dual_qp", refused)
    ev = knee2d
    for x in [ev.study.nominal()] + corners(ev.study, 4):
        r = cs.solve_contact(**problem(ev, x), tol=1e-10)
        assert r.status == Status.SOLVED, r.message
        assert np.any(r.active == cs.STICK)         # what holds the femur sideways


def agree(M, direct, iterative):
    """Displacements and contact forces (normal, tangential) of the two methods to `AGREE`."""
    assert direct.status == Status.SOLVED, direct.message
    assert iterative.status == Status.SOLVED, iterative.message
    states = [M.contact_state(r.lam_n, r.lam_t, M.elim.T @ r.u, r.active) for r in (direct, iterative)]
    assert rel(iterative.u, direct.u) <= AGREE
    assert rel(states[1].force_n, states[0].force_n) <= AGREE
    assert rel(states[1].force_t, states[0].force_t) <= AGREE


def both_at(ev, x):
    """The direct and the iterative answer of data set x (contact and Krylov tolerances 1e-10,
    1e-12: both answers within ~1e-10 of the exact one, three orders below `AGREE`)."""
    P = problem(ev, x)
    direct = cs.solve_contact(**P, tol=1e-10)
    iterative = solve_contact_iterative(**P, tol=1e-10, rtol=1e-12, near_nullspace=ev.model.near_nullspace)
    return direct, iterative


@pytest.mark.slow
def test_the_iterative_method_agrees_on_the_2d_knee(knee2d):
    """The nominal data: the iterative active set on the floating femur (exact steps, shortened)
    ends at the direct method's answer (measured 4e-11 in u, 2e-10 in the tangential forces); its
    loose full steps wandered to the budget (121 Newton steps, status 1). (At the box's corner
    `corners(study, 1)` it still ends at the budget: open.)"""
    agree(knee2d.model, *both_at(knee2d, knee2d.study.nominal()))


KNEE3D = ROOT / "studies" / "knee-replacement-3d.yaml"
# the 3D knee with half the shipped mesh sizes' resolution (4 → 8 mm, 1.5 → 3 mm in the condyles'
# spheres): 1.3e4 unknowns and 200 contact nodes against the shipped mesh's 7.3e4 and 642
COARSE = {"size": 0.008, "refine": [{"ball": {"center": [-0.019, 0.0, 0.02], "radius": 0.021}, "size": 0.003},
                                    {"ball": {"center": [0.019, 0.0, 0.02], "radius": 0.021}, "size": 0.003}]}


@pytest.mark.slow
def test_the_iterative_method_agrees_on_the_3d_knee():
    """The floating femur under Coulomb friction on discs (F = 0.05), on the coarse mesh: nominal
    and a corner of the box (a tilted load, friction at its ends); the nominal measured 3e-13 in u
    and 8e-13 in the forces, 15 Newton steps and 5691 CG iterations."""
    ev = Evaluator(load_study(study(KNEE3D, **COARSE), base_dir=KNEE3D.parent))
    for x in [ev.study.nominal()] + corners(ev.study, 1):
        agree(ev.model, *both_at(ev, x))



@pytest.mark.slow
def test_the_3d_knee_iterative_gradients_are_the_monolithic_ones():
    """The adjoint gradients of the coarse 3D knee's criterion by the iterative method (CG on the
    final active set, the Coulomb slipping rows by GMRES) against the monolithic adjoint's, per
    parameter to 1e-6 relative or below the resolution floor 1e-9 |Φ| / range (the rule of
    tests/contact/test_iterative_adjoint.py); measured ≤ 2.4e-8. Contact tolerance 1e-10: at 1e-13 the
    iterative method's Coulomb fixed point does not settle (its λ, a residual f − K u, carries round-off
    ~1e-12 of itself: `test_the_3d_knee_gradients_against_finite_differences`)."""
    evs = {}
    for method in ("monolithic", "iterative"):
        doc = study(KNEE3D, method, **COARSE)
        doc["solver"]["tolerance"] = 1e-10
        if method == "iterative":
            doc["solver"]["iterative"] = {"tolerance": 1e-12}
        s = load_study(doc, base_dir=KNEE3D.parent)
        evs[method] = s.evaluate(s.nominal(), gradients=True)
        assert evs[method].status == 0, evs[method].message
    span = s.parameters.upper - s.parameters.lower
    for name, g in evs["monolithic"].grad.items():
        floor = 1e-9 * abs(evs["monolithic"].phi[name]) / span
        assert np.all(np.abs(evs["iterative"].grad[name] - g) <= 1e-6 * np.maximum(np.abs(g), floor)), name


# Central differences of the coarse 3D knee's criterion (`test_the_3d_knee_gradients_against_finite_differences`)
FD_TOL = 2e-14     # contact and fixed-point tolerance of the differences' direct solves
NOISE = 1e-14      # bound on Φ's relative change between two solves of one data set (asserted at each point)
STEP = 1e-3        # h_k = STEP × the range of x_k
REL = 1e-5         # the differences' own error bound, relative, and the agreement asserted beyond it
# a point of the box away from the nominal's symmetry (t_x ≠ 0: one condyle carries more), as fractions of the ranges
INTERIOR = (0.25, 0.7, 0.6, 0.35, 0.3, 0.75, 0.3, 0.65, 0.4)


def knee3d(method, tol):
    doc = study(KNEE3D, method, **COARSE)
    doc["solver"]["tolerance"] = tol
    if method == "iterative":
        doc["solver"]["iterative"] = {"tolerance": 1e-12}
    return load_study(doc, base_dir=KNEE3D.parent)


def pattern(e):
    """What a derivative needs unchanged: every node's state (open, stick, slip) and the maximising region."""
    crit = e.evaluator.criteria[0]
    return e.state.raw.active.tobytes(), int(np.argmax(crit.region_values(e.evaluator.model, e.state)))


def cold_phi(s, x, tol):
    """Φ of data set x solved again from the glued start (not the nominal's answer) to `tol`."""
    ev = s._evaluator
    M, crit = ev.model, ev.criteria[0]
    r = cs.solve_contact(**problem(ev, x), tol=tol, tol_fp=tol, max_fp_iter=100)
    assert r.status == Status.SOLVED, r.message
    force_n = M.contact_state(r.lam_n, r.lam_t, M.elim.T @ r.u, r.active).force_n
    return max(f @ force_n for f in crit.functionals)


def differences(s, x, e):
    """(D, E): central differences D_k = (Φ(x + h e_k) − Φ(x − h e_k)) / 2h and a bound E_k of their
    own error — the truncation h²Φ'''/6 estimated from the step 2h, |D(2h) − D(h)| / 3, plus the
    noise NOISE |Φ| / h — where every node's state and the maximising region are those at x on the
    whole stencil x ± h e_k, x ± 2h e_k (else Φ is not differentiable within it: the test fails)."""
    lo, hi = s.parameters.lower, s.parameters.upper
    name = "insert_pressure"
    phi, at_x = e.phi[name], pattern(e)
    D, E = np.zeros(len(x)), np.zeros(len(x))
    for k, path in enumerate(s.parameters.names):
        h = STEP * (hi[k] - lo[k])
        v = {}
        for j in (-2, -1, 1, 2):
            xj = x.copy()
            xj[k] += j * h
            ej = s.evaluate(xj)
            assert ej.status == Status.SOLVED, ej.message
            assert pattern(ej) == at_x, f"{path}: the active set or the maximising region changes within {j} h"
            v[j] = ej.phi[name]
        D[k] = (v[1] - v[-1]) / (2 * h)
        E[k] = abs((v[2] - v[-2]) / (4 * h) - D[k]) / 3 + NOISE * abs(phi) / h
    return D, E


@pytest.mark.slow
def test_the_3d_knee_gradients_against_finite_differences():
    """Both adjoints of the coarse 3D knee (the floating femur under Coulomb friction, every
    contact node closed and slipping at the nominal data) against central differences in all nine
    parameters, at the nominal data and at an interior point of the box.

    The differences come from the direct method at FD_TOL = 2e-14: its Coulomb fixed point settles
    there (10–11 Tresca problems), and Φ of one data set solved from the nominal answer and again
    from the glued start at half the tolerance differs by ≤ NOISE = 1e-14 of itself (measured
    3e-15; asserted at both points). The iterative method cannot serve for the differences: it
    gets λ as the residual f − K u on the pivots, where |K||u| is ~7e3 times the contact forces
    (the stiff CoCrMo condyles), so λ carries round-off ~1e-12 of itself and its fixed point stalls
    at ‖Δp‖ ≈ 1.2e-12 ‖p‖ (at 1e-13 it ran out of its 100 Tresca problems); its adjoint is taken at
    its own answer to 1e-11. Steps h = 1e-3 of each range: the differences' error bound (truncation
    from the step 2h, noise NOISE |Φ| / h) is asserted below REL = 1e-5 of each derivative — also
    for the moduli of the stiff parts, whose derivatives move Φ by only ~1e-5 of itself over their
    range — and each adjoint must agree with them to REL beyond that bound. Where the stencil
    reaches an active-set change or the other condyle's pressure (t_x ± 2 % of its range from the
    nominal does), Φ is not differentiable there and the test fails rather than compares."""
    direct, iterative = knee3d("monolithic", FD_TOL), knee3d("iterative", 1e-11)
    lo, hi = direct.parameters.lower, direct.parameters.upper
    for x in (direct.nominal(), lo + np.array(INTERIOR) * (hi - lo)):
        e = direct.evaluate(x, gradients=True)
        assert e.status == Status.SOLVED and not e.nonsmooth, e.message
        phi = e.phi["insert_pressure"]
        assert abs(cold_phi(direct, x, FD_TOL / 2) - phi) <= NOISE * abs(phi)
        D, E = differences(direct, x, e)
        assert np.all(E <= REL * np.abs(D)), E / np.abs(D)
        it = iterative.evaluate(x, gradients=True)
        assert it.status == Status.SOLVED and "iterative" in it.message, it.message
        for g in (e.grad["insert_pressure"], it.grad["insert_pressure"]):
            assert np.all(np.abs(g - D) <= REL * np.abs(D) + E), (g - D) / np.abs(D)
