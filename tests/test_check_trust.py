"""`wcs check` refuses what will fail (issue 15, B8-B14): the nominal solve, facing contact
sides, physical ranges, the resource guard, P1-locking warnings, degenerate geometry, and
every message naming the study file."""
from pathlib import Path

import numpy as np
import pytest
import yaml

from bad_studies import demo_doc, write_study
from wcs.cli import main
from wcs.errors import StudyError
from wcs.scene import estimate, geometry, mesher
from wcs.study import load_study

ROOT = Path(__file__).resolve().parents[1]
VALIDATION = ROOT / "studies" / "validation"


def doc_of(name: str) -> dict:
    return yaml.safe_load((VALIDATION / name).read_text(encoding="utf-8"))


def check(doc: dict, tmp_path, capsys, *extra):
    path = write_study(doc, tmp_path)
    code = main(["check", str(path), *extra])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err and "internal failure" not in err
    return code, out, err, path


# ---------------------------------------------------------------- B8: the nominal solve


def test_check_refuses_an_unsolvable_nominal_like_solve(tmp_path, capsys):
    """Shear 5e5 N/m on a floating pad held by Tresca friction g = 3e5 Pa over 1 m: the
    solvability condition fails (status 3); `solve` exits 2 and now `check` does too."""
    doc = doc_of("tresca-pad.yaml")
    doc["scene"]["loads"]["pad_top"]["traction"][0] = 5.0e5
    doc["uncertain"]["loads.pad_top.traction.0"] = [1.0e5, 6.0e5]
    code, out, err, path = check(doc, tmp_path, capsys)
    assert code == 2, (out, err)
    assert str(path) in err and "nominal data set cannot be solved" in err and "status 3" in err
    assert "pad" in err                                     # the body
    solve_code = main(["solve", str(path), "-o", str(tmp_path / "n.nc"), "--quiet"])
    solve_err = capsys.readouterr().err
    assert solve_code == 2 and "pad" in solve_err


def test_check_reports_the_nominal_values(tmp_path, capsys):
    code, out, err, _ = check(doc_of("contact-patch.yaml"), tmp_path, capsys)
    assert code == 0, err
    line = next(l for l in out.splitlines() if "nominal solve" in l)
    # uniform uniaxial stress: the contact pressure is the applied 1e6 Pa to round-off
    assert "pressure = 1e+06" in line


# ---------------------------------------------------------------- B9: sides that do not face


def test_contact_sides_facing_away_are_bad_input(tmp_path, capsys):
    """The top of the upper block against the bottom of the base: normals oppose (+y, -y) but
    the slave starts 1.6 m inside the master body; every evaluation would fail."""
    doc = doc_of("contact-patch.yaml")
    doc["scene"]["contacts"]["interface"] = {"slave": "block_top", "master": "base_bottom"}
    code, out, err, path = check(doc, tmp_path, capsys)
    assert code == 2, (out, err)
    assert "scene.contacts.interface" in err and "do not face each other" in err
    assert "1.6 deep" in err and str(path) in err


@pytest.mark.parametrize("discretization", ["node-to-node", "mortar"])
def test_facing_away_refused_by_either_discretization(tmp_path, capsys, discretization):
    doc = doc_of("stacked-layers.yaml")
    doc["scene"]["contacts"]["interface"].update(slave="block_top", master="base_bottom",
                                                 discretization=discretization)
    code, _, err, _ = check(doc, tmp_path, capsys, "--quiet")
    assert code == 2 and "do not face each other" in err


# ---------------------------------------------------------------- B10: sensible ranges


def test_empty_uncertain_runs_the_nominal_data():
    """`uncertain: {}` is U_ad = {nominal}: a run is one evaluation, the nominal one."""
    from wcs.evaluation import Evaluator
    from wcs.runner import run
    doc = doc_of("contact-patch.yaml")
    doc["uncertain"] = {}
    study = load_study(doc)
    ds = run(study, output=False)
    assert ds.sizes["eval"] == 1 and int(ds["status"].values[0]) == 0
    nominal = Evaluator(study).evaluate(study.nominal())
    assert float(ds["phi"].values.ravel()[0]) == nominal.phi["pressure"]


@pytest.mark.parametrize("value", [1e-300, 1e300, 0.5])
def test_moduli_outside_physical_range(value):
    doc = demo_doc()
    doc["scene"]["materials"]["steel"]["E"] = value
    doc["uncertain"]["materials.rubber.E"] = [0.8e7, 1.2e7]
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert info.value.path == "scene.materials.steel.E"


