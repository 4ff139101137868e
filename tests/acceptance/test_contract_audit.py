"""The public contract's three dimensions and ranges / fuzzy sets (its §5, §6) as an independent
checker tries them: study files written from the contract alone, then mutated, through the
`wcs` command. Each test here is a check that found a fault (it failed before the fix).

The slow fuzz loop: 200 seeded mutations of the shipped 3D studies and of a 3D range study
through `wcs check` (exit 0 or 2, one line naming the file and the key path, never a
traceback), the accepted ones of the range study run for a few solves (a `check` that says ok
must not be followed by a `run` that fails on the input)."""
from __future__ import annotations

import copy
import io
import os
import random
import re
import subprocess
import sys
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.acceptance.test_fuzz_check import mutate
from wcs.cli import main
from wcs.errors import StudyError
from wcs.scene.mesher3d import build_mesh3d
from wcs import load_study
from wcs.study.source import _read_yaml

ROOT = Path(__file__).resolve().parents[2]

# A soft block on a stiff one, written from the contract's §5 and §6 alone: three-component
# vectors, a fuzzy traction component, a Lipschitz slip limit on a [2, 2] grid, senses max, min
# and both, limits as a number and as {lower, upper}, two α-levels.
RANGE_3D = """
study: contract-3d
scene:
  dimension: 3
  mesh: {size: 0.25}
  materials:
    stiff: {E: 2.0e+10, nu: 0.25}
    soft: {E: 5.0e+9, nu: 0.3}
  bodies:
    base: {regions: [{material: stiff, shape: {box: [0, 0, -0.5, 1, 1, 0]}}]}
    block: {regions: [{material: soft, shape: {box: [0, 0, 0, 1, 1, 0.5]}}]}
  boundaries:
    base_bottom: {plane: {point: [0, 0, -0.5], normal: [0, 0, 1]}}
    block_top: {plane: {point: [0, 0, 0.5], normal: [0, 0, 1]}}
    x0: {box: [0, 0, -0.5, 0, 1, 0.5]}
    y0: {plane: {point: [0, 0, 0], normal: [0, 1, 0]}}
    base_top: {body: base, plane: {point: [0, 0, 0], normal: [0, 0, 1]}}
    block_bottom: {body: block, plane: {point: [0, 0, 0], normal: [0, 0, 1]}}
  supports:
    base_bottom: {u: [0.0, 0.0, 0.0]}
    x0: {u: [0.0, null, null]}
    y0: {normal: 0.0}
  loads:
    block_top: {traction: [1.0e+5, 0.0, -2.0e+6]}
  body_forces:
    block: [0.0, 0.0, -2.0e+4]
  contacts:
    interface: {slave: block_bottom, master: base_top, friction: {slip_limit: 3.0e+5}}
  regions_of_interest:
    interface: {boundary: base_top}
    core: {box: [0.25, 0.25, -0.4, 0.75, 0.75, -0.1], body: base}
    ball: {ball: {center: [0.5, 0.5, 0.25], radius: 0.2}}
uncertain:
  loads.block_top.traction.2: {support: [-3.0e+6, -1.0e+6], core: [-2.5e+6, -1.5e+6]}
  body_forces.block.2: [-3.0e+4, -1.0e+4]
  contacts.interface.friction.slip_limit:
    range: [2.0e+5, 4.0e+5]
    lipschitz: 1.0e+5
    points: [2, 2]
criteria:
  - {name: pressure, kind: contact_pressure, regions: [interface], sense: both}
  - {name: stress, kind: von_mises, regions: [core], sense: min}
  - {name: settle, kind: mean_normal_displacement, regions: [ball], direction: [0, 0, -1]}
limits:
  pressure: {lower: 1.0e+5, upper: 1.0e+7}
  stress: {lower: 1.0}
  settle: 1.0
fuzzy: {levels: [0.0, 1.0]}
search: {method: auto, budget: 40}
solver: {method: monolithic}
"""


def write(folder: Path, doc: dict) -> Path:
    path = folder / "study.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


