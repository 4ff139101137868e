"""`wcs check` refuses what will fail: the nominal solve, facing contact
sides, physical ranges, the resource guard, P1-locking warnings, degenerate geometry, and
every message naming the study file."""
from pathlib import Path

import pytest
import yaml

from tests.support.bad_studies import demo_doc, write_study
from wcs.cli import main
from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs.scene import estimate, geometry
from wcs.scene import mesher2d as mesher
from wcs import load_study

ROOT = Path(__file__).resolve().parents[2]
VALIDATION = ROOT / "studies" / "validation"


def doc_of(name: str) -> dict:
    return yaml.safe_load((VALIDATION / name).read_text(encoding="utf-8"))


def check(doc: dict, tmp_path, capsys, *extra):
    path = write_study(doc, tmp_path)
    code = main(["check", str(path), *extra])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err and "internal failure" not in err
    return code, out, err, path


# ---------------------------------------------------------------- the nominal solve


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


# ---------------------------------------------------------------- sides that do not face


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


# ---------------------------------------------------------------- sensible ranges


def test_empty_uncertain_runs_the_nominal_data():
    """`uncertain: {}` is U_ad = {nominal}: a run is one evaluation, the nominal one."""
    from wcs.model.evaluation import Evaluator
    from wcs.app.runner import run
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
    assert info.value.path == "uncertain.materials.rubber.E" and "<= 1e+20" in info.value.fault


def test_mesh_size_larger_than_a_quarter_of_the_scene():
    doc = demo_doc()
    doc["scene"]["mesh"]["size"] = 0.6                      # scene 2 m wide: 3.3 cells along it
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert info.value.path == "scene.mesh.size" and "fewer than 4 cells" in info.value.fault
    doc["scene"]["mesh"]["size"] = 0.5
    load_study(doc)


# ---------------------------------------------------------------- resource guard


def test_guard_refuses_a_tiny_size_before_meshing(tmp_path, capsys):
    doc = demo_doc()
    doc["scene"]["mesh"]["refine"][0]["size"] = 1e-6
    code, _, err, _ = check(doc, tmp_path, capsys)
    assert code == 2 and "scene.mesh.refine.0.size" in err and "mesh.max_cells" in err
    # both bodies: 2.31 (A/h^2 + A_zone (1/s^2 - 1/h^2) + the halo's ~P_zone/(g s)), the zone (0.24 m^2)
    # at s = 1e-6 counted in each body for its share inside the body's box, on 16 x 16 samples: the
    # base's lower half, the pad's upper half of 14 of 16 columns (x in [0.5, 1.5] of [0.4, 1.6]);
    # the halo, 2.8 / (0.5 s) = 5.6e6, is below the 3 digits of 2.3e11
    s, h = 1e-6, 0.05
    cells = estimate.CELLS_PER_H2 * (2.5 / h**2 + 0.24 * (1 / 2 + 7 / 16) * (1 / s**2 - 1 / h**2))
    assert f"about {cells:.3g} cells" in err


def test_guard_limit_is_a_study_option():
    doc = demo_doc()
    doc["scene"]["mesh"]["max_cells"] = 5000
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert "more than mesh.max_cells = 5000" in info.value.fault
    doc["scene"]["mesh"]["max_cells"] = 50_000
    assert 5e3 < load_study(doc).estimated_cells < 5e4


