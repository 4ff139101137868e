"""One status enumeration (wcs/status.py): the codes of the results file, their descriptions, and
no layer that compares a status with a bare integer."""
import ast
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import wcs
from wcs.status import DDOutcome
from wcs.model.evaluation import Evaluator
from wcs.report.data import status_meanings
from wcs.results.dataset import run_dataset, solve_dataset, write_netcdf
from wcs.status import Status, describe

ROOT = Path(__file__).resolve().parents[2]

# the public contract: the `status` integers and descriptions results files have always carried
CONTRACT = {0: "solved", 1: "contact solver did not converge", 2: "Coulomb fixed point did not converge",
            3: "solvability violated: a floating body is not balanced",
            4: "singular system or factorization failed", 5: "domain decomposition failed",
            6: "other failure", 7: "solution not unique: a rigid motion of a floating body is free"}


def test_codes_and_descriptions_are_the_contract():
    assert {s.value: s.description for s in Status} == CONTRACT
    assert len({s.flag_meaning for s in Status}) == len(Status)
    assert all(s.flag_meaning.replace("_", "").isalnum() for s in Status)
    assert {s for s in Status if s.scene_fault} == {Status.UNSOLVABLE, Status.NOT_UNIQUE}
    assert describe(6) == "other failure" and describe(42) == "unknown"


def test_dd_outcomes_are_not_statuses():
    """The DD's "stagnated" is its own outcome, equal to no status code (it leaves the model as
    DD_FAILED, tests/dd/test_method_dd.py)."""
    assert all(not isinstance(o.value, int) for o in DDOutcome)
    assert DDOutcome.STAGNATED != Status.OTHER_FAILURE and DDOutcome.CONVERGED != Status.SOLVED


@pytest.fixture(scope="module")
def heated():
    study = wcs.load_study(ROOT / "studies" / "heated-plate.yaml")
    ev = Evaluator(study)
    return study, ev, ev.evaluate(study.nominal())


def test_results_files_flag_the_enumeration(heated, tmp_path):
    study, ev, res = heated
    assert res.status is Status.SOLVED
    rec = {"x": res.x, "phi": np.array(list(res.phi.values())), "status": int(Status.NOT_UNIQUE),
           "message": "m", "stage": "sample", "iterations": 0, "wall_time": 0.1, "grad": None, "nonsmooth": 0}
    write_netcdf(run_dataset(study, ev, [rec], worst={}, certificate={}), tmp_path / "run.nc")
    write_netcdf(solve_dataset(study, ev, res), tmp_path / "solve.nc")
    for name in ("run.nc", "solve.nc"):
        var = xr.open_dataset(tmp_path / name, engine="h5netcdf")["status"]
        assert var.attrs["flag_values"].dtype == np.int32
        assert var.attrs["flag_values"].tolist() == [s.value for s in Status]
        assert var.attrs["flag_meanings"].split() == [s.flag_meaning for s in Status]
        assert status_meanings(var)[7] == "solution not unique a rigid motion of a floating body is free"
    run = xr.open_dataset(tmp_path / "run.nc", engine="h5netcdf")["status"]
    assert run.values.tolist() == [7]
    assert run.attrs["codes"] == "; ".join(f"{k}: {v}" for k, v in CONTRACT.items())


def _bare_status_comparisons(tree: ast.AST) -> list[int]:
    """Lines comparing something named `status` with an integer literal other than 0, or passing
    `status=<integer literal>`."""
    def named_status(node):
        return "status" in ast.unparse(node).lower()

    def int_literals(node):
        elts = node.elts if isinstance(node, (ast.Tuple, ast.List, ast.Set)) else [node]
        return [e.value for e in elts if isinstance(e, ast.Constant) and type(e.value) is int]

    lines = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(named_status(s) for s in sides) and any(v != 0 for s in sides for v in int_literals(s)):
                lines.append(node.lineno)
        elif isinstance(node, ast.keyword) and node.arg == "status" and any(v != 0 for v in int_literals(node.value)):
            lines.append(node.value.lineno)
    return lines


def test_the_check_finds_bare_codes():
    assert _bare_status_comparisons(ast.parse("a = r.status == 3\nb = x.status in (0, 7)\nf(status=5)\n"
                                              "c = r.status != 0\nd = r.status == Status.SOLVED")) == [1, 2, 3]


def test_no_module_compares_a_status_with_a_bare_code():
    found = {str(p.relative_to(ROOT)): lines for p in sorted((ROOT / "wcs").rglob("*.py"))
             if (lines := _bare_status_comparisons(ast.parse(p.read_text())))}
    assert found == {}
