"""The command line as a user runs it: exit codes, messages, files.

Bad input must exit 2 with a message naming the file and the key path, and
never print a traceback."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from tests.support.bad_studies import CASES, broken, demo_doc, write_study
from wcs.cli import main

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "studies"


def run_cli(args, capsys):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("case_id,mutate,fragment", CASES, ids=[c[0] for c in CASES])
def test_check_rejects_bad_input(case_id, mutate, fragment, tmp_path, capsys):
    path = write_study(broken(mutate), tmp_path)
    code, out, err = run_cli(["check", path], capsys)
    assert code == 2, (out, err)
    assert "Traceback" not in err + out
    assert fragment in err and path.name in err


def _mesh_level_cases():
    """Faults only the mesh can reveal: they still exit 2 with the key path."""
    def nothing_selected(doc):
        doc["scene"]["boundaries"]["pad_top"] = {"body": "pad", "segment": [[5.0, 5.0], [6.0, 5.0]]}
    def overlapping_bodies(doc):
        doc["scene"]["bodies"]["pad"]["regions"][0]["shape"] = {"rectangle": [0.5, 0.8, 1.5, 1.5]}
    def roi_selects_nothing(doc):
        doc["scene"]["regions_of_interest"]["under_pad"] = {"box": [5.0, 5.0, 6.0, 6.0]}
    def glue_within_one_body(doc):            # the slave side is supported: it was blamed on that
        doc["scene"]["boundaries"]["base_strip"] = {"segment": [[0.2, 1.0], [0.4, 1.0]]}
        doc["scene"]["glue"] = {"g": {"slave": "base_bottom", "master": "base_strip"}}
    def subdomains_beyond_the_mesh(doc):       # 588 cells: at most 588 // 16 = 36 subdomains
        doc["scene"]["mesh"] = {"size": 0.1}
        doc["solver"] = {"method": "dd", "dd": {"subdomains": 64}}
    return [("boundary selects no edge", nothing_selected, "scene.boundaries.pad_top"),
            ("glue within one body", glue_within_one_body, "scene.glue.g.master: slave and master of a glue belong "
             "to the same body ('base')"),
            ("dd subdomains beyond the mesh", subdomains_beyond_the_mesh, "solver.dd.subdomains: 64 subdomains of a "
             "mesh of 588 cells leave fewer than 16 cells to a subdomain: give at most 36"),
            ("bodies overlap", overlapping_bodies, "scene.bodies"),
            ("region of interest selects nothing", roi_selects_nothing, "scene.regions_of_interest.under_pad")]


@pytest.mark.parametrize("case_id,mutate,fragment", _mesh_level_cases(), ids=[c[0] for c in _mesh_level_cases()])
def test_check_rejects_mesh_level_faults(case_id, mutate, fragment, tmp_path, capsys):
    path = write_study(broken(mutate), tmp_path)
    code, out, err = run_cli(["check", path], capsys)
    assert code == 2, (out, err)
    assert fragment in err and "Traceback" not in err


def test_unheld_body_without_contact_is_bad_input(tmp_path, capsys):
    doc = demo_doc()
    for key in ("contacts", "thermal"):
        doc["scene"].pop(key)
    doc["uncertain"].pop("contacts.interface.friction.slip_limit")
    doc["scene"]["supports"].pop("pad_left")
    code, out, err = run_cli(["solve", write_study(doc, tmp_path), "-o", tmp_path / "o.nc"], capsys)
    assert code == 2 and "scene.bodies.pad" in err and "not held" in err


def test_check_prints_summary(capsys):
    code, out, err = run_cli(["check", ROOT.parent / "shared" / "examples" / "two-blocks-demo.yaml"
                              if (ROOT.parent / "shared").exists() else STUDIES / "two-blocks-demo.yaml"], capsys)
    assert code == 0, err
    for word in ("bodies:", "base:", "pad:", "base_bottom:", "edges", "contact interface", "Tresca",
                 "parameters (9)", "slip_limit[5]", "criteria:", "settlement", "limit 4e+12"):
        assert word in out, word


def test_solve_writes_netcdf_and_vtu(tmp_path, capsys):
    out = tmp_path / "plate.nc"
    code, text, err = run_cli(["solve", STUDIES / "heated-plate.yaml", "-o", out], capsys)
    assert code == 0, err
    ds = xr.open_dataset(out, engine="h5netcdf")
    for var in ("coords", "cells", "displacement", "temperature", "stress", "von_mises",
                "principal_stress", "shear_stress_intensity", "x", "phi", "param_lower", "param_upper"):
        assert var in ds, var
    assert list(ds["criterion"].values) == ["heave", "shear", "temperature"]
    for attr in ("study", "study_yaml", "study_sha256", "wcs_version", "created", "solver",
                 "mesh_nodes", "mesh_cells", "Conventions"):
        assert attr in ds.attrs, attr
    assert ds.attrs["mesh_nodes"] == ds.sizes["node"]
    import meshio
    m = meshio.read(out.with_suffix(".vtu"))
    assert m.points.shape[0] == ds.sizes["node"] and "von Mises stress [Pa]" in m.cell_data
    assert np.array_equal(m.point_data["temperature [K]"], ds["temperature"].values)


def test_console_script_exit_status_and_no_traceback(tmp_path):
    """The installed `wcs` entry point itself (a subprocess, as a user runs it)."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("study: x\nscene: {dimension: 2, bodies: {}}\nbogus_key: 1\n")
    wcs = Path(sys.executable).with_name("wcs")
    proc = subprocess.run([str(wcs), "check", str(bad)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "bad.yaml" in proc.stderr and "Traceback" not in proc.stderr
    proc = subprocess.run([str(wcs), "check", str(tmp_path / "missing.yaml")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "missing.yaml" in proc.stderr and "Traceback" not in proc.stderr


def test_library_warnings_stay_off_stderr_unless_verbose(tmp_path, capsys, monkeypatch):
    """cvxpy's and numpy's warnings came before the error they led to; the error is now the
    only line, and `--verbose` shows the warnings."""
    import warnings

    import wcs.cli
    from wcs.errors import StudyError

    def check(args):
        warnings.warn("Solution may be inaccurate.", UserWarning)
        warnings.warn("invalid value encountered in divide", RuntimeWarning)
        raise StudyError("the fault", path="scene.x")
    monkeypatch.setattr(wcs.cli, "cmd_check", check)
    path = write_study(demo_doc(), tmp_path)
    code, out, err = run_cli(["check", path], capsys)
    assert (code, out, err) == (2, "", f"error: {path}: scene.x: the fault\n")
    monkeypatch.setattr(warnings, "showwarning", lambda message, category, *a, **k:   # to stderr (pytest records them)
                        print(f"{category.__name__}: {message}", file=sys.stderr))
    code, out, err = run_cli(["check", path, "--verbose"], capsys)
    assert code == 2 and "Solution may be inaccurate." in err and "invalid value encountered in divide" in err
    assert err.splitlines()[-1] == f"error: {path}: scene.x: the fault"


# ---- the command-line traps -------------------------------------------------------------------
def tiny_study(folder: Path, name: str = "hp.yaml", budget: int = 3) -> Path:
    """The heated plate with a search of `budget` solves (no contact: a solve takes milliseconds)."""
    import yaml
    doc = yaml.safe_load((STUDIES / "heated-plate.yaml").read_text())
    doc["search"] = {"method": "auto", "sample": {"n": 2}, "budget": budget}
    path = folder / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_run_refuses_an_earlier_run_unless_resume_or_fresh_says_what_to_do(tmp_path, capsys):
    """A complete or partial earlier run (results file, store) is neither overwritten nor
    continued by omission: exit 2 naming both options; --fresh discards it, --resume continues it."""
    study, out = tiny_study(tmp_path), tmp_path / "hp.nc"
    assert main(["run", str(study), "-o", str(out), "-q", "--no-mesh-check"]) == 0
    before = out.read_bytes()
    code, text, err = run_cli(["run", study, "-o", out, "-q", "--no-mesh-check"], capsys)
    assert code == 2 and "--resume" in err and "--fresh" in err and "complete results file of 3" in err, err
    assert out.read_bytes() == before and "Traceback" not in err
    out.unlink()                                         # a partial run: only its store is left
    code, text, err = run_cli(["sweep", study, "-o", out], capsys)
    assert code == 2 and "partial run" in err and "holds 3" in err, err
    code, text, err = run_cli(["run", study, "-o", out, "--resume", "--no-mesh-check"], capsys)
    assert code == 0 and "0 solved now, 3 from the store" in text, text + err
    code, text, err = run_cli(["run", study, "-o", out, "--fresh", "--no-mesh-check"], capsys)
    assert code == 0 and "3 solved now, 0 from the store" in text, text + err
    with pytest.raises(SystemExit) as e:                 # one of them at most
        main(["run", str(study), "-o", str(out), "--resume", "--fresh"])
    assert e.value.code == 2


@pytest.mark.parametrize("command", ["run", "sweep", "solve", "report"])
def test_output_into_a_missing_directory_is_bad_input_and_nothing_is_created(command, tmp_path, capsys):
    study = tiny_study(tmp_path)
    target = tmp_path / "missing" / "deeper" / ("r.html" if command == "report" else "x.nc")
    source = tmp_path / "r.nc" if command == "report" else study
    if command == "report":                             # a real results file to report on
        assert main(["run", str(study), "-o", str(source), "--quiet", "--no-mesh-check"]) == 0
    code, text, err = run_cli([command, source, "-o", target], capsys)
    assert code == 2 and f"the directory {target.parent} does not exist" in err and "-o" in err, err
    assert not (tmp_path / "missing").exists()


def test_quiet_and_verbose_are_the_same_options_on_every_command(tmp_path, capsys):
    from wcs.cli import build_parser
    study = tiny_study(tmp_path)
    for argv in (["check", "S"], ["solve", "S"], ["run", "S"], ["sweep", "S"], ["report", "R"], ["compare", "A", "B"]):
        for flag in ("-q", "--quiet", "-v", "--verbose"):
            args = build_parser().parse_args(argv + [flag])
            assert (args.quiet, args.verbose) == (flag in ("-q", "--quiet"), flag in ("-v", "--verbose")), argv
    code, text, err = run_cli(["check", study, "-q"], capsys)
    assert (code, text) == (0, "")


def test_library_logging_stays_off_stderr_unless_verbose(tmp_path, capsys, monkeypatch):
    """A library's logged warning (skfem logs through `logging`: with no handler the logging module
    prints it to stderr) is held back as its `warnings` are; --verbose shows it."""
    import logging

    import wcs.cli
    monkeypatch.setattr(logging.getLogger(), "handlers", [])          # as outside pytest: no handler

    def check(args):
        logging.getLogger("skfem").warning("a library's note")
        return 0
    monkeypatch.setattr(wcs.cli, "cmd_check", check)
    path = write_study(demo_doc(), tmp_path)
    assert run_cli(["check", path], capsys) == (0, "", "")
    code, out, err = run_cli(["check", path, "--verbose"], capsys)
    assert code == 0 and "a library's note" in err


SLOW_EVALUATIONS = """
import functools, sys, time
import wcs.model.evaluation as E
solve = E.Evaluator.evaluate
E.Evaluator.evaluate = functools.wraps(solve)(lambda self, *a, **k: (time.sleep(0.3), solve(self, *a, **k))[1])
from wcs.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_ctrl_c_exits_130_says_how_to_resume_and_the_resumed_run_is_the_uninterrupted_one(tmp_path, capsys):
    """SIGINT after the first evaluations are stored: exit 130, a message with the exact command
    that continues; that command gives the results of a run never interrupted, solving only what
    the store lacks."""
    import os
    import shlex
    import signal
    import time
    study, out = tiny_study(tmp_path, budget=8), tmp_path / "hp.nc"
    script = tmp_path / "slow.py"
    script.write_text(SLOW_EVALUATIONS)
    proc = subprocess.Popen([sys.executable, str(script), "run", str(study), "-o", str(out), "--no-mesh-check"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))   # as in a terminal
                            # (a process started with `&` by a non-interactive shell ignores SIGINT)
    store = tmp_path / "hp.nc.store"
    deadline = time.monotonic() + 120
    while len(list(store.glob("*.npz"))) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    line = err.strip().splitlines()[-1]
    assert line.startswith("interrupted: the ") and "Traceback" not in err, err
    command = shlex.split(line.split("`")[1])
    assert command[:2] == ["wcs", "run"] and "--resume" in command
    stored = len(list(store.glob("*.npz")))
    with xr.open_dataset(out, engine="h5netcdf") as partial:        # the results file holds them too
        assert partial.attrs["complete"] == "no" and partial.sizes["eval"] == stored >= 2
    code, text, _ = run_cli(command[1:], capsys)
    assert main(["run", str(study), "-o", str(tmp_path / "whole.nc"), "-q", "--no-mesh-check"]) == 0
    a, b = xr.open_dataset(out, engine="h5netcdf"), xr.open_dataset(tmp_path / "whole.nc", engine="h5netcdf")
    assert code == 0 and f"{b.sizes['eval'] - stored} solved now, {stored} from the store" in text, text
    assert b.sizes["eval"] > stored                     # it was stopped before its end
    for v in ("x", "phi", "status", "worst_value", "worst_x"):
        assert np.array_equal(a[v].values, b[v].values, equal_nan=True), v


def _readme_block(after: str, fence: str = "```yaml", page: str = "README.md") -> str:
    """The first fenced block of `page` (README.md) after the line `after`."""
    text = (ROOT / page).read_text(encoding="utf-8")
    rest = text[text.index(after):]
    start = rest.index(fence) + len(fence)
    return rest[start:rest.index("```", start)]


def test_the_docs_3d_example_is_a_study_that_checks(tmp_path, capsys):
    """The 3D syntax of docs/study-format.md (solids, face and region selectors, 3-vectors) is a
    study `check` takes."""
    import yaml
    doc = yaml.safe_load(_readme_block("### Three dimensions", page="docs/study-format.md"))
    assert doc["scene"]["dimension"] == 3
    shape = doc["scene"]["bodies"]["block"]["regions"][0]["shape"]
    assert {"box", "minus"} <= set(shape)
    path = write_study(doc, tmp_path)
    code, out, err = run_cli(["check", path], capsys)
    assert code == 0 and out.endswith("ok\n"), err
    assert "hole:" in out and "region of interest under_pad" in out and "warning" not in err


def test_the_readme_mpi_line_runs_as_written(tmp_path):
    """The README's MPI command, typed in a checkout whose .venv this is (mpiexec is not on PATH
    there: it is the venv's, from the mpich wheel)."""
    line = next(ln.strip() for ln in (ROOT / "README.md").read_text().splitlines()
                if "mpiexec -n" in ln and ln.startswith("    ") and "wcs run" in ln)
    command = line.split("#")[0].split()
    assert "STUDY.yaml" in command
    (tmp_path / ".venv").symlink_to(Path(sys.executable).parent.parent)
    tiny_study(tmp_path, "STUDY.yaml")
    env = {k: v for k, v in __import__("os").environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_"))}
    env["PATH"] = ":".join(p for p in env.get("PATH", "").split(":") if Path(p) != Path(sys.executable).parent)
    env["PYTHONPATH"] = str(ROOT)
    proc = subprocess.run(command + ["--no-mesh-check", "-q"], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    with xr.open_dataset(tmp_path / "results" / "heated-plate.nc", engine="h5netcdf") as ds:
        assert ds.sizes["eval"] == 3 and ds.attrs["complete"] == "yes"