def test_a_raised_max_cells_is_held_to_the_machine_memory(monkeypatch, tmp_path, capsys):
    """max_cells: 1e10 at size 1e-3 (5.8e6 cells, ~30 GB) meshed and solved until the machine
    swapped. An estimate beyond the memory is refused before meshing; the cells made are held
    to the memory itself, before any assembly. At size 0.0025 the demo estimates 9.2e5 cells, 4.8 GB at 5200 bytes
    a cell: refused on a machine of 4 GB, loaded on one of 8 GB."""
    import wcs.scene.estimate as estimate
    import wcs.study.resources
    doc = demo_doc()
    doc["scene"]["mesh"].update(size=0.0025, max_cells=10**10)
    monkeypatch.setattr(wcs.study.resources, "machine_memory", lambda: 8e9)
    cells = load_study(doc).estimated_cells
    assert 9e5 < cells < 9.5e5
    monkeypatch.setattr(wcs.study.resources, "machine_memory", lambda: 4e9)
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert info.value.path == "scene.mesh.size" and info.value.fault.startswith(
        f"the mesh would have about {cells:.3g} cells ({cells:.3g} unknowns), which needs about "
        f"{cells * 5200 / 1e9:.3g} GB (5200 bytes a cell with solver.method auto), more than this machine's 4 GB "
        "of memory")
    # the cells made: a coarse demo (size 0.05, ~2e3 cells, ~1e7 bytes) on a machine of 1 MB
    monkeypatch.setattr(estimate, "machine_memory", lambda: 1e6)
    path = tmp_path / "demo.yaml"
    path.write_text(yaml.safe_dump(demo_doc(), sort_keys=False))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: scene.mesh: the mesh has " in err and "more than this machine's 0.001 GB of memory" in err


def test_profile_points_capped():
    doc = demo_doc()
    doc["uncertain"]["contacts.interface.friction.slip_limit"]["points"] = 10**7
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert info.value.path == "uncertain.contacts.interface.friction.slip_limit.points"


@pytest.mark.parametrize("name", ["contact-patch.yaml", "tresca-pad.yaml", "glued-mortar.yaml"])
def test_estimate_within_a_factor_two_of_the_mesh(name):
    """Not below the 0.65 the guard relies on (wcs.scene.estimate ESTIMATE_EXCESS), nor 2x above."""
    study = load_study(VALIDATION / name)
    cells = mesher.build_mesh(study.scene).mesh.t.shape[1]
    assert 0.65 < study.estimated_cells / cells < 2.0


def test_estimate_grading_is_the_mesher_default():
    assert estimate.DEFAULT_GRADING == mesher.DEFAULT_GRADING


def test_check_prints_estimate_and_count(tmp_path, capsys):
    code, out, _, _ = check(doc_of("contact-patch.yaml"), tmp_path, capsys)
    assert code == 0
    assert "estimated 739 cells before meshing" in out and "774 meshed" in out


# ---------------------------------------------------------------- P1 locking


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


# ---------------------------------------------------------------- degenerate geometry


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


# ---------------------------------------------------------------- the file in every message


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


# ---------------------------------------------------------------- inputs that change the physics


def claims_of(doc: dict):
    """The study's evaluator, built as `check` builds it (the claims checked after the model)."""
    return Evaluator(load_study(doc))


def patch_with(**scene) -> dict:
    """The contact-patch study (a block on a base, rollers, 1e6 Pa on top) with scene entries added."""
    doc = doc_of("contact-patch.yaml")
    for block, entries in scene.items():
        doc["scene"].setdefault(block, {}).update(entries)
    return doc


BASE_BOTTOM_AGAIN = {"boundaries": {"again": {"segment": [[0.0, 0.0], [2.0, 0.0]]}}}


@pytest.mark.parametrize("again", [{"u": [None, 1.0e-3]}, {"u": [None, 0.0]}, {"normal": 0.0}])
def test_two_supports_on_one_face_and_direction_are_refused(tmp_path, capsys, again):
    """base_bottom holds u_y = 0; a second boundary on the same edge holding u_y = 1e-3 was
    averaged with it by the elimination (5e-4); the same value twice, or a roller (u_n = 0 along
    n = (0, -1)), is refused too: one support per face and direction."""
    doc = patch_with(**BASE_BOTTOM_AGAIN, supports={"again": again})
    code, out, err, path = check(doc, tmp_path, capsys, "--quiet")
    assert code == 2, (out, err)
    assert f"{path}: scene.supports.again:" in err and "hold the same direction on 20 common edges" in err


