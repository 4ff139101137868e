"""`wcs run` / `wcs sweep` / `wcs solve --worst`: the runner, its results file, kill -9 and resume.

The runner is tested with a tiny deterministic strategy of its own (`tiny`), so these tests do
not depend on the search strategies (wcs/search/) beyond their contract.
"""
import os
import re
import signal
import subprocess
import sys
import textwrap
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr
import yaml

import wcs
import wcs.app.runner as runner
from wcs.cli import main
from wcs.app.solve import solve_worst
from wcs.app.problem import build_problem
from wcs.search import Batch, Worst
from wcs.results.store import Store, store_path
from tests.support.processes import wait_for_records

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "studies"
REAL_GET_STRATEGY = runner.get_strategy


def tiny(problem, config, rng):
    """The centre (with gradients), then `sample.n` uniform samples in batches of 3."""
    lo, hi = problem.lower, problem.upper
    n = config.sample.n
    seen = []
    outs = yield Batch((0.5 * (lo + hi))[None, :], "centre", True)
    seen += outs
    for i in range(0, n, 3):
        pts = lo + (hi - lo) * rng.random((min(3, n - i), len(lo)))
        outs = yield Batch(pts, "sample", False)
        seen += outs
        if len(outs) < len(pts):
            break
    best = {}
    for c in problem.criteria:
        ok = [o for o in seen if np.isfinite(o.phi[c])]
        if ok:
            best[c] = max(ok, key=lambda o: o.phi[c])
    return Worst(x={c: o.x for c, o in best.items()}, value={c: o.phi[c] for c, o in best.items()},
                 certificate={c: "heuristic" for c in best})


@pytest.fixture(autouse=True)
def tiny_strategy(monkeypatch):
    monkeypatch.setattr(runner, "get_strategy", lambda name: tiny)


def study_file(tmp_path, source, name=None, **changes):
    """A copy of a study file with top-level keys changed (search, uncertain, sweep, ...)."""
    doc = yaml.safe_load((STUDIES / source).read_text())
    for k, v in changes.items():
        doc[k] = v
    path = tmp_path / (name or Path(source).name)
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


SEARCH = {"method": "auto", "sample": {"design": "lhs", "n": 9, "seed": 3}, "budget": 10}
EVAL_VARS = {"x": ("eval", "param"), "phi": ("eval", "criterion"), "status": ("eval",), "stage": ("eval",),
             "wall_time": ("eval",), "iterations": ("eval",), "grad": ("eval", "criterion", "param"),
             "nonsmooth": ("eval",), "message": ("eval",)}
CRIT_VARS = {"worst_value": ("criterion",), "worst_x": ("criterion", "param"), "limit": ("criterion",),
             "certificate": ("criterion",), "worst_eval": ("criterion",)}
GLOBAL_ATTRS = ("Conventions", "study", "study_yaml", "study_sha256", "wcs_version", "git_commit", "seed",
                "created", "solver", "mesh_nodes", "mesh_cells")


