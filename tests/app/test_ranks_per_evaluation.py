"""`solver.ranks_per_evaluation: k`: under `mpiexec -n N`, N/k groups evaluate different data
sets and each solve spans its group (the iterative method's CG + GAMG on the group's
communicator). Same layout: the same bits; k = 1 against k = 2: the same answer to the
solver's tolerance. A layout that does not divide the ranks, or a method that is not
distributed, is exit 2 naming the key."""
import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from wcs.status import Status

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "studies" / "validation" / "tresca-shear-patch-3d.yaml"
BIN = Path(sys.executable).parent
KRYLOV_TOLERANCE = 1e-10      # the Krylov solves' relative residual in the layout comparison
COMPARED = ("x", "phi", "grad", "status", "worst_value", "worst_x", "worst_displacement", "worst_contact_pressure",
            "worst_contact_slip")


def patch_doc(k: int, method: str = "iterative") -> dict:
    """The 3D Tresca shear patch (slip and pressure criteria) by `method` on k ranks per
    evaluation; a local search, so that the adjoint's CG spans the group too."""
    doc = yaml.safe_load(STUDY.read_text())
    doc["solver"] = {"method": method, "ranks_per_evaluation": k, "iterative": {"tolerance": KRYLOV_TOLERANCE}}
    doc["search"] = {"method": "local", "budget": 6, "sample": {"n": 2}, "local": {"starts": 1}}
    return doc


def run_layouts(out: str) -> None:
    """Under mpiexec -n 2: the patch's study run with k = 2 twice and with k = 1 (two groups of
    one rank), the compared variables and the layout attributes saved by rank 0 to `out`."""
    import wcs
    from wcs.app.runner import Runner
    from wcs.app.parallel import world
    saved = {}
    for name, k in (("a", 2), ("b", 2), ("one", 1)):
        study = wcs.load_study(patch_doc(k), base_dir=STUDY.parent)
        ds = Runner(study, False).run()
        saved |= {f"{name}_{v}": ds[v].values for v in COMPARED if v in ds}
        saved |= {f"{name}_ranks": ds.attrs["ranks"], f"{name}_ranks_per_evaluation": ds.attrs["ranks_per_evaluation"]}
    if world().rank == 0:
        np.savez(out, **saved)


def failing_rank(out: str) -> None:
    """Under mpiexec -n 2 (one group of 2): rank 1 alone raises a MemoryError while it builds
    its rows of a Newton step's matrix (inside the group's collective assembly), then before a
    step's Krylov solve (between the group's collective steps), then in a criterion after the
    solve; each an evaluation by the runner, then one where nothing fails. Each rank's (status,
    message, φ) of the four saved by rank 0 to `out`."""
    import wcs
    from wcs.app.runner import Runner
    from wcs.app.parallel import world
    from wcs.contact import iterative
    from wcs.group import spanning
    study = wcs.load_study(patch_doc(2), base_dir=STUDY.parent)
    runner = Runner(study, False)
    comm = world()

    def fail(*args, **kwargs):
        raise MemoryError("injected on rank 1")
    seen = []
    for owner, name in ((iterative, "_eliminated"), (iterative, "_basis"), (runner.evaluator.criteria[0], "value"),
                        (None, None)):
        failing = owner is not None and comm.rank == 1
        before = getattr(owner, name) if failing else None
        if failing:
            setattr(owner, name, fail)
        with spanning(runner.group):
            ev = runner.evaluate(study.nominal(), False, "test")
        if failing:
            setattr(owner, name, before)
        seen.append((int(ev.status), ev.message, [float(v) for v in ev.phi.values()]))
    model = runner.evaluator.model        # K(c) of the group (each rank its node rows, gathered) and alone
    coefficients = model.stiffness_coefficients(runner.evaluator.map.coefficients(*study.data_set(study.nominal())))
    with spanning(runner.group):
        spread = model.K(coefficients)
    alone = model.K(coefficients)
    same = all(np.array_equal(getattr(spread, a), getattr(alone, a)) for a in ("data", "indices", "indptr"))
    everyone = comm.gather({"seen": seen, "same_k": same})
    if comm.rank == 0:
        Path(out).write_text(json.dumps(everyone))


def mpiexec(ranks: int, *args, cwd=ROOT, timeout=600) -> subprocess.CompletedProcess:
    """`mpiexec -n ranks ARGS` with this checkout's wcs on every rank."""
    launcher = BIN / "mpiexec"
    if not launcher.exists():
        pytest.fail("mpiexec is missing from the environment (the mpich wheel provides it)")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_"))}
    env["PYTHONPATH"] = str(ROOT)
    return subprocess.run([str(launcher), "-n", str(ranks), *map(str, args)], env=env, cwd=cwd, capture_output=True,
                          text=True, timeout=timeout)


