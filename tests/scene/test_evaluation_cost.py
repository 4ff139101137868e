"""Never a memory death: one evaluation's peak memory and time estimated from
the assembled model (wcs.scene.estimate.evaluation_cost), printed by `wcs check`, refused (exit 2)
where it exceeds the machine's memory, and `solver.method: auto` choosing the iterative method
where the direct condensation would not fit or (3D) would be slower."""
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

import wcs.scene.estimate as estimate
from wcs.choose import ITERATIVE_MARGIN, SolverFacts, solver_method
from wcs.cli import main
from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs.results.dataset import provenance
from wcs.scene.estimate import USABLE_SHARE, W_COPIES, EvaluationFacts, evaluation_cost
from wcs import load_study

ROOT = Path(__file__).resolve().parents[2]
# the facts of the assembled model (reduced unknowns, nnz of the reduced K, contact rows) as
# printed by Model: the shipped 3D tunnel, and its copy with the ring at 0.4 m and the fault at
# 0.5 m, whose `check` died after 3 minutes on a 3.27 GiB W (MemoryError at 14.5 GB under a cap,
# killed by the kernel at 24 GB without one)
SHIPPED_TUNNEL = EvaluationFacts(dimension=3, unknowns=15845, stiffness_nnz=541361, contact_rows=1587)
SPLIT_TUNNEL = EvaluationFacts(dimension=3, unknowns=113362, stiffness_nnz=4373922, contact_rows=5856)
FINE_TUNNEL = EvaluationFacts(dimension=3, unknowns=137005, stiffness_nnz=5255141, contact_rows=20961)
MACHINE = USABLE_SHARE * 25.3e9      # what this machine (machine_memory(): 25.3 GB) gives one evaluation


def facts_of(f: EvaluationFacts, memory: float) -> SolverFacts:
    costs = {m: evaluation_cost(f, m) for m in ("monolithic", "iterative")}
    return SolverFacts(unknowns=f.unknowns, friction="tresca", dimension=f.dimension, costs=costs, memory=memory)


def test_fine_tunnel_direct_estimate_is_what_killed_it():
    need, _ = evaluation_cost(FINE_TUNNEL, "monolithic")
    # the kernel killed it at 24 GB, when the model held its cell matrices (280 bytes a stiffness
    # entry then, MODEL_BYTES_PER_NNZ now): it would die ~1 GB later today
    assert need > 24e9 - (280.0 - estimate.MODEL_BYTES_PER_NNZ) * FINE_TUNNEL.stiffness_nnz
    assert need > (W_COPIES[3] + 1) * 8 * 20961**2              # the dense W: W_COPIES and the one unit's
    assert evaluation_cost(FINE_TUNNEL, "iterative")[0] < 8e9     # the bound set for the iterative method
    assert evaluation_cost(FINE_TUNNEL, "dd")[0] == need     # dd falls back to the monolithic solver


def test_auto_picks_iterative_where_direct_would_not_fit():
    method, why = solver_method(facts_of(FINE_TUNNEL, MACHINE))
    assert method == "iterative" and "would not fit in the 22.8 GB this machine gives one evaluation" in why
    assert re.search(r"monolithic method, \S+ GB and \S+ s by the iterative one", why)


