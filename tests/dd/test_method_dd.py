"""`solver.method: dd` through the model: agreement with monolithic (`fallback: false`, so a
DD failure fails the test), the fallback when the chosen outer iteration fails, and answers
that do not depend on the evaluation order."""
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

import wcs

ROOT = Path(__file__).resolve().parents[2] / "studies"
VALIDATION = ROOT / "validation"
STRICT = {"method": "dd", "tolerance": 1e-10, "fallback": False}


def assert_agree(a, b, rel=1e-6):
    """Displacements and the nodal contact forces λn, λt of two evaluations agree to `rel`
    relative (both stop at 1e-10; 1e-6 leaves the conditioning of the interface problem a
    factor 1e4) — at a node on a roller too, where only Bnᵀλn + Btᵀλt is unique and every
    solver reports its canonical split (tests/contact/test_tied_nodes.py). Node states are not
    compared: a node at the stick–slip threshold (|λt| = g w to rounding) may be labelled
    either way."""
    assert b.status == 0, b.message
    ca, cb = a.state.contact, b.state.contact
    for x, y in ((b.state.u, a.state.u), (cb.force_n, ca.force_n), (cb.force_t, ca.force_t)):
        assert np.linalg.norm(x - y) <= rel * max(np.linalg.norm(y), 1e-300) or not np.any(y) and not np.any(x)


def study(name, solver, edit=None):
    doc = yaml.safe_load((VALIDATION / f"{name}.yaml").read_text())
    if edit:
        edit(doc)
    doc["solver"] = solver
    return wcs.load_study(doc)


