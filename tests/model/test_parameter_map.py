"""The parameter map x → coefficients (exact Jacobian, no copies) and solutions that own
their factorizations (an adjoint does not depend on what was solved after its solve)."""
import copy
from pathlib import Path

import numpy as np
import pytest
import threadpoolctl
import yaml

import wcs
from wcs.model.coefficients import ParameterMap, flatten
from wcs.model.model import Model
from wcs.model.sensitivity import gradients

DATA = Path(__file__).resolve().parents[1] / "data"
ALL_KINDS = DATA / "gradients-all-kinds.yaml"     # every parameter kind, thermal step, contact, a profile


def _doc(plane):
    doc = yaml.safe_load(ALL_KINDS.read_text())
    doc["scene"]["plane"] = plane
    return doc


@pytest.fixture(scope="module", params=["strain", "stress"])
def evaluator(request):
    study = wcs.load_study(_doc(request.param), base_dir=DATA)
    study.evaluate(study.nominal())
    return study._evaluator


def _inside(study, rng):
    lo, hi = study.parameters.lower, study.parameters.upper
    return lo + (0.2 + 0.6 * rng.random(lo.size)) * (hi - lo)


def test_jacobian_against_central_differences_of_the_map(evaluator):
    """Every column of ∂c/∂x against (c(x + h e_k) − c(x − h e_k)) / 2h, h = 1e-6 of the box
    width: the map is affine but for the moduli (smooth), so the difference quotient is exact
    to O(h²) ~ 1e-12 relative and to its round-off 1e-16 |c| / h, allowed 100 times over."""
    study, pmap = evaluator.study, evaluator.map
    x = _inside(study, np.random.default_rng(1))
    J = pmap.jacobian(x)
    assert J.shape == (pmap.size, len(study.parameters))
    c = np.abs(pmap.flat(x))
    for k, name in enumerate(study.parameters.names):
        h = 1e-6 * (study.parameters.upper[k] - study.parameters.lower[k])
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        fd = (pmap.flat(xp) - pmap.flat(xm)) / (2 * h)
        tol = 1e-8 * np.abs(fd) + 100 * np.finfo(float).eps * c / h
        assert np.all(np.abs(J[:, k] - fd) <= tol), (name, np.max(np.abs(J[:, k] - fd) - tol))
        assert np.any(J[:, k] != 0), name          # every parameter reaches a coefficient


def test_map_agrees_with_the_layout_of_the_coefficients(evaluator):
    study, pmap = evaluator.study, evaluator.map
    x = _inside(study, np.random.default_rng(2))
    c = pmap.coefficients(x)
    flat, slices = flatten(c)
    assert np.array_equal(flat, pmap.flat(x)) and slices == pmap.slices
    i = study.parameters.names.index("loads.pad_top.pressure")
    assert c.pressure["pad_top"] == x[i]


def test_the_nominal_data_give_the_model_s_nominal_coefficients(evaluator):
    pmap, model = evaluator.map, evaluator.model
    assert np.array_equal(pmap.flat(evaluator.study.nominal()), flatten(model.nominal)[0])


def test_an_evaluation_copies_nothing(monkeypatch, evaluator):
    """The data reach the model through the compiled map: no copy of the scene per data set."""
    study = evaluator.study
    before = copy.deepcopy(study.scene)
    maps = []
    monkeypatch.setattr(ParameterMap, "__init__", lambda *a, **k: maps.append(a))

    def refuse(*a, **k):
        raise AssertionError("an evaluation deep-copied something")
    monkeypatch.setattr(copy, "deepcopy", refuse)
    rng = np.random.default_rng(3)
    for _ in range(2):
        assert evaluator.evaluate(_inside(study, rng), gradients=True).status == 0
    assert maps == []
    monkeypatch.undo()
    assert study.scene == before


def test_adjoint_of_a_solution_after_another_solve(evaluator):
    """Solve A, solve B, then the adjoint of A: bitwise the adjoint taken right after A
    (the factors of the heat step and of the contact problem hold B's matrices by then)."""
    study = evaluator.study
    rng = np.random.default_rng(4)
    xa, xb = _inside(study, rng), _inside(study, rng)
    a = evaluator.evaluate(xa, gradients=True)
    evaluator.evaluate(xb, gradients=True)
    again, nonsmooth = gradients(evaluator, a.state, xa)
    assert nonsmooth == a.nonsmooth
    for name, g in a.grad.items():
        assert np.array_equal(again[name], g), (name, np.max(np.abs(again[name] - g) / np.abs(g)))


def test_adjoint_without_contact_after_another_solve():
    study = wcs.load_study(Path(__file__).resolve().parents[2] / "studies" / "glued-layers.yaml")
    rng = np.random.default_rng(5)
    xa, xb = _inside(study, rng), _inside(study, rng)
    a = study.evaluate(xa, gradients=True)
    study.evaluate(xb, gradients=True)
    again, _ = gradients(a.evaluator, a.state, xa)
    for name, g in a.grad.items():
        assert np.array_equal(again[name], g), name


def test_the_model_is_read_only_and_leaves_threads_alone(evaluator):
    model = evaluator.model
    with pytest.raises(AttributeError, match="read-only"):
        model.comm = object()
    for array in (model.cell_area, model.Bt_r.data, model.zone.gap, model.elim.U0.data):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1.0
    with threadpoolctl.threadpool_limits(limits=2):
        before = [i["num_threads"] for i in threadpoolctl.threadpool_info()]
        Model(evaluator.study.scene, evaluator.smesh, evaluator.study.solver)
        assert [i["num_threads"] for i in threadpoolctl.threadpool_info()] == before
