"""Adjoint gradients in 3D against central finite differences.

The contact adjoint on the final active set with two tangents per node: a node slipping on
the disc |λt| ≤ gw has λt = gw s/|s|, linearized in the frame of its slip (νᵀδλt = δgw, and
|s| ν⊥ᵀδλt = gw ν⊥ᵀδs). Checked first on the solver's own systems (the pad on a base of
tests/contact/test_solver_3d.py: stuck and slipping nodes whose slip directions vary over the face,
Tresca and Coulomb, held and floating), then through studies.

Tolerance (the rule of tests/model/test_gradients.py): 1e-5 relative, plus the finite differences' noise
floor 10·tol·|Φ|/h (the solver stops at a relative residual `tol`; a difference quotient with
step h cannot resolve derivatives below that)."""
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

import wcs
from wcs.contact import solver as cs
from wcs.model.sensitivity import ContactAdjoint
from tests.contact.test_patch_3d import E_BASE, E_BLOCK, G, H, shear_patch
from tests.contact.test_solver_3d import args, pad_on_base
from tests.model.test_gradients import check_against_fd

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

    model = SimpleNamespace(Bn_r=P["Bn"], Bt_r=P["Bt"], R_r=P["R"], contact_rows=sp.vstack([P["Bn"], P["Bt"]]).tocsr())
    state = SimpleNamespace(raw=r, contact=SimpleNamespace(slip=P["Bt"] @ r.u),
                            coefficients=SimpleNamespace(coulomb=np.zeros(m) if F is None else F),
                            contact_factor=lambda model: r.factor)
    z, mu, sigma = ContactAdjoint(model, state).solve(lw, ll)
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


# ---------------------------------------------------------------- through studies

def _plane(point, normal):
    return {"plane": {"point": point, "normal": normal}}


def two_region_block(size=0.25) -> dict:
    """A thermo-elastic block [0, 2]×[0, 1]×[0, 1] of two regions (steel below z = 0.5 by λ/μ,
    aluminium above by E/ν), clamped below, on a roller at x = 0, pressed on top and pulled
    obliquely at x = 2, with a body force, specific weight, a heat source and regions of
    interest of every 3D kind (box, ball, cylinder, boundary); every criterion kind but the
    contact ones, every parameter kind of a scene without contact."""
    return {
        "study": "gradients-3d",
        "scene": {
            "dimension": 3, "mesh": {"size": size},
            "materials": {
                "steel": {"lambda": 1.2e11, "mu": 8.0e10, "conductivity": 45.0, "expansion": 1.2e-5,
                          "density_weight": 7.7e4},
                "alu": {"E": 7.0e10, "nu": 0.33, "conductivity": 200.0, "expansion": 2.3e-5}},
            "bodies": {"block": {"regions": [
                {"name": "lower", "material": "steel", "shape": {"box": [0, 0, 0, 2, 1, 0.5]}},
                {"name": "upper", "material": "alu", "shape": {"box": [0, 0, 0.5, 2, 1, 1]}}]}},
            "boundaries": {"bottom": _plane([0, 0, 0], [0, 0, 1]), "top": _plane([0, 0, 1], [0, 0, 1]),
                           "left": _plane([0, 0, 0], [1, 0, 0]), "right": _plane([2, 0, 0], [1, 0, 0])},
            "supports": {"bottom": {"u": [None, 0.0, 0.0]}, "left": {"normal": 0.0}},   # x held by left alone
            "loads": {"top": {"pressure": 2.0e6}, "right": {"traction": [1.0e5, 2.0e5, -1.0e5]}},
            "body_forces": {"upper": [0.0, 1.0e4, -1.0e4]},
            "thermal": {"reference": 293.0, "temperature": {"bottom": 303.0}, "sources": {"upper": 1.0e4}},
            "regions_of_interest": {
                "core": {"box": [0.8, 0.3, 0.6, 1.2, 0.7, 0.9]},
                "knot": {"ball": {"center": [1.4, 0.5, 0.85], "radius": 0.15}},
                "rod": {"cylinder": {"start": [0.3, 0.5, 0.25], "end": [0.7, 0.5, 0.25], "radius": 0.12}},
                "top": {"boundary": "top"}}},
        "uncertain": {
            "materials.steel.lambda": [1.1e11, 1.3e11], "materials.steel.mu": [7.5e10, 8.5e10],
            "materials.steel.expansion": [1.0e-5, 1.4e-5], "materials.steel.density_weight": [7.0e4, 8.0e4],
            "materials.steel.conductivity": [40.0, 50.0],
            "materials.alu.E": [6.5e10, 7.5e10], "materials.alu.nu": [0.30, 0.36],
            "loads.top.pressure": [1.5e6, 2.5e6], "loads.right.traction.1": [1.0e5, 3.0e5],
            "loads.right.traction.2": [-2e5, 0.0], "body_forces.upper.2": [-2.0e4, 0.0],
            "supports.bottom.u.1": [-1.0e-5, 1.0e-5], "supports.left.normal": [-1.0e-5, 1.0e-5],
            "thermal.temperature.bottom": [298.0, 308.0], "thermal.sources.upper": [0.5e4, 1.5e4],
            "thermal.reference": [290.0, 296.0]},
        "criteria": [
            {"name": "T_vol", "kind": "mean_temperature", "regions": ["core", "knot"]},
            {"name": "T_face", "kind": "mean_temperature", "regions": ["top"]},
            {"name": "settle", "kind": "mean_normal_displacement", "regions": ["knot"], "point": [1.4, 0.5, 1.0]},
            {"name": "lift", "kind": "mean_normal_displacement", "regions": ["top"]},
            {"name": "shift", "kind": "mean_normal_displacement", "regions": ["rod"], "direction": [1.0, 1.0, 0.0]},
            {"name": "shear", "kind": "shear_stress_intensity", "regions": ["core", "rod"]},
            {"name": "mises", "kind": "von_mises", "regions": ["knot"]},
            {"name": "s1", "kind": "principal_stress", "regions": ["rod"]}],
        "solver": {"method": "monolithic", "tolerance": TOL},
    }


