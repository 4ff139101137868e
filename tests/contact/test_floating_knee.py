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
    tests/contact/test_iterative_adjoint.py); measured ≤ 2.4e-8. Contact tolerance 1e-10: at its
    1e-13 the Coulomb fixed point did not settle in 100 Tresca problems."""
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
