"""Adjoint gradients in 3D against central finite differences.

The contact adjoint on the final active set with two tangents per node: a node slipping on
the disc |λt| ≤ gw has λt = gw s/|s|, linearized in the frame of its slip (νᵀδλt = δgw, and
|s| ν⊥ᵀδλt = gw ν⊥ᵀδs). Checked first on the solver's own systems (the pad on a base of
tests/test_contact3d.py: stuck and slipping nodes whose slip directions vary over the face,
Tresca and Coulomb, held and floating), then through studies.

Tolerance (the rule of test_gradients.py): 1e-5 relative, plus the finite differences' noise
floor 10·tol·|Φ|/h (the solver stops at a relative residual `tol`; a difference quotient with
step h cannot resolve derivatives below that)."""
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from wcs.contact import solver as cs
from wcs.sensitivity import _contact_adjoint

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_contact3d import args, pad_on_base  # noqa: E402

TOL = 1e-13
REL = 1e-5


def _solve(P, g, F, f=None):
    K, f0, Bn, Bt, d, w = args(P)
    return cs.solve_contact(K, f0 if f is None else f, Bn, Bt, d, w, g=g, F=F, R=P["R"], tol=TOL, tol_fp=TOL)


def _assert_close(ad, fd, phi, h):
    noise = 10 * TOL * abs(phi) / h
    assert abs(ad - fd) <= REL * abs(fd) + noise, (ad, fd)


@pytest.mark.parametrize("case", ["tresca held", "coulomb held", "coulomb floating"])
def test_disc_slip_adjoint_on_the_solver_system(case):
    """Φ = ℓ_w · w + ℓ_λ · λn (random ℓ): the adjoint's z and μ give dΦ/df = z and dΦ/dg_i =
    μ_ν,i w_i (Tresca) or dΦ/dF_i = μ_ν,i λn,i (Coulomb), against central differences of the
    solver along random directions. Every case has stuck and slipping nodes (slip directions
    spread by the twist or the oblique load)."""
    floating = case.endswith("floating")
    P = (pad_on_base(floating=True, load=(0.001, -0.0015, -0.01)) if floating
         else pad_on_base(top=(0.002, 0.001, -0.01), twist=0.03))
    m, n = len(P["w"]), P["K"].shape[0]
    coulomb = case.startswith("coulomb")
    g = np.zeros(m) if coulomb else np.full(m, 0.01)
    F = np.full(m, 0.3) if coulomb else None
    r = _solve(P, g, F)
    assert r.status == 0 and {cs.STICK, cs.SLIP} <= set(r.active)
    rng = np.random.default_rng(0)
    lw, ll = rng.standard_normal(n), rng.standard_normal(m)

    def phi(res):
        return lw @ res.u + ll @ res.lam_n

    model = SimpleNamespace(Bn_r=P["Bn"], Bt_r=P["Bt"], R_r=P["R"])
    state = SimpleNamespace(raw=r, contact=SimpleNamespace(slip=P["Bt"] @ r.u),
                            coefficients=SimpleNamespace(coulomb=np.zeros(m) if F is None else F),
                            contact_factor=lambda model: r.factor)
    z, mu, sigma = _contact_adjoint(model, state, lw, ll)
    h = 1e-5
    df = rng.standard_normal(n) * np.abs(P["f"]).max()
    fd = (phi(_solve(P, g, F, P["f"] + h * df)) - phi(_solve(P, g, F, P["f"] - h * df))) / (2 * h)
    _assert_close(z @ df, fd, phi(r), h)
    tang = np.flatnonzero(~r.free[m:] & (sigma != 0))
    node = tang % m
    assert np.array_equal(np.sort(node), np.flatnonzero(r.active == cs.SLIP))   # one ν row per slipping node
    grad = np.zeros(m)
    np.add.at(grad, node, mu[m + tang] * sigma[tang] * (r.lam_n if coulomb else P["w"])[node])
    e = rng.standard_normal(m) * (0.1 if coulomb else 0.001)
    if coulomb:
        fd = (phi(_solve(P, g, F + h * e)) - phi(_solve(P, g, F - h * e))) / (2 * h)
    else:
        fd = (phi(_solve(P, g + h * e, F)) - phi(_solve(P, g - h * e, F))) / (2 * h)
    _assert_close(grad @ e, fd, phi(r), h)