def test_uncertain_box_bounded_too():
    doc = demo_doc()
    doc["uncertain"]["materials.rubber.E"] = [0.8e7, 1e300]
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert info.value.path == "uncertain.materials.rubber.E" and "<= 1e+13" in info.value.fault


def test_mesh_size_larger_than_a_quarter_of_the_scene():
    doc = demo_doc()
    doc["scene"]["mesh"]["size"] = 0.6                      # scene 2 m wide: 3.3 cells along it
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert info.value.path == "scene.mesh.size" and "fewer than 4 cells" in info.value.fault
    doc["scene"]["mesh"]["size"] = 0.5
    load_study(doc)


# ---------------------------------------------------------------- B11: resource guard


def test_guard_refuses_a_tiny_size_before_meshing(tmp_path, capsys):
    doc = demo_doc()
    doc["scene"]["mesh"]["refine"][0]["size"] = 1e-6
    code, _, err, _ = check(doc, tmp_path, capsys)
    assert code == 2 and "scene.mesh.refine.0.size" in err and "mesh.max_cells" in err
    # both bodies: 2.31 (A/h^2 + A_zone/s^2 + P_zone/(g s) + ...), the zone (0.24 m^2) at s = 1e-6
    s, h, g = 1e-6, 0.05, 0.5
    zone = 0.24 / s**2 + 2.8 / g * (1 / s - 1 / h) + 2 * np.pi / g**2 * (np.log(h / s) + s / h - 1)
    cells = estimate.CELLS_PER_H2 * (2.5 / h**2 + 2 * zone)
    assert f"about {cells:.3g} cells" in err


def test_guard_limit_is_a_study_option():
    doc = demo_doc()
    doc["scene"]["mesh"]["max_cells"] = 5000
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert "more than mesh.max_cells = 5000" in info.value.fault
    doc["scene"]["mesh"]["max_cells"] = 50_000
    assert 1e4 < load_study(doc).estimated_cells < 5e4


def test_a_raised_max_cells_is_held_to_the_machine_memory(monkeypatch):
    """max_cells: 1e10 at size 1e-3 (5.8e6 cells, ~30 GB) meshed and solved until the machine
    swapped: the estimated cells times BYTES_PER_CELL must fit in the machine's memory. At size
    0.0025 the demo estimates 9.2e5 cells, 4.8 GB at 5200 bytes a cell: refused on a machine
    of 4 GB, loaded on one of 8 GB."""
    import wcs.study
    doc = demo_doc()
    doc["scene"]["mesh"].update(size=0.0025, max_cells=10**10)
    monkeypatch.setattr(wcs.study, "machine_memory", lambda: 8e9)
    cells = load_study(doc).estimated_cells
    assert 9e5 < cells < 9.5e5
    monkeypatch.setattr(wcs.study, "machine_memory", lambda: 4e9)
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert info.value.path == "scene.mesh.size" and info.value.fault == (
        f"the mesh would have about {cells:.3g} cells ({cells:.3g} unknowns), which needs about "
        f"{cells * 5200 / 1e9:.3g} GB (5200 bytes a cell), more than this machine's 4 GB of memory (this size "
        "contributes most); coarsen the mesh")


def test_profile_points_capped():
    doc = demo_doc()
    doc["uncertain"]["contacts.interface.friction.slip_limit"]["points"] = 10**7
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert info.value.path == "uncertain.contacts.interface.friction.slip_limit.points"


@pytest.mark.parametrize("name", ["contact-patch.yaml", "tresca-pad.yaml", "glued-mortar.yaml"])
def test_estimate_within_a_factor_two_of_the_mesh(name):
    """Measured on every shipped study: estimate / cells from 0.84 to 2.95 (knee: refine discs
    straddling two bodies count in both)."""
    study = load_study(VALIDATION / name)
    cells = mesher.build_mesh(study.scene).mesh.t.shape[1]
    assert 0.8 < study.estimated_cells / cells < 2.0


def test_estimate_grading_is_the_mesher_default():
    assert estimate.DEFAULT_GRADING == mesher.DEFAULT_GRADING


def test_check_prints_estimate_and_count(tmp_path, capsys):
    code, out, _, _ = check(doc_of("contact-patch.yaml"), tmp_path, capsys)
    assert code == 0
    assert "estimated 739 cells before meshing" in out and "774 meshed" in out


# ---------------------------------------------------------------- B12: P1 locking