def wcs(*argv) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of the `wcs` command."""
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def range_doc() -> dict:
    return yaml.safe_load(RANGE_3D)


# ---------------------------------------------------------------- what `check` prints


def test_check_of_a_3d_range_study_prints_the_levels_units_senses_and_limits(tmp_path):
    """`wcs check` prints what the study will do: in 3D as in 2D the fuzzy levels with the cores,
    each criterion's units, sense and both limits (before: only `sense max` and no limit, no level)."""
    code, out, err = wcs("check", write(tmp_path, range_doc()))
    assert code == 0, err
    assert ("fuzzy: levels 0, 1, searched from the core (α = 1) outwards; the boxes above are the supports; "
            "cores: loads.block_top.traction.2 [-2.5e+06, -1.5e+06]") in out
    assert "pressure: mean contact pressure (Φ6) over interface (contact_pressure) [Pa], sense both, lower limit 1e+05, limit 1e+07" in out
    assert "stress: mean von Mises stress over core (von_mises) [Pa], sense min, lower limit 1\n" in out
    assert "settle: mean normal displacement (Φ3/Φ4) over ball (mean_normal_displacement) [m], limit 1\n" in out
    assert "search: auto, budget 40 solves; solver: monolithic" in out
    assert "contacts.interface.friction.slip_limit[1,1]: [2e+05, 4e+05]  nominal 3e+05" in out


def test_the_locking_warning_of_a_3d_study_names_tetrahedra():
    doc = range_doc()
    doc["scene"]["materials"]["soft"]["nu"] = 0.47
    (warning,) = load_study(doc).warnings
    assert "P1 tetrahedra lock" in warning and "triangles" not in warning


@pytest.mark.parametrize("output", ["folder", "a-file/results.nc"])
def test_check_refuses_an_output_that_run_refuses(tmp_path, output):
    """`check` exit 0 must not be followed by a `run` that refuses the same file: an `output`
    that is a folder, or under a file, is exit 2 at `output` in both (before: `check` said ok)."""
    (tmp_path / "folder").mkdir()
    (tmp_path / "a-file").write_text("")
    doc = range_doc()
    doc["output"] = str(tmp_path / output)
    path = write(tmp_path, doc)
    for command in ("check", "run"):
        code, _, err = wcs(command, path, "--quiet")
        assert code == 2 and err.startswith(f"error: {path}: output: "), (command, err)
        assert ("is a directory" if output == "folder" else "a-file is a file") in err
    assert not (tmp_path / "folder" / "results.nc").exists()


def test_solve_worst_of_a_min_only_criterion_says_its_maximum_was_not_searched(tmp_path):
    """`solve --worst RUN C` for a criterion of sense min: exit 2 saying the maximum was not
    searched (before: "the run has no solved data set", untrue: every evaluation solved)."""
    doc = _read_yaml(ROOT / "studies" / "heated-plate.yaml")[0]
    doc["criteria"][0]["sense"] = "min"
    doc["limits"] = {}
    doc["search"] = {"method": "auto", "budget": 3}
    doc["output"] = str(tmp_path / "plate.nc")
    path = write(tmp_path, doc)
    code, _, err = wcs("run", path, "--no-mesh-check", "--quiet")
    assert code == 0, err
    code, _, err = wcs("solve", path, "--worst", tmp_path / "plate.nc", "heave", "-o", tmp_path / "w.nc")
    assert code == 2 and "did not search the maximum of criterion 'heave' (its sense is min)" in err, err
    code, _, err = wcs("solve", path, "--worst", tmp_path / "plate.nc", "shear", "-o", tmp_path / "w.nc")
    assert code == 0, err


def test_compare_of_a_folder_is_exit_2_in_one_line(tmp_path):
    """`wcs compare` of an unreadable file: exit 2, one line naming it (HDF5's message for a
    folder holds a line break; before, the message ran over two lines)."""
    code, _, err = wcs("compare", tmp_path, tmp_path / "b.nc")
    assert code == 2 and err.startswith(f"error: {tmp_path}: cannot read the results file (")
    assert len(err.strip().splitlines()) == 1, err