def test_results_file_layout(tmp_path):
    path = study_file(tmp_path, "heated-plate.yaml", search=SEARCH)
    out = tmp_path / "run.nc"
    ds_mem = wcs.run(wcs.load_study(path), out)
    ds = xr.open_dataset(out, engine="h5netcdf")
    assert list(ds["param"].values) == ["materials.steel.E", "materials.steel.nu", "materials.steel.expansion",
                                        "thermal.temperature.top", "thermal.temperature.bottom"]
    assert list(ds["criterion"].values) == ["heave", "shear", "temperature"]
    assert ds.sizes["eval"] == 10 == ds_mem.sizes["eval"]            # the budget is a hard cap
    for name, dims in {**EVAL_VARS, **CRIT_VARS, "param_lower": ("param",), "param_upper": ("param",)}.items():
        assert ds[name].dims == dims, name
    for a in GLOBAL_ATTRS:
        assert a in ds.attrs, a
    assert ds.attrs["study_sha256"] == wcs.load_study(path).sha256 and ds.attrs["seed"] == 3
    assert ds.attrs["complete"] == "yes"
    # CF: units, long names, the box, flag values
    assert ds["wall_time"].attrs["units"] == "s"
    assert ds["x"].attrs["valid_min"] <= ds["param_lower"].min() and ds["x"].attrs["valid_max"] >= ds["param_upper"].max()
    assert len(ds["status"].attrs["flag_values"]) == len(ds["status"].attrs["flag_meanings"].split())
    assert ds["status"].attrs["flag_values"][0] == 0 and ds["status"].attrs["flag_meanings"].startswith("solved")
    assert np.all((ds["x"] >= ds["param_lower"]) & (ds["x"] <= ds["param_upper"]))
    assert list(ds["stage"].values[:2]) == ["centre", "sample"]
    # gradients where asked (the centre), NaN elsewhere
    if ds.attrs["gradients"] == "adjoint":
        assert np.isfinite(ds["grad"].values[0]).all()
    assert np.isnan(ds["grad"].values[1:]).all()
    assert ds["nonsmooth"].dtype == np.int8
    # worst: the maximum of the record, and its data set
    phi = ds["phi"].values
    assert np.array_equal(ds["worst_value"].values, phi.max(axis=0))
    for j in range(3):
        assert np.array_equal(ds["worst_x"].values[j], ds["x"].values[phi[:, j].argmax()])
    assert np.isnan(ds["limit"].sel(criterion="shear")) and ds["limit"].sel(criterion="heave") == 1e-4
    assert set(ds["certificate"].values) <= {"corner-kkt", "local-kkt", "heuristic"}
    # worst-case fields with a leading criterion dimension, the mesh once
    for name in ("displacement", "temperature", "stress", "von_mises", "shear_stress_intensity"):
        assert ds[f"worst_{name}"].dims[0] == "criterion", name
    assert ds["coords"].dims == ("node", "dim") and ds["cells"].dims == ("cell", "vertex")
    # the worst fields are the worst case: heave ~ the mean displacement of the top-edge nodes
    top = np.isclose(ds["coords"].values[:, 1], 0.5)
    heave = ds["worst_displacement"].sel(criterion="heave").values[top, 1].mean()
    assert heave == pytest.approx(float(ds["worst_value"].sel(criterion="heave")), rel=1e-2)
    # attributes are strings and numbers only
    for v in [ds, *ds.variables.values()]:
        for a, val in v.attrs.items():
            assert isinstance(val, (str, int, float, np.number, np.ndarray)) and not isinstance(val, bool), a


def test_contact_study_layout_and_lipschitz(tmp_path):
    study = wcs.load_study(STUDIES / "two-blocks-demo.yaml")
    from wcs.model.evaluation import Evaluator
    problem = build_problem(study, Evaluator(study))
    # 6 profile points -> 5 differences, two signs each; ds = 1.0 m / 5
    assert problem.A_ub.shape == (10, 9)
    assert np.allclose(problem.b_ub, 2.0e5 * 0.2)
    assert np.array_equal(problem.A_ub[0, 3:5], [-1.0, 1.0])


@pytest.fixture(scope="module")
def tresca(tmp_path_factory):
    """A clean run of the tresca pad (contact, warm starts), the reference of the resume tests."""
    tmp = tmp_path_factory.mktemp("tresca")
    search = {"method": "auto", "sample": {"design": "lhs", "n": 14, "seed": 5}, "budget": 15}
    path = study_file(tmp, "validation/tresca-pad.yaml", search=search)
    runner_get = runner.get_strategy
    runner.get_strategy = lambda name: tiny
    try:
        ds = wcs.run(wcs.load_study(path), tmp / "clean.nc")
    finally:
        runner.get_strategy = runner_get
    return path, ds


BITWISE = ("x", "phi", "status", "worst_value", "worst_x")


def _assert_bitwise(a, b):
    for name in BITWISE:
        assert np.array_equal(a[name].values, b[name].values, equal_nan=True), name
    worst = [v for v in a.data_vars if v.startswith("worst_") and v not in BITWISE]
    assert "worst_contact_pressure" in worst and "worst_displacement" in worst
    for name in worst:
        assert np.array_equal(a[name].values, b[name].values, equal_nan=True), name


def test_rerun_is_bitwise_identical(tresca, tmp_path):
    path, clean = tresca
    again = wcs.run(wcs.load_study(path), tmp_path / "again.nc")
    _assert_bitwise(clean, again)
    assert again.attrs["solves_this_session"] == 15 and again.attrs["answered_from_store"] == 0


