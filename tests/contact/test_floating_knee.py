"""The knee's femur, held only by its two condyle contacts under Coulomb friction (a floating body).

In 2D its sideways position is held by the few nodes that stick at the bottom of the dishes
(the answer: 2 of 140 contact nodes). Full semismooth Newton steps cycled there: a step with
every closed node slipping puts the femur's sideways balance on the normals' small lateral
components alone and slides it by ±1–2 mm (10⁴ times the answer's 2e-7 m), which turns every
slip the other way, period 2. From a repeated pattern on, the steps are shortened (Armijo) in
both methods, and they end at the answer without the direct method's dual QP.
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
    return Evaluator(load_study(study(KNEE)))


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