@pytest.mark.parametrize("values, words", [
    ({"contacts.interface.friction.slip_limit": [2.5e5, 3.0e5]},
     "values.contacts.interface.friction.slip_limit: a profile of 4 points takes one value or a list of 4, got 2"),
    ({"loads.block_top.traction.2": "abc"}, "values.loads.block_top.traction.2: must be a valid number (got 'abc')"),
    ({"contacts.interface.friction.slip_limit[0,1]": float("nan")},
     "values.contacts.interface.friction.slip_limit[0,1]: must be a finite number (got nan)"),
])
def test_a_bad_data_set_mapping_is_a_study_error_at_its_path(values, words):
    """`study.evaluate` / `data_set` of a mapping: a wrong-length profile or a non-number is a
    StudyError at `values.<path>` (before: numpy's ValueError, or NaN taken as data)."""
    study = load_study(range_doc())
    with pytest.raises(StudyError, match=re.escape(words)):
        study.data_set(values)
    x, _ = study.data_set({"contacts.interface.friction.slip_limit": [2.1e5, 2.2e5, 2.3e5, 2.4e5],
                           "loads.block_top.traction.2": -2.2e6})
    assert x.tolist() == [-2.2e6, -2.0e4, 2.1e5, 2.2e5, 2.3e5, 2.4e5]


@pytest.mark.parametrize("misspelt, hint", [
    ("loads.block_top.tractoin.2", "no 'tractoin' under 'loads.block_top' (did you mean 'traction'?)"),
    ("materials.soft.EE", "no 'EE' under 'materials.soft' (did you mean 'E'?)"),
])
def test_a_misspelt_uncertain_path_is_exit_2_with_did_you_mean(tmp_path, misspelt, hint):
    """A misspelt key of an uncertain path: exit 2 at `uncertain.<path>` with "did you mean"
    (before: only the list of the forms that can vary)."""
    doc = range_doc()
    doc["uncertain"][misspelt] = doc["uncertain"].pop("loads.block_top.traction.2") \
        if "traction" in misspelt else [4.0e9, 6.0e9]
    path = write(tmp_path, doc)
    code, _, err = wcs("check", path, "--quiet")
    assert code == 2 and err.startswith(f"error: {path}: uncertain.{misspelt}: "
                                        f"'{misspelt}' is not a number that can vary: {hint}; these can: "), err


def test_report_of_a_solve_of_a_fuzzy_study_with_lower_and_upper_limits(tmp_path):
    """`wcs report` of the file `wcs solve` writes, for a study with `limits.<c>: {lower, upper}`
    and a fuzzy number: exit 0, the upper limit in the table, no claim that the study is crisp
    (before: an internal failure, float() of the {lower, upper} mapping)."""
    doc = _read_yaml(ROOT / "studies" / "heated-plate.yaml")[0]
    doc["criteria"][0]["sense"] = "both"
    doc["limits"] = {"heave": {"lower": 1.0e-5, "upper": 1.0e-3}}
    doc["uncertain"]["materials.steel.E"] = {"support": [1.9e11, 2.3e11], "core": [2.05e11, 2.15e11]}
    path = write(tmp_path, doc)
    code, _, err = wcs("solve", path, "-o", tmp_path / "nominal.nc", "--quiet")
    assert code == 0, err
    code, _, err = wcs("report", tmp_path / "nominal.nc", "-o", tmp_path / "nominal.html", "--quiet")
    assert code == 0, err
    page = (tmp_path / "nominal.html").read_text(encoding="utf-8")
    assert "A single solve at one data set" in page and "A crisp study" not in page
    assert re.search(r'<tr data-criterion="heave">(<td[^>]*>[^<]*</td>){4}<td class="num">0.001000 m</td>', page)


def test_a_3d_refine_zone_may_name_its_body():
    """§5: region selectors of `refine` take an optional `body` (before: exit 2, unknown key).
    A ball inside the base (0.15 m below the block): named for the base it refines the base as
    the zone without `body` does, cell for cell (gmsh meshes the same size field the same way);
    named for the block it leaves the base at its unrefined count but for the face it shares
    with the block (409 cells against 385 without the zone, 1384 with it)."""
    def cells(refine):
        doc = range_doc()
        doc["scene"]["mesh"] = {"size": 0.25, "refine": refine}
        sm = build_mesh3d(load_study(doc).scene)
        return np.bincount(sm.cell_body, minlength=2).tolist()
    zone = {"ball": {"center": [0.5, 0.5, -0.25], "radius": 0.1}, "size": 0.05}
    plain, everywhere = cells([]), cells([zone])
    assert everywhere[0] > 3 * plain[0]
    assert cells([{**zone, "body": "base"}]) == everywhere
    assert cells([{**zone, "body": "block"}])[0] < 1.1 * plain[0]
    with pytest.raises(StudyError, match=r"scene\.mesh\.refine\.0\.body: unknown body 'bse' \(did you mean 'base'\?\)"):
        load_study({**range_doc(), "scene": {**range_doc()["scene"], "mesh": {"size": 0.25, "refine": [{**zone, "body": "bse"}]}}})


