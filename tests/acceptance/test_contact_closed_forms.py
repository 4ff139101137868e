"""Contact through the whole pipeline (study -> mesh -> pairs -> solver), against
closed forms (patch test, Hertz), the friction laws (Tresca pad) and an
independent formulation (the cvxpy QP)."""
import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

import wcs
from wcs.cli import main

from tests.support.scenes import VALIDATION, load, solve  # noqa: F401 - shared scene helpers




def test_contact_patch_test_gives_uniform_pressure():
    _, ev = solve("contact-patch")
    c = ev.state.contact
    # P1 with matching node pairs reproduces uniform uniaxial stress exactly: round-off only
    np.testing.assert_allclose(c.pressure, 1.0e6, rtol=1e-8)
    assert np.max(np.abs(c.gap)) <= 1e-12 and np.all(c.shear == 0)
    assert ev.phi["pressure"] == pytest.approx(1.0e6, rel=1e-10)
    f = ev.fields
    for v in ("contact_coords", "contact_pair", "contact_pressure", "contact_gap", "contact_slip", "contact_shear"):
        assert v in f and f[v].sizes["contact_node"] == c.pressure.size
    assert set(f["contact_pair"].values) == {"interface"}


HERTZ = dict(E=2.0e11, nu=0.3, R=1.0, p_top=1.0786e8)


def hertz_errors(h):
    def refine(doc):
        doc["scene"]["mesh"]["refine"][0]["size"] = h
    _, ev = solve("hertz", refine)
    c = ev.state.contact
    P = 2 * HERTZ["p_top"] * HERTZ["R"]                    # whole cylinder, per unit length
    Es = HERTZ["E"] / (2 * (1 - HERTZ["nu"] ** 2))
    a = np.sqrt(4 * P * HERTZ["R"] / (np.pi * Es))
    p0 = 2 * P / (np.pi * a)
    x, F = c.zone.coords[:, 0], c.force_n
    width = 2 * np.sqrt((x**2 * F).sum() / F.sum())         # ∫x²p/∫p = a²/4 for the Hertz profile
    assert 2 * F.sum() == pytest.approx(P, rel=1e-9)       # the half model carries half the load
    return c.pressure.max() / p0 - 1, width / a - 1


def test_hertz_peak_pressure_and_width_converge():
    # a = 0.05 m; h = a/6 and a/12 in the contact zone
    coarse, fine = hertz_errors(0.008), hertz_errors(0.004)
    assert max(map(abs, fine)) < 0.03
    assert abs(fine[0]) < abs(coarse[0]) and abs(fine[1]) < abs(coarse[1])


def test_tresca_partial_slip():
    study, ev = solve("tresca-pad")
    c = ev.state.contact
    g = 3.0e5
    scale = np.abs(c.slip).max()
    slipping = np.abs(c.slip) > 1e-9 * scale
    assert 0 < slipping.sum() < slipping.size                   # partial slip
    assert np.all(np.abs(c.shear) <= g * (1 + 1e-8))            # |τ| ≤ g
    np.testing.assert_allclose(np.abs(c.shear[slipping]), g, rtol=1e-8)   # |τ| = g where it slips
    # tangential equilibrium of the pad: friction forces balance the applied shear (1 m long top)
    applied = 2.0e5 * 1.0
    assert np.sum(c.force_t) == pytest.approx(applied, rel=0.01)
    assert np.all(c.pressure >= 0) and np.all(c.gap >= -1e-12)


def _pressed_only(doc):
    doc["scene"]["loads"]["pad_top"] = {"traction": [0.0, -1.0e6]}
    doc["scene"]["boundaries"]["pad_left"] = {"body": "pad", "segment": [[0.5, 1.0], [0.5, 1.5]]}
    doc["scene"]["supports"]["pad_left"] = {"u": [0.0, None]}
    doc["uncertain"] = {"contacts.interface.friction.slip_limit": [0.0, 1.0e12]}
    doc["criteria"] = [{"name": "pressure", "kind": "contact_pressure", "regions": ["interface"]}]