def small_pad(doc):
    doc["scene"]["mesh"] = {"size": 0.1, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": 0.04}]}


def test_dd_agrees_with_monolithic_through_the_model():
    mono = study("contact-patch", {"method": "monolithic", "tolerance": 1e-10})
    dd = study("contact-patch", {**STRICT, "dd": {"subdomains": 6}})
    a, b = mono.evaluate(mono.nominal()), dd.evaluate(dd.nominal())
    assert b.status == 0 and b.state.solver.startswith("dd: ") and b.iterations >= 1
    assert "ρ(S0⁻¹ dS_con) ≥" in b.message          # the bound that chose the step, in the evaluation
    assert_agree(a, b)


def test_failing_outer_iteration_falls_back_and_says_so():
    # Tresca pad, the seed's plain step (ω = 1) asked for: ρ(S0⁻¹ dS_con) ≈ 25, its successive
    # approximations' contraction estimate stays ≥ 1 (step auto takes Newton there: tests/dd/test_solver.py)
    seed = {"subdomains": 6, "step": "seed", "relaxation": 1.0}
    dd = study("tresca-pad", {"method": "dd", "dd": seed}, small_pad)
    ev = dd.evaluate(dd.nominal())
    assert ev.status == 0 and "monolithic after dd" in ev.message and "contraction" in ev.message
    mono = study("tresca-pad", {"method": "monolithic"}, small_pad)
    ref = mono.evaluate(mono.nominal())
    assert np.linalg.norm(ev.state.u - ref.state.u) <= 1e-10 * np.linalg.norm(ref.state.u)
    strict = study("tresca-pad", {"method": "dd", "fallback": False, "dd": seed}, small_pad)
    failed = strict.evaluate(strict.nominal())
    assert failed.status == 5 and "domain decomposition" in failed.message
    assert np.isnan(list(failed.phi.values())).all()


def test_dd_answers_do_not_depend_on_the_order():
    s = study("contact-patch", {"method": "dd", "dd": {"subdomains": 6}})
    x1 = s.nominal()
    x2 = x1.copy()
    x2[0] *= 1.3
    first = s.evaluate(x1).state.u.copy()
    s.evaluate(x2)
    again = s.evaluate(x1).state.u
    assert np.array_equal(first, again)


def test_dd_with_mortar_contact_agrees_with_monolithic():
    """Nonmatching sides (dual mortar rows reach several master nodes) inside the DD pairs."""
    mono = study("mortar-patch", {"method": "monolithic", "tolerance": 1e-10})
    dd = study("mortar-patch", {**STRICT, "dd": {"subdomains": 6}})
    a, b = mono.evaluate(mono.nominal()), dd.evaluate(dd.nominal())
    assert b.state.solver.startswith("dd: ")
    assert_agree(a, b)


def tunnel(solver, edit=None):
    doc = yaml.safe_load((ROOT / "tunnel-fault.yaml").read_text())
    if edit:
        edit(doc)
    doc["solver"] = solver
    return wcs.load_study(doc)


def test_newton_solves_the_tunnel_where_the_seeds_step_fails():
    """The tunnel (12 subdomains): ρ(S0⁻¹ dS_con) ≈ 100–300 — the seed's successive steps
    stagnate or diverge and fall back; step auto sees ρ ≫ 1, takes interface Newton, and agrees
    with monolithic."""
    seed = tunnel({"method": "dd", "tolerance": 1e-6, "dd": {"subdomains": 12, "step": "seed"}})
    assert re.search(r"monolithic after dd successive approximations (stagnated|diverged) at step \d+: contraction",
                     seed.evaluate(seed.nominal()).message)
    mono = tunnel({"method": "monolithic", "tolerance": 1e-10})
    dd = tunnel({**STRICT, "dd": {"subdomains": 12}})
    b = dd.evaluate(dd.nominal())
    assert b.status == 0, b.message
    assert b.state.solver.startswith("dd: ρ(S0⁻¹ dS_con) ≥ ") and ": newton; interface Newton converged" in b.message
    assert_agree(mono.evaluate(mono.nominal()), b)


def corner(study, ev, name):
    """The box corner that the criterion's gradient at the nominal data points to (its worst
    data where the criterion is monotone over the box)."""
    p = study.parameters
    return np.where(ev.grad[name] > 0, p.upper, p.lower)


@pytest.mark.slow
def test_dd_agrees_on_the_tunnel_at_the_worst_data_of_each_criterion():
    mono = tunnel({"method": "monolithic", "tolerance": 1e-10})
    dd = tunnel({**STRICT, "dd": {"subdomains": 12}})
    nominal = mono.evaluate(mono.nominal(), gradients=True)
    for name in nominal.phi:
        x = corner(mono, nominal, name)
        a, b = mono.evaluate(x), dd.evaluate(x)
        assert not np.array_equal(x, mono.nominal())
        assert_agree(a, b)
        assert b.phi[name] == pytest.approx(a.phi[name], rel=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("pair_size", [1.0, 2.0])
def test_dd_agrees_on_the_knee_coulomb_with_a_floating_femur(pair_size):
    """Coulomb at the condyles (F = 0.05), the femur held only by the contacts: the DD's Coulomb
    fixed point over Tresca problems, each by interface Newton, as the monolithic path. At
    pair_size 2 (and at 1 on an unsmoothed mesh) the femur held by 20 closed nodes and one
    stuck one makes the linearised pair singular to rounding beyond its rigid motions: its
    Neumann solve by the pinned Cholesky failed ("not positive definite")."""
    doc = yaml.safe_load((ROOT / "knee-replacement.yaml").read_text())
    results = []
    for solver in ({"method": "monolithic", "tolerance": 1e-10},
                   {**STRICT, "dd": {"subdomains": 13, "pair_size": pair_size}}):
        doc["solver"] = solver
        s = wcs.load_study(doc, base_dir=ROOT)
        results.append(s.evaluate(s.nominal()))
    assert "Coulomb fixed point" in results[1].message
    # a local semismooth Newton cycled at some interface values (1 at pair_size 1, 2 at 2) and restarted
    # from the dual QP; its steps are shortened after a cycle now, and no local solve needs the restart
    assert "restarted from the dual QP" not in results[1].message
    assert_agree(*results)


def test_dd_agrees_on_a_thermal_contact_scene():
    """The heated tunnel (coarse): the thermal step and the Tresca contact both by the DD."""
    def small(doc):
        doc["scene"]["mesh"]["size"] = 8.0
        doc["scene"]["mesh"]["refine"] = [{"disc": {"center": [0.0, 0.0], "radius": 6.0}, "size": 1.5}]
    out = []
    for solver in ({"method": "monolithic", "tolerance": 1e-10}, {**STRICT, "dd": {"subdomains": 8}}):
        doc = yaml.safe_load((ROOT / "tunnel-thermal.yaml").read_text())
        small(doc)
        doc["solver"] = solver
        s = wcs.load_study(doc, base_dir=ROOT)
        out.append(s.evaluate(s.nominal()))
    assert out[1].state.T is not None and np.any(out[1].state.contact.force_t)
    assert re.search(r"ρ\(S0⁻¹ dS_con\) ≥ \S+ at U⁰ \(\d power steps; ≥ 0.5\): newton; interface Newton converged", out[1].message)
    assert np.allclose(out[1].state.T, out[0].state.T, rtol=1e-8, atol=0)
    assert_agree(*out)


def test_dd_thermal_step_of_a_scene_without_contact():
    """The cooled layer (heat, no contact): the thermal step by the decomposition, the
    elasticity direct; the settlement equals the monolithic one (before: an internal
    failure, the heat partition was taken from the contact decomposition)."""
    mono = study("cooled-layer", {"method": "monolithic"})
    dd = study("cooled-layer", {"method": "dd", "dd": {"subdomains": 4}})
    a, b = mono.evaluate(mono.nominal()), dd.evaluate(dd.nominal())
    assert b.status == 0, b.message
    assert np.allclose(b.state.T, a.state.T, rtol=1e-8, atol=0)
    assert abs(b.phi["settlement"] - a.phi["settlement"]) <= 1e-8 * abs(a.phi["settlement"])


def test_check_prints_the_rho_estimate(tmp_path, capsys):
    from wcs.cli import main
    doc = yaml.safe_load((VALIDATION / "contact-patch.yaml").read_text())
    doc["solver"] = {"method": "dd", "fallback": False, "dd": {"subdomains": 6}}
    path = tmp_path / "patch-dd.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    assert main(["check", str(path)]) == 0
    line = next(s for s in capsys.readouterr().out.splitlines() if "nominal solve" in s)
    assert "solved (dd: ρ(S0⁻¹ dS_con) ≥ " in line and "interface Newton converged" in line, line