def test_auto_keeps_monolithic_on_the_shipped_tunnel():
    method, why = solver_method(facts_of(SHIPPED_TUNNEL, MACHINE))
    assert method == "monolithic" and "the iterative method estimated at" in why
    # split once by the mesh check: 150 s estimated by the monolithic method, 89 s by the iterative one
    assert solver_method(facts_of(SPLIT_TUNNEL, MACHINE))[0] == "monolithic"
    # 3D, both fit: the iterative method for speed only beyond ITERATIVE_MARGIN
    slow = {"monolithic": (1e9, 100.0), "iterative": (0.5e9, 100.0 / ITERATIVE_MARGIN * 1.01)}
    assert solver_method(SolverFacts(unknowns=10**5, dimension=3, costs=slow, memory=MACHINE))[0] == "monolithic"
    fast = {"monolithic": (1e9, 100.0), "iterative": (0.5e9, 100.0 / ITERATIVE_MARGIN * 0.99)}
    method, why = solver_method(SolverFacts(unknowns=10**5, dimension=3, costs=fast, memory=MACHINE))
    assert method == "iterative" and why.endswith("the monolithic method would be more than 2x slower")
    # a body held by contact alone: for speed when frictionless (the block patch), not with friction
    # (its Krylov solves there take far more iterations than the estimate assumes: the knees); for memory it still is
    method, why = solver_method(SolverFacts(unknowns=10**5, dimension=3, costs=fast, memory=MACHINE, floating=True))
    assert method == "iterative" and why.endswith("2x slower; a body held by contact alone, frictionless")
    for friction in ("tresca", "coulomb"):
        method, why = solver_method(SolverFacts(unknowns=10**5, dimension=3, costs=fast, memory=MACHINE,
                                                floating=True, friction=friction))
        assert method == "monolithic" and f"held by contact alone with {friction} friction" in why
    assert solver_method(SolverFacts(unknowns=10**5, dimension=3, costs=fast, memory=0.8e9,
                                     floating=True, friction="coulomb"))[0] == "iterative"
    # and in 2D only memory moves the choice (its zones are small; the measured rules stay)
    costs = {"monolithic": (1e9, 100.0), "iterative": (0.5e9, 1.0)}
    assert solver_method(SolverFacts(unknowns=15845, costs=costs, memory=MACHINE))[0] == "monolithic"
    assert solver_method(SolverFacts(unknowns=15845, costs=costs, memory=0.8e9))[0] == "iterative"
    # never the iterative method where PETSc is not installed: the direct one, and the reason says so
    method, why = solver_method(SolverFacts(unknowns=15845, costs=costs, memory=0.8e9, iterative_installed=False))
    assert method == "monolithic" and "the iterative method (not installed: PETSc, the wheel dolfinx-solver-real)" in why


# the 3D block patch with its contact face at 0.04 (tests/bench/test_bench_kratos.py), as its model
# prints it: 2 Newton steps from its closed start, 0.4 s evaluated iteratively, 2.8 s monolithically
PATCH_004 = EvaluationFacts(dimension=3, unknowns=10046, stiffness_nnz=364610, contact_rows=2364, units=2)


def test_a_contact_that_starts_closed_is_estimated_at_its_few_newton_steps():
    """Frictionless, every contact node closed at the start: the iterative method's estimate is
    CLOSED_START_STEPS Newton steps, not ITERATIVE_STEPS, and the block patch goes to it (it took
    2 at every face); at the assumed 20 the estimate was 18x the measured time and auto took the
    monolithic method, 7x slower in the solve."""
    import dataclasses
    closed = dataclasses.replace(PATCH_004, newton_steps=estimate.CLOSED_START_STEPS)
    assert estimate.CLOSED_START_STEPS == 2 and PATCH_004.newton_steps == estimate.ITERATIVE_STEPS == 20
    steps = lambda f: (evaluation_cost(f, "iterative")[1] - estimate.ITERATIVE_SECONDS) / (
        estimate.ITERATIVE_STEP_SECONDS * f.stiffness_nnz)
    assert steps(closed) == pytest.approx(2) and steps(PATCH_004) == pytest.approx(20)
    assert evaluation_cost(closed, "monolithic") == evaluation_cost(PATCH_004, "monolithic")
    pick = lambda f: solver_method(SolverFacts(unknowns=f.unknowns, dimension=3, memory=MACHINE, floating=True,
                                               costs={m: evaluation_cost(f, m) for m in ("monolithic", "iterative")}))[0]
    assert pick(closed) == "iterative" and pick(PATCH_004) == "monolithic"


@pytest.mark.parametrize("name,closed", [("block-on-block-3d.yaml", True), ("hertz-3d.yaml", False),
                                         ("tresca-shear-patch-3d.yaml", False)])
