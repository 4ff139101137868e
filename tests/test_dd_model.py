"""`solver.method: dd` through the model: agreement with monolithic, the fallback when the
successive approximations fail, and answers that do not depend on the evaluation order."""
from pathlib import Path

import numpy as np
import yaml

import wcs

VALIDATION = Path(__file__).resolve().parents[1] / "studies" / "validation"


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
    dd = study("contact-patch", {"method": "dd", "tolerance": 1e-10, "dd": {"subdomains": 6}})
    a, b = mono.evaluate(mono.nominal()), dd.evaluate(dd.nominal())
    assert b.status == 0 and b.state.solver == "dd" and b.iterations >= 1
    assert np.linalg.norm(a.state.u - b.state.u) <= 1e-6 * np.linalg.norm(a.state.u)
    assert np.linalg.norm(a.state.contact.force_n - b.state.contact.force_n) <= 1e-6 * np.linalg.norm(a.state.contact.force_n)


def test_failing_successive_approximations_fall_back_and_say_so():
    # Tresca pad, the seed's plain steps (ω = 1): the contraction estimate stays ≥ 1
    dd = study("tresca-pad", {"method": "dd", "dd": {"subdomains": 6, "relaxation": 1.0}}, small_pad)
    ev = dd.evaluate(dd.nominal())
    assert ev.status == 0 and "monolithic after dd" in ev.message and "contraction" in ev.message
    mono = study("tresca-pad", {"method": "monolithic"}, small_pad)
    ref = mono.evaluate(mono.nominal())
    assert np.linalg.norm(ev.state.u - ref.state.u) <= 1e-10 * np.linalg.norm(ref.state.u)
    strict = study("tresca-pad", {"method": "dd", "fallback": False, "dd": {"subdomains": 6, "relaxation": 1.0}},
                   small_pad)
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
    dd = study("mortar-patch", {"method": "dd", "tolerance": 1e-10, "dd": {"subdomains": 6}})
    a, b = mono.evaluate(mono.nominal()), dd.evaluate(dd.nominal())
    assert b.status == 0 and b.state.solver == "dd"
    assert np.linalg.norm(a.state.u - b.state.u) <= 1e-6 * np.linalg.norm(a.state.u)


def test_glued_step_converges_where_the_seeds_step_stagnates():
    """The tunnel: the seed's successive steps with S0 stagnate (q ≈ 1.1) and fall back; steps
    with S0 + the pairs' glued response iterate only the nonlinear correction and converge."""
    root = Path(__file__).resolve().parents[1] / "studies"
    doc = yaml.safe_load((root / "tunnel-fault.yaml").read_text())
    results = {}
    for key, solver in (("mono", {"method": "monolithic"}),
                        ("seed", {"method": "dd", "tolerance": 1e-6, "dd": {"subdomains": 12}}),
                        ("glued", {"method": "dd", "tolerance": 1e-6, "dd": {"subdomains": 12, "step": "glued"}})):
        doc["solver"] = solver
        s = wcs.load_study(doc)
        results[key] = s.evaluate(s.nominal())
    assert "monolithic after dd" in results["seed"].message
    glued, mono = results["glued"], results["mono"]
    assert glued.status == 0 and glued.state.solver == "dd"
    # DD stops at ‖ΔU‖ ≤ 1e-6 ‖U‖: the displacements agree to a few times that
    assert np.linalg.norm(glued.state.u - mono.state.u) <= 1e-5 * np.linalg.norm(mono.state.u)


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