def test_supports_on_different_directions_of_one_face_are_fine():
    claims_of(patch_with(**BASE_BOTTOM_AGAIN, supports={"again": {"u": [0.0, None]}}))


@pytest.mark.parametrize("left, box", [([0.0, 1.0e-3], None), ([0.0, 0.0], [-1.0e-3, 1.0e-3])])
def test_supports_meeting_at_a_corner_with_other_values(left, box):
    """base_left and base_bottom meet at (0, 0): base_bottom holds u_y = 0 there, base_left would
    hold u_y = 1e-3 (or a box around 0): the corner's displacement would be their average."""
    doc = patch_with(supports={"base_left": {"u": left}})
    if box:
        doc["uncertain"]["supports.base_left.u.1"] = box
    with pytest.raises(StudyError) as info:
        claims_of(doc)
    assert info.value.path == "scene.supports.base_left" and "meet at (0, 0)" in info.value.fault
    assert ("varies over the study" if box else "with different values") in info.value.fault


def test_supports_meeting_at_a_corner_with_one_value_are_fine():
    claims_of(patch_with(supports={"base_left": {"u": [0.0, 0.0]}}))


@pytest.mark.parametrize("again", [{"slave": "block_bottom", "master": "base_top"},
                                   {"slave": "base_top", "master": "block_bottom"},
                                   {"slave": "half", "master": "base_top"}])
def test_one_interface_in_two_contacts_is_refused(tmp_path, capsys, again):
    """The same pair twice, reversed, or over half the interface: the contact pressure came out
    halved (5e5 Pa for the 1e6 Pa on top)."""
    doc = patch_with(boundaries={"half": {"body": "block", "segment": [[1.0, 1.0], [2.0, 1.0]]}},
                     contacts={"again": again})
    code, out, err, path = check(doc, tmp_path, capsys, "--quiet")
    assert code == 2, (out, err)
    assert f"{path}: scene.contacts.again:" in err and "an interface is one contact or glue" in err


def test_a_support_on_a_contact_slave_side_is_refused():
    """u_y = 0 on the slave side gave contact pressure 0 (the support took the load)."""
    with pytest.raises(StudyError) as info:
        claims_of(patch_with(supports={"block_bottom": {"u": [None, 0.0]}}))
    assert info.value.path == "scene.supports.block_bottom" and "20 edges" in info.value.fault


def test_a_held_master_side_is_a_rigid_obstacle_and_accepted():
    """The master side held (u = 0) is the rigid foundation engineers model so: the slave rows
    act and carry the contact force (tests/acceptance/test_stiff_bodies.py checks its pressure)."""
    claims_of(patch_with(supports={"base_top": {"u": [0.0, 0.0]}}))


def test_supports_meeting_a_contact_side_at_its_end_or_across_it_are_fine():
    """block_left (u = 0, 0) ends on the slave side at (0, 1): a shared node, not a common edge
    (the tunnel's fault meets its held sides so); u_x = 0 on the slave side holds no normal motion."""
    claims_of(patch_with(supports={"block_left": {"u": [0.0, 0.0]}}))
    claims_of(patch_with(supports={"block_bottom": {"u": [0.0, None]}}))


def test_a_support_on_part_of_a_glued_side_is_refused():
    """u_x = 0 on the left half of the glued side: those nodes left the glue (all of it would
    have been refused by the glue already)."""
    doc = doc_of("glued-mortar.yaml")
    doc["scene"]["boundaries"]["half"] = {"body": "hard", "segment": [[0.0, 0.3], [0.5, 0.3]]}
    doc["scene"]["supports"]["half"] = {"u": [0.0, None]}
    with pytest.raises(StudyError) as info:
        Evaluator(load_study(doc))
    assert info.value.path == "scene.supports.half" and "(glue ties every direction)" in info.value.fault


