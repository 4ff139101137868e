"""Faults around the output of `wcs run` and around the study file it reads: each
ends in one clear line and a defined exit status, and loses nothing already stored.

- a directory, an over-long name or an unwritable folder as the output: exit 2 before solving,
  nothing written beside it;
- a full disk (a real 2 MB tmpfs when we may mount one, else RLIMIT_FSIZE), a SIGINT inside a
  store or NetCDF write: exit 1 with one line, no temporary left, the store whole, `--resume`
  finishes with the bits of a clean run;
- two runs on one output: the second is refused naming the first's pid; kill -9 leaves no lock;
- a run stopped by kill -9: `report` and `solve --worst` say it is incomplete and how to resume;
- a run in which no evaluation solved: exit 1;
- the study's warnings and every fallback of the solver are shown in the file and the report.
"""
import contextlib
import dataclasses
import os
import resource
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

import wcs
import wcs.app.runner as runner
from wcs.cli import main
from wcs.report.data import from_dataset, load
from wcs.report.html import Report
from wcs.results.store import store_path, writer
from tests.support.processes import wait_for_records

ROOT = Path(__file__).resolve().parents[2]


def err_lines(err: str) -> list[str]:
    """What a run printed on stderr, less the study's warnings (printed before solving)."""
    return [line for line in err.splitlines() if not line.startswith("warning: ")]
STUDIES = ROOT / "studies"
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
BITWISE = ("x", "phi", "status", "worst_value", "worst_x")


def study_file(tmp_path, source, name=None, **changes):
    doc = yaml.safe_load((STUDIES / source).read_text())
    doc.update(changes)
    path = tmp_path / (name or Path(source).name)
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def plate(tmp_path, budget=15, **changes):
    """heated-plate with the tests' own tiny strategy (`budget` evaluations), no limit broken."""
    return study_file(tmp_path, "heated-plate.yaml", search={"method": "auto", "sample": {"n": budget - 1, "seed": 3},
                                                             "budget": budget}, limits={"heave": 1.0}, **changes)


def pad(tmp_path, budget):
    """The Tresca pad (contact) with the tiny strategy, whose resumed runs are bitwise the clean one
    (tests/app/test_runner.py). Not heated-plate: there an evaluation's last bits depend on the evaluations
    solved before it in the process (shear 2e16 Pa^2 off by ~200), a value that depended on history."""
    return study_file(tmp_path, "validation/tresca-pad.yaml",
                      search={"method": "auto", "sample": {"n": budget - 1, "seed": 5}, "budget": budget})


@pytest.fixture(autouse=True)
def tiny_strategy(monkeypatch):
    from tests.app.test_runner import tiny
    monkeypatch.setattr(runner, "get_strategy", lambda name: tiny)


# `wcs` in a subprocess with the tiny strategy, each evaluation slowed by SLEEP s, and an optional
# SIGINT sent to itself inside the N-th call of a write function (WHERE: "store" or "netcdf")
SCRIPT = """
import os, signal, sys, time, functools
sys.path.insert(0, {root!r})
import numpy as np
import wcs.model.evaluation, wcs.app.runner
from tests.app.test_runner import tiny
wcs.app.runner.get_strategy = lambda name: tiny
solve = wcs.model.evaluation.Evaluator.evaluate
@functools.wraps(solve)
def slow(self, *a, **k):
    time.sleep(float(os.environ.get("SLEEP", "0")))
    return solve(self, *a, **k)
wcs.model.evaluation.Evaluator.evaluate = slow
where, nth, calls = os.environ.get("WHERE"), int(os.environ.get("NTH", "0")), []
def interrupting(real):
    def write(*a, **k):
        calls.append(1)
        if len(calls) == nth:             # Ctrl-C in the middle of the write
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
        return real(*a, **k)
    return write
if where == "store":
    np.savez = interrupting(np.savez)
elif where == "netcdf":                  # every results file is encoded here (`write_netcdf`)
    import wcs.results.netcdf
    wcs.results.netcdf.encode = interrupting(wcs.results.netcdf.encode)
from wcs.cli import main
sys.exit(main(sys.argv[1:]))
"""


