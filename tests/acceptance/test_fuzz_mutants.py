"""Structured fuzzing of `wcs check` (and `wcs sweep`): seeded mutants of small studies
(tests/support/fuzz_mutants.py), each run in a forked child under a timeout and an address-space limit
(tests/support/fuzz_runner.py), each classified:

* fine: exit 0 or 2, an exit 2 with one `error:` line, no traceback; exit 0 only where the
  input may be right;
* traceback: exit 1 or any other code, or a traceback on stderr; crash: killed by a signal;
* hang: past the timeout; blow-up: MemoryError (the RLIMIT_AS refused an allocation) or a
  resident peak over 3 GB;
* accepted-bad: exit 0 for an input the mutant classifies as wrong (negative size, NaN modulus,
  a range with lower > upper, a name with a NUL...).

The default suite runs a fast handful (`FAST`); `make validate` runs 320 seeded mutants.
"""
from __future__ import annotations

import collections
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support import fuzz_mutants as fm
from tests.support.fuzz_runner import TIMEOUT

ROOT = Path(__file__).resolve().parents[2]
RUNNER = Path(__file__).resolve().parents[1] / "support" / "fuzz_runner.py"
MEMORY_WORDS = ("MemoryError", "bad_alloc", "Cannot allocate memory", "out of memory")
PEAK_GB = 3.0
FAILURES = ("traceback", "crash", "hang", "blow-up", "accepted-bad", "unclear")


def classify(m: fm.Mutant, r: dict) -> str:
    """How the run of mutant `m` ended (one of fine, FAILURES)."""
    err = r["stderr"]
    if r["timeout"]:
        return "hang"
    if r["maxrss_gb"] > PEAK_GB or any(w in err for w in MEMORY_WORDS):
        return "blow-up"
    if r["signal"] is not None:
        return "crash"
    if r["code"] not in (0, 2) or "Traceback" in err:
        return "traceback"
    if r["code"] == 2 and sum(line.startswith("error: ") for line in err.splitlines()) != 1:
        return "unclear"
    if r["code"] == 0 and m.expect == "bad":
        return "accepted-bad"
    return "fine"


def run_mutants(mutants: list[fm.Mutant], folder: Path) -> list[tuple[fm.Mutant, dict, str]]:
    """Build every mutant in its own folder, run them all in one fork server, classify each."""
    jobs = []
    for i, m in enumerate(mutants):
        case = folder / f"m{i:03d}"
        jobs.append({"id": f"m{i:03d}", "argv": m.build(case), "cwd": str(case)})
    (folder / "jobs.json").write_text(json.dumps(jobs), encoding="utf-8")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    subprocess.run([sys.executable, str(RUNNER), str(folder / "jobs.json"), str(folder / "results.json")],
                   env=env, check=True, timeout=len(jobs) * (TIMEOUT + 5) + 60)
    results = json.loads((folder / "results.json").read_text(encoding="utf-8"))
    return [(m, r, classify(m, r)) for m, r in zip(mutants, results)]


def report(outcomes) -> tuple[str, list[str]]:
    """A tally (counts per class, per kind) and a line per failing mutant."""
    tally = collections.Counter(c for _, _, c in outcomes)
    kinds = collections.defaultdict(collections.Counter)
    for m, _, c in outcomes:
        kinds[m.kind][c] += 1
    lines = [f"{len(outcomes)} mutants: " + ", ".join(f"{k} {tally[k]}" for k in ("fine",) + FAILURES)]
    lines += [f"  {k}: " + ", ".join(f"{c} {n}" for c, n in sorted(v.items())) for k, v in sorted(kinds.items())]
    bad = [f"{c}: {m.id} [{m.base}, expect {m.expect}{', known: ' + m.known if m.known else ''}] "
           f"exit {r['code']} signal {r['signal']} {r['wall']:.1f} s {r['maxrss_gb']:.2f} GB: "
           f"{' | '.join(r['stderr'].strip().splitlines()[-2:])[:300]}"
           for m, r, c in outcomes if c != "fine"]
    return "\n".join(lines), bad


def test_mutants_are_seeded_distinct_and_of_every_kind():
    a, b = fm.mutants(320), fm.mutants(320)
    assert [m.id for m in a] == [m.id for m in b]
    assert len({m.id for m in a}) == 320
    assert {m.kind for m in a} >= {"solid3d", "selector", "glue", "refine", "meshfile", "range", "fuzzy",
                                   "lipschitz", "sweep", "solver", "names", "special", "numbers"}
    assert sum(m.expect == "bad" for m in a) > 200


def test_written_mesh_files_are_consistent():
    """The bases' meshes: the 2D grid's triangles are counter-clockwise, the cube's six
    tetrahedra fill it (volumes 1/6 each), and each face group holds its two facets."""
    import numpy as np
    nodes, groups = fm.grid2d()
    p = np.array(nodes)[:, :2]
    t = np.array(groups["a"][2])
    (ax, ay), (bx, by) = (p[t[:, 1]] - p[t[:, 0]]).T, (p[t[:, 2]] - p[t[:, 0]]).T
    area = (ax * by - ay * bx) / 2
    assert np.allclose(area, 1 / 18) and len(groups["top"][2]) == 3
    nodes, groups = fm.cube3d()
    p = np.array(nodes)
    t = np.array(groups["a"][2])
    vol = np.abs(np.linalg.det(np.stack([p[t[:, k]] - p[t[:, 0]] for k in (1, 2, 3)], axis=1))) / 6
    assert np.allclose(vol, 1 / 6) and len(groups["bottom"][2]) == 2 and len(groups["top"][2]) == 2


# a quick handful, one or two a kind, each refused at load time or on a small 2D mesh
FAST = ["solid3d: box reversed", "selector: segment off the scene", "glue: slave = master",
        "refine: size 1e-300", "meshfile: msh2d: truncated at 75 %", "meshfile: msh2d: a node at NaN",
        "range: E box lower above upper", "fuzzy: support reversed", "lipschitz: 2d: points [2, 2.5]",
        "lipschitz: 3d: points [1, 3]", "sweep: a NaN value", "solver: dd pcg_tolerance 1",
        "names: body with a dot", "names: boundary key given twice", "special: study is not UTF-8",
        "special: 60 levels of nesting", "numbers: 2d: scene.materials.steel.E = 1e+300",
        "numbers: 3d: scene.mesh.max_cells = True"]


def test_fast_mutants(tmp_path):
    """The default suite's handful: every one refused with one line (about 5 s)."""
    outcomes = run_mutants(fm.find(FAST), tmp_path)
    tally, bad = report(outcomes)
    print(tally)
    assert not bad, "\n".join(bad)
    assert all(r["code"] == 2 for _, r, _ in outcomes)


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_seeded_mutants(tmp_path):
    """The bases check (exit 0), then 320 seeded mutants: no traceback, crash, hang, blow-up or
    accepted-bad (4 to 8 minutes on the shared 2-core machine)."""
    controls = run_mutants([fm.Mutant("control", b, b, "any") for b in fm.BASES], tmp_path / "controls")
    assert [r["code"] for _, r, _ in controls] == [0] * len(fm.BASES), [r["stderr"] for _, r, _ in controls]
    outcomes = run_mutants(fm.mutants(320), tmp_path / "mutants")
    tally, bad = report(outcomes)
    print(tally)
    print("\n".join(bad))
    assert not bad, tally + "\n" + "\n".join(bad)
