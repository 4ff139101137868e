"""The adjoint of `solver.method: iterative` (`wcs.contact.iterative.IterativeAdjoint`): one CG +
GAMG solve per criterion on the iterative answer's final active set, no dense W.

Tolerances: the gradients agree with the monolithic adjoint (`wcs.model.sensitivity.ContactAdjoint`,
LU of W) to AGREE = 1e-6 relative — both solve the same linear system on the same active set,
the iterative one to the Krylov tolerance 1e-12 of the right-hand side (measured agreement
1e-9–1e-16); against central finite differences the rule of tests/model/test_gradients.py (1e-5
relative plus the differences' noise floor)."""
from pathlib import Path

import numpy as np
import pytest
import yaml

import wcs
from wcs.model import model as model_module
from wcs.model import sensitivity
from tests.model.test_gradients import TOL, check_against_fd, coulomb_pad

ROOT = Path(__file__).resolve().parents[2]
VALIDATION = ROOT / "studies" / "validation"
AGREE = 1e-6


def load(path, method, **mesh):
    d = yaml.safe_load(Path(path).read_text())
    d["scene"].setdefault("mesh", {}).update(mesh)
    d["solver"] = {**d.get("solver", {}), "method": method, "tolerance": TOL}
    if method == "iterative":
        d["solver"]["iterative"] = {"tolerance": 1e-12}
    return wcs.load_study(d)


def gradients(path, method, **mesh):
    study = load(path, method, **mesh)
    ev = study.evaluate(study.nominal(), gradients=True)
    assert ev.status == 0, ev.message
    return ev


def assert_agree(path, expect_refused=(), **mesh):
    """Every criterion's iterative gradient equals the monolithic one (except those refused), per
    parameter to AGREE relative or below the resolution floor 1e-9 |Φ| / (range of x_k): a
    derivative that moves Φ by less than 1e-9 of itself over the whole range is round-off here
    (10× below the noise floor of the finite-difference checks, 10 TOL |Φ| / (1e-4 range))."""
    direct, iterative = gradients(path, "monolithic", **mesh), gradients(path, "iterative", **mesh)
    assert "iterative" in iterative.message and "polished" not in iterative.message, iterative.message
    study = load(path, "monolithic", **mesh)
    span = study.parameters.upper - study.parameters.lower
    resolved = 0
    for name, g in direct.grad.items():
        if name in expect_refused:
            assert iterative.grad[name] is None and iterative.nonsmooth
            continue
        floor = 1e-9 * abs(direct.phi[name]) / span
        assert np.all(np.abs(iterative.grad[name] - g) <= AGREE * np.maximum(np.abs(g), floor)), name
        resolved += int(np.sum(np.abs(g) > floor))
    assert resolved > 0


def test_2d_floating_block_agrees_with_the_monolithic_adjoint():
    """contact-patch: a block on a base held by contact alone (one rigid mode), all closed."""
    assert_agree(VALIDATION / "contact-patch.yaml")


def test_3d_tresca_shear_patch_agrees_with_the_monolithic_adjoint():
    """Discs: every node slips along x (ν rows fixed, ν⊥ rows with compliance); the block floats
    in z (three rigid modes), the adjoint of its mean pressure mostly a rigid motion."""
    assert_agree(VALIDATION / "tresca-shear-patch-3d.yaml")


def test_iterative_gradient_builds_no_dense_delassus_operator(monkeypatch):
    """A gradient solve with iterative never factors the contact stiffness nor forms W."""
    def refuse(*args, **kwargs):
        raise AssertionError("dense W / contact factor built")
    monkeypatch.setattr(model_module.Model, "factored", refuse)
    monkeypatch.setattr(model_module.Model, "contact_factor", refuse)
    monkeypatch.setattr(sensitivity, "ContactAdjoint", refuse)
    ev = gradients(VALIDATION / "contact-patch.yaml", "iterative")
    assert all(g is not None for g in ev.grad.values())


def test_iterative_gradients_against_finite_differences():
    assert check_against_fd(load(VALIDATION / "contact-patch.yaml", "iterative")) < 1e-5