def test_kill_9_then_resume(tresca, tmp_path):
    path, clean = tresca
    out = tmp_path / "killed.nc"
    script = tmp_path / "run_tiny.py"
    script.write_text(textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        import functools
        import time
        import wcs.model.evaluation
        import wcs.app.runner
        from tests.app.test_runner import tiny
        wcs.app.runner.get_strategy = lambda name: tiny
        solve = wcs.model.evaluation.Evaluator.evaluate
        @functools.wraps(solve)           # keeps the signature: the runner asks for gradients by it
        def slow(self, *a, **k):          # 0.2 s per evaluation: the kill lands mid-run, not after it
            time.sleep(0.2)
            return solve(self, *a, **k)
        wcs.model.evaluation.Evaluator.evaluate = slow
        from wcs.cli import main
        sys.exit(main(sys.argv[1:]))
    """))
    proc = subprocess.Popen([sys.executable, str(script), "run", str(path), "-o", str(out), "--quiet"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    store = store_path(out)
    wait_for_records(proc, out, 6)
    assert proc.poll() is None, proc.communicate()
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    stored = len(list(store.glob("*.npz")))
    assert 6 <= stored < 15
    # the file on disk is a complete, readable file of the evaluations up to its last rewrite
    assert out.exists()
    with xr.open_dataset(out, engine="h5netcdf") as part:
        n = part.sizes["eval"]
        assert 1 <= n <= stored and part.attrs["complete"] == "no"
        assert np.array_equal(part["x"].values, clean["x"].values[:n])
        assert np.array_equal(part["phi"].values, clean["phi"].values[:n])
    # resume: stored points are answered from the store, only the rest is solved, same bits
    resumed = wcs.run(wcs.load_study(path), out, resume=True)
    assert resumed.attrs["answered_from_store"] == stored
    assert resumed.attrs["solves_this_session"] == 15 - stored
    _assert_bitwise(clean, resumed)
    on_disk = xr.open_dataset(out, engine="h5netcdf")
    _assert_bitwise(clean, on_disk)
    assert on_disk.attrs["complete"] == "yes"


def test_resume_refuses_another_study(tresca, tmp_path, capsys):
    path, _ = tresca
    out = tmp_path / "r.nc"
    small = {"method": "auto", "sample": {"n": 2, "seed": 5}, "budget": 3}
    p1 = study_file(tmp_path, "validation/tresca-pad.yaml", name="a.yaml", search=small)
    assert main(["run", str(p1), "-o", str(out), "--quiet"]) == 0
    p2 = study_file(tmp_path, "validation/tresca-pad.yaml", name="b.yaml", search={**small, "budget": 4})
    capsys.readouterr()
    assert main(["run", str(p2), "-o", str(out), "--resume", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "another study file" in err and "Traceback" not in err
    # resuming the same study again solves nothing
    assert main(["run", str(p1), "-o", str(out), "--resume", "--quiet"]) == 0
    assert xr.open_dataset(out, engine="h5netcdf").attrs["solves_this_session"] == 0


def test_failures_are_data(tmp_path):
    """Shear loads above the slip limit break solvability: recorded with their status, the run goes on."""
    doc = yaml.safe_load((STUDIES / "validation/tresca-pad.yaml").read_text())
    uncertain = dict(doc["uncertain"])
    uncertain["loads.pad_top.traction.0"] = [1.0e5, 4.5e5]
    search = {"method": "auto", "sample": {"n": 9, "seed": 1}, "budget": 10}
    path = study_file(tmp_path, "validation/tresca-pad.yaml", uncertain=uncertain, search=search)
    ds = wcs.run(wcs.load_study(path), tmp_path / "fail.nc")
    status = ds["status"].values
    assert ds.sizes["eval"] == 10 and (status == 3).any() and (status == 0).any()
    bad = status != 0
    assert np.isnan(ds["phi"].values[bad]).all() and np.isfinite(ds["phi"].values[~bad]).all()
    assert all("solvability" in m for m in ds["message"].values[bad])
    assert ds.attrs["failed_evaluations"] == int(bad.sum())
    assert np.isfinite(ds["worst_value"].values).all()


def test_evaluation_that_raises_is_recorded(tmp_path, monkeypatch):
    path = study_file(tmp_path, "glued-layers.yaml", search={"method": "auto", "sample": {"n": 3}, "budget": 4})
    study = wcs.load_study(path)
    r = runner.Runner(study, tmp_path / "raise.nc")
    real, calls = r.evaluator.evaluate, []

    def flaky(x, **kw):
        calls.append(1)
        if len(calls) == 2:
            raise FloatingPointError("boom")
        return real(x, **kw)
    r.evaluator.evaluate = flaky
    ds = r.run(tiny)
    assert list(ds["status"].values) == [0, 6, 0, 0]
    assert "boom" in ds["message"].values[1]


def test_budget_is_a_hard_cap(tmp_path):
    def greedy(problem, config, rng):
        outs = yield Batch(np.tile(problem.lower, (7, 1)) + np.arange(7)[:, None] * 1e-3 * problem.upper,
                           "sample", False)
        assert len(outs) == 4
        outs = yield Batch(problem.upper[None, :], "sample", False)
        return Worst({}, {}, {})
    path = study_file(tmp_path, "glued-layers.yaml", search={"method": "auto", "budget": 4})
    ds = wcs.run(wcs.load_study(path), False, strategy=greedy)
    assert ds.sizes["eval"] == 4


def test_fail_on_limit_exit_3(tmp_path, capsys):
    path = study_file(tmp_path, "heated-plate.yaml", search={"method": "auto", "sample": {"n": 2}, "budget": 3})
    out = tmp_path / "h.nc"
    assert main(["run", str(path), "-o", str(out), "--fail-on-limit"]) == 3
    text = capsys.readouterr().out
    assert "heave" in text and "FAIL" in text and "certificate" in text
    assert main(["run", str(path), "-o", str(out), "--quiet", "--fresh"]) == 0


def test_sweep(tmp_path):
    grid = {"loads.top.pressure": [0.8e6, 1.2e6], "materials.concrete.E": [2.5e10, 3.5e10],
            "materials.steel.nu": [0.25, 0.3, 0.35]}          # the last one is not a parameter
    path = study_file(tmp_path, "glued-layers.yaml", sweep={"grid": grid})
    out = tmp_path / "sweep.nc"
    assert main(["sweep", str(path), "-o", str(out), "--quiet"]) == 0
    ds = xr.open_dataset(out, engine="h5netcdf")
    assert ds.sizes["eval"] == 12 and set(ds["stage"].values) == {"sweep"}
    assert list(ds["sweep_path"].values) == list(grid)
    assert ds["sweep_value"].dims == ("eval", "sweep_path")
    sv = ds["sweep_value"].values
    assert np.array_equal(sv[:, 0], ds["x"].sel(param="loads.top.pressure").values)
    assert set(sv[:, 2]) == {0.25, 0.3, 0.35}
    # settlement (downwards) is largest at the highest pressure on the softest concrete
    i = int(ds["worst_eval"].sel(criterion="settlement"))
    assert sv[i, 0] == 1.2e6 and sv[i, 1] == 2.5e10
    assert set(ds["certificate"].values) == {"grid"}


def test_solve_worst(tresca, tmp_path):
    path, clean = tresca
    run_file = tmp_path / "w.nc"
    clean.to_netcdf(run_file, engine="h5netcdf")
    out = tmp_path / "worst.nc"
    args = SimpleNamespace(study=str(path), worst=[str(run_file), "shift"], output=str(out), quiet=True)
    assert solve_worst(args) == 0
    ds = xr.open_dataset(out, engine="h5netcdf")
    assert out.with_suffix(".vtu").exists()
    assert np.array_equal(ds["x"].values, clean["worst_x"].sel(criterion="shift").values)
    assert float(ds["phi"].sel(criterion="shift")) == pytest.approx(
        float(clean["worst_value"].sel(criterion="shift")), rel=1e-10)
    bad = SimpleNamespace(study=str(path), worst=[str(run_file), "nope"], output=str(out), quiet=True)
    with pytest.raises(wcs.StudyError, match="no criterion 'nope'"):
        solve_worst(bad)


def test_store_keys_exact_bits(tmp_path):
    from wcs.results.store import key
    x = np.array([1.0, 2.0])
    assert key("s", x) == key("s", x.copy()) != key("s", np.nextafter(x, 3)) != key("t", x)
    st = Store(tmp_path / "st", "abc")
    st.put(key("abc", x), {"x": x, "phi": np.array([np.nan])})
    assert np.array_equal(Store(tmp_path / "st", "abc").get(key("abc", x))["x"], x)
    with pytest.raises(wcs.StudyError):
        Store(tmp_path / "st", "other")


def test_progress_modes(capsys):
    import io
    from wcs.progress import Progress
    s = io.StringIO()
    p = Progress("line", stream=s, interval=0, tick=None)
    p.start(10, ["a", "b"])
    rec = {"phi": np.array([1.0, 2.0]), "status": 0, "message": "solved", "stage": "sample", "wall_time": 0.1}
    p.update(1, rec, {"a": 1.0, "b": 2.0})
    p.update(2, rec, {"a": 1.5, "b": 2.0})
    p.update(3, {**rec, "status": 3, "phi": np.full(2, np.nan)}, {"a": 1.5, "b": 2.0})   # the line counts failures
    p.finish()
    text = s.getvalue()
    assert text.startswith("\revals 1/10  best: a=1 b=2  [0:00, eta") and "\revals 2/10" in text
    assert "\n" not in text[:-1] and text.endswith("[done in 0:00]  \n")
    assert "\revals 3/10  best: a=1.5 b=2  1 failed  [" in text
    q = io.StringIO()
    p = Progress("quiet", stream=q)
    p.start(10, ["a"])
    p.update(1, rec, {"a": 1.0})
    assert q.getvalue() == ""
    assert Progress(None, stream=io.StringIO()).mode == "quiet"        # not a terminal: quiet


def shown(stream) -> str:
    """The line a terminal shows last (each drawn over the one before it after a carriage return)."""
    return stream.getvalue().split("\r")[-1].rstrip(" ")


class Clock:
    """time.perf_counter for wcs.progress: `now` seconds."""
    def __init__(self):
        self.now = 0.0

    def perf_counter(self):
        return self.now


def test_the_eta_of_a_search_is_its_batch_at_the_measured_rate_not_its_budget(monkeypatch):
    """The first ETA of the 3D knee said 22 min (its whole budget at the first evaluation's pace)
    for a run of under 3: the search stops by itself, its budget is a cap. The ETA is the batch
    being answered at the rate measured over the last evaluations, the cold first one left out."""
    import io

    import wcs.progress
    clock = Clock()
    monkeypatch.setattr(wcs.progress, "time", clock)
    s = io.StringIO()
    p = wcs.progress.Progress("line", stream=s, interval=0, tick=None)
    p.start(200, ["a"], budget=True)
    p.batch("sample", 10)
    rec = {"phi": np.array([1.0]), "status": 0, "message": "solved", "stage": "sample", "wall_time": 2.0}
    clock.now = 8.0                        # a cold first evaluation: 8 s
    p.update(1, rec, {"a": 1.0})
    assert s.getvalue().endswith("evals 1 (budget 200)  sample 1/10  best: a=1  [0:08, eta 1:12 for sample]")
    for k in range(2, 5):                  # then 2 s each
        clock.now += 2.0
        p.update(k, rec, {"a": 1.0})
    assert s.getvalue().endswith("sample 4/10  best: a=1  [0:14, eta 0:12 for sample]")    # 6 left x 2 s
    p.batch("corner", 3)
    assert p.eta() == pytest.approx(3 * 2.0)
    for k in range(5, 5 + wcs.progress.WINDOW):
        clock.now += 2.0
        p.update(k, rec, {"a": 1.0})
    assert p.eta() == 0.0 and p.stage_end == 7
    p.batch("local", 5)
    assert p.eta() == pytest.approx(5 * 2.0)
    p.finish()
    assert s.getvalue().split("\r")[-1].rstrip(" \n") == "evals 24 (budget 200)  best: a=1  [done in 0:54]"
    assert "\revals 5 (budget 200)  corner 1/3  best: a=1  [0:16, eta 0:04 for corner]" in s.getvalue()


def test_a_phase_shows_its_parts_and_eta_and_its_line_goes_when_it_ends(monkeypatch):
    import io

    import wcs.progress
    from wcs.progress import Progress, phase, reporting
    clock = Clock()
    monkeypatch.setattr(wcs.progress, "time", clock)
    s = io.StringIO()
    with reporting(Progress("line", stream=s, interval=0, tick=None)):
        with phase("mesh check", 4) as p:
            assert shown(s) == "mesh check 0/4  [eta …]"
            clock.now = 10.0
            p.step()
            with phase("meshing"):          # inside it: both on the line
                clock.now = 12.0
                phase("assembly").__enter__().__exit__()
                assert shown(s) == "mesh check 1/4  [eta 0:36] › meshing  [0:02]"
            p.step()
            assert shown(s) == "mesh check 2/4  [eta 0:12]"
    assert s.getvalue().endswith("\r" + " " * len("mesh check 2/4  [eta 0:12]") + "\r")     # cleared
    v = io.StringIO()
    with reporting(Progress("verbose", stream=v)):
        with phase("report", 2) as p:
            p.step()
            p.step()
    assert v.getvalue() == "report 2/2 in 0:00\n"
    q = io.StringIO()                       # a log (not a terminal): nothing
    with reporting(Progress(None, stream=q)), phase("mesh check", 2) as p:
        p.step()
    assert q.getvalue() == "" and wcs.progress.current().mode == "quiet"


def test_a_run_and_its_report_show_every_long_phase_on_a_terminal(tmp_path, capsys, monkeypatch):
    """Meshing, assembly, the search, the worst cases' fields, the drivers, the mesh check and the
    report's sections each have their line (they ran silent after the search's "done": a minute
    of mesh check and of report on the 3D knee)."""
    monkeypatch.setattr(runner, "get_strategy", REAL_GET_STRATEGY)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    path = study_file(tmp_path, "heated-plate.yaml", search={"method": "auto", "sample": {"n": 2}, "budget": 4})
    out = tmp_path / "hp.nc"
    assert main(["run", str(path), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert re.search(r"\revals [1-4] \(budget 4\)  \w+ \d/\d  best: heave=", err)     # throttled: 0.2 s apart
    for line in ("\rmeshing  [", "\rassembly  [", "\rworst cases' fields 1/",
                 "\rdrivers", "\rmesh check 0/", "\rmesh check 1/"):
        assert line in err, line
    # a phase inside another one: the outer's ETA (wall clock: any value on a loaded machine), then the inner
    assert re.search(r"  \[eta \d+:\d\d\] › meshing  \[", err)
    one = tmp_path / "one.nc"                              # a solve file: a report of few figures
    assert main(["solve", str(path), "-o", str(one)]) == 0 and "\rsolve  [" in capsys.readouterr().err
    assert main(["report", str(one)]) == 0
    err = capsys.readouterr().err
    assert "\rreport 0/" in err and "\rreport 1/" in err
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    assert main(["check", str(path)]) == 0
    assert "\r" not in capsys.readouterr().err           # a log: no carriage returns


def test_with_the_registered_strategy(tmp_path, monkeypatch, capsys):
    """`wcs run` end to end with the strategy of `search.method` from wcs.search.registry."""
    pytest.importorskip("wcs.search.registry")
    monkeypatch.setattr(runner, "get_strategy", REAL_GET_STRATEGY)
    out = tmp_path / "hp.nc"
    assert main(["run", str(STUDIES / "heated-plate.yaml"), "-o", str(out), "--quiet"]) == 0
    ds = xr.open_dataset(out, engine="h5netcdf")
    assert 1 <= ds.sizes["eval"] <= 40 and ds.attrs["complete"] == "yes"
    assert set(ds["certificate"].values) <= {"corner-kkt", "local-kkt", "heuristic"}
    assert main(["run", str(STUDIES / "heated-plate.yaml"), "-o", str(out), "--resume", "--quiet"]) == 0
    again = xr.open_dataset(out, engine="h5netcdf")
    assert again.attrs["solves_this_session"] == 0
    assert np.array_equal(again["x"].values, ds["x"].values) and np.array_equal(again["phi"].values, ds["phi"].values)
