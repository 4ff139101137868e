"""The reference answers of the impact benchmarks (issue 29): Hertz's quasi-static impact theory for
a sphere on a block (3D) and a cylinder on a block (2D, plane strain), `tests/reference_forms.py`;
each closed form (or quadrature) is checked against the impact ODE m δ̈ = −F(δ) integrated numerically."""
import numpy as np
import pytest

from scipy.optimize import brentq

from reference_forms import (boussinesq_compliance, contact_modulus, cylinder_approach, cylinder_force, cylinder_impact, hertz_sphere_force,
                             hertz_sphere_impact, impact_ode, line_law, sphere_on_block_force)

STEEL = (2.1e11, 0.3)
RHO = 7850.0


def test_impact_ode_of_a_linear_spring():
    """F = kδ: half a period of the oscillator, t_c = π √(m/k), and F_max = v √(m k)."""
    m, k, v = 2.0, 3.0e6, 1.5
    t_c, F_max, delta_max = impact_ode(m, v, lambda d: k * d, v * np.sqrt(m / k))
    assert t_c == pytest.approx(np.pi * np.sqrt(m / k), rel=1e-9)
    assert F_max == pytest.approx(v * np.sqrt(m * k), rel=1e-9)


@pytest.mark.parametrize("R, v, block", [(0.05, 1.0, STEEL), (0.01, 5.0, (7.0e10, 0.33))])
def test_hertz_sphere_impact_closed_form_is_the_ode(R, v, block):
    """t_c = 2.868 (m²/(R E*² v))^{1/5}, F_max = (4/3) E* √R δ_max^{3/2} with δ_max from the energy;
    the ODE with F(δ) = (4/3) E* √R δ^{3/2} reproduces both to 1e-6 (it does to ~1e-11)."""
    E_star = contact_modulus(*STEEL, *block)
    m = 4.0 / 3.0 * np.pi * R ** 3 * RHO
    t_c, F_max, delta_max = hertz_sphere_impact(m, R, E_star, v)
    assert t_c == pytest.approx(2.868 * (m ** 2 / (R * E_star ** 2 * v)) ** 0.2, rel=2e-4)   # 2.868 is rounded
    assert 0.5 * m * v ** 2 == pytest.approx(8.0 / 15.0 * E_star * np.sqrt(R) * delta_max ** 2.5, rel=1e-13)
    ode = impact_ode(m, v, lambda d: hertz_sphere_force(d, R, E_star), delta_max)
    assert ode == pytest.approx((t_c, F_max, delta_max), rel=1e-6)


def test_sphere_on_a_block_held_at_depth():
    """Hertz in series with the block's Boussinesq compliance c: δ = a F^{2/3} + c F, so the energy
    ½ m v² = (2/5) a F^{5/3} + c F²/2 at the peak; the ODE reproduces it, and the block's 10 cm
    lengthens the steel sphere's contact (t_c +0.5 %, F_max −0.65 %: this reference's size term)."""
    R, v = 0.05, 1.0
    E_star = contact_modulus(*STEEL, *STEEL)
    m = 4.0 / 3.0 * np.pi * R ** 3 * RHO
    c = boussinesq_compliance(*STEEL, 0.1)
    t_h, F_h, delta_h = hertz_sphere_impact(m, R, E_star, v)
    t_c, F_max, _ = impact_ode(m, v, lambda d: sphere_on_block_force(d, R, E_star, c), delta_h)
    a = (0.75 / (E_star * np.sqrt(R))) ** (2.0 / 3.0)
    assert F_max == pytest.approx(brentq(lambda F: 0.4 * a * F ** (5 / 3) + 0.5 * c * F ** 2 - 0.5 * m * v ** 2,
                                         0.0, F_h, xtol=1e-300, rtol=1e-15), rel=1e-6)
    assert 0.003 < t_c / t_h - 1 < 0.007 and 0.004 < 1 - F_max / F_h < 0.009


def test_line_law_is_johnsons_form():
    """δ = q(1−ν₁²)/(πE₁)(2 ln(4R/b) − 1) + q(1−ν₂²)/(πE₂)(2 ln(2d/b) − ν₂/(1−ν₂)), b = √(4qR/(πE*)),
    written as q (c − s ln q); `cylinder_force` inverts it."""
    R, d, (E1, nu1), (E2, nu2) = 0.05, 0.1, STEEL, (7.0e10, 0.33)
    law = line_law(R, E1, nu1, E2, nu2, d)
    for q in (1e3, 1e5, 2e6):
        b = np.sqrt(4 * q * R / (np.pi * contact_modulus(E1, nu1, E2, nu2)))
        delta = (q * (1 - nu1 ** 2) / (np.pi * E1) * (2 * np.log(4 * R / b) - 1)
                 + q * (1 - nu2 ** 2) / (np.pi * E2) * (2 * np.log(2 * d / b) - nu2 / (1 - nu2)))
        assert cylinder_approach(q, *law) == pytest.approx(delta, rel=1e-13)
        assert cylinder_force(delta, *law) == pytest.approx(q, rel=1e-12)


def test_cylinder_impact_quadrature_is_the_ode():
    """A steel cylinder (R = 5 cm, per unit length) on a steel block 10 cm deep at 1 m/s: t_c and
    q_max by the energy and one quadrature agree with the ODE to 1e-6 (they do to ~1e-11)."""
    R, v = 0.05, 1.0
    m = np.pi * R ** 2 * RHO
    law = line_law(R, *STEEL, *STEEL, 0.1)
    t_c, q_max, delta_max = cylinder_impact(m, v, *law)
    ode = impact_ode(m, v, lambda d: cylinder_force(d, *law), delta_max)
    assert ode == pytest.approx((t_c, q_max, delta_max), rel=1e-6)


def test_cylinder_impact_depends_on_the_bodies_sizes():
    """The line law's size terms: a deeper block or larger constants make it softer, the contact
    longer and the peak lower; t_c moves by a few per cent (the reference's own uncertainty when the
    scene is not the law's geometry: `cylinder_impact`'s docstring gives the numbers)."""
    R, v = 0.05, 1.0
    m = np.pi * R ** 2 * RHO
    t0, q0, _ = cylinder_impact(m, v, *line_law(R, *STEEL, *STEEL, 0.1))
    for law in (line_law(R, *STEEL, *STEEL, 0.2), line_law(R, *STEEL, *STEEL, 0.1, k1=0.0)):
        t_c, q_max, _ = cylinder_impact(m, v, *law)
        assert 0.01 < t_c / t0 - 1 < 0.05 and 0.01 < 1 - q_max / q0 < 0.05
