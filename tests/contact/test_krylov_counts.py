"""Newton steps and Krylov iterations in the results (`iterations`, `krylov_iterations`,
`krylov_step_max`, and in `wcs solve`'s file `krylov_steps`): the counts in the file are the
ones PETSc reported to the iterative method's CG solves, contact solve by contact solve."""
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

import wcs.contact.iterative as iterative
from wcs.cli import main
from wcs.model.evaluation import Evaluation, Evaluator
from wcs.app.record import from_evaluation
from wcs.status import Status
from wcs import load_study

STUDIES = Path(__file__).resolve().parents[2] / "studies"


@pytest.fixture
def cg_counts(monkeypatch):
    """The CG iterations of every evaluation's contact solve, as PETSc gave them: one list per
    `Evaluator.evaluate` with a contact solve, one entry per Newton step of its last contact solve
    (the nominal anchor solved before it is not its own; a preconditioner rebuilt within a step:
    both solves' iterations in the step's entry)."""
    solves, evaluations, depth = [], [], [0]
    stepper_init, krylov_solve, evaluate = iterative._Stepper.__init__, iterative.Krylov.solve, Evaluator.evaluate

    def init(self, *args, **kw):
        stepper_init(self, *args, **kw)
        solves.append([])

    def solve(self, A, b, rtol, step=None):
        depth[0] += 1
        try:
            x, its, ok = krylov_solve(self, A, b, rtol, step)
        finally:
            depth[0] -= 1
        if depth[0] == 0 and solves:
            solves[-1].append(its)
        return x, its, ok

    def evaluated(self, *args, **kw):
        start = len(solves)
        out = evaluate(self, *args, **kw)
        if len(solves) > start:
            evaluations.append(solves[-1])
        return out
    monkeypatch.setattr(iterative._Stepper, "__init__", init)
    monkeypatch.setattr(iterative.Krylov, "solve", solve)
    monkeypatch.setattr(Evaluator, "evaluate", evaluated)
    return evaluations


def study_file(tmp_path, name, method, **top) -> Path:
    doc = yaml.safe_load((STUDIES / name).read_text())
    doc["solver"] = {**doc.get("solver", {}), "method": method}
    doc.update(top)
    path = tmp_path / Path(name).name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_solve_files_and_prints_the_newton_steps_and_cg_iterations_of_a_2d_iterative_solve(tmp_path, capsys,
                                                                                          cg_counts):
    out = tmp_path / "pad.nc"
    assert main(["solve", str(study_file(tmp_path, "validation/tresca-pad.yaml", "iterative")), "-o", str(out)]) == 0
    [steps] = cg_counts
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert ds["krylov_steps"].values.tolist() == steps
        assert int(ds["iterations"]) == len(steps) >= 1
        assert int(ds["krylov_iterations"]) == sum(steps) and int(ds["krylov_step_max"]) == max(steps)
        assert "CG" in ds["krylov_iterations"].attrs["long_name"]
    assert f"{len(steps)} outer steps, {sum(steps)} Krylov iterations ({max(steps)} at most" in capsys.readouterr().out


def test_a_direct_solve_files_no_krylov_iterations(tmp_path, capsys):
    out = tmp_path / "pad.nc"
    assert main(["solve", str(study_file(tmp_path, "validation/tresca-pad.yaml", "monolithic")), "-o", str(out)]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert int(ds["iterations"]) >= 1 and int(ds["krylov_iterations"]) == 0 and "krylov_steps" not in ds
    assert "no Krylov iterations (direct factorization)" in capsys.readouterr().out


def test_a_3d_iterative_run_files_each_evaluations_own_counts(tmp_path, cg_counts):
    """Every evaluation's row holds its own contact solve's counts (the nominal anchor that
    starts the other data sets is a solve of its own, not in any row unless evaluated)."""
    search = {"method": "sample", "sample": {"design": "lhs", "n": 3, "seed": 1}, "budget": 3}
    path = study_file(tmp_path, "validation/tresca-shear-patch-3d.yaml", "iterative", search=search)
    out = tmp_path / "patch.nc"
    assert main(["run", str(path), "-o", str(out), "-q", "--no-mesh-check"]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert (ds["status"].values == 0).all() and ds.sizes["eval"] == 3
        rows = np.c_[ds["iterations"].values, ds["krylov_iterations"].values, ds["krylov_step_max"].values]
    solved = np.array([[len(s), sum(s), max(s)] for s in cg_counts[:3]])     # then the worst cases' fields
    np.testing.assert_array_equal(rows, solved)
    assert (solved[:, 0] >= 1).all()


def test_a_failed_evaluation_has_its_krylov_iterations_not_counted():
    ev = Evaluation(np.zeros(1), {"a": np.nan}, Status.CONTACT_NOT_CONVERGED, "no", 0, 0.1)
    rec = from_evaluation(ev, ["a"], 1, "sample", False)
    assert rec["krylov_iterations"] == rec["krylov_step_max"] == -1


def test_the_dd_and_its_monolithic_polish_leave_the_krylov_iterations_not_counted():
    """The DD's PCG iterations are in its message, not counted as the file's Krylov iterations;
    polished by monolithic for the adjoint the solve ran the DD's PCG all the same."""
    doc = yaml.safe_load((STUDIES / "validation" / "contact-patch.yaml").read_text())
    doc["solver"] = {"method": "dd", "dd": {"subdomains": 4}}
    ev = Evaluator(load_study(doc))
    for gradients in (False, True):
        res = ev.evaluate(ev.study.nominal(), gradients=gradients)
        assert res.status == 0 and res.message.startswith("solved (dd")
        rec = from_evaluation(res, [c.name for c in ev.criteria], len(res.x), "sample", gradients)
        assert (rec["krylov_iterations"], rec["krylov_step_max"]) == (-1, -1)
