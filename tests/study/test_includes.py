"""`include:` presets (wcs/study/includes.py): merged under the study's own keys, found next to the
study or among the shipped configs/, and every fault an exit 2 naming the file and key path."""
from pathlib import Path

import pytest
import yaml

import wcs
from wcs.cli import main
from wcs.errors import StudyError
from wcs.study.includes import SHIPPED

ROOT = Path(__file__).resolve().parents[2]
PLATE = yaml.safe_load((ROOT / "studies" / "heated-plate.yaml").read_text())


def write(path: Path, doc) -> Path:
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def plate(**changes) -> dict:
    """heated-plate without its include, with top-level keys changed."""
    doc = {k: v for k, v in PLATE.items() if k != "include"}
    return {**doc, **changes}


def test_an_included_mapping_merges_key_by_key_and_the_study_wins(tmp_path):
    write(tmp_path / "preset.yaml", {"search": {"method": "sample", "budget": 7, "sample": {"n": 5, "seed": 9}},
                                     "solver": {"method": "monolithic", "tolerance": 1.0e-9}})
    study = wcs.load_study(write(tmp_path / "s.yaml", plate(include="preset.yaml",
                                                           search={"budget": 3, "sample": {"seed": 4}})))
    assert study.search.method == "sample"                              # from the preset
    assert study.search.budget == 3 and study.search.sample.seed == 4   # the study's own keys win
    assert study.search.sample.n == 5                                   # a nested key it leaves out
    assert study.solver.method == "monolithic" and study.solver.tolerance == 1.0e-9
    assert "# preset.yaml\n" in study.text and "tolerance: 1.0e-09" in study.text   # recorded


def test_a_later_include_wins_over_an_earlier_one_and_includes_nest(tmp_path):
    (tmp_path / "sub").mkdir()
    write(tmp_path / "sub" / "inner.yaml", {"search": {"budget": 11, "method": "sample"}})
    write(tmp_path / "sub" / "outer.yaml", {"include": "inner.yaml", "search": {"budget": 12}})   # own folder
    write(tmp_path / "last.yaml", {"search": {"budget": 13}})
    study = wcs.load_study(write(tmp_path / "s.yaml", plate(include=["sub/outer.yaml", "last.yaml"])))
    assert (study.search.method, study.search.budget) == ("sample", 13)
    study = wcs.load_study(write(tmp_path / "t.yaml", plate(include=["last.yaml", "sub/outer.yaml"])))
    assert study.search.budget == 12


def test_a_shipped_preset_is_found_from_anywhere_and_a_local_file_comes_first(tmp_path):
    study = wcs.load_study(write(tmp_path / "s.yaml", plate(include="configs/solver-large-3d.yaml")))
    assert study.solver.method == "iterative" and study.solver.iterative.preconditioner == "amg"
    (tmp_path / "configs").mkdir()
    write(tmp_path / "configs" / "solver-large-3d.yaml", {"solver": {"method": "qp"}})
    assert wcs.load_study(tmp_path / "s.yaml").solver.method == "qp"


def test_the_shipped_heated_plate_takes_search_quick_as_its_search_block_was():
    study = wcs.load_study(ROOT / "studies" / "heated-plate.yaml")
    assert study.search == wcs.load_study(plate(search={"method": "auto", "budget": 40}), base_dir=ROOT).search


def test_configs_is_one_folder_in_the_clone_and_the_package():
    assert SHIPPED.resolve() == (ROOT / "configs").resolve()
    names = {p.name for p in SHIPPED.glob("*.yaml")}
    assert {"solver-large-3d.yaml", "solver-direct-2d.yaml", "search-quick.yaml", "search-thorough.yaml",
            "materials-rock.yaml", "materials-implants.yaml"} <= names
    for name in names - {n for n in names if n.startswith("materials-")}:     # every preset is a study fragment
        wcs.load_study(plate(include=f"configs/{name}"), base_dir=ROOT / "studies")


@pytest.mark.parametrize("files, study, path, words", [
    ({}, {"include": "configs/solver-larg-3d.yaml"}, "include",
     ["file 'configs/solver-larg-3d.yaml' not found", "solver-large-3d.yaml"]),
    ({"a.yaml": {"include": "b.yaml"}, "b.yaml": {"include": "a.yaml"}}, {"include": ["a.yaml"]}, "include",
     ["includes itself", "a.yaml -> ", "b.yaml"]),
    ({"p.yaml": {"solver": {"iterative": {"tolerance": 1e-8}}}}, {"include": "p.yaml", "solver": {"iterative": 3}},
     "solver.iterative", ["is a scalar here but a mapping in p.yaml"]),
    ({"p.yaml": {"search": {"budget": 5}}}, {"include": ["p.yaml"], "search": [1]},
     "search", ["is a list here but a mapping in p.yaml"]),
    ({}, {"include": [3]}, "include", ["a file name or a list of file names"]),
])
def test_a_bad_include_is_exit_2_naming_the_file_and_key(tmp_path, capsys, files, study, path, words):
    for name, doc in files.items():
        write(tmp_path / name, doc)
    file = write(tmp_path / "s.yaml", plate(**study))
    with pytest.raises(StudyError) as info:
        wcs.load_study(file)
    assert info.value.path == path
    for word in words:
        assert word in info.value.fault
    assert main(["check", str(file)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(file) in err and path in err and "Traceback" not in err


def test_an_included_file_that_is_not_a_mapping_is_named(tmp_path):
    (tmp_path / "p.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(StudyError) as info:
        wcs.load_study(write(tmp_path / "s.yaml", plate(include="p.yaml")))
    assert info.value.file == str(tmp_path / "p.yaml") and "mapping of study keys (got list)" in info.value.fault
