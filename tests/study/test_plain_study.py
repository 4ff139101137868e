"""A study is plain data; whoever runs it builds the evaluator. `wcs.study.load_study` returns the
plain `Study` (nothing to solve with), `wcs.load_study` the same study paired with an evaluator
built on the first `evaluate`, and `wcs.run(study)` runs it (the package `wcs.app`)."""
import dataclasses
from pathlib import Path

import numpy as np

import wcs
import wcs.app.runner
from wcs.study import Study, load_study

DEMO = Path(__file__).resolve().parents[2] / "studies" / "two-blocks-demo.yaml"


def test_the_study_a_file_loads_into_is_plain_data():
    study = load_study(DEMO)
    assert dataclasses.is_dataclass(study) and type(study) is Study
    assert not hasattr(study, "evaluate") and not hasattr(study, "_evaluator")
    name = study.parameters.names[0]
    x, others = study.data_set({name: study.parameters.upper[0]})
    assert x[0] == study.parameters.upper[0] and np.array_equal(x[1:], study.nominal()[1:]) and others == {}


def test_wcs_load_study_pairs_the_same_study_with_an_evaluator_built_on_first_use():
    plain, paired = load_study(DEMO), wcs.load_study(DEMO)
    assert isinstance(paired, Study) and callable(paired.evaluate)
    for f in dataclasses.fields(Study):
        a, b = getattr(plain, f.name), getattr(paired, f.name)
        assert (np.array_equal(a.lower, b.lower) and a.names == b.names) if f.name == "parameters" else a == b, f.name
    assert "_evaluator" not in vars(paired)          # nothing meshed or assembled before the first solve


def test_wcs_run_is_the_call_that_runs_a_study(monkeypatch):
    calls = []
    monkeypatch.setattr(wcs.app.runner, "run", lambda study, **kw: calls.append((study, kw)) or "dataset")
    assert wcs.run("a study", output="out.nc") == "dataset"
    assert calls == [("a study", {"output": "out.nc", "resume": False, "progress": None})]
