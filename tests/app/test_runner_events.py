"""The run's modules, one job each with imports pointing one way, and the timing events the
search loop reports (what benchmarks measure, instead of patching the runner)."""
import ast
import importlib.util
from pathlib import Path

import numpy as np

import wcs
from tests.app.test_runner import study_file, tiny
from wcs.app.runner import Runner

WCS = Path(wcs.__file__).resolve().parent / "app"
LAYERS = ("problem", "record", "writer", "runner", "commands")     # each imports only those before it


def _imports(module: str):
    """(modules of wcs imported at the top, imports inside functions) of wcs/app/<module>.py."""
    tree = ast.parse((WCS / f"{module}.py").read_text())
    top = {n.module.split(".")[0] for n in tree.body if isinstance(n, ast.ImportFrom) and n.level == 1 and n.module}
    inner = [n.lineno for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
             for n in ast.walk(f) if isinstance(n, (ast.Import, ast.ImportFrom))]
    return top, inner


def test_run_modules_import_one_way():
    for i, module in enumerate(LAYERS):
        top, inner = _imports(module)
        assert inner == [], f"wcs/app/{module}.py imports inside functions (lines {inner})"
        later = top & set(LAYERS[i:])
        assert not later, f"wcs/app/{module}.py imports {sorted(later)}"
    assert importlib.util.find_spec("wcs.dd.bench") is None          # benchmarks live in tests/bench


def test_timing_events_account_for_the_run(tmp_path):
    path = study_file(tmp_path, "glued-layers.yaml", search={"method": "auto", "sample": {"n": 4}, "budget": 5})
    study = wcs.load_study(path)
    out = tmp_path / "events.nc"
    events = []
    r = Runner(study, out, on_event=events.append)
    ds = r.run(tiny)
    stages = list(ds["stage"].values)
    assert [e.what for e in events[:1]] == ["prepare"] and sum(e.what == "prepare" for e in events) == 1
    evals = [e for e in events if e.what == "evaluate"]
    solved = [e for e in evals if e.stage != "worst-fields"]
    assert len(solved) == r.stats["solved"] == ds.sizes["eval"] == 5
    assert len(evals) - len(solved) == r.stats["field_solves"] >= 1
    assert [e.stage for e in solved] == stages
    # each evaluation's event encloses the wall time the evaluation measured itself
    assert all(e.seconds >= w for e, w in zip(solved, ds["wall_time"].values))
    batches = [e for e in events if e.what == "batch"]
    assert [s for e in batches for s in [e.stage] * e.records] == stages
    writes = [e for e in events if e.what == "write"]
    assert len(writes) == r.stats["writes"] >= 1
    assert sum(e.seconds for e in writes) == r.stats["write_time"]
    assert not any(e.what == "gather" for e in events)               # serial: no MPI gathers
    # resumed: every record comes from the store, the only solves re-solve the worst fields
    again = []
    ds2 = wcs.run(study, out, resume=True, strategy=tiny, on_event=again.append)
    assert {e.stage for e in again if e.what == "evaluate"} == {"worst-fields"}
    assert sum(e.records for e in again if e.what == "batch") == ds2.attrs["answered_from_store"] == 5
    assert np.array_equal(ds2["phi"].values, ds["phi"].values)