def layouts_on(ranks: int, folder: Path) -> dict:
    """`run_layouts` under mpiexec -n `ranks`: what rank 0 saved."""
    out = folder / "layouts.npz"
    done = mpiexec(ranks, sys.executable, __file__, out)
    assert done.returncode == 0, done.stderr + done.stdout
    with np.load(out, allow_pickle=True) as f:
        return dict(f)


@pytest.fixture(scope="module")
def layouts(tmp_path_factory) -> dict:
    return layouts_on(2, tmp_path_factory.mktemp("layouts"))


def test_the_same_layout_gives_the_same_bits(layouts):
    assert layouts["a_phi"].shape[0] >= 3 and np.all(layouts["a_status"] == 0)
    assert np.isfinite(layouts["a_grad"]).any()              # the adjoint ran on the group
    for v in COMPARED:
        assert np.array_equal(layouts[f"a_{v}"], layouts[f"b_{v}"], equal_nan=True), v


def test_one_and_two_ranks_per_evaluation_agree_to_the_solver_tolerance(layouts):
    """CG stops at a relative residual of 1e-10 on either layout; the answers, and the search
    they drive, agree to 1e-8 relative (an array's largest difference over its largest entry).
    The worst case is compared for the slip only: the patch's contact pressure is P at every
    data set, its maximiser a tie that round-off decides."""
    assert int(layouts["a_ranks"]) == int(layouts["one_ranks"]) == 2
    assert int(layouts["a_ranks_per_evaluation"]) == 2 and int(layouts["one_ranks_per_evaluation"]) == 1
    assert np.array_equal(layouts["a_status"], layouts["one_status"])
    for v in COMPARED:
        if v == "status":
            continue
        a, b = layouts[f"a_{v}"].astype(float), layouts[f"one_{v}"].astype(float)
        if v.startswith("worst_"):
            a, b = a[0], b[0]                   # the slip (the criterion axis comes first)
        assert np.array_equal(np.isnan(a), np.isnan(b)), v
        scale = np.nanmax(np.abs(b))
        assert np.nanmax(np.abs(a - b)) <= 1e-8 * scale, (v, np.nanmax(np.abs(a - b)) / scale)
        assert not np.array_equal(a, b) or v in ("x", "worst_x"), v   # two layouts, two roundings: a real comparison


@pytest.mark.slow
def test_the_bits_depend_on_the_ranks_per_evaluation_only(layouts, tmp_path):
    """On 4 ranks (two groups of 2, or four of 1) every evaluation is bitwise the one on 2 ranks
    with the same k: an evaluation does not depend on which group solves it or on what it solved before."""
    four = layouts_on(4, tmp_path)
    assert int(four["a_ranks"]) == 4 and int(four["a_ranks_per_evaluation"]) == 2
    for v in COMPARED:
        for name in ("a", "one"):
            assert np.array_equal(four[f"{name}_{v}"], layouts[f"{name}_{v}"], equal_nan=True), (name, v)


@pytest.mark.parametrize("method", ["monolithic", "qp", "dd", "auto"])
def test_a_method_that_is_not_distributed_is_refused_by_name(tmp_path, capsys, method):
    from wcs.cli import main
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(patch_doc(2, method)))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}: solver.ranks_per_evaluation: 2 ranks per evaluation need a distributed "
                          "method, solver.method iterative (the only one): "), err
    assert "Traceback" not in err and err.count("\n") == 1


@pytest.mark.parametrize("size, k", [(None, 2), (3, 2), (2, 4)])
def test_a_layout_that_does_not_divide_the_ranks_is_refused(size, k):
    from wcs.errors import StudyError
    from wcs.app.parallel import groups
    comm = None if size is None else SimpleNamespace(size=size, rank=0)
    with pytest.raises(StudyError) as e:
        groups(comm, k, "study.yaml")
    assert e.value.path == "solver.ranks_per_evaluation" and e.value.file == "study.yaml"
    assert f"{k} ranks per evaluation do not divide the {size or 1} rank" in str(e.value)