def block_on_block_apart(dz: float, glue: bool) -> dict:
    """block-on-block-3d with the block lifted by `dz` (its faces parallel to the base's top),
    the contact a contact or a glue; a coarse mesh."""
    doc = doc_of("block-on-block-3d.yaml")
    scene = doc["scene"]
    scene["mesh"]["size"] = 0.25
    scene["bodies"]["block"]["regions"][0]["shape"]["box"] = [0, 0, dz, 1, 1, dz + 0.5]
    scene["boundaries"]["block_top"]["plane"]["point"] = [0, 0, dz + 0.5]
    scene["boundaries"]["block_bottom"]["plane"]["point"] = [0, 0, dz]
    if glue:
        scene["glue"] = {"interface": scene.pop("contacts")["interface"]}
        doc["criteria"] = [c for c in doc["criteria"] if c["kind"] != "contact_pressure"]
    return doc


def test_contact_sides_10_m_apart_are_refused_in_3d():
    """The 2D rule (some slave node within max(5 h, 1 % of the master side) of it) holds for
    3D mortar rows too: before, 10 m apart solved (the block sliding 10 m rigidly) with the
    contact pressure of touching sides."""
    with pytest.raises(StudyError) as info:
        Evaluator(load_study(block_on_block_apart(10.0, glue=False)))
    assert info.value.path == "scene.contacts.interface" and "the closest is 10 away" in info.value.fault


def test_glue_between_faces_1_m_apart_is_refused():
    with pytest.raises(StudyError) as info:
        Evaluator(load_study(block_on_block_apart(1.0, glue=True)))
    assert info.value.path == "scene.glue.interface" and "is 1 from the master side" in info.value.fault


def test_contact_sides_10_m_apart_are_refused_by_2d_mortar():
    doc = doc_of("contact-patch.yaml")
    scene = doc["scene"]
    scene["bodies"]["block"]["regions"][0]["shape"]["rectangle"] = [0.0, 11.0, 2.0, 11.6]
    scene["boundaries"].update(block_left={"segment": [[0.0, 11.0], [0.0, 11.6]]},
                               block_top={"segment": [[0.0, 11.6], [2.0, 11.6]]},
                               block_bottom={"body": "block", "segment": [[0.0, 11.0], [2.0, 11.0]]})
    scene["contacts"]["interface"]["discretization"] = "mortar"
    with pytest.raises(StudyError) as info:
        Evaluator(load_study(doc))
    assert info.value.path == "scene.contacts.interface" and "the closest is 10 away" in info.value.fault


def test_glue_between_sides_apart_is_refused_in_2d():
    """glued-mortar with the upper layer lifted 0.2 m off the lower: glued, it hung there."""
    doc = doc_of("glued-mortar.yaml")
    scene = doc["scene"]
    scene["bodies"]["hard"]["regions"][0]["shape"]["rectangle"] = [0.0, 0.5, 1.0, 0.7]
    scene["boundaries"].update(top={"segment": [[0.0, 0.7], [1.0, 0.7]]},
                               hard_bottom={"body": "hard", "segment": [[0.0, 0.5], [1.0, 0.5]]})
    with pytest.raises(StudyError) as info:
        Evaluator(load_study(doc))
    assert info.value.path == "scene.glue.interface" and "is 0.2 from the master side" in info.value.fault


def test_two_temperatures_on_one_face_are_refused():
    """A second boundary on the plate's top held at 300 K: the top's nodes took the mean of the
    two (321.5 K), neither temperature the study states."""
    doc = yaml.safe_load((ROOT / "studies" / "heated-plate.yaml").read_text(encoding="utf-8"))
    doc["scene"]["boundaries"]["lid"] = {"segment": [[0.0, 0.5], [1.0, 0.5]]}
    doc["scene"]["thermal"]["temperature"]["lid"] = 300.0
    with pytest.raises(StudyError) as info:
        claims_of(doc)
    assert info.value.path == "scene.thermal.temperature.lid" and "20 common boundary facets" in info.value.fault
