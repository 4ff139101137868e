"""The study loader: every broken rule gives one clear StudyError; good studies load."""
import dataclasses
import hashlib
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from pydantic import BaseModel, ValidationError

from tests.support.bad_studies import CASES, DEMO, broken, demo_doc, write_study
from wcs.errors import StudyError
from wcs.scene.spec import Material, Scene, Shape
from wcs import load_study
from wcs.options import DomainDecomposition, SampleDesign, Search
from wcs.study.paths import get_path
from wcs.study.source import LIBRARIES
from wcs.study.uncertain import Uncertain

SLIP = "contacts.interface.friction.slip_limit"


@pytest.mark.parametrize("mutate, fragment", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_broken_study_names_file_and_key_path(mutate, fragment):
    with pytest.raises(StudyError) as info:          # as a mapping; test_cli runs them as files
        load_study(broken(mutate))
    message = str(info.value)
    assert message.startswith("<mapping>: ")
    assert fragment in message


def test_case_ids_are_unique():
    ids = [c[0] for c in CASES]
    assert len(ids) == len(set(ids))


@pytest.fixture(scope="module")
def demo():
    return load_study(DEMO)


def test_demo_loads(demo):
    assert demo.name == "two-blocks-demo"
    assert demo.output == "results/two-blocks-demo.nc"
    assert demo.scene.plane == "strain"
    assert demo.scene.bodies["pad"].regions[0].name == "pad_0"
    assert demo.scene.bodies["pad"].regions[0].shape == Shape(rectangle=[0.5, 1.0, 1.5, 1.5])
    assert demo.sha256 == hashlib.sha256(demo.text.encode()).hexdigest()
    assert demo.text == DEMO.read_text()
    assert demo.search == Search(sample=SampleDesign(seed=7))      # the rest: the defaults
    assert demo.search.method == "auto" and demo.search.budget == 200 and demo.search.local.starts == 3
    assert demo.solver.dd == DomainDecomposition(subdomains=8)
    assert demo.solver.dd.pair_size == 1.0 and demo.solver.dd.relaxation == "aitken" and demo.solver.fallback is True
    assert demo.limits == {"shear": 4.0e12}
    assert demo.sweep is None
    assert demo.criteria[0].point == [1.0, 1.0] and demo.criteria[1].point is None


def test_parameters_in_file_order_with_profile_expanded(demo):
    names = ["materials.rubber.E", "materials.rubber.nu", "loads.pad_top.pressure"]
    names += [f"{SLIP}[{i}]" for i in range(6)]
    assert demo.parameters.names == names
    assert len(demo.parameters) == 9
    np.testing.assert_array_equal(demo.parameters.lower, [0.8e7, 0.40, 1.5e6] + [0.5e5] * 6)
    np.testing.assert_array_equal(demo.parameters.upper, [1.2e7, 0.48, 2.5e6] + [1.5e5] * 6)
    assert demo.uncertain[3] == Uncertain(SLIP, 0.5e5, 1.5e5, lipschitz=2.0e5, points=6)


def test_nominal_is_the_scene(demo):
    np.testing.assert_array_equal(demo.nominal(), [1.0e7, 0.45, 2.0e6] + [1.0e5] * 6)


def test_data_set_of_a_vector_is_the_vector(demo):
    x = demo.parameters.lower.copy()
    got, others = demo.data_set(x)
    assert np.array_equal(got, x) and others == {}


def test_data_set_of_a_mapping(demo):
    x, others = demo.data_set({"materials.rubber.nu": 0.41, f"{SLIP}[2]": 0.6e5, "materials.steel.E": 2.0e11})
    np.testing.assert_array_equal(x, [1.0e7, 0.41, 2.0e6] + [1.0e5, 1.0e5, 0.6e5, 1.0e5, 1.0e5, 1.0e5])
    assert others == {"materials.steel.E": 2.0e11}
    whole, _ = demo.data_set({SLIP: 0.7e5})
    np.testing.assert_array_equal(whole[3:], [0.7e5] * 6)


def test_data_set_rejects_unknown_names_and_wrong_length(demo):
    with pytest.raises(StudyError, match="materials.rubber.G"):
        demo.data_set({"materials.rubber.G": 1.0})
    with pytest.raises(StudyError, match="expected a vector of 9 parameters"):
        demo.data_set(np.zeros(3))


def test_get_path_reads_the_typed_scene(demo):
    assert get_path(demo.scene, "materials.rubber.E") == 1.0e7
    assert get_path(demo.scene, f"{SLIP}") == 1.0e5
    lame = load_study(_lame_doc()).scene
    assert get_path(lame, "materials.rubber.lambda") == 3.1e7            # the file's name of `lam`
    with pytest.raises(KeyError, match="did you mean 'pad_top'"):
        get_path(demo.scene, "loads.pad_tp.pressure")
    with pytest.raises(KeyError, match="no 'traction' under 'loads.pad_top'"):   # a field the scene leaves out
        get_path(demo.scene, "loads.pad_top.traction.0")


def test_unknown_key_hint():
    doc = demo_doc()
    doc["serach"] = doc.pop("search")
    with pytest.raises(StudyError, match="did you mean 'search'"):
        load_study(doc)


def test_unknown_name_hint():
    doc = demo_doc()
    doc["scene"]["bodies"]["pad"]["regions"][0]["material"] = "rubbr"
    with pytest.raises(StudyError, match="did you mean 'rubber'"):
        load_study(doc)


def test_yaml_syntax_error_has_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("study: x\nscene:\n  dimension: [2\n  plane: strain\n")
    with pytest.raises(StudyError, match=r"bad\.yaml.*line \d+"):
        load_study(path)


def test_duplicate_key_is_an_error(tmp_path):
    path = tmp_path / "dup.yaml"
    path.write_text(DEMO.read_text().replace("  budget: 200", "  budget: 200\n  budget: 100"))
    with pytest.raises(StudyError, match=r"line \d+, column \d+: duplicate key 'budget'"):
        load_study(path)


def test_missing_file(tmp_path):
    with pytest.raises(StudyError, match="not found"):
        load_study(tmp_path / "nothing.yaml")


def test_not_a_mapping(tmp_path):
    path = tmp_path / "list.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(StudyError, match="list.yaml"):
        load_study(path)


def test_exponent_without_dot_is_a_number(tmp_path):
    path = tmp_path / "exp.yaml"
    path.write_text(DEMO.read_text().replace("{E: 1.0e7,", "{E: 1e7,"))
    assert load_study(path).scene.materials["rubber"].E == 1.0e7


def test_mapping_loads_as_its_file(demo):
    study = load_study(demo_doc())
    assert study.file == Path("<mapping>") and study.name == demo.name
    assert study.text == yaml.safe_dump(demo_doc(), sort_keys=False)
    assert study.sha256 == hashlib.sha256(study.text.encode()).hexdigest()
    for field in ("scene", "uncertain", "criteria", "limits", "search", "solver", "sweep", "output",
                  "notes", "warnings", "estimated_cells"):
        assert getattr(study, field) == getattr(demo, field), field
    assert study.parameters.names == demo.parameters.names


def test_mapping_is_not_changed_and_needs_no_name():
    doc = demo_doc()
    del doc["study"], doc["output"]
    before = yaml.safe_dump(doc)
    study = load_study(doc)
    assert yaml.safe_dump(doc) == before
    assert study.name == "study" and study.output == "results/study.nc"


@pytest.mark.parametrize("value", [np.float64(1.0), object()], ids=["numpy", "object"])
def test_mapping_of_non_yaml_data_names_the_mapping(value):
    doc = demo_doc()
    doc["scene"]["materials"]["rubber"]["E"] = value
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert str(info.value).startswith("<mapping>: not YAML data (numbers, strings, booleans, null, lists, mappings)")


def test_mapping_nesting_is_capped():
    deep = {}
    node = deep
    for _ in range(60):
        node["a"] = {}
        node = node["a"]
    with pytest.raises(StudyError, match="nests deeper than 50 levels") as info:
        load_study({"study": "x", "scene": deep})
    assert info.value.file == "<mapping>"


def test_base_dir_resolves_the_files_a_mapping_names(tmp_path):
    _scene_file_study(tmp_path)                      # tmp_path/scene.yaml
    doc = yaml.safe_load((tmp_path / "study.yaml").read_text())
    with pytest.raises(StudyError) as info:          # relative to the current directory
        load_study(doc)
    assert info.value.file == "<mapping>" and info.value.path == "scene"
    assert "file 'scene.yaml' not found" in info.value.fault
    study = load_study(doc, base_dir=tmp_path)
    assert study.scene == load_study(tmp_path / "study.yaml").scene
    assert "# scene.yaml\n" in study.text


def test_base_dir_of_a_study_file(tmp_path):
    (tmp_path / "libs").mkdir()
    (tmp_path / "libs" / "materials-implants.yaml").write_text("uhmwpe: {E: 3.6e8, nu: 0.4}\ncocrmo: {E: 2e11, nu: 0.3}\n")
    doc = demo_doc()
    doc["scene"]["materials"] = "materials-implants.yaml"
    for body, material in (("base", "cocrmo"), ("pad", "uhmwpe")):
        doc["scene"]["bodies"][body]["regions"][0]["material"] = material
    del doc["scene"]["thermal"]
    doc["uncertain"] = {}
    path = write_study(doc, tmp_path)
    assert load_study(path).scene.materials["uhmwpe"].E == 3.4e8                   # shipped
    assert load_study(path, base_dir=tmp_path / "libs").scene.materials["uhmwpe"].E == 3.6e8


def _scene_file_study(tmp_path, materials="materials-implants.yaml"):
    doc = demo_doc()
    scene = doc["scene"]
    scene["materials"] = materials
    for body, material in (("base", "cocrmo"), ("pad", "uhmwpe")):
        scene["bodies"][body]["regions"][0]["material"] = material
    del scene["thermal"]
    write_study(scene, tmp_path, "scene.yaml")
    doc["scene"] = "scene.yaml"
    doc["uncertain"] = {"materials.uhmwpe.E": [3.0e8, 4.0e8], SLIP: doc["uncertain"][SLIP]}
    return write_study(doc, tmp_path)


def test_scene_file_and_material_library_shipped(tmp_path):
    study = load_study(_scene_file_study(tmp_path))
    assert study.scene.materials["uhmwpe"] == Material(E=3.4e8, nu=0.4)
    assert study.parameters.names[0] == "materials.uhmwpe.E"
    assert study.text.count("\n---\n") == 2
    assert "scene.yaml" in study.text and "materials-implants.yaml" in study.text
    assert "cocrmo:" in study.text
    assert study.sha256 == hashlib.sha256(study.text.encode()).hexdigest()


def test_material_library_next_to_the_scene_wins(tmp_path):
    (tmp_path / "materials-implants.yaml").write_text("uhmwpe: {E: 3.5e8, nu: 0.4}\ncocrmo: {E: 2e11, nu: 0.3}\n")
    study = load_study(_scene_file_study(tmp_path))
    assert study.scene.materials["uhmwpe"].E == 3.5e8


def test_errors_in_scene_file_name_that_file(tmp_path):
    study = _scene_file_study(tmp_path)
    scene = yaml.safe_load((tmp_path / "scene.yaml").read_text())
    scene["bodies"]["pad"]["regions"][0]["material"] = "gum"
    write_study(scene, tmp_path, "scene.yaml")
    with pytest.raises(StudyError) as info:
        load_study(study)
    assert info.value.file.endswith("scene.yaml")
    assert info.value.path == "bodies.pad.regions.0.material"


def test_errors_in_material_library_name_that_file(tmp_path):
    (tmp_path / "lib.yaml").write_text("uhmwpe: {E: 3.4e8, nu: 0.7}\ncocrmo: {E: 2e11, nu: 0.3}\n")
    with pytest.raises(StudyError) as info:
        load_study(_scene_file_study(tmp_path, materials="lib.yaml"))
    assert info.value.file.endswith("lib.yaml")
    assert info.value.path == "uhmwpe.nu"


@pytest.mark.parametrize("library", sorted(p.name for p in LIBRARIES.glob("materials-*.yaml")))
def test_shipped_material_libraries_load(library):
    materials = yaml.safe_load((LIBRARIES / library).read_text())
    doc = demo_doc()
    doc["scene"]["materials"] = library
    first = next(iter(materials))
    for body in ("base", "pad"):
        doc["scene"]["bodies"][body]["regions"][0]["material"] = first
    del doc["scene"]["thermal"]
    doc["uncertain"] = {}
    study = load_study(doc)
    assert set(study.scene.materials) == set(materials)


def _lame_doc():
    doc = demo_doc()
    doc["scene"]["materials"]["rubber"] = {"lambda": 3.1e7, "mu": 3.4e6, "conductivity": 0.2}
    del doc["uncertain"]["materials.rubber.E"], doc["uncertain"]["materials.rubber.nu"]
    doc["uncertain"]["materials.rubber.mu"] = [3.0e6, 4.0e6]
    return doc


def test_lame_material_with_lame_box():
    study = load_study(_lame_doc())
    assert study.parameters.names[-1] == "materials.rubber.mu"
    assert any("rubber" in note and "expansion" in note for note in study.notes)


def test_defaults_when_optional_blocks_are_absent(tmp_path):
    doc = demo_doc()
    for key in ("study", "search", "solver", "output", "limits", "criteria", "uncertain"):
        del doc[key]
    del doc["scene"]["plane"]
    study = load_study(write_study(doc, tmp_path, "plain.yaml"))
    assert study.name == "plain" and study.output == "results/plain.nc"
    assert study.scene.plane == "strain"
    assert study.search.sample == SampleDesign(design="lhs", n=32, seed=0)
    assert study.solver.tolerance == 1e-8 and study.solver.max_iterations == 200
    assert len(study.parameters) == 0 and study.nominal().shape == (0,)


def test_sweep_and_named_regions():
    doc = demo_doc()
    doc["sweep"] = {"grid": {"loads.pad_top.pressure": [1e6, 2e6], "materials.steel.E": [2e11]}}
    doc["scene"]["bodies"]["pad"]["regions"][0]["name"] = "pad"
    doc["scene"]["body_forces"]["pad"] = [0.0, -1.0e4]
    study = load_study(doc)
    assert study.sweep.grid == doc["sweep"]["grid"]
    assert study.scene.bodies["pad"].regions[0].name == "pad"
    assert math.isclose(study.scene.body_forces["pad"][1], -1.0e4)


def _dicts_of_entries(node, where="study"):
    """Key paths below `node` where a plain dict or list holds a dict or list: the YAML shape
    the loader once handed on. A frozen model's mapping fields hold models or numbers."""
    found = []
    if isinstance(node, BaseModel):
        found += [f"{where}: not frozen"] if not node.model_config.get("frozen") else []
        children = {name: getattr(node, name) for name in type(node).model_fields}
    elif dataclasses.is_dataclass(node) and not isinstance(node, type):
        children = {f.name: getattr(node, f.name) for f in dataclasses.fields(node)}
    elif isinstance(node, (dict, list, tuple)):
        items = node.items() if isinstance(node, dict) else enumerate(node)
        children = dict(items)
        found += [f"{where}.{k}" for k, v in children.items() if isinstance(v, (dict, list)) and
                  any(isinstance(w, (dict, list)) for w in (v.values() if isinstance(v, dict) else v))]
    else:
        return found
    for key, value in children.items():
        found += _dicts_of_entries(value, f"{where}.{key}")
    return found


@pytest.mark.parametrize("path", [DEMO, DEMO.parent / "user-mesh-demo.yaml", DEMO.parent / "tunnel-thermal.yaml"],
                         ids=lambda p: p.stem)
def test_the_study_below_the_loader_is_frozen_typed_data(path):
    """Nothing downstream of loading reads a dict: the study, its scene (down to every shape,
    region and selector), criteria, sweep and uncertain entries are frozen objects."""
    study = load_study(path)
    with pytest.raises(dataclasses.FrozenInstanceError):
        study.scene = None
    with pytest.raises(ValidationError, match="frozen"):
        study.scene.plane = "stress"
    body = next(iter(study.scene.bodies.values()))
    with pytest.raises(ValidationError, match="frozen"):
        body.regions[0].material = "other"
    assert isinstance(study.scene, Scene)
    assert _dicts_of_entries(study.scene.model_dump()) != []           # the finder sees the YAML shape
    assert _dicts_of_entries(study) == []
    assert all(isinstance(e, Uncertain) for e in study.uncertain)


def test_a_fault_that_names_its_value_does_not_repeat_it():
    """The validator's own "got 1" is not followed by the loader's "(got 1)"."""
    doc = demo_doc()
    doc["uncertain"][SLIP]["points"] = 1
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert str(info.value) == (f"<mapping>: uncertain.{SLIP}.points: points needs at least 2 values per direction "
                               "and at most 1000 in all, got 1")
