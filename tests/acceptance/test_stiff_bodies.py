"""Stiff bodies standing in for rigid obstacles: a foundation of E = 1e14 to
1e20 Pa is accepted, and its answers are those of a rigid obstacle to within the contrast.

Why no digit is lost: bodies in contact share no stiffness entry, so K is block diagonal over
them and W = C K⁻¹ Cᵀ = Σ_b C K_b⁻¹ Cᵀ is a sum of each body's own compliance (each factored
alone, well conditioned whatever its modulus). The stiff body's share of W is then
E_soft/E_stiff of the soft one's, and the solution differs from the rigid obstacle's (the
same body held by supports on its contact side) by a model error C·E_soft/E_stiff: it
converges linearly in 1/E_stiff, with the same C at every contrast as long as round-off
stays below it. The tests assert both: the distance to the rigid answer is at most
10·E_soft/E_stiff (C measured 0.5 to 3.9 on the pad) and C is the same to 1 % from 1e14 to
1e17 Pa (round-off below 1 % of a model error of 5e-11, i.e. below 5e-13 relative).
"""
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.support.bad_studies import demo_doc, write_study
from tests.support.scenes import load
from tests.contact.test_patch_3d import DELTA, E_BLOCK, G, H, P, shear_patch
from wcs.cli import main
from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs import load_study

ROOT = Path(__file__).resolve().parents[2]
SSNV128 = ROOT / "tests" / "data" / "ssnv128.yaml"
STIFF = [1e14, 1e15, 1e16, 1e17]


def _pad(rigid: bool):
    """tresca-pad (rubber 1e7 Pa on a base, Tresca): the base's E uncertain over the stiff
    range, or (rigid) the base's top held by supports."""
    def edit(doc):
        if rigid:
            doc["scene"]["supports"]["base_top"] = {"u": [0.0, 0.0]}
        else:
            doc["scene"]["materials"]["steel"]["E"] = 1e14
            doc["uncertain"] = {"materials.steel.E": [1e14, 1e17]}
    return load("tresca-pad", edit)


def _contact(study, values):
    ev = study.evaluate(values)
    assert ev.status == 0, ev.message
    c = ev.state.contact
    return {"slip": c.slip, "pressure": c.pressure, "shear": c.shear}


def test_a_tresca_pad_on_a_stiff_foundation_converges_to_the_rigid_obstacle():
    """Slip, contact pressure and shear on a foundation of E_f = 1e14 … 1e17 Pa against the same
    pad on a rigid (support-held) base: distance ≤ 10·E_pad/E_f, and distance·E_f/E_pad the
    same constant to 1 % at every E_f (linear convergence, no round-off floor)."""
    rigid = _contact(_pad(True), {})
    stiff = _pad(False)
    e_pad = 1.0e7
    constants = []
    for e_f in STIFF:
        fields = _contact(stiff, np.array([e_f]))
        dist = {k: np.abs(fields[k] - rigid[k]).max() / np.abs(rigid[k]).max() for k in rigid}
        assert all(d <= 10 * e_pad / e_f for d in dist.values()), (e_f, dist)
        constants.append([d * e_f / e_pad for d in dist.values()])
    constants = np.array(constants)
    assert np.all(constants[0] > 0.1)                       # a real model error, not round-off
    assert np.abs(constants / constants[0] - 1).max() < 0.01, constants


def test_the_3d_shear_patch_on_a_rigid_like_base_keeps_its_closed_form():
    """The 3D Tresca shear patch (tests/contact/test_patch_3d.py) with the base at 1e14 … 1e20 Pa (a
    contrast of 2e10 with the block): slip δ − G H (1/μ_block + 1/μ_base), pressure P and shear
    G at every contact node, τ_zz = −P and τ_xz = G in both blocks (the stiff one too), to
    the closed form's 1e-6."""
    d = shear_patch()
    d["scene"]["materials"]["base"]["E"] = 1e14
    d["uncertain"] = {"materials.base.E": [1e14, 1e20]}
    ev = Evaluator(load_study(d))
    for e_base in (1e14, 1e17, 1e20):
        res = ev.evaluate(np.array([e_base]))
        assert res.status == 0, res.message
        c = res.state.contact
        slip = DELTA - G * H / (E_BLOCK / 2) - G * H / (e_base / 2)
        assert np.abs(c.pressure - P).max() < 1e-6 * P
        assert np.abs(c.by_node(c.slip) - [slip, 0.0]).max() < 1e-6 * slip
        assert np.abs(c.shear - [G, 0.0]).max() < 1e-6 * G
        stress = res.state.stress
        assert np.abs(stress[2] + P).max() < 1e-6 * P and np.abs(stress[4] - G).max() < 1e-6 * G


# code_aster SSNV128: the slips DX along the contact at PPA … PPE and its tolerance (5 %)
SSNV128_DX = {0.0: 2.86e-5, 0.00125: 2.72e-5, 0.005: 2.28e-5, 0.0075: 1.98e-5, 0.01125: 1.50e-5}