def test_an_unbalanced_pair_of_bodies_is_named_by_the_body_whose_load_drives_it(tmp_path):
    """Without the base's support nothing holds the two blocks along z: the block's load drives
    both down (status 3, exit 2). The message names the block, its net load, the base moving
    with it and the motion's load work, positive (before: 'base', whose own load is zero: "net
    load (0, 0, 0) N drives a rigid motion ... (load work 0 > friction work)"). The `wcs`
    process itself: cvxpy's "Solution may be inaccurate" of the disc-friction solvability
    program is one `warning:` line (before: Python's two, the second a line of wcs's source)."""
    doc = range_doc()
    del doc["scene"]["supports"]["base_bottom"]
    path = write(tmp_path, doc)
    run = subprocess.run([str(Path(sys.executable).parent / "wcs"), "check", str(path), "--quiet"],
                         env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True, timeout=300)
    code, err = run.returncode, run.stderr
    assert code == 2, err
    assert all(line.startswith(("warning: ", "error: ")) for line in err.strip().splitlines()), err
    line = err.strip().splitlines()[-1]
    assert "body 'block' is held only by contact and its load is not balanced: net load (" in line, line
    assert "-2.01e+06) N drives a rigid motion (with body 'base') that friction and contact do not resist" in line
    work = float(re.search(r"load work ([0-9.e+-]+) > friction work", line).group(1))
    assert work > 1e5, line


def test_a_3d_scene_without_its_dimension_is_told_so(tmp_path):
    """A scene written in §5's words but without `dimension: 3` (a 2D scene is the default):
    exit 2 at `scene.dimension` (before: at the first 3D word the 2D schema does not know,
    "scene.bodies.base.regions.0.shape.box: unknown key 'box' ... (and 14 more)")."""
    doc = range_doc()
    del doc["scene"]["dimension"]
    path = write(tmp_path, doc)
    code, _, err = wcs("check", path, "--quiet")
    assert code == 2 and err.startswith(f"error: {path}: scene.dimension: required key is missing: the scene "
                                        "is a 3D one"), err


# ---------------------------------------------------------------- the fuzz loop


HEAVY_3D = [ROOT / "studies" / n for n in ("tunnel-fault-3d.yaml", "tunnel-fault-oblique-3d.yaml",
                                           "knee-replacement-3d.yaml")]
MESSAGE = re.compile(r"error: (\S+): ([\w.\[\],-]+): \S")


def fuzz_cases(count: int, seed: int = 20) -> list[tuple[str, str, dict]]:
    """`count` (study, description, document) mutations, the shipped 3D studies (read as wcs reads
    them: `1.0e7` a number; their material library is found by name) and the range study in turn,
    the same for the same seed."""
    rng = random.Random(seed)
    bases = [(p.name, _read_yaml(p)[0]) for p in HEAVY_3D] + [("range-3d", range_doc())]   # 1e7: a number
    out = []
    for i in range(count):
        name, base = bases[i % len(bases)]
        doc = copy.deepcopy(base)
        out.append((name, mutate(doc, rng), doc))
    return out


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_mutated_3d_and_range_studies_are_exit_0_or_2_at_a_key_path(tmp_path):
    bad = []
    for i, (study, what, doc) in enumerate(fuzz_cases(200)):
        path = write(tmp_path, doc)
        code, _, err = wcs("check", path, "--quiet")
        errors = [line for line in err.splitlines() if not line.startswith("warning:")]
        if code == 2:
            m = MESSAGE.match(errors[0]) if len(errors) == 1 else None
            if m is None or m.group(1) != str(path):
                bad.append((study, what, code, err))
        elif code != 0 or errors:
            bad.append((study, what, code, err))
        elif study == "range-3d":
            doc["search"] = {"method": "auto", "budget": 3}
            code, _, err = wcs("run", write(tmp_path, doc), "-o", tmp_path / f"run-{i}.nc", "--no-mesh-check", "--quiet")
            if code != 0:
                bad.append((study, what + " (run)", code, err))
    assert not bad, "\n".join(f"{s}: {w}: exit {c}: {e.strip()[-400:]}" for s, w, c, e in bad)
