"""The 3D study format (`scene.dimension: 3`): a block pressed on a block is loaded into the typed
3D scene, `wcs check` meshes it and prints its mesh and what the study holds, and the commands
that solve it (solve, run, sweep) write their results. Every bad input is exit 2 with its key path; seeded mutations never fail inside.

The printed volumes and areas are those of the boxes, exact to round-off: planar solids are
meshed exactly."""
import copy
import io
import random
import re
from contextlib import redirect_stderr, redirect_stdout

import pytest
import yaml

from tests.acceptance.test_fuzz_check import mutate
from wcs.cli import main
from wcs.scene import spec3d
from wcs import load_study

STUDY = """
study: block-on-block-3d
scene:
  dimension: 3
  mesh: {size: 0.25}
  materials:
    stiff: {E: 1.0e10, nu: 0.25}
    soft: {E: 1.0e9, nu: 0.35}
  bodies:
    base: {regions: [{material: stiff, shape: {box: [0, 0, -0.5, 1, 1, 0]}}]}
    block: {regions: [{material: soft, name: pad, shape: {box: [0, 0, 0, 1, 1, 0.5],
                                                         minus: [{halfspace: {point: [0, 0, 0.4], normal: [0, 0, -1]}}]}}]}
  boundaries:
    base_bottom: {plane: {point: [0, 0, -0.5], normal: [0, 0, 1]}}
    block_top: {plane: {point: [0, 0, 0.4], normal: [0, 0, 1]}}
    base_top: {body: base, box: [0, 0, 0, 1, 1, 0]}
    block_bottom: {body: block, plane: {point: [0, 0, 0], normal: [0, 0, 1], tolerance: 1.0e-9}}
  supports:
    base_bottom: {u: [0.0, 0.0, 0.0]}
  loads:
    block_top: {traction: [0.0, 0.0, -1.0e6]}
  body_forces:
    pad: [0.0, 0.0, -2.0e4]
  contacts:
    interface: {slave: block_bottom, master: base_top, friction: {slip_limit: 1.0e5}}
  regions_of_interest:
    core: {ball: {center: [0.5, 0.5, -0.25], radius: 0.2}, body: base}
    contact: {boundary: base_top}
uncertain:
  loads.block_top.traction.2: [-1.5e6, -0.5e6]
  materials.soft.E: [0.8e9, 1.2e9]
criteria:
  - {name: stress, kind: von_mises, regions: [core]}
"""


def doc() -> dict:
    return yaml.safe_load(STUDY)


def run(args) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(args)
    return code, out.getvalue(), err.getvalue()