def _slips_at_references(doc) -> np.ndarray:
    ev = Evaluator(load_study(doc))
    res = ev.evaluate(ev.study.nominal())
    assert res.status == 0, res.message
    x = res.fields["contact_coords"].values[:, 0]
    slip = res.fields["contact_slip"].values.ravel()
    return np.array([slip[np.argmin(np.abs(x - xr))] for xr in SSNV128_DX])


def test_ssnv128_on_its_stiff_plate_checks_and_meets_code_aster(tmp_path, capsys):
    """The study passes `wcs check` (E_rigid = 1.3e16 Pa, refused before); its slips meet
    code_aster's reference to its 5 %, and they are the rigid obstacle's (the bed's top held)
    to within 10·E_plate/E_rigid."""
    assert main(["check", str(SSNV128)]) == 0, capsys.readouterr().err
    doc = yaml.safe_load(SSNV128.read_text())
    stiff = _slips_at_references(doc)
    ref = np.array(list(SSNV128_DX.values()))
    assert np.abs(stiff / ref - 1).max() < 0.05
    doc["scene"]["supports"]["bed_top"] = {"u": [0.0, 0.0]}
    rigid = _slips_at_references(doc)
    assert np.abs(stiff - rigid).max() <= 10 * 1.3e11 / 1.3e16 * np.abs(rigid).max()


@pytest.mark.parametrize("where", ["scene", "uncertain"])
def test_a_modulus_beyond_the_range_says_how_to_model_a_rigid_body(where):
    doc = demo_doc()
    if where == "scene":
        doc["scene"]["materials"]["steel"]["E"] = 1e21
    else:
        doc["uncertain"]["materials.rubber.E"] = [0.8e7, 1e21]
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert "1e+20" in info.value.fault and "hold its contact side fixed with a support" in info.value.fault


@pytest.mark.parametrize("e_f", [1e13, 1e17])
def test_the_qp_reference_solves_a_pad_on_a_stiff_foundation_as_the_newton_does(e_f):
    """The cvxpy reference (`solver.method: qp`) scaled by one displacement scale called the
    pad on a 1e13 Pa base unbounded (status 3, 'load not balanced': a wrong diagnosis; the pad's
    stiffness was 1e-6 of the mean diagonal); scaled DOF by DOF it meets the Newton to within
    its own tolerance (1e-8 relative; measured 5e-10)."""
    def edit(method):
        def f(doc):
            doc["scene"]["materials"]["steel"]["E"] = e_f
            doc["solver"]["method"] = method
        return f
    answers = []
    for method in ("qp", "monolithic"):
        study = load("tresca-pad", edit(method))
        ev = study.evaluate(study.nominal())
        assert ev.status == 0, ev.message
        answers.append(ev.phi)
    for name, value in answers[1].items():
        assert answers[0][name] == pytest.approx(value, rel=1e-8)


def _layers(soft: float, stiff: float, name: str = "studies/glued-layers.yaml") -> dict:
    """glued-layers (one body: concrete under steel; closed form in its header), or glued-mortar
    (the same layers as two glued bodies), with these moduli and the moduli not uncertain."""
    doc = yaml.safe_load((ROOT / name).read_text())
    doc["scene"]["materials"]["concrete"]["E"] = soft
    doc["scene"]["materials"]["steel"]["E"] = stiff
    doc["uncertain"] = {k: v for k, v in doc["uncertain"].items() if ".E" not in k}
    return doc


@pytest.mark.parametrize("name, where", [("studies/glued-layers.yaml", "body 'column'"),
                                         ("studies/validation/glued-mortar.yaml", "the glued bodies 'soft', 'hard'")])
def test_a_contrast_beyond_double_precision_in_one_factorization_is_refused(tmp_path, capsys, name, where):
    """Bonded regions share one factorization, whose round-off grows like 1e-14 × their contrast:
    10 Pa bonded to 2.1e12 Pa (a contrast of 2e11, both in main's range; stresses off by ~1e-3)
    is exit 2 naming the materials, the bodies and what to do."""
    code = main(["check", str(write_study(_layers(10.0, 2.1e12, name), tmp_path)), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "scene.materials.steel" in err and where in err, err
    assert "2.1e+11 (> 1e+10)" in err and "a body of its own in contact" in err


def test_a_bonded_contrast_within_the_bound_keeps_the_closed_form_to_its_round_off():
    """glued-layers at a contrast of 7e8 (steel stand-in 2.1e19 Pa, concrete 3e10 Pa): stresses
    σ_yy = −p in both layers and the settlement Σ h p/(λ+2μ) to 1e-13 × the contrast (ten
    times the measured 1e-14)."""
    from wcs.model.materials import lame
    ev = Evaluator(load_study(_layers(3e10, 2.1e19)))
    res = ev.evaluate(ev.study.nominal())
    assert res.status == 0, res.message
    p, (lc, mc), (ls, ms) = 1e6, lame({"E": 3e10, "nu": 0.2}), lame({"E": 2.1e19, "nu": 0.3})
    tol = 1e-13 * (ls + 2 * ms) / (lc + 2 * mc)
    assert np.abs(res.state.stress[1] + p).max() < tol * p
    settlement = 0.3 * p / (lc + 2 * mc) + 0.2 * p / (ls + 2 * ms)
    assert res.phi["settlement"] == pytest.approx(settlement, rel=tol)