def wcs_process(tmp_path, *args, preexec=None, **env):
    script = tmp_path / "wcs_slow.py"
    script.write_text(SCRIPT.format(root=str(ROOT)))
    return subprocess.Popen([sys.executable, str(script), *map(str, args)], cwd=tmp_path,
                            env={**ENV, **{k: str(v) for k, v in env.items()}}, preexec_fn=preexec,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def assert_intact(folder: Path):
    """No temporary left anywhere; every stored evaluation and the results file readable."""
    assert not [p for p in folder.rglob("*") if p.name.endswith(".part")]
    for f in folder.rglob("*.npz"):
        with np.load(f) as z:
            assert "phi" in z.files
    for f in folder.glob("*.nc"):
        with xr.open_dataset(f, engine="h5netcdf") as ds:
            assert ds.sizes["eval"] >= 1


def assert_bitwise(a, b):
    for name in BITWISE:
        assert np.array_equal(a[name].values, b[name].values, equal_nan=True), name


# ---------------------------------------------------------------- refused before solving (exit 2)


def test_a_directory_as_output_is_refused_and_nothing_is_written_beside_it(tmp_path, capsys):
    target = tmp_path / "D"
    target.mkdir()
    path = plate(tmp_path, output=str(target))
    assert main(["run", str(path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{path}: output: the output {target} is a directory" in err and len(err.splitlines()) == 1
    assert main(["run", str(path), "-o", str(target), "--quiet"]) == 2
    assert capsys.readouterr().err.startswith(f"error: {path}: -o: the output {target} is a directory")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["D", path.name]
    assert list(target.iterdir()) == []


def test_an_output_name_too_long_or_under_a_file_is_refused(tmp_path, capsys):
    path = plate(tmp_path)
    name_max = os.pathconf(tmp_path, "PC_NAME_MAX")
    long = tmp_path / ("x" * (name_max - 10) + ".nc")     # fits, but OUT.store and .OUT.<pid>.part do not
    assert main(["run", str(path), "-o", str(long), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "-o: the output file name" in err and f"the filesystem allows {name_max - 14}" in err
    (tmp_path / "afile").write_text("")
    assert main(["run", str(path), "-o", str(tmp_path / "afile" / "out.nc"), "--quiet"]) == 2
    assert f"the directory {tmp_path / 'afile'} is not a directory" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", path.name]


def test_an_output_name_with_a_nul_is_refused_before_solving(tmp_path, capsys, monkeypatch):
    """No file system takes a NUL in a name: `check` said ok to it and `run` failed at its output
    lock as an internal error (exit 1, ValueError: embedded null byte)."""
    path = plate(tmp_path, output=str(tmp_path / "o\x00ut.nc"))
    import wcs.model.evaluation
    monkeypatch.setattr(wcs.model.evaluation, "Evaluator", lambda *a: pytest.fail("meshed before the output was checked"))
    for command in ("check", "run"):
        assert main([command, str(path), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"error: {path}: output: the output name ") and "NUL" in err, err
        assert len(err.splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


@contextlib.contextmanager
def read_only_folder(folder: Path):
    """A folder nobody may write in: a read-only tmpfs for root (who ignores modes), else mode 555."""
    folder.mkdir()
    if os.geteuid() != 0:
        folder.chmod(0o555)
        yield folder
        folder.chmod(0o755)
        return
    subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(folder)], check=True)
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


def test_a_read_only_output_folder_is_refused_before_solving(tmp_path, capsys, monkeypatch):
    path = plate(tmp_path)
    import wcs.model.evaluation
    monkeypatch.setattr(wcs.model.evaluation, "Evaluator", lambda *a: pytest.fail("meshed before the output was checked"))
    with read_only_folder(tmp_path / "ro") as ro:
        assert main(["run", str(path), "-o", str(ro / "out.nc"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"error: {path}: -o: cannot write beside the output {ro / 'out.nc'}: " in err
    assert "Read-only file system" in err or "Permission denied" in err


# ---------------------------------------------------------------- faults during the run (exit 1)


@contextlib.contextmanager
def small_disk(folder: Path, free: int):
    """A folder with `free` bytes left: a 2 MB tmpfs filled up (root), else RLIMIT_FSIZE = free
    for the child (a write past it fails with EFBIG instead of ENOSPC). Yields a preexec_fn."""
    folder.mkdir()
    mounted = os.geteuid() == 0 and subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(folder)]).returncode == 0
    if not mounted:
        def limit():
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (free, free))
        yield limit, None
        return
    filler = folder / "filler"
    filler.write_bytes(b"\0" * (2 * 1024 * 1024 - free))
    try:
        yield None, filler
    finally:
        subprocess.run(["umount", str(folder)], check=True)


@pytest.mark.slow
def test_a_full_disk_stops_with_one_line_and_resume_finishes(tmp_path):
    path = pad(tmp_path, budget=30)
    clean = wcs.run(wcs.load_study(path), tmp_path / "clean.nc")
    disk = tmp_path / "disk"
    with small_disk(disk, free=650_000) as (preexec, filler):     # one results file (0.6 MB) fits, not two
        out = disk / "out.nc"
        proc = wcs_process(tmp_path, "run", path, "-o", out, "--quiet", preexec=preexec, SLEEP=0.1)  # rewrites mid-run
        _, err = proc.communicate(timeout=300)
        assert proc.returncode == 1, err
        lines = err_lines(err)
        assert len(lines) == 1 and lines[0].startswith("error: cannot write ") and "--resume" in lines[0], lines
        assert ("No space left on device" if filler else "File too large") in lines[0]
        stored = len(list(store_path(out).glob("*.npz")))
        assert 1 <= stored < 30 and f"keeps every evaluation finished so far ({stored})" in lines[0]
        assert_intact(disk)
        if filler:
            filler.unlink()                   # space again: the run continues from its store
        if filler:
            assert main(["run", str(path), "-o", str(out), "--resume", "--quiet"]) == 0
            with xr.open_dataset(out, engine="h5netcdf") as ds:
                assert ds.attrs["complete"] == "yes" and ds.attrs["answered_from_store"] == stored
                assert_bitwise(clean, ds)


@pytest.mark.parametrize("where,nth", [("store", 3), pytest.param("netcdf", 2, marks=pytest.mark.slow)])
def test_ctrl_c_inside_a_write_ends_between_writes_and_resume_is_bitwise(tmp_path, where, nth):
    path = pad(tmp_path, budget=6)
    clean = wcs.run(wcs.load_study(path), tmp_path / "clean.nc")
    out = tmp_path / "out.nc"
    proc = wcs_process(tmp_path, "run", path, "-o", out, "--quiet", WHERE=where, NTH=nth,
                       preexec=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))   # as in a terminal, not
    _, err = proc.communicate(timeout=120)                                            # as pytest run with `&`
    lines = err_lines(err)                # exit 130 and the command that continues
    assert proc.returncode == 130 and len(lines) == 1 and lines[0].startswith("interrupted: the "), err
    assert lines[0].endswith(f"continue with `wcs run {path} -o {out} --resume`"), err
    assert_intact(tmp_path)
    if where == "store":                  # the interrupted record was finished, then the run stopped
        assert len(list(store_path(out).glob("*.npz"))) == nth
    assert writer(out) is None and not (tmp_path / "out.nc.lock").exists()
    resumed = wcs.run(wcs.load_study(path), out, resume=True)
    assert_bitwise(clean, resumed)


@pytest.mark.slow
def test_a_store_removed_mid_run_stops_with_one_line(tmp_path):
    path = pad(tmp_path, budget=15)
    out = tmp_path / "out.nc"
    proc = wcs_process(tmp_path, "run", path, "-o", out, "--quiet", SLEEP=0.2)
    wait_for_records(proc, out, 3)
    shutil.rmtree(store_path(out))
    _, err = proc.communicate(timeout=120)
    lines = err_lines(err)
    assert proc.returncode == 1 and len(lines) == 1, err
    assert lines[0].startswith(f"error: cannot write {store_path(out)}/") and "No such file or directory" in err
    assert_intact(tmp_path)
    assert writer(out) is None


# ---------------------------------------------------------------- two runs, kill -9, incomplete files


def test_second_run_refused_and_a_killed_run_says_it_is_incomplete(tmp_path, capsys):
    path = plate(tmp_path)
    out = tmp_path / "out.nc"
    proc = wcs_process(tmp_path, "run", path, "-o", out, "--quiet", SLEEP=0.2)
    wait_for_records(proc, out, 4)
    os.kill(proc.pid, signal.SIGSTOP)     # held where it is: on a loaded machine it finished all 15 before the kill
    # a second run on the same output, fresh or resumed, is refused; the first one's files are untouched
    for extra in ([], ["--resume"]):
        assert main(["run", str(path), "-o", str(out), "--quiet", *extra]) == 2
        err = capsys.readouterr().err
        assert f"another `wcs run` (pid {proc.pid}) is writing {out}" in err, err
    assert len(list(store_path(out).glob("*.npz"))) >= 4
    assert f"still running (pid {proc.pid})" in load(out).incomplete
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert writer(out) is None                      # the lock died with the process
    stored = len(list(store_path(out).glob("*.npz")))
    res = load(out)
    assert 1 <= res.n_eval <= stored < 15
    assert (f"evaluation{'s' * (res.n_eval != 1)}, the store beside it ({store_path(out)}) {stored};" in res.incomplete
            and f"wcs run {path} -o {out} --resume" in res.incomplete)
    summary = Report(res, str(out)).summary()
    assert 'id="incomplete"' in summary and ">INCOMPLETE RUN<" in summary and "PASS" not in summary
    # `wcs solve --worst` refuses the incomplete run, saying how to finish it
    assert main(["solve", str(path), "--worst", str(out), "heave", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "the run is incomplete" in err and f"-o {out} --resume" in err
    # resumed, the run is whole and says so
    assert main(["run", str(path), "-o", str(out), "--resume", "--quiet"]) == 0
    res = load(out)
    assert res.incomplete == "" and res.n_eval == 15 and res.attrs["answered_from_store"] == stored
    assert ">PASS<" in Report(res, str(out)).summary()


def test_a_run_in_which_no_evaluation_solved_exits_1(tmp_path, capsys):
    """Every shear load above every slip limit: solvability fails at every data set."""
    doc = yaml.safe_load((STUDIES / "validation/tresca-pad.yaml").read_text())
    doc["scene"]["loads"]["pad_top"]["traction"][0] = 4.3e5
    uncertain = {**doc["uncertain"], "loads.pad_top.traction.0": [4.1e5, 4.5e5]}
    path = study_file(tmp_path, "validation/tresca-pad.yaml", uncertain=uncertain, scene=doc["scene"],
                      search={"method": "auto", "sample": {"n": 3, "seed": 1}, "budget": 4})
    out = tmp_path / "none.nc"
    assert main(["run", str(path), "-o", str(out), "--quiet"]) == 1
    lines = err_lines(capsys.readouterr().err)
    assert len(lines) == 1 and lines[0].startswith("error: no evaluation solved (4 with status 3 (solvability violated")
    assert f"{out} records their statuses" in lines[0]
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert list(ds["status"].values) == [3, 3, 3, 3] and ds.attrs["complete"] == "yes"


# ---------------------------------------------------------------- warnings and fallbacks are visible


def test_study_warnings_and_fallbacks_reach_the_file_and_the_report(tmp_path):
    study = dataclasses.replace(wcs.load_study(plate(tmp_path, budget=3)),
                                warnings=["materials.steel.nu: ν = 0.49 ≥ 0.45: P1 elements lock", "a second warning"])
    ds = wcs.run(study, tmp_path / "w.nc")
    with xr.open_dataset(tmp_path / "w.nc", engine="h5netcdf") as f:
        assert f.attrs["warnings"] == "materials.steel.nu: ν = 0.49 ≥ 0.45: P1 elements lock\na second warning"
    summary = Report(load(tmp_path / "w.nc")).summary()
    assert 'id="study-warnings"' in summary
    assert "<li>materials.steel.nu: ν = 0.49 ≥ 0.45: P1 elements lock</li>" in summary
    assert 'id="fallbacks"' not in summary
    fallback = "solved (monolithic after dd did not converge in 40 steps)"
    ds["message"].values[[0, 2]] = fallback
    summary = Report(from_dataset(ds)).summary()
    assert "2 of 3 evaluations were solved by a fallback" in summary and f"<li>2 × {fallback}</li>" in summary
    plain = wcs.run(wcs.load_study(plate(tmp_path, budget=3)), False)
    assert plain.attrs["warnings"] == "" and 'id="study-warnings"' not in Report(from_dataset(plain)).summary()


def test_run_prints_the_study_warnings(tmp_path, capsys):
    """A study whose Poisson ratio reaches 0.48 (P1 locking): `wcs run` says so on stderr
    before solving, as `check` does, besides the file and the report."""
    doc = yaml.safe_load((ROOT / "studies" / "two-blocks-demo.yaml").read_text())
    doc["search"] = {"method": "sample", "budget": 1, "sample": {"n": 1}}
    doc["scene"]["mesh"] = {"size": 0.2}
    doc["solver"] = {"method": "monolithic"}
    path = tmp_path / "demo.yaml"
    path.write_text(yaml.safe_dump(doc))
    assert main(["run", str(path), "-o", str(tmp_path / "d.nc"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert f"warning: {path}: " in err and "Poisson ratio up to 0.48" in err


# ---------------------------------------------------------------- study files that never end


def test_a_device_a_fifo_or_an_oversized_study_file_is_refused_unread(tmp_path, capsys):
    """/dev/zero never ends and a FIFO blocks until written: refused from their file type, never
    read; a study over MAX_FILE_BYTES (a valid one, padded with a comment) is refused with its size."""
    from wcs.study.source import MAX_FILE_BYTES
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    for path, kind in (("/dev/zero", "a device"), (fifo, "a FIFO"), (tmp_path, "a directory")):
        assert main(["check", str(path), "--quiet"]) == 2
        assert capsys.readouterr().err == (f"error: {path}: not a regular file ({kind}): study, scene and material "
                                           "files are YAML files\n")
    scene = tmp_path / "scene.yaml"                  # a scene file the study names: the same
    os.mkfifo(scene)
    study = plate(tmp_path, scene="scene.yaml")
    assert main(["check", str(study), "--quiet"]) == 2
    assert capsys.readouterr().err == (f"error: {scene}: not a regular file (a FIFO): study, scene and material "
                                       "files are YAML files\n")
    big = plate(tmp_path)
    size = MAX_FILE_BYTES + 1000
    with big.open("a") as f:
        f.write("#" * (size - big.stat().st_size - 1) + "\n")
    assert big.stat().st_size == size
    assert main(["check", str(big), "--quiet"]) == 2
    assert capsys.readouterr().err == (f"error: {big}: the file has {size} bytes, more than the {MAX_FILE_BYTES} "
                                       "a study, scene or material file may have\n")


def test_a_shape_tree_multiplied_by_aliases_is_refused_before_validation(tmp_path, capsys):
    """Seven levels of ten aliases each make one region's `minus` a tree of 1e7 rectangles in 3 kB
    of YAML (before: validating it never ended): the expanded document is counted first."""
    from wcs.study.source import MAX_NODES

    def tree(level):
        hole = "{rectangle: [0.9, 0.4, 1.1, 0.6]}" if level == 0 else tree(level - 1)
        return (f"{{rectangle: [0.8, 0.3, 1.2, 0.7], minus: [&s{level} {hole}"
                + f", *s{level}" * 9 + "]}")
    text = (STUDIES / "two-blocks-demo.yaml").read_text()
    shape = "shape: {rectangle: [0.0, 0.0, 2.0, 1.0]}"
    assert text.count(shape) == 1
    path = tmp_path / "bomb.yaml"
    path.write_text(text.replace(shape, f"shape: {{rectangle: [0.0, 0.0, 2.0, 1.0], minus: [{tree(6)}]}}"))
    assert path.stat().st_size < 4000
    assert main(["check", str(path), "--quiet"]) == 2
    assert capsys.readouterr().err == (f"error: {path}: the file holds more than {MAX_NODES} values once its "
                                       "aliases (*name) are expanded\n")


def test_a_fifo_as_a_results_file_is_refused_unread(tmp_path, capsys):
    """`report` and `compare` of a FIFO waited for a writer forever."""
    fifo = tmp_path / "run.nc"
    os.mkfifo(fifo)
    assert main(["report", str(fifo)]) == 2
    assert capsys.readouterr().err == (f"error: {fifo}: not a regular file (a FIFO, a device or a socket), "
                                       "not a results file\n")
    assert main(["compare", str(fifo), str(fifo)]) == 2
    assert capsys.readouterr().err == f"error: {fifo}: not a regular file, not a results file\n"