def test_every_criterion_and_parameter_kind_without_contact():
    assert check_against_fd(wcs.load_study(two_region_block())) < REL


def pad_on_base_study(friction: dict, size=0.125) -> dict:
    """A soft pad [0.25, 0.75]²×[0, 0.25] on a clamped base [0, 1]²×[−0.5, 0] (matching faces:
    node-to-node), its top pressed down and shifted by support values, pulled by a body force, heated:
    stuck in the middle, slipping near its edges in directions that vary along them. Criteria
    of every kind on either side of the contact; parameters: λ/μ and E/ν, support values (a
    component and a roller), a pressure, a body force, heating (a source in the pad, a cooled
    base: expansion, conductivity, temperature), and the friction's coefficient or its slip limit (a
    Lipschitz function on the contact surface: its values on a 3×2 grid, bilinear between)."""
    return {
        "study": "contact-gradients-3d",
        "scene": {
            "dimension": 3, "mesh": {"size": size},
            "materials": {"stiff": {"lambda": 8.0e9, "mu": 8.0e9, "conductivity": 40.0, "expansion": 1.0e-5},
                          "soft": {"E": 1.0e9, "nu": 0.3, "conductivity": 0.5, "expansion": 2.0e-5}},
            "bodies": {"base": {"regions": [{"material": "stiff", "shape": {"box": [0, 0, -0.5, 1, 1, 0]}}]},
                       "pad": {"regions": [{"material": "soft", "shape": {"box": [0.25, 0.25, 0, 0.75, 0.75, 0.25]}}]}},
            "boundaries": {
                "base_bottom": _plane([0, 0, -0.5], [0, 0, 1]),
                "base_side": _plane([1, 0, 0], [1, 0, 0]),
                "base_front": _plane([0, 0, 0], [0, 1, 0]),
                "base_top": {"body": "base", "box": [0.25, 0.25, 0, 0.75, 0.75, 0]},
                "pad_bottom": {"body": "pad", "plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}},
                "pad_top": _plane([0, 0, 0.25], [0, 0, 1])},
            "supports": {"base_bottom": {"u": [None, 0.0, 0.0]}, "base_side": {"normal": 0.0},
                         "pad_top": {"u": [1.0e-4, 0.5e-4, -1.0e-3]}},
            "body_forces": {"pad": [2.0e5, 1.0e5, -1.0e5]},
            "loads": {"base_front": {"pressure": 1.0e6}},
            "thermal": {"reference": 293.0, "temperature": {"base_bottom": 283.0}, "sources": {"pad": 1.0e2}},
            "contacts": {"interface": {"slave": "pad_bottom", "master": "base_top", "friction": friction}},
            "regions_of_interest": {
                "corner": {"box": [0.5, 0.5, -0.1, 0.75, 0.75, 0.1]},
                "edge": {"box": [0.25, 0.25, -0.1, 0.5, 0.75, 0.0], "body": "base"},
                "interface": {"boundary": "base_top"},
                "heel": {"ball": {"center": [0.4, 0.4, 0.1], "radius": 0.08}}}},
        "uncertain": {
            "materials.stiff.lambda": [7.0e9, 9.0e9], "materials.stiff.mu": [7.0e9, 9.0e9],
            "materials.soft.E": [0.8e9, 1.2e9], "materials.soft.nu": [0.25, 0.35],
            "supports.pad_top.u.0": [0.8e-4, 1.2e-4], "supports.pad_top.u.2": [-1.1e-3, -0.9e-3],
            "supports.base_side.normal": [-1.0e-5, 1.0e-5], "body_forces.pad.1": [0.5e5, 1.5e5],
            "loads.base_front.pressure": [0.5e6, 1.5e6], "materials.soft.expansion": [1.5e-5, 2.5e-5],
            "materials.soft.conductivity": [0.4, 0.6], "thermal.sources.pad": [0.5e2, 1.5e2],
            "thermal.temperature.base_bottom": [278.0, 288.0],
            **({"contacts.interface.friction.coefficient": [0.25, 0.35]} if "coefficient" in friction
               else {"contacts.interface.friction.slip_limit":              # bilinear on a 3×2 grid
                     {"range": [0.8e6, 1.2e6], "lipschitz": 4.0e6, "points": [3, 2]}})},
        "criteria": [
            {"name": "pressure", "kind": "contact_pressure", "regions": ["corner", "edge"]},
            {"name": "pressure_all", "kind": "contact_pressure", "regions": ["interface"]},
            {"name": "slip", "kind": "contact_slip", "regions": ["corner"]},
            {"name": "mises", "kind": "von_mises", "regions": ["heel"]},
            {"name": "s1", "kind": "principal_stress", "regions": ["heel"]},
            {"name": "sink", "kind": "mean_normal_displacement", "regions": ["interface"]}],
        "solver": {"method": "monolithic", "tolerance": TOL},
    }


@pytest.mark.parametrize("friction", [{"slip_limit": 1.0e6}, {"coefficient": 0.3}], ids=["tresca", "coulomb"])
def test_every_criterion_kind_with_frictional_contact(friction):
    """Node-to-node Tresca and Coulomb contact (the Coulomb fixed point: ~25 Tresca solves)."""
    study = wcs.load_study(pad_on_base_study(friction))
    ev = study.evaluate(study.nominal())
    assert {1, 2} <= set(ev.state.raw.active.tolist())      # stuck and slipping nodes
    assert check_against_fd(study) < REL


@pytest.mark.parametrize("delta, flagged", [(2.0e-3, False), (None, True)], ids=["slipping", "at the switch"])
def test_a_node_at_the_disc_boundary_is_flagged_non_smooth(delta, flagged):
    """The Tresca shear patch (every node under the shear g, tests/contact/test_patch_3d.py): with the
    block's top moved by more than the elastic shift γH of both blocks, every node slips (s > 0,
    |λt| = gw): smooth. Moved by exactly that shift, the nodes are at the switch between stick
    and slip (s = 0 and |λt| = gw at once): the gradient is one-sided, flagged non-smooth."""
    d = shear_patch()
    shift = G / (E_BLOCK / 2) * H + G / (E_BASE / 2) * H
    d["scene"]["supports"]["block_top"]["u"][0] = delta if delta is not None else shift
    d["scene"]["regions_of_interest"] = {"face": {"boundary": "base_top"}}
    d["uncertain"] = {"loads.block_top_load.pressure": [0.9e6, 1.1e6]}
    d["criteria"] = [{"name": "p", "kind": "contact_pressure", "regions": ["face"]}]
    d["solver"] = {"method": "monolithic", "tolerance": TOL}
    study = wcs.load_study(d)
    ev = study.evaluate(study.nominal(), gradients=True)
    assert ev.status == 0 and ev.nonsmooth is flagged
    assert ev.grad["p"][0] == pytest.approx(1.0, rel=1e-9)       # the mean pressure is the applied one
