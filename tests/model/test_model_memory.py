"""The memory of the model's build (issue 25: a 3D contact evaluation at 1e6 unknowns within 8 GB).

The build (meshing, assembly, criteria) held 11.4 GB at its peak at 1e6 unknowns before any solve:
elasticity's cell matrices held for every tetrahedron (2 pieces × 4 × 4 nodes × 3 × 3 float64 =
2304 bytes a cell), the reduction TᵀKT's terms made all at once (≈ 94 bytes an entry of K at its
peak), the strain operator from int64 COO triplets. Measured here by tracemalloc (numpy's arrays
included) on the 3D block-on-block patch at size 0.1 (5.5e3 tetrahedra, 3 s): before, 5.2 kB a cell
held and 6.8 kB at the peak; now 3.0 and 3.4 kB. The bounds below sit between: 4.0 kB held (the
cell matrices' 2.3 kB could not come back unnoticed) and 4.5 kB at the peak.
"""
import tracemalloc
from pathlib import Path

import yaml

from wcs.model.evaluation import Evaluator
from wcs.fem.affine import CellMatrices
from wcs.study import load_study

ROOT = Path(__file__).resolve().parents[2]


def test_the_model_holds_no_cell_matrices_and_builds_lean():
    doc = yaml.safe_load((ROOT / "studies" / "validation" / "block-on-block-3d.yaml").read_text())
    doc["scene"]["mesh"]["size"] = 0.1
    doc["solver"] = {"method": "iterative"}
    study = load_study(doc)
    tracemalloc.start()
    try:
        ev = Evaluator(study)
        held, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    cells = ev.smesh.mesh.t.shape[1]
    assert isinstance(ev.model.K.local, CellMatrices)         # made from the gradients, chunk by chunk
    assert ev.model.K.local.g.nbytes + ev.model.K.local.measure.nbytes == cells * (4 * 3 + 1) * 8
    assert held / cells < 4000, held / cells
    assert peak / cells < 4500, peak / cells
