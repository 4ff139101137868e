"""The start-up of a `wcs` process. `import wcs.cli` loads none of the numerical libraries (`wcs
--help` parses and prints without them). A command that is the process' own (`main()` reading
sys.argv) imports with the cyclic garbage collector off and then freezes what the imports made:
at the solve the collector is on again and the start-up's objects are out of its passes, and a 3D
study has built its 3D scene's validators, not the 2D scene's. `main(argv)` in a host process
leaves the host's collector as it was. Guarded by what the process holds, not by its time."""
import gc
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from wcs.cli import main

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}

STUDY = """study: startup
scene:
  dimension: 3
  mesh: {size: 0.25}
  materials: {steel: {E: 2.0e11, nu: 0.3}}
  bodies: {block: {regions: [{material: steel, shape: {box: [0, 0, 0, 1, 1, 1]}}]}}
  boundaries:
    bottom: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}
    top: {plane: {point: [0, 0, 1], normal: [0, 0, 1]}}
  supports: {bottom: {u: [0.0, 0.0, 0.0]}}
  loads: {top: {pressure: 1.0e6}}
  regions_of_interest: {top: {boundary: top}}
uncertain: {loads.top.pressure: [0.5e6, 1.5e6]}
criteria: [{name: heave, kind: mean_normal_displacement, regions: [top]}]
"""

PROBE = r"""
import gc, json, sys
import wcs.model.evaluation as evaluation
from wcs.study import schema
seen = {}
evaluate = evaluation.Evaluator.evaluate
def at_start(self, *args, **kwargs):
    seen.setdefault("solve", {"enabled": gc.isenabled(), "frozen": gc.get_freeze_count(),
                              "scene3d_built": schema._SCENE3D.pydantic_complete,
                              "scene2d_built": schema._SCENE.pydantic_complete})
    return evaluate(self, *args, **kwargs)
evaluation.Evaluator.evaluate = at_start
from wcs.cli import main
sys.argv = ["wcs", "solve", "-q", "-o", "out.nc", "study.yaml"]
seen["code"] = main()
seen["enabled_after"] = gc.isenabled()
print(json.dumps(seen))
"""


def test_importing_the_command_line_loads_no_numerical_library():
    code = ("import json, sys, wcs.cli; print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('numpy', 'scipy', 'pydantic', 'skfem', 'yaml', 'xarray', 'petsc4py'))))")
    out = subprocess.run([sys.executable, "-c", code], env=ENV, capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == []


def test_a_command_of_its_own_process_freezes_its_imports_and_solves_with_the_collector_on(tmp_path):
    (tmp_path / "study.yaml").write_text(STUDY)
    out = subprocess.run([sys.executable, "-c", PROBE], cwd=tmp_path, env=ENV, capture_output=True, text=True,
                         check=True)
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    assert seen["code"] == 0, out.stderr
    solve = seen["solve"]
    assert solve["enabled"] and seen["enabled_after"]
    assert solve["frozen"] > 10_000, f"the start-up froze {solve['frozen']} objects"   # the imports' functions, classes, ...
    assert solve["scene3d_built"] and not solve["scene2d_built"]


@pytest.mark.parametrize("enabled", [True, False])
def test_a_command_called_in_a_host_process_leaves_its_collector_alone(tmp_path, enabled):
    frozen = gc.get_freeze_count()
    (gc.enable if enabled else gc.disable)()
    try:
        assert main(["solve", "-q", str(tmp_path / "missing.yaml")]) == 2     # imports, then: file not found
        assert gc.isenabled() is enabled
    finally:
        gc.enable()
    assert gc.get_freeze_count() == frozen
