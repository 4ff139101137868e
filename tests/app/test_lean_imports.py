"""`wcs solve` of a file-mesh study by the iterative method loads what its path needs: at the
solve's start neither the results file's libraries (xarray, pandas, h5py) nor gmsh (a MSH 2.2 file is
read by wcs' own reader, `wcs.scene.meshfile`) nor PARDISO (MKL); by its end, with the results written, h5py alone of them
(`wcs.results.netcdf`: no xarray, no pandas), still no gmsh and no MKL (the iterative method
makes no direct factor), and never scipy.spatial. Guarded by what the process imported and
mapped, not by its time or memory.

A `wcs` process of its own (`main()` on sys.argv) defers numpy's submodules that scipy's import
would load (`wcs.cli.DEFERRED`): its solve loads none of them, and each works on first use."""
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "bench"))
from kratos_mesh import write_patch_msh  # noqa: E402

STUDY = """study: lean
scene:
  dimension: 3
  mesh: {file: mesh.msh}
  materials:
    soft: {E: 5.0e9, nu: 0.35}
    stiff: {E: 2.0e10, nu: 0.25}
  bodies:
    base: {regions: [{material: stiff}]}
    block: {regions: [{material: soft}]}
  contacts:
    interface: {master: base_top, slave: block_bottom}
  loads:
    block_top: {pressure: 2.0e6}
  supports:
    base_bottom: {u: [null, null, 0.0]}
    x0: {u: [0.0, null, null]}
    y0: {normal: 0.0}
  regions_of_interest:
    interface: {boundary: base_top}
criteria:
- {kind: contact_pressure, name: pressure, regions: [interface]}
uncertain:
  loads.block_top.pressure: [1.0e6, 3.0e6]
solver: {method: iterative}
"""

HEAVY = ["xarray", "pandas", "h5py", "gmsh", "pypardiso", "matplotlib", "cvxpy"]
# what a static solve does not use: the time stepping, the run's machinery, the search; ssl
# (8 MB with urllib.request, which xml.sax.saxutils loads); scipy.spatial (8 MB: the mesh file's
# overlap check, the matching faces' pairs and the pressure region's facets search near points
# by `wcs.geometry.near`)
UNUSED = ["wcs.dynamics.history", "wcs.dynamics.stepping", "wcs.app.dynamics", "wcs.app.runner",
          "wcs.results.meshcheck", "wcs.search", "ssl", "scipy.spatial"]

PROBE = r"""
import json, sys
import wcs.model.evaluation as evaluation
HEAVY, UNUSED = json.loads(sys.argv[1]), json.loads(sys.argv[2])
seen = {}
evaluate = evaluation.Evaluator.evaluate
def at_start(self, *args, **kwargs):
    seen.setdefault("solve", [m for m in HEAVY if m in sys.modules])
    return evaluate(self, *args, **kwargs)
evaluation.Evaluator.evaluate = at_start
from wcs.cli import main
seen["code"] = main(["solve", "-q", "-o", "out.nc", "lean.yaml"])
seen["end"] = [m for m in HEAVY if m in sys.modules]
seen["unused"] = [m for m in UNUSED if m in sys.modules]
maps = open("/proc/self/maps").read()
seen["mapped"] = [lib for lib in ("libgmsh", "libmkl", "libpetsc") if lib in maps]
print(json.dumps(seen))
"""


def test_an_iterative_file_mesh_solve_loads_no_results_library_before_its_solve_and_no_gmsh_or_mkl(tmp_path):
    write_patch_msh(tmp_path / "mesh.msh", 0.25)
    (tmp_path / "lean.yaml").write_text(STUDY)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", PROBE, json.dumps(HEAVY), json.dumps(UNUSED)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, check=True)
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    assert seen["code"] == 0, out.stderr
    assert seen["solve"] == [], f"loaded before the solve: {seen['solve']}"
    assert seen["end"] == ["h5py"], f"loaded by the end: {seen['end']}"     # the file written without xarray
    assert seen["mapped"] == ["libpetsc"], f"libraries mapped: {seen['mapped']}"
    assert seen["unused"] == [], f"a static solve loaded: {seen['unused']}"


OWN_PROCESS = r"""
import json, sys, types
from wcs.cli import DEFERRED, main
sys.argv = ["wcs", "solve", "-q", "-o", "out.nc", "lean.yaml"]
seen = {"code": main()}
seen["executed"] = [m for m in DEFERRED + ("unittest",) if type(sys.modules.get(m)) is types.ModuleType]
import numpy as np
import numpy.testing
seen["draw"] = np.random.default_rng(7).uniform(1.0, 2.0, 3).tolist()     # the deferred modules, used
numpy.testing.assert_array_equal(np.arange(3), [0, 1, 2])
seen["after"] = [m for m in ("numpy.random", "numpy.testing") if type(sys.modules.get(m)) is types.ModuleType]
print(json.dumps(seen))
"""


def test_a_wcs_process_solves_without_numpys_random_testing_and_f2py_and_they_work_when_used(tmp_path):
    write_patch_msh(tmp_path / "mesh.msh", 0.25)
    (tmp_path / "lean.yaml").write_text(STUDY)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", OWN_PROCESS], cwd=tmp_path, env=env, capture_output=True, text=True,
                         check=True)
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    assert seen["code"] == 0, out.stderr
    assert seen["executed"] == [], f"a solve executed {seen['executed']}"
    plain = subprocess.run([sys.executable, "-c", "import numpy as np; print(np.random.default_rng(7).uniform(1.0, 2.0, 3)"
                            ".tolist())"], capture_output=True, text=True, check=True)
    assert seen["draw"] == json.loads(plain.stdout)          # the same generator, the same draws
    assert seen["after"] == ["numpy.random", "numpy.testing"]