def test_zero_slip_limit_is_frictionless():
    def zero(doc):
        _pressed_only(doc)
        doc["scene"]["contacts"]["interface"]["friction"] = {"slip_limit": 0.0}
    def none(doc):
        _pressed_only(doc)
        doc["scene"]["contacts"]["interface"].pop("friction")
        doc["uncertain"] = {"loads.pad_top.traction.1": [-2.0e6, -0.5e6]}
    _, a = solve("tresca-pad", zero)
    _, b = solve("tresca-pad", none)
    assert np.linalg.norm(a.state.u - b.state.u) <= 1e-10 * np.linalg.norm(b.state.u)


def test_large_slip_limit_is_glued():
    def sticky(doc):
        _pressed_only(doc)
        doc["scene"]["contacts"]["interface"]["friction"] = {"slip_limit": 1.0e12}
    def glued(doc):
        _pressed_only(doc)
        sc = doc["scene"]
        sc["bodies"] = {"block": {"regions": [
            {"name": "base", "material": "steel", "shape": {"rectangle": [0.0, 0.0, 2.0, 1.0]}},
            {"name": "pad", "material": "rubber", "shape": {"rectangle": [0.5, 1.0, 1.5, 1.5]}}]}}
        for b in sc["boundaries"].values():
            b["body"] = "block"
        for name in ("pad_bottom", "base_top"):
            sc["boundaries"].pop(name)
        sc.pop("contacts")
        sc["regions_of_interest"] = {"pad_top": {"boundary": "pad_top"}}
        doc["uncertain"] = {"loads.pad_top.traction.1": [-2.0e6, -0.5e6]}
        doc["criteria"] = [{"name": "shift", "kind": "mean_normal_displacement", "regions": ["pad_top"]}]
    _, stick = solve("tresca-pad", sticky)
    _, glue = solve("tresca-pad", glued)
    # nothing opened (round-off relative to the displacements): the same discrete problem
    assert np.all(stick.state.contact.gap <= 1e-10 * np.abs(stick.state.u).max())
    key = lambda p: [tuple(np.round(q, 9)) for q in p.T]        # noqa: E731
    index = {k: i for i, k in enumerate(key(glue.evaluator.smesh.mesh.p))}
    nodes = [index[k] for k in key(stick.evaluator.smesh.mesh.p)]
    us, ug = stick.state.u.reshape(-1, 2), glue.state.u.reshape(-1, 2)[nodes]
    assert np.abs(us - ug).max() <= 1e-8 * np.abs(ug).max()


def test_unbalanced_floating_body_is_bad_input(tmp_path, capsys):
    def pull(doc):
        doc["scene"]["loads"]["pad_top"] = {"traction": [4.0e5, -1.0e6]}   # shear 4e5 > g = 3e5
        doc["uncertain"] = {"loads.pad_top.traction.0": [3.5e5, 4.5e5]}
    study = load("tresca-pad", pull)
    ev = study.evaluate(study.nominal())
    assert ev.status == 3 and "'pad'" in ev.message
    path = tmp_path / "pull.yaml"                    # the CLI reads a file: the study's own text
    path.write_text(study.text)
    code = main(["solve", str(path), "-o", str(tmp_path / "o.nc")])
    err = capsys.readouterr().err
    assert code == 2 and "'pad'" in err and "not balanced" in err and "Traceback" not in err