def write(tmp_path, d, name="study.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


def test_a_3d_study_loads_into_the_typed_3d_scene():
    study = load_study(doc())
    scene = study.scene
    assert isinstance(scene, spec3d.Scene) and scene.dimension == 3
    assert [r.name for b in scene.bodies.values() for r in b.regions] == ["base_0", "pad"]
    assert scene.bodies["block"].regions[0].shape.minus[0].halfspace.normal == [0, 0, -1]
    assert scene.loads["block_top"].traction == [0, 0, -1e6]
    assert study.parameters.names == ["loads.block_top.traction.2", "materials.soft.E"]
    assert list(study.nominal()) == [-1e6, 1e9]


def test_check_prints_the_mesh_and_solves_the_nominal_data(tmp_path):
    code, out, err = run(["check", str(write(tmp_path, doc()))])
    assert code == 0, err
    assert "nominal solve: solved" in out and out.strip().endswith("ok")
    assert "solved again on the mesh split once and twice" in out         # tests/results/test_meshcheck_3d.py
    cells = int(re.search(r"P1 tetrahedra, (\d+) nodes, (\d+) cells", out).group(2))
    estimate = float(re.search(r"estimated ([0-9.e+]+) cells before meshing", out).group(1))
    # the resource guard's estimate is an upper one (the ball of interest refines the base at its
    # curvature size: 2725 of the 2917 cells); 6.57e3 against 2917 meshed
    assert cells < estimate < 3 * cells
    vols = [float(v) for v in re.findall(r"volume ([0-9.e+-]+)\]", out)]
    assert vols == pytest.approx([0.5, 0.4], rel=1e-12)
    areas = dict(re.findall(r"    (\w+): \d+ triangles, area ([0-9.e+-]+)", out))
    assert {k: float(v) for k, v in areas.items()} == pytest.approx(
        {"base_bottom": 1.0, "block_top": 1.0, "base_top": 1.0, "block_bottom": 1.0}, rel=1e-12)
    ball = float(re.search(r"region of interest core: \d+ cells, volume ([0-9.e+-]+)", out).group(1))
    assert 0.9 < ball / (4 / 3 * 3.141592653589793 * 0.2 ** 3) < 1.0      # an inscribed polyhedron
    assert "loads.block_top.traction.2: [-1.5e+06, -5e+05]  nominal -1e+06" in out


@pytest.mark.parametrize("command", [["solve"], ["run", "--no-mesh-check"], ["sweep"]])   # the check: tests/results/test_meshcheck_3d.py
def test_commands_that_solve_run_a_3d_study(tmp_path, command):
    d = doc()
    d["sweep"] = {"grid": {"materials.soft.E": [0.9e9, 1.1e9]}}
    nc = tmp_path / "out.nc"
    code, _, err = run(command + [str(write(tmp_path, d)), "-o", str(nc)])
    assert code == 0, err
    assert nc.exists()


def _put(keys, value):
    def change(d):
        node = d["scene"]
        for k in keys[:-1]:
            node = node[k]
        node[keys[-1]] = value
    return change


BLOCK = ["bodies", "block", "regions", 0, "shape"]
BAD = [
    (_put(["supports", "base_bottom", "u"], [0.0, 0.0]), "scene.supports.base_bottom.u", "at least 3"),
    (_put(["loads", "block_top", "traction"], [0.0, 1.0]), "scene.loads.block_top.traction", "at least 3"),
    (_put(["body_forces", "pad"], [0.0, 0.0, 0.0, 1.0]), "scene.body_forces.pad", "at most 3"),
    (_put(BLOCK + ["box"], [0, 0, 1, 1]), f"scene.{'.'.join(map(str, BLOCK))}.box", "at least 6"),
    (_put(BLOCK + ["box"], [0, 0, 0.5, 1, 1, 0]), "shape.box", "min < max"),
    (_put(BLOCK, {"cylinder": {"start": [0, 0, 0], "end": [0, 0, 1], "radius": 0}}), "shape.cylinder.radius", "greater than or equal"),
    (_put(BLOCK, {"cylinder": {"start": [0, 0, 0], "end": [0, 0, 0], "radius": 1}}), "shape.cylinder",
     "start and end must differ"),
    (_put(BLOCK, {"sphere": {"center": [0, 0, 0]}}), "shape.sphere.radius", "missing"),
    (_put(BLOCK, {"extrude": {"shape": {"rectangle": [0, 0, 1, 1]}, "vector": [1, 0, 0]}}), "shape.extrude",
     "z component"),
    (_put(BLOCK, {"extrude": {"shape": {"rectangle": [0, 0, 1]}, "vector": [0, 0, 1]}}),
     "shape.extrude.shape.rectangle", "at least 4"),
    (_put(BLOCK + ["minus"], [{"halfspace": {"point": [0, 0, 0], "normal": [0, 0, 0]}}]),
     "shape.minus.0.halfspace.normal", "must not be zero"),
    (_put(BLOCK, {"halfspace": {"point": [0, 0, 0], "normal": [0, 0, 1]}}), "regions.0.shape.halfspace",
     "unbounded"),
    (_put(BLOCK, {"box": [0, 0, 0, 1, 1, 1], "sphere": {"center": [0, 0, 0], "radius": 1}}), "shape",
     "exactly one"),
    (_put(["plane"], "strain"), "scene.plane", "unknown key"),
    (_put(["boundaries", "block_top"], {"segment": [[0, 0], [1, 0]]}), "scene.boundaries.block_top.segment",
     "unknown key"),
    (_put(["boundaries", "block_top", "plane", "tolerance"], -1.0), "scene.boundaries.block_top.plane.tolerance",
     "greater than 0"),
    (_put(["boundaries", "block_top", "body"], "lid"), "scene.boundaries.block_top.body", "unknown body"),
    (_put(["boundaries", "nothing"], {"plane": {"point": [0, 0, 9], "normal": [0, 0, 1]}}),
     "scene.boundaries.nothing", "selects no boundary face"),
    (_put(["regions_of_interest", "core"], {"disc": {"center": [0, 0], "radius": 1}}),
     "scene.regions_of_interest.core.disc", "unknown key"),
    (_put(["regions_of_interest", "core", "ball", "radius"], -0.2), "scene.regions_of_interest.core.ball.radius",
     "greater than or equal"),
    (_put(["regions_of_interest", "core", "body"], "lid"), "scene.regions_of_interest.core.body", "unknown body"),
    (_put(["supports", "lid"], {"u": [0, 0, 0]}), "scene.supports.lid", "unknown boundary"),
    (_put(["mesh", "size"], 0.3), "scene.mesh.size", "fewer than 4 cells"),
    (_put(["mesh", "max_cells"], 100), "scene.mesh.size", "more than mesh.max_cells = 100"),
    (_put(["mesh", "file"], "block.msh"), "scene.mesh", "a mesh `file` is used as it is: drop `size`"),
    (_put(["mesh", "refine"], [{"boundary": "nowhere", "size": 0.1}]), "scene.mesh.refine.0.boundary",
     "unknown boundary"),
    (_put(["mesh", "refine"], [{"disc": {"center": [0, 0], "radius": 1}, "size": 0.1}]), "scene.mesh.refine.0.disc",
     "unknown key"),
    (_put(["mesh", "refine"], [{"ball": {"center": [0.5, 0.5, 0], "radius": 0.1}, "size": 1e-4}]), "scene.mesh.refine.0.size",
     "more than mesh.max_cells"),
    (_put(["bodies", "block", "regions", 0, "shape", "box"], [0, 0, -0.2, 1, 1, 0.5]), "scene.bodies.block",
     "overlaps body 'base'"),
    # meshed as a piece of its own, it was blamed on the body ("consists of 2 pieces")
    (_put(["regions_of_interest", "core"], {"box": [0.5, 0.5, -0.25, 0.50001, 0.50001, -0.24999], "body": "base"}),
     "scene.regions_of_interest.core", "the region of interest is meshed apart from body 'base'"),
]


@pytest.mark.parametrize("change, path, words", BAD, ids=[b[1].split("scene.")[-1] + f"-{i}" for i, b in enumerate(BAD)])
def test_bad_3d_input_is_exit_2_at_its_key_path(tmp_path, change, path, words):
    d = doc()
    change(d)
    study = write(tmp_path, d)
    code, _, err = run(["check", str(study), "--quiet"])
    assert code == 2, err
    line = err.strip().splitlines()[-1]
    assert line.startswith(f"error: {study}: ") and path in line and words in line, line


def test_a_profile_grid_is_counted_in_exact_integers(tmp_path):
    """points: [2**62, 4] holds 2**64 values: the cap counts them as Python integers (before: the
    int64 product wrapped to 0, passed the cap, and the loader built 2**64 parameter names)."""
    d = doc()
    d["uncertain"]["contacts.interface.friction.slip_limit"] = {"range": [0.5e5, 1.5e5], "lipschitz": 2.0e5,
                                                               "points": [2**62, 4]}
    study = write(tmp_path, d)
    code, _, err = run(["check", str(study), "--quiet"])
    assert code == 2
    assert err == (f"error: {study}: uncertain.contacts.interface.friction.slip_limit.points: points needs at least "
                   f"2 values per direction and at most 1000 in all, got {[2**62, 4]}\n")


def test_mutated_3d_studies_never_fail_inside(tmp_path):
    """Seeded mutations (those of tests/acceptance/test_fuzz_check.py) of the 3D study: every check is exit 0
    (a study still good) or 2 (a bad input: a key path named), never an internal failure."""
    rng = random.Random(13)
    for i in range(25):
        d = copy.deepcopy(doc())
        what = mutate(d, rng)
        code, _, err = run(["check", str(write(tmp_path, d, f"m{i}.yaml")), "--quiet"])
        assert code in (0, 2) and "internal failure" not in err and "Traceback" not in err, (what, err)
        assert code == 0 or err.strip().splitlines()[-1].startswith("error: "), (what, err)