def test_a_serial_run_of_a_two_rank_layout_is_exit_2(tmp_path, capsys):
    from wcs.cli import main
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(patch_doc(2)))
    assert main(["run", str(path), "-o", str(tmp_path / "out.nc"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err == (f"error: {path}: solver.ranks_per_evaluation: 2 ranks per evaluation do not divide the 1 rank of "
                   "a serial run into groups: run it under mpiexec -n with a multiple of 2\n")
    assert not (tmp_path / "out.nc").exists()



def test_check_says_how_to_launch_a_layout(tmp_path, capsys):
    from wcs.cli import main
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(patch_doc(2)))
    assert main(["check", str(path)]) == 0
    assert "; each solve on 2 ranks: run it under mpiexec -n with a multiple of 2\n" in capsys.readouterr().out


@pytest.fixture(scope="module")
def failing(tmp_path_factory) -> list:
    """`failing_rank` under mpiexec -n 2: each rank's outcomes."""
    out = tmp_path_factory.mktemp("failing") / "seen.json"
    done = mpiexec(2, sys.executable, __file__, "failing", out, timeout=240)
    assert done.returncode == 0, done.stderr + done.stdout
    return json.loads(out.read_text())


def test_a_rank_that_fails_alone_fails_its_group_and_not_the_next_evaluation(failing):
    """A failure of one rank reaches the other (no rank left waiting in a collective step, so
    no hang: the launch has a deadline), wherever it happens: each rank records the evaluation
    failed, rank 0 (whose record the run keeps) with rank 1's message; the group then solves
    the next evaluation together, as it would have without the failures."""
    zero, one = (rank["seen"] for rank in failing)
    for status, message, _ in zero[:3]:
        assert status == Status.OTHER_FAILURE, message
        assert message == ("GroupFailure: rank 1 of the evaluation's 2 ranks failed: MemoryError: injected on rank 1")
    assert [(s, m) for s, m, _ in one[:3]] == [(Status.OTHER_FAILURE, "MemoryError: injected on rank 1")] * 3
    assert zero[3][0] == one[3][0] == Status.SOLVED and zero[3][2] == one[3][2]
    assert np.all(np.isfinite(zero[3][2]))


def test_the_stiffness_of_a_group_is_the_stiffness_alone_to_the_bit(failing):
    """K(c) spanning the group (each rank the entries of its node rows, gathered) has the bits of
    K(c) assembled by one rank, on both ranks."""
    assert [rank["same_k"] for rank in failing] == [True, True]


def test_a_serial_solve_of_a_two_rank_layout_is_exit_2(tmp_path, capsys):
    """`wcs solve` solves on the ranks the study asks for, never silently on fewer."""
    from wcs.cli import main
    path = tmp_path / "k2.yaml"
    path.write_text(yaml.safe_dump(patch_doc(2)))
    assert main(["solve", str(path), "-o", str(tmp_path / "serial2.nc"), "--quiet"]) == 2
    assert capsys.readouterr().err == (
        f"error: {path}: solver.ranks_per_evaluation: wcs solve solves one data set on 2 ranks per "
        "evaluation, not on the 1 of a serial run: run it under mpiexec -n 2\n")
    assert not (tmp_path / "serial2.nc").exists()


@pytest.mark.slow
def test_solve_spans_the_ranks_of_its_launch(tmp_path):
    """`mpiexec -n 2 wcs solve` of a study with 2 ranks per evaluation solves its one data set on
    both (rank 0 writes; the file records the layout); the answer is the serial one's (k = 1) to
    the solver's tolerance. mpiexec -n 2 of k = 1 is exit 2 naming the key."""
    import xarray as xr
    from wcs.cli import main
    for k in (1, 2):
        (tmp_path / f"k{k}.yaml").write_text(yaml.safe_dump(patch_doc(k)))
    assert main(["solve", str(tmp_path / "k1.yaml"), "-o", str(tmp_path / "one.nc"), "--quiet"]) == 0
    done = mpiexec(2, BIN / "wcs", "solve", "k2.yaml", "-o", "two.nc", "--quiet", cwd=tmp_path)
    assert done.returncode == 0, done.stderr + done.stdout
    refused = mpiexec(2, BIN / "wcs", "solve", "k1.yaml", "-o", "mpi1.nc", "--quiet", cwd=tmp_path)
    assert refused.returncode == 2 and "Traceback" not in refused.stderr
    assert set(refused.stderr.splitlines()) == {
        "error: k1.yaml: solver.ranks_per_evaluation: wcs solve solves one data set on 1 rank per evaluation, not "
        "on the 2 of mpiexec -n 2: run it without mpiexec"}
    assert not (tmp_path / "mpi1.nc").exists()
    with xr.open_dataset(tmp_path / "one.nc", engine="h5netcdf") as a, \
            xr.open_dataset(tmp_path / "two.nc", engine="h5netcdf") as b:
        assert int(b.attrs["ranks_per_evaluation"]) == 2 and int(a.attrs["ranks_per_evaluation"]) == 1
        for v in ("phi", "displacement"):
            x, y = a[v].values.astype(float), b[v].values.astype(float)
            assert np.max(np.abs(x - y)) <= 1e-8 * np.max(np.abs(x)), v


if __name__ == "__main__":
    if sys.argv[1] == "failing":
        failing_rank(sys.argv[2])
    else:
        run_layouts(sys.argv[1])