def test_locking_warning_on_nominal_and_box(tmp_path, capsys):
    doc = demo_doc()                                        # rubber nu 0.45 in [0.40, 0.48]
    code, _, err, _ = check(doc, tmp_path, capsys, "--quiet")
    assert code == 0 and "warning:" in err and "material 'rubber': Poisson ratio up to 0.48" in err
    doc["scene"]["materials"]["rubber"]["nu"] = 0.42
    doc["uncertain"]["materials.rubber.nu"] = [0.40, 0.449]
    assert load_study(doc).warnings == []
    for key in ("materials.rubber.nu", "materials.rubber.E"):
        doc["uncertain"].pop(key)
    doc["scene"]["materials"]["rubber"] = {"lambda": 9.0e7, "mu": 3.4e6, "conductivity": 0.2}
    warnings = load_study(doc).warnings
    assert len(warnings) == 1 and f"{9.0e7 / (2 * (9.0e7 + 3.4e6)):.4g}" in warnings[0]


# ---------------------------------------------------------------- B13: degenerate geometry


POLY = ["scene", "bodies", "base", "regions", 0, "shape"]


@pytest.mark.parametrize("shape,words", [
    ({"polygon": [[0, 0], [2, 0], [2, 0], [2, 1], [0, 1]]}, "repeated vertex"),
    ({"polygon": [[0, 0], [2, 1], [2, 0], [0, 1]]}, "self-intersecting"),
    ({"polygon": [[0, 0], [2, 0], [2, 1], [1, 0], [0, 1]]}, "self-intersecting"),   # touches
    ({"rectangle": [0, 0, 1e-9, 1e-9]}, "below 1e-06"),
    ({"rectangle": [0, 0, 1e308, 1]}, "less than or equal to 1000000"),
])
def test_degenerate_shapes_are_bad_input(tmp_path, capsys, shape, words):
    doc = demo_doc()
    doc["scene"]["bodies"]["base"]["regions"][0]["shape"] = shape
    code, _, err, _ = check(doc, tmp_path, capsys, "--quiet")
    assert code == 2 and "scene.bodies.base.regions.0.shape" in err and words in err, err


def test_a_geometry_kernel_exception_names_the_shape():
    def refuse():
        raise Exception("Could not create line")
    with pytest.raises(StudyError) as info:
        geometry.kernel("scene.bodies.b.regions.0.shape", refuse)
    assert info.value.path == "scene.bodies.b.regions.0.shape" and "Could not create line" in info.value.fault


def test_deeply_nested_yaml_is_bad_input(tmp_path, capsys):
    path = tmp_path / "deep.yaml"
    path.write_text("a: " + "[" * 10_000 + "]" * 10_000 + "\n")
    assert main(["check", str(path)]) == 2
    assert "nests deeper than" in capsys.readouterr().err


# ---------------------------------------------------------------- B14: the file in every message


def test_mesh_stage_errors_name_the_study_file(tmp_path, capsys):
    doc = demo_doc()
    doc["scene"]["regions_of_interest"]["under_pad"] = {"box": [5.0, 5.0, 6.0, 6.0]}
    code, _, err, path = check(doc, tmp_path, capsys)
    assert code == 2 and err.startswith(f"error: {path}: scene.regions_of_interest.under_pad")


def test_an_error_that_names_its_file_keeps_it():
    e = StudyError("bad", file="lib.yaml", path="x")
    assert e.in_file("study.yaml") is e
    assert str(StudyError("bad", path="x").in_file("study.yaml")) == "study.yaml: x: bad"


def test_no_criteria_is_a_warning(tmp_path, capsys):
    doc = doc_of("contact-patch.yaml")
    doc["criteria"] = []
    code, _, err, _ = check(doc, tmp_path, capsys, "--quiet")
    assert code == 0 and "warning:" in err and "no criteria" in err


# ---------------------------------------------------------------- a body in pieces


def test_a_body_in_two_pieces_is_bad_input(tmp_path, capsys):
    """A body of two regions that do not touch: one piece held, the other free, so its
    stiffness is singular (before: exit 1 'singular factorization' at the nominal solve)."""
    doc = doc_of("contact-patch.yaml")
    body = next(iter(doc["scene"]["bodies"]))
    regions = doc["scene"]["bodies"][body]["regions"]
    far = dict(regions[0], name="far", shape={"rectangle": [50.0, 50.0, 51.0, 51.0]})
    regions.append(far)
    code, out, err, path = check(doc, tmp_path, capsys)
    assert code == 2, (out, err)
    assert f"{path}: scene.bodies.{body}: body '{body}' consists of 2 pieces" in err
