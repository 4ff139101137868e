"""Friction laws (`wcs.contact.laws`): the bounds of the Tresca problems a method solves, and
Coulomb's one fixed point over them, driven here by a stand-in Tresca solve with a known
answer (λn = a + b·gw, a contraction of the fixed point for F b < 1) and by both contact
solvers on a small two-block problem (tests/contact/test_solver.py)."""
import numpy as np
import pytest
from tests.contact.test_solver import args, two_blocks

from wcs.contact import solver as cs
from wcs.contact.laws import Coulomb, Tresca, frictionless, law_of
from wcs.contact.qp import solve_contact_qp
from wcs.status import Status


class Linear:
    """A Tresca solve whose normal forces are λn = a + b·gw; `fail_at`: the call that does not
    converge (1-based); `bounds`: the bounds it was asked for."""

    def __init__(self, a, b, steps=3, fail_at=None):
        self.a, self.b, self.steps, self.fail_at, self.bounds = a, b, steps, fail_at, []

    def __call__(self, gw):
        self.bounds.append(gw)
        ok = len(self.bounds) != self.fail_at
        return self.a + self.b * gw, ok, self.steps


def coulomb(m=3):
    return Coulomb(np.full(m, 0.1), np.full(m, 0.4), np.linspace(1.0, 2.0, m))


def test_coulomb_settles_at_the_fixed_point_of_its_bounds():
    """λn = 2 + 0.5 (0.1 + 0.4 λn) has the fixed point λn* = 2.05 / 0.8 = 2.5625 and the bounds
    g·w + F λn* = 1.125; the iteration contracts by F b = 0.2 a step, so ‖Δp‖ ≤ 1e-10 ‖p‖ leaves
    the last bounds within 0.2 · 1e-10 · (1 + 0.2 + …) of it: 1e-9 relative is a safe margin."""
    law, tresca = coulomb(), Linear(2.0, 0.5)
    gw0 = law.start(None, 10.0)
    assert np.array_equal(gw0, np.full(3, 10.1))                   # stuck: 10 above g·w
    out = law.drive(tresca, gw0, 1e-10, 50)
    assert out.ok and out.settled
    np.testing.assert_allclose(out.gw, 1.125, rtol=1e-9)
    assert out.fixed_point_iterations == len(tresca.bounds) - 1     # the first problem is no fixed-point step
    assert out.iterations == 3 * len(tresca.bounds)
    assert 10 <= out.fixed_point_iterations <= 20                   # 0.2^n ~ 1e-10: n ≈ 15
    np.testing.assert_array_equal(tresca.bounds[0], gw0)


def test_coulomb_starts_from_warm_pressures():
    law = coulomb()
    lam_n = np.array([1.0, 2.0, 3.0])
    np.testing.assert_array_equal(law.start(lam_n, np.inf), 0.1 + 0.4 * lam_n)
    assert np.all(law.start(None, np.inf) == np.inf)                # no warm start: all stick


def test_coulomb_stops_at_its_budget_and_at_a_failed_tresca_problem():
    out = coulomb().drive(Linear(2.0, 0.5), np.full(3, 10.1), 1e-10, 2)
    assert out.ok and not out.settled and out.fixed_point_iterations == 2
    tresca = Linear(2.0, 0.5, fail_at=2)
    out = coulomb().drive(tresca, np.full(3, 10.1), 1e-10, 50)
    assert not out.ok and not out.settled and out.fixed_point_iterations == 1 and len(tresca.bounds) == 2


def test_tresca_and_frictionless_solve_one_problem_at_fixed_bounds():
    for law, gw in ((Tresca(np.array([0.3, 0.6])), [0.3, 0.6]), (frictionless(2), [0.0, 0.0])):
        tresca = Linear(2.0, 0.5)
        gw0 = law.start(np.array([5.0, 5.0]), np.inf)               # the normal forces do not matter
        out = law.drive(tresca, gw0, 1e-10, 50)
        np.testing.assert_array_equal(out.gw, gw)
        assert out.ok and out.settled and out.iterations == 3 and out.fixed_point_iterations == 0
        assert len(tresca.bounds) == 1


def test_the_law_of_a_zone():
    w = np.array([1.0, 2.0])
    assert isinstance(law_of(w), Tresca) and np.array_equal(law_of(w).gw, [0.0, 0.0])
    assert isinstance(law_of(w, g=np.array([0.5, 0.5]), F=np.zeros(2)), Tresca)
    law = law_of(w, g=np.array([0.5, 0.5]), F=np.array([0.0, 0.3]))  # one Coulomb node: the zone's law
    assert isinstance(law, Coulomb) and np.array_equal(law.gw, [0.5, 1.0])


@pytest.mark.parametrize("solve", [cs.solve_contact, solve_contact_qp], ids=["newton", "qp"])
def test_both_solvers_end_on_coulomb_bounds(solve):
    """Either solver's Coulomb answer (the one fixed point of the laws) has slip bounds g·w + F λn
    of its own normal forces, to the fixed point's tolerance: ‖Δp‖ ≤ 1e-8 ‖p‖ on the last step,
    i.e. bounds within ~1e-8 of max F λn (2e-8 there: rounding of the solvers themselves)."""
    P = two_blocks(shear=0.01)
    m = len(P["w"])
    F = np.full(m, 0.3)
    r = solve(*args(P), F=F)
    assert r.status == Status.SOLVED and r.fixed_point_iterations >= 1
    lt = np.abs(r.lam_t)
    assert np.all(lt <= F * r.lam_n + 2e-8 * (F * r.lam_n).max())
    assert np.any(np.isclose(lt, F * r.lam_n, rtol=1e-6) & (r.lam_n > 0))   # some node slips at its bound
