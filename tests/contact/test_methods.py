"""Contact methods by name (`wcs.contact.methods`): the model solves through the method the
registry holds for the study's `solver.method`, never through an if-chain on the name."""
import dataclasses

import numpy as np
import pytest
from tests.support import scenes

import wcs.contact.methods as methods
from wcs.contact.methods import METHODS, Primal, method_of
from wcs.dd.method import Decomposition
from wcs.model.evaluation import Evaluator


def patch(study):
    return scenes.load("contact-patch", lambda d: d["solver"].update(method=study))


def test_the_registry_holds_every_method_a_study_can_name():
    from typing import get_args

    from wcs.options import Solver
    named = set(get_args(Solver.model_fields["method"].annotation)) - {"auto"}
    assert named <= set(METHODS)
    assert isinstance(method_of("dd"), Decomposition) and isinstance(method_of("qp"), Primal)
    assert method_of("monolithic").anchored and not method_of("qp").anchored


@pytest.mark.parametrize("name", ["monolithic", "qp"])
def test_a_model_solves_through_its_registered_method(monkeypatch, name):
    """A method registered under a study's name is the one its model calls: a counting wrapper
    around the registered problem function sees every contact solve, and the answer is the
    registered method's own to the bit."""
    study = patch(name)
    x = study.nominal()
    plain = Evaluator(study).evaluate(x)
    assert plain.status == 0, plain.message
    calls = []
    method = method_of(name)
    counted = dataclasses.replace(method, solve_problem=lambda model, p: calls.append(p) or method.solve_problem(model, p))
    monkeypatch.setitem(METHODS, name, counted)
    ev = Evaluator(study)
    assert ev.model.method is counted
    again = ev.evaluate(x)
    assert len(calls) == 1 and calls[0].m == len(ev.model.zone.weight)
    assert np.array_equal(again.state.u, plain.state.u) and again.phi == plain.phi


def test_registering_a_method_is_one_line(monkeypatch):
    """A new method: one function of the model and its `ContactProblem`, and its registration."""
    seen = []

    def probe(model, problem):
        seen.append(problem)
        return methods.newton(model, problem)

    monkeypatch.setitem(METHODS, "probe", Primal("probe", probe, anchored=True, units=True, assembles=False))
    monkeypatch.setitem(METHODS, "monolithic", METHODS["probe"])     # a study can name only the options' methods
    ev = Evaluator(patch("monolithic"))
    out = ev.evaluate(ev.study.nominal())
    assert out.status == 0 and len(seen) == 1 and ev.model.method.name == "probe"
    assert out.message == "solved"                                   # a method's own name reads as plainly solved
