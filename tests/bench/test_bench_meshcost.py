"""The mesh check's contact bound (`wcs/results/meshcheck.py`): the dense blocks a contact solve holds at
its peak, DENSE_BLOCKS[d] × 8 k² bytes on k contact rows, and the k³ time law of CONDENSATION,
measured on one cold nominal solve of the 2D and the 3D tunnel at finer fault meshes than the
shipped ones, each in a fresh process: the rise of the resident set's peak (VmHWM) over the
resident set of the built evaluator, in units of 8 k² bytes, must stay within DENSE_BLOCKS[d]
(else the plan would split a mesh whose condensation does not fit); the cold solve's seconds
are reported beside the law's estimate (a loaded machine: no assertion on them).

Tables: results/bench/bench_meshcost_2d.csv, results/bench/bench_meshcost_3d.csv.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from common import ROOT, STUDIES, write_table
from wcs.results.meshcheck import DENSE_BLOCKS, condensation_seconds

pytestmark = pytest.mark.bench

PEAK = r"""
import json, sys, time
from pathlib import Path
import yaml
from wcs import linalg
linalg.configure_threads()
from wcs.model.evaluation import Evaluator
from wcs import load_study

def status(key):
    line = next(s for s in Path("/proc/self/status").read_text().splitlines() if s.startswith(key))
    return 1024 * int(line.split()[1])

study, out, sizes = sys.argv[1], Path(sys.argv[2]), json.loads(sys.argv[3])
doc = yaml.safe_load(Path(study).read_text())
for j, size in enumerate(sizes):
    doc["scene"]["mesh"]["refine"][j]["size"] = size
doc["output"] = str(out.with_suffix(".nc"))
out.write_text(yaml.safe_dump(doc, sort_keys=False))
ev = Evaluator(load_study(out))
rss = status("VmRSS")
t = time.perf_counter()
res = ev.evaluate(ev.study.nominal())
seconds = time.perf_counter() - t
k = ev.model.dim * ev.model.Bn_r.shape[0]
print(json.dumps({"status": int(res.status), "k": k, "seconds": seconds, "rise": status("VmHWM") - rss}))
"""


@pytest.mark.parametrize("study, sizes, dim", [
    ("tunnel-fault.yaml", [0.1, 0.1, 0.1], 2),           # 1346 fault nodes, 2692 contact rows
    ("tunnel-fault-3d.yaml", [0.67, 1.33], 3),           # 1224 fault nodes, 3672 contact rows
])
def test_a_contact_solve_holds_at_most_dense_blocks_k_by_k(tmp_path, study, sizes, dim):
    out = subprocess.run([sys.executable, "-c", PEAK, str(STUDIES / study), str(tmp_path / study), json.dumps(sizes)],
                         capture_output=True, text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout.splitlines()[-1])
    assert r["status"] == 0
    blocks = r["rise"] / (8.0 * r["k"] ** 2)
    rows = [["study", study], ["contact rows k", r["k"]], ["peak rise / 8 k^2", f"{blocks:.2f}"],
            ["DENSE_BLOCKS", DENSE_BLOCKS[dim]], ["cold solve [s]", f"{r['seconds']:.1f}"],
            ["k^3 law [s]", f"{condensation_seconds(dim, r['k']):.1f}"]]
    write_table(f"bench_meshcost_{dim}d", ["quantity", "value"], rows)
    print("\n".join(f"{a}: {b}" for a, b in rows))
    assert blocks <= DENSE_BLOCKS[dim]