def test_floating_pad_whose_pressure_adjoint_is_round_off_is_refused():
    """The floating Tresca pad: the adjoint of the mean pressure over the whole face is a rigid
    motion whose deformation (which sets μ) is 1e-14 of it, below round-off; its multipliers do not
    balance the pad: None (and the point flagged), never noise; the shift's gradient agrees."""
    assert_agree(VALIDATION / "tresca-pad.yaml", expect_refused=("pressure",))


@pytest.mark.slow
def test_2d_tunnel_agrees_with_the_monolithic_adjoint():
    """The 2D tunnel: Tresca with stuck and slipping fault nodes, fault ends held by supports and
    rollers on both sides (held and tied rows, μ = 0 there)."""
    assert_agree(ROOT / "studies" / "tunnel-fault.yaml")


@pytest.mark.slow
def test_2d_tunnel_iterative_gradients_against_finite_differences():
    assert check_against_fd(load(ROOT / "studies" / "tunnel-fault.yaml", "iterative")) < 1e-5


def test_coulomb_slip_on_closed_nodes_agrees_with_the_monolithic_adjoint():
    """Coulomb: a slipping closed node's λt = σ(g w + F λn) couples its tangent to its normal
    (Nᵀ not symmetric); the iterative adjoint gives the monolithic gradients (it refused them
    before: None)."""
    study = coulomb_pad("iterative")
    ev = study.evaluate(study.nominal(), gradients=True)
    assert ev.status == 0 and "iterative" in ev.message, ev.message
    raw = ev.state.raw
    m = raw.lam_n.size
    assert np.any(raw.free[:m] & ~raw.free[m:2 * m])           # closed and slipping nodes
    direct = coulomb_pad("monolithic")
    ref = direct.evaluate(direct.nominal(), gradients=True)
    for name, g in ref.grad.items():
        assert ev.grad[name] is not None, name
        assert np.allclose(ev.grad[name], g, rtol=AGREE, atol=1e-9 * abs(ref.phi[name])), name


@pytest.mark.slow
def test_coulomb_iterative_gradients_against_finite_differences():
    assert check_against_fd(coulomb_pad("iterative")) < 1e-5


def coulomb_shear_patch(method):
    """The 3D shear patch with Coulomb friction F = 0.3 (gw = F P, the Tresca patch's limit): every
    node closed and slipping on its disc. Tolerance 1e-11: the fixed point over Tresca bounds cannot
    settle below the Krylov answers' own accuracy (at 1e-13 it stalled at ‖Δp‖ ~ 1e-11 ‖p‖)."""
    d = yaml.safe_load((VALIDATION / "tresca-shear-patch-3d.yaml").read_text())
    d["scene"]["contacts"]["interface"]["friction"] = {"coefficient": 0.3}
    d["uncertain"] = {"contacts.interface.friction.coefficient": [0.25, 0.35],
                      "supports.block_top.u.0": [0.8e-3, 1.2e-3]}
    d["solver"] = {"method": method, "tolerance": 1e-11}
    if method == "iterative":
        d["solver"]["iterative"] = {"tolerance": 1e-12}
    return wcs.load_study(d)


def test_3d_coulomb_slip_on_discs_agrees_with_the_monolithic_adjoint():
    """Discs: the ν row of a closed slipping node carries λν = g w + F λn (coupled to its normal),
    the ν⊥ row its compliance; per parameter to AGREE or below the resolution floor (`assert_agree`):
    the mean pressure is P whatever the data, its gradient round-off."""
    grads = {}
    for method in ("iterative", "monolithic"):
        study = coulomb_shear_patch(method)
        grads[method] = study.evaluate(study.nominal(), gradients=True)
        assert grads[method].status == 0, grads[method].message
    raw = grads["iterative"].state.raw
    m = raw.lam_n.size
    assert np.all(raw.free[:m] & ~raw.free[m:2 * m])            # every node closed and slipping
    span = study.parameters.upper - study.parameters.lower
    for name, g in grads["monolithic"].grad.items():
        floor = 1e-9 * abs(grads["monolithic"].phi[name]) / span
        assert grads["iterative"].grad[name] is not None, name
        assert np.all(np.abs(grads["iterative"].grad[name] - g) <= AGREE * np.maximum(np.abs(g), floor)), name
    assert np.abs(grads["monolithic"].grad["slip"]).max() > 1e-3
