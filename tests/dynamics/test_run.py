"""`wcs run` / `wcs sweep` on a dynamic study: one evaluation is one
simulation, each criterion's history reduced by its `over_time`; the results file holds
`phi_history` (eval, criterion, time) and the worst cases' fields at the output times; resume
and two MPI ranks give the serial run's bits; the file says where the gradients come from."""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from tests.support.bad_studies import write_study
from tests.dynamics.test_bars import DURATION, bars
from wcs.cli import main
from wcs.dynamics.history import simulate
from wcs.model.evaluation import Evaluator
from wcs.study import load_study
from wcs.results.store import store_path

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
REDUCE = {"max": np.max, "min": np.min, "final": lambda h: h[-1], "mean": np.mean}


def tiny(budget=4):
    """The two bars, coarse, to just past the impact, with an uncertain modulus and density and
    one criterion per reduction."""
    doc = bars(0.05, 1e-5, "stabilized", width=0.05, end=DURATION / 2)
    doc["dynamics"]["output_every"] = 5
    doc["scene"]["boundaries"]["t_end"] = {"body": "target", "segment": [[2.0, 0.0], [2.0, 0.05]]}
    doc["scene"]["regions_of_interest"]["end"] = {"boundary": "t_end"}
    doc["uncertain"] = {"materials.steel.E": [1.9e11, 2.3e11], "materials.steel.density": [7700.0, 8000.0]}
    doc["criteria"] = [
        {"name": "peak", "kind": "contact_pressure", "regions": ["face"], "over_time": "max"},
        {"name": "travel", "kind": "mean_normal_displacement", "regions": ["end"], "direction": [1.0, 0.0],
         "over_time": "final"},
        {"name": "least", "kind": "contact_pressure", "regions": ["face"], "over_time": "min"},
        {"name": "average", "kind": "contact_pressure", "regions": ["face"], "over_time": "mean"}]
    doc["search"] = {"method": "sample", "sample": {"design": "lhs", "n": budget, "seed": 3}, "budget": budget}
    return doc


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dyn-run")
    path = write_study(tiny(), folder, "study.yaml")
    out = folder / "serial.nc"
    assert main(["run", str(path), "-o", str(out), "--quiet", "--no-mesh-check"]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        return path, out, ds.load()


def test_each_evaluation_is_a_simulation_reduced_over_time(serial):
    path, _, ds = serial
    study = load_study(path)
    levels = study.dynamics.levels
    assert ds["phi_history"].dims == ("eval", "criterion", "time") and ds.sizes["time"] == levels + 1
    assert ds["time"].values == pytest.approx(np.arange(levels + 1) * 1e-5)
    assert (ds["status"].values == 0).all() and ds.sizes["eval"] == 4
    over = dict(zip(map(str, ds["criterion"].values), map(str, ds["over_time"].values)))
    assert over == {"peak": "max", "travel": "final", "least": "min", "average": "mean"}
    for c, how in over.items():       # phi is each history reduced, bit for bit
        h = ds["phi_history"].sel(criterion=c).values
        assert np.array_equal(ds["phi"].sel(criterion=c).values, [REDUCE[how](row) for row in h]), c
    # one evaluation is the simulation `wcs solve` runs at that data set
    x = ds["x"].values[2]
    hist = simulate(Evaluator(study), x)
    assert np.array_equal(ds["phi_history"].values[2, 0], hist.phi["peak"])
    # the peak contact stress grows with sqrt(E rho) (d'Alembert: rho c v0 / 2): the worst is the stiffest,
    # densest sample
    peak = ds["phi"].sel(criterion="peak").values
    assert int(ds["worst_eval"].sel(criterion="peak")) == int(np.argmax(peak))
    assert np.argmax(peak) == np.argmax(ds["x"].values[:, 0] * ds["x"].values[:, 1])


def test_the_worst_fields_are_kept_at_the_output_times(serial):
    path, _, ds = serial
    dyn = load_study(path).dynamics
    out = [n for n in range(dyn.levels + 1) if n % 5 == 0 or n == dyn.levels]
    assert ds["output_time"].values == pytest.approx(np.array(out) * 1e-5)
    u = ds["worst_displacement"]
    assert u.dims == ("criterion", "output_time", "node", "dim")
    assert ds["worst_contact_pressure"].dims[:2] == ("criterion", "output_time")
    # the target's far end at the end time is the `final` criterion of the worst case
    j = list(map(str, ds["criterion"].values)).index("travel")
    end = np.isclose(ds["coords"].values[:, 0], 2.0)
    assert u.values[j, -1, end, 0].mean() == pytest.approx(float(ds["worst_value"].sel(criterion="travel")),
                                                            rel=1e-12)
    assert np.all(np.isfinite(ds["worst_small_strain_gradient"].values))


def test_the_worst_fields_name_the_bodies_and_regions(serial, capsys):
    """The worst cases' fields at the output times carry the names of the bodies and regions their
    `cell_body` and `cell_region` number (the report's scene section and ParaView read them)."""
    from wcs.report.data import load
    _, out, ds = serial
    assert list(map(str, ds["body"].values)) == ["striker", "target"]
    assert ds.sizes["region"] == 2 and int(ds["cell_region"].max()) == 1
    assert load(out).mesh.bodies == ["striker", "target"]


def test_the_results_say_where_the_gradients_come_from(serial):
    """The stabilized scheme has the adjoint through time; a sampling search asks for no gradient."""
    _, _, ds = serial
    assert ds.attrs["gradients"].startswith("adjoint through time")
    assert all("gradients through time by the adjoint" in str(n) for n in ds["certificate_note"].values)
    assert np.isnan(ds["grad"].values).all()


def test_the_solver_choice_gives_the_reason_of_a_time_level(serial):
    """`auto` on a dynamic study: the results file's `solver_choice` says what decides each
    level's method (the adjoint through time takes any method's levels) and the cost of one level's solve, never the
    static search's adjoint-gradient rule; with friction, the friction rule decides."""
    from tests.dynamics.test_friction import sliding
    from wcs.results.dataset import provenance
    choice = serial[2].attrs["solver_choice"]
    assert choice.startswith("monolithic: each time level is one contact solve (the adjoint through time")
    assert "adjoint gradients, which need" not in choice and "one time level estimated at" in choice
    assert "one evaluation" not in choice
    study = load_study(sliding("seed"))
    tresca = provenance(study, Evaluator(study))["solver_choice"]
    assert tresca.startswith("monolithic: each time level is one contact solve") and "): friction: " in tresca


def test_resume_answers_from_the_store_with_the_same_bits(serial, tmp_path):
    path, out, ds = serial
    folder = tmp_path / "resumed"
    shutil.copytree(out.parent, folder)
    again = folder / "serial.nc"
    stored = sorted(store_path(again).glob("*.npz"))
    assert len(stored) == 4
    for f in stored[::2]:              # the run was cut short: half its evaluations are lost
        f.unlink()
    assert main(["run", str(folder / "study.yaml"), "-o", str(again), "--resume", "--quiet", "--no-mesh-check"]) == 0
    with xr.open_dataset(again, engine="h5netcdf") as r:
        assert r.attrs["answered_from_store"] == 2 and r.attrs["solves_this_session"] == 2
        for v in ("x", "phi", "phi_history", "status", "worst_value", "worst_x", "worst_displacement",
                  "worst_contact_pressure"):
            assert np.array_equal(r[v].values, ds[v].values, equal_nan=True), v


def test_sweep_over_a_dynamic_study(tmp_path):
    doc = tiny()
    doc["sweep"] = {"grid": {"materials.steel.E": [1.9e11, 2.3e11]}}
    path = write_study(doc, tmp_path, "study.yaml")
    out = tmp_path / "sweep.nc"
    assert main(["sweep", str(path), "-o", str(out), "--quiet"]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        peak = ds["phi"].sel(criterion="peak").values
        assert ds["phi_history"].shape[:2] == (2, 4) and peak[1] > peak[0]


@pytest.mark.slow
def test_two_ranks_give_the_serial_dynamic_run_bitwise(serial, tmp_path):
    mpiexec = BIN / "mpiexec"
    if not mpiexec.exists():
        pytest.fail("mpiexec is missing from the environment (the mpich wheel provides it)")
    path, _, ds = serial
    shutil.copy(path, tmp_path / "study.yaml")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_"))}
    env["PYTHONPATH"] = str(ROOT)
    run = subprocess.run([str(mpiexec), "-n", "2", str(BIN / "wcs"), "run", "study.yaml", "-o", "mpi.nc",
                          "--quiet", "--no-mesh-check"], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr + run.stdout
    with xr.open_dataset(tmp_path / "mpi.nc", engine="h5netcdf") as m:
        for v in ("x", "phi", "phi_history", "status", "worst_value", "worst_x", "worst_displacement"):
            assert np.array_equal(m[v].values, ds[v].values, equal_nan=True), v


def test_solve_worst_runs_the_levels_at_the_worst_data(serial, tmp_path):
    path, out, ds = serial
    one = tmp_path / "worst.nc"
    assert main(["solve", str(path), "--worst", str(out), "peak", "-o", str(one), "--quiet"]) == 0
    row = int(ds["worst_eval"].sel(criterion="peak"))
    with xr.open_dataset(one, engine="h5netcdf") as w:
        assert np.array_equal(w["phi_history"].values, ds["phi_history"].values[row])
        assert float(w["phi"].sel(criterion="peak")) == float(ds["worst_value"].sel(criterion="peak"))
    assert one.with_suffix(".pvd").is_file()


def test_check_says_what_an_evaluation_is_and_names_the_reductions(serial, capsys):
    """`wcs check` of a dynamic study: the search line is the dynamic one (an evaluation is a
    simulation; the gradients as the results file records them), the solver line says the levels'
    scheme, step and method, and one evaluation's time and memory are its levels' (no static
    solve's estimate)."""
    path, _, ds = serial
    capsys.readouterr()
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "peak: the peak over time of mean contact pressure" in out and "the least over time of" in out
    assert "one evaluation is one simulation (17 levels of two contact solves" in out
    assert f"gradients: {ds.attrs['gradients']}" in out
    assert "solver: each level (stabilized scheme, Δt = 1e-05 s) by monolithic (auto): the condensed Newton" in out
    assert "A = 2M/Δt² + C/Δt + K/2" in out and "solves; solver:" not in out and "adjoint gradients, which" not in out
    line = next(row for row in out.splitlines() if "one evaluation estimated at" in row)
    words = re.search(r"about ([\d.e+-]+) GB peak and ([\d.e+-]+) s: the static state and the first level "
                      r"([\d.e+-]+) s \+ 16 levels × ([\d.e+-]+) s \(timed on 16 levels", line)
    assert words, line
    peak, total, first, level = map(float, words.groups())
    assert total == pytest.approx(first + 16 * level, rel=0.06)     # the printed figures' 2 digits
    assert 0.05 < peak < 64


def test_check_prints_the_mesh_checks_cost_of_simulations(serial, capsys):
    """Each solve of a dynamic study's mesh check is a whole simulation: `wcs check` prints its
    cost from one evaluation's measured time and memory (4 extremes × the evaluation's time grown
    as nodes^1.15 on the mesh split once and twice; memory the evaluation's peak grown as the
    nodes of the mesh split twice)."""
    from wcs.results.meshcheck import refined_nodes
    path = serial[0]
    capsys.readouterr()
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    first = re.search(r"one evaluation estimated at about ([\d.e+-]+) GB peak and ([\d.e+-]+) s", out)
    line = next(row for row in out.splitlines() if row.startswith("  mesh check"))
    words = re.search(r"up to 4 extreme data set\(s\) simulated again \(17 levels each\) on the mesh split once "
                      r"and twice, (\d+) unknowns and (\d+) unknowns; about ([\d.e+-]+) s and ([\d.e+-]+) GB peak", line)
    assert first and words, line
    peak, seconds = map(float, first.groups())
    mesh = Evaluator(load_study(tiny())).smesh.mesh
    r = [refined_nodes(mesh, s) / mesh.p.shape[1] for s in (1, 2)]
    assert [int(words[1]), int(words[2])] == [2 * refined_nodes(mesh, s) for s in (1, 2)]
    assert float(words[3]) == pytest.approx(4 * seconds * sum(x ** 1.15 for x in r), rel=0.1)   # 2 digits each
    assert float(words[4]) == pytest.approx(peak * r[1], rel=0.01)


def test_check_does_not_count_what_the_process_held_before(serial, capsys):
    """The evaluation's memory is measured from the levels (the high-water mark reset before
    them): an earlier 0.8 GB array, freed, does not enter the estimate (it did, as this process's
    peak, and a `wcs check` after a large study in the same process refused its mesh check)."""
    from pathlib import Path
    capsys.readouterr()
    status = Path("/proc/self/status").read_text().splitlines()
    before = float(next(v for v in status if v.startswith("VmRSS:")).split()[1]) * 1024.0 / 1e9
    big = np.ones(100_000_000)
    big[::512] = 2.0                                # touched: resident
    del big
    assert main(["check", str(serial[0])]) == 0
    out = capsys.readouterr().out
    peak = float(re.search(r"one evaluation estimated at about ([\d.e+-]+) GB peak", out)[1])
    assert peak < before + 0.4                      # the two bars' levels add a few MB; the array 0.8 GB


def test_check_refuses_a_mesh_check_that_would_not_fit(serial, capsys, monkeypatch):
    """A machine too small for a simulation on the mesh split twice: exit 2, the way out named."""
    monkeypatch.setattr("wcs.app.dynamics.machine_memory", lambda: 1.0e8)
    capsys.readouterr()
    assert main(["check", str(serial[0]), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "the mesh check would need about" in err and "beyond the 0.05 GB it may take" in err
    assert "`wcs run --no-mesh-check`" in err and err.count("\n") == 1


def test_a_failed_simulation_is_a_record_with_its_status_and_no_history(monkeypatch):
    """A level that fails fails its evaluation (status and message, NaN criteria and history);
    the run goes on."""
    import wcs
    import wcs.dynamics.history as history
    from wcs.errors import SolveError
    from wcs.status import Status
    study = load_study(tiny(budget=3))
    real = history.simulate

    def fails_when_soft(ev, x, others=None):
        if x[0] < 2.1e11:
            raise SolveError("time level 3 (t = 3e-05 s), step: no convergence", status=Status.CONTACT_NOT_CONVERGED)
        return real(ev, x, others)
    monkeypatch.setattr(history, "simulate", fails_when_soft)
    ds = wcs.run(study, output=False)
    bad = ds["x"].values[:, 0] < 2.1e11
    assert bad.any() and (~bad).any()
    assert (ds["status"].values[bad] == int(Status.CONTACT_NOT_CONVERGED)).all() and (ds["status"].values[~bad] == 0).all()
    assert "time level 3" in str(ds["message"].values[bad][0])
    assert np.isnan(ds["phi_history"].values[bad]).all() and np.isfinite(ds["phi_history"].values[~bad]).all()
    assert "sum over the time levels" in ds["iterations"].attrs["long_name"]


def test_compare_looks_at_the_histories(serial, tmp_path, capsys):
    _, out, ds = serial
    changed = ds.copy(deep=True)
    changed["phi_history"].values[1, 0, 3] *= 1 + 1e-9         # one level of one evaluation, phi unchanged
    changed.to_netcdf(tmp_path / "changed.nc", engine="h5netcdf")
    capsys.readouterr()
    assert main(["compare", str(out), str(tmp_path / "changed.nc")]) == 4
    assert "phi_history" in capsys.readouterr().out
