"""A contact answer is checked on itself before it is reported (`conditions_violated`): the
semismooth Newton's convergence test is relative to its largest scaled residual, which a
numerically null row (W_ii ~ 1e-41, c = 1/W_ii ~ 1e40: a 3D fault node held by supports on
both sides, its normal left with round-off components) inflated until an all-open λ = 0
passed with 1.24 m of penetration on a 3D tunnel. Each contact condition is checked on the
answer against 1e-6 of its own scale."""
import numpy as np
import pytest

from wcs.contact.solver import CERTIFICATE, conditions_violated

U = np.array([1e-3, -2e-3, 5e-4])                       # the displacement scale: 2e-3 m


@pytest.mark.parametrize("gap_error, lam_n, lam_t, gw, k, words", [
    ([-1e-4, 0.0, 5e-9], [0.0, 2.0, 1.0], [0.5, -1.0, 0.2], [1.0, 1.0, 1.0], 1, "non-penetration"),
    ([-1e-4, 0.0, 0.0], [0.0, 2.0, -1e-5], [0.5, -1.0, 0.2], [1.0, 1.0, 1.0], 1, "λn ≥ 0"),
    ([-1e-4, 0.0, 0.0], [0.0, 2.0, 1.0], [0.5, -1.0, 1.01], [1.0, 1.0, 1.0], 1, "|λt| ≤ g w"),
    # discs (3D): node 0's tangent pair (0.8, 0.7) has norm 1.06 > g w = 1
    ([-1e-4, 0.0], [0.0, 2.0], [0.8, 0.1, 0.7, 0.1], [1.0, 1.0], 2, "|λt| ≤ g w"),
])
def test_an_answer_that_breaks_a_contact_condition_is_named(gap_error, lam_n, lam_t, gw, k, words):
    out = conditions_violated(U, np.array(gap_error), np.array(lam_n), np.array(lam_t), np.array(gw), k)
    assert words in out


def test_an_answer_within_round_off_of_every_condition_passes():
    scale_u, scale_l = 2e-3, 2.0
    tiny = 0.5 * CERTIFICATE
    out = conditions_violated(U, np.array([-1e-4, tiny * scale_u, 0.0]), np.array([0.0, 2.0, -tiny * scale_l]),
                              np.array([0.5, -1.0, 1.0 + tiny * scale_l]), np.array([1.0, 1.0, 1.0]))
    assert out == ""
    # and Coulomb's first pass: an infinite g w (all stuck) bounds nothing
    assert conditions_violated(U, np.array([-1e-4]), np.array([1.0]), np.array([3.0]), np.array([np.inf])) == ""