def test_the_model_says_where_its_contact_starts_closed(name, closed):
    """The block patch starts closed and is frictionless; the Hertz sphere touches at one point
    (its other gaps are positive); the Tresca patch starts closed but slips: only the first is
    estimated at CLOSED_START_STEPS, and auto's reason says what it assumed."""
    doc = yaml.safe_load((ROOT / "studies" / "validation" / name).read_text())
    doc["solver"] = {"method": "auto"}
    model = Evaluator(load_study(doc)).model
    assert ("the iterative method's estimate assumes 2 Newton steps (frictionless, every contact node starts "
            "closed)" in model.solver_reason) == closed


def block_doc(method: str) -> dict:
    doc = yaml.safe_load((ROOT / "studies" / "validation" / "block-on-block-3d.yaml").read_text())
    doc["solver"] = {"method": method}
    return doc


def test_check_prints_the_estimate_and_refuses_beyond_the_memory(tmp_path, capsys, monkeypatch):
    """The estimate is in `check`'s solver line and the results' solver_choice; a machine too
    small for it is exit 2 before any solve, naming the estimate, the memory and the way out."""
    path = tmp_path / "block.yaml"
    doc = block_doc("monolithic")
    doc["output"] = str(tmp_path / "block.nc")
    path.write_text(yaml.safe_dump(doc))
    study = load_study(path)
    ev = Evaluator(study)
    need, seconds = evaluation_cost(EvaluationFacts(
        dimension=3, unknowns=ev.model.elim.T.shape[1], stiffness_nnz=ev.model.reduce.pattern.nnz,
        contact_rows=ev.model.Bn_r.shape[0] + ev.model.Bt_r.shape[0], units=2), "monolithic")
    words = f"about {need / 1e9:.3g} GB peak and {seconds:.2g} s"
    assert provenance(study, ev)["solver_choice"] == f"monolithic: chosen in the study; one evaluation estimated at {words}"
    monkeypatch.setattr(estimate, "machine_memory", lambda: need)
    assert main(["check", str(path)]) == 2
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "nominal solve" not in out
    assert (f"{path}: solver.method: one evaluation with the monolithic method is estimated at {words}" in err
            and f"more than the {USABLE_SHARE * need / 1e9:.3g} GB it may take of this machine's {need / 1e9:.3g} GB "
                "of memory; use solver.method: iterative" in err)
    # fits alone; two MPI processes on the machine (each its own model and evaluations) do not
    monkeypatch.setattr(estimate, "machine_memory", lambda: 1.5 * need / USABLE_SHARE)
    assert main(["check", str(path), "--quiet"]) == 0
    monkeypatch.setenv("MPI_LOCALNRANKS", "2")
    assert main(["check", str(path), "--quiet"]) == 2
    assert (f"more than the {0.75 * need / 1e9:.3g} GB it may take of this machine's {1.5 * need / USABLE_SHARE / 1e9:.3g} "
            "GB of memory, shared by 2 MPI processes; use solver.method: iterative" in capsys.readouterr().err)


@pytest.mark.slow
def test_fine_tunnel_refused_by_monolithic_and_iterative_by_auto(tmp_path, capsys):
    """The tunnel copy with the ring at 0.4 m and the fault at 0.5 m: `check` with the monolithic
    method is exit 2 after meshing and assembly (no W formed); `auto` resolves to iterative."""
    doc = yaml.safe_load((ROOT / "studies" / "tunnel-fault-3d.yaml").read_text())
    refine = doc["scene"]["mesh"]["refine"]
    refine[0]["size"], refine[1]["size"] = 0.4, 0.5
    doc["output"] = str(tmp_path / "fine.nc")
    doc["solver"] = {"method": "monolithic"}
    path = tmp_path / "fine.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "solver.method: one evaluation with the monolithic method is estimated at" in err
    rows = int(re.search(r"(\d+) contact rows: the dense W alone is", err).group(1))
    assert 20000 < rows < 22000 and "use solver.method: iterative" in err
    doc["solver"] = {"method": "auto"}
    model = Evaluator(load_study(doc)).model
    assert model.solver_method == "iterative" and "would not fit" in model.solver_reason
    assert "polished" not in model.solver_reason     # its adjoint is iterative too (`IterativeAdjoint`)


