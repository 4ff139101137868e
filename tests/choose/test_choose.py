"""The benchmark-derived choices of `auto` (wcs/choose.py) and their wiring."""
from pathlib import Path

from tests.support.scenes import typed_scene
import wcs
from wcs.choose import MeshFacts, SearchFacts, SolverFacts, mesh_size, search_method, solver_method


def test_solver_rules():
    assert solver_method(SolverFacts(unknowns=10**5, contact=False))[0] == "monolithic"
    assert solver_method(SolverFacts(unknowns=10**7, gradients=True, dd_converges=True))[0] == "monolithic"
    big = SolverFacts(unknowns=2 * 10**6, gradients=False, dd_converges=True)
    assert solver_method(big)[0] == "dd"
    assert solver_method(SolverFacts(unknowns=2 * 10**6, gradients=False, dd_converges=None))[0] == "monolithic"
    assert solver_method(SolverFacts(unknowns=2 * 10**6, gradients=False, friction="tresca",
                                     dd_converges=True))[0] == "monolithic"
    method, why = solver_method(SolverFacts(unknowns=10**4, max_nu=0.499))
    assert method == "monolithic" and "lock" in why


def test_search_and_mesh_rules():
    assert search_method(SearchFacts(dimension=6, budget=40, gradients=True))[0] == "auto"
    assert search_method(SearchFacts(dimension=6, budget=40, gradients=False))[0] == "sample"
    assert search_method(SearchFacts(dimension=6, budget=400, gradients=False))[0] == "global"
    h, _ = mesh_size(MeshFacts(diagonal=100.0, contact_width=0.06, feature=5.0))
    assert h == min(100.0 / 20, 5.0 / 10, 0.06 / 6)


def test_auto_solver_is_resolved_and_reported():
    study = wcs.load_study(Path(__file__).resolve().parents[2] / "studies" / "knee-replacement.yaml")
    ev = study.evaluate(study.nominal())
    assert ev.status == 0
    model = ev.evaluator.model
    assert study.solver.method == "auto" and model.solver_method == "monolithic" and model.solver_reason


def test_default_mesh_size_follows_the_rule():
    from wcs.scene.mesher2d import default_size
    def rock(**shape):
        return typed_scene({"mesh": {"size": 1.0}, "bodies": {"rock": {"regions": [
            {"material": "m", "shape": {"rectangle": [-60, -60, 60, 60], **shape}}]}}})
    diag = 120 * 2 ** 0.5
    assert default_size(rock(minus=[{"disc": {"center": [0, 0], "radius": 5.0}}]), diag) == min(diag / 20, 5.0 / 10)
    assert default_size(rock(), diag) == diag / 20