def _small(doc):
    doc["scene"]["mesh"] = {"size": 0.1, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": 0.05}]}


def _coulomb(doc):
    _small(doc)
    doc["scene"]["contacts"]["interface"]["friction"] = {"coefficient": 0.4}
    doc["uncertain"] = {"contacts.interface.friction.coefficient": [0.3, 0.5]}


def with_method(edit, method):
    """The study edit `edit` (or none), then `solver.method: method`."""
    def e(doc):
        if edit:
            edit(doc)
        doc["solver"] = {"method": method}
    return e


@pytest.mark.parametrize("name,edit", [("contact-patch", None), ("tresca-pad", _small), ("tresca-pad", _coulomb)],
                         ids=["patch-floating", "tresca-floating", "coulomb-floating"])
def test_monolithic_agrees_with_qp(name, edit):
    _, mono = solve(name, with_method(edit, "monolithic"))
    _, qp = solve(name, with_method(edit, "qp"))
    # Clarabel at 1e-10 gaps on a scaled program; Coulomb adds the fixed point's 1e-8
    assert np.linalg.norm(mono.state.u - qp.state.u) <= 1e-6 * np.linalg.norm(qp.state.u)
    cm, cq = mono.state.contact, qp.state.contact
    assert np.linalg.norm(cm.force_n - cq.force_n) <= 1e-6 * np.linalg.norm(cq.force_n)


def test_knee_coulomb_solves_without_the_fallback_and_satisfies_kkt(monkeypatch):
    """The knee replacement (floating femur on two curved condyles, Coulomb friction): the
    semismooth Newton revisits an active set in the Coulomb fixed point (full steps slide the
    femur sideways and flip every slip); its steps are then shortened (Armijo), and it ends
    without the dual-QP fallback. Checked on the KKT conditions themselves (the cvxpy reference
    is unreliable here: stiffness contrast 600, it reports 'inaccurate' / 'unbounded')."""
    import functools
    import wcs.contact.solver as cs
    knee = Path(__file__).resolve().parents[2] / "studies" / "knee-replacement.yaml"
    monkeypatch.setattr(cs, "_newton", functools.partial(cs._newton, fallback=False))
    bare = wcs.load_study(knee)
    ev = bare.evaluate(bare.nominal())
    assert ev.status == 0, ev.message
    model, res = ev.evaluator.model, ev.state.raw
    c = ev.evaluator.map.coefficients(bare.nominal())
    K = model.K(model.stiffness_coefficients(c))
    u0 = model.elim.U0 @ c.support_values
    rhs = model.Tt @ (model.mechanical_load(c, None) - K @ u0)
    Kr = model.Tt @ K @ model.elim.T
    lam_n, lam_t, w = res.lam_n, res.lam_t, model.zone.weight
    eq = Kr @ res.u + model.Bn_r.T @ lam_n + model.Bt_r.T @ lam_t - rhs
    assert np.abs(eq).max() <= 1e-8 * np.abs(rhs).max()                 # equilibrium
    con = ev.state.contact
    us, fs = np.abs(ev.state.u).max(), lam_n.max()
    assert con.gap.min() >= -1e-8 * us and lam_n.min() >= -1e-8 * fs    # non-penetration, λn ≥ 0
    assert np.abs(lam_n * con.gap).max() <= 1e-8 * fs * us               # complementarity
    bound = c.coulomb * lam_n + c.slip * w
    assert np.all(np.abs(lam_t) <= bound * (1 + 1e-6) + 1e-8 * fs)     # Coulomb cone (fixed point 1e-8)
    slipping = np.abs(con.slip) > 1e-6 * np.abs(con.slip).max()
    np.testing.assert_allclose(lam_t[slipping], (bound * np.sign(con.slip))[slipping], rtol=1e-6, atol=1e-8 * fs)


@pytest.mark.parametrize("name,edit", [("tresca-pad", _small), ("tresca-shear-patch-3d", None)], ids=["2d", "3d"])
def test_a_qp_evaluation_with_gradients_is_polished_by_newton_and_says_so(name, edit):
    """The dual QP gives no active set or factorization for the adjoint: with gradients its
    answer is polished by the semismooth Newton (the message says so), and the gradients are
    the monolithic solver's. (Before, every such evaluation failed with a TypeError: a `qp`
    study under a gradient search solved nothing.)"""
    mono, qp = load(name, with_method(edit, "monolithic")), load(name, with_method(edit, "qp"))
    m, q = mono.evaluate(mono.nominal(), gradients=True), qp.evaluate(qp.nominal(), gradients=True)
    assert q.status == 0 and q.message == "solved (qp, polished by monolithic for the adjoint)", q.message
    assert qp.evaluate(qp.nominal()).message == "solved"
    span = np.array(mono.parameters.upper, float) - np.array(mono.parameters.lower, float)
    for k in m.grad:        # the change over the box against the criterion's size (a flat one's gradient is round-off)
        scale = max(abs(m.phi[k]), np.abs(m.grad[k] * span).max())
        assert np.abs((q.grad[k] - m.grad[k]) * span).max() <= 1e-6 * scale, k