PEAK = """
import re, sys, yaml
import dolfinx_solver
from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs import load_study
doc = yaml.safe_load(open(sys.argv[1]))
doc["solver"] = {"method": sys.argv[2]}
ev = Evaluator(load_study(doc))
assert ev.evaluate(ev.study.nominal()).status == 0
m = ev.model
print(m.elim.T.shape[1], m.reduce.pattern.nnz, m.Bn_r.shape[0] + m.Bt_r.shape[0], len(set(m.region_material)),
      int(re.search(r"VmHWM:\\s+(\\d+)", open("/proc/self/status").read()).group(1)) * 1024)
"""


@pytest.mark.slow
@pytest.mark.parametrize("study, size, method", [
    ("studies/validation/block-on-block-3d.yaml", 0.05, "monolithic"),
    ("studies/tunnel-fault-3d.yaml", None, "monolithic"),
    ("studies/validation/block-on-block-3d.yaml", 0.05, "iterative")])
def test_estimate_within_a_factor_two_of_the_measured_peak(study, size, method, tmp_path):
    """The peak memory (VmHWM of a fresh process: meshing, assembly, one nominal solve) against
    the estimate from the same model's facts: within a factor 2 either way."""
    doc = yaml.safe_load((ROOT / study).read_text())
    if size is not None:
        doc["scene"]["mesh"]["size"] = size
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(doc))
    out = subprocess.run([sys.executable, "-c", PEAK, str(path), method], capture_output=True, text=True,
                         check=True, env={"PYTHONPATH": str(ROOT), "PATH": ""}).stdout
    n, nnz, rows, units, peak = map(int, out.split())
    need, _ = evaluation_cost(EvaluationFacts(dimension=3, unknowns=n, stiffness_nnz=nnz, contact_rows=rows,
                                              units=units), method)
    assert 0.5 < need / peak < 2.0


def test_cells_are_held_to_the_assembly_not_to_the_direct_solve(monkeypatch):
    """After meshing, the cells are held to the memory of assembling them (3.5 kB a tetrahedron);
    the solve's memory is the method's, estimated after assembly: 1.8e6 tetrahedra (1e6 unknowns,
    the iterative method's scale) are no longer refused on 25.3 GB for the direct method's 16 kB a
    cell (28.8 GB); 8e6 are (28 GB to assemble)."""
    monkeypatch.setattr(estimate, "machine_memory", lambda: 25.3e9)
    assert estimate.memory_fault(1_800_000, 3) is None
    assert estimate.memory_fault(8_000_000, 3).startswith(
        "the mesh has 8000000 cells, which need about 28 GB to assemble (3500 bytes a cell, measured)")


@pytest.mark.parametrize("method, refused", [("monolithic", True), ("iterative", False), ("auto", False)])
def test_the_guard_before_meshing_counts_the_methods_own_bytes_a_cell(method, refused, monkeypatch):
    """Before meshing, a 3D contact scene's estimated cells are held to the chosen method's bytes a
    cell: the direct methods' 16 kB (their factor and dense W), the iterative method's own measured
    figure (ITERATIVE_BYTES_PER_CELL; `auto` too, PETSc being installed: it picks the iterative
    method where the direct one would not fit). On a machine where the patch's estimate needs 1.6x
    ESTIMATE_EXCESS times the memory at 16 kB a cell, the monolithic method is refused and the
    iterative one is not (the bench patched 16 kB to 8 kB to mesh 1e6 unknowns)."""
    import wcs.study.resources
    doc = yaml.safe_load((ROOT / "studies/validation/block-on-block-3d.yaml").read_text())
    doc["solver"] = {"method": method}
    cells = load_study(doc).estimated_cells
    memory = cells * estimate.BYTES_PER_CELL[3] / estimate.ESTIMATE_EXCESS[3] / 1.6
    assert cells * estimate.ITERATIVE_BYTES_PER_CELL[3] < estimate.ESTIMATE_EXCESS[3] * memory
    monkeypatch.setattr(wcs.study.resources, "machine_memory", lambda: memory)
    if not refused:
        assert load_study(doc).estimated_cells == cells
        return
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert info.value.path == "scene.mesh.size"
    assert f"({estimate.BYTES_PER_CELL[3]:g} bytes a cell with solver.method monolithic)" in info.value.fault
