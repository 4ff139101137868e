"""The memory of the model's build (issue 25: a 3D contact evaluation at 1e6 unknowns within 8 GB).

The build (meshing, assembly, criteria) held 11.4 GB at its peak at 1e6 unknowns before any solve:
elasticity's cell matrices held for every tetrahedron (2 pieces × 4 × 4 nodes × 3 × 3 float64 =
2304 bytes a cell), the reduction TᵀKT's terms made all at once (≈ 94 bytes an entry of K at its
peak), the strain operator from int64 COO triplets. Measured here by tracemalloc (numpy's arrays
included) on the 3D block-on-block patch at size 0.1 (5.5e3 tetrahedra, 3 s): before, 5.2 kB a cell
held and 6.8 kB at the peak; then 2.5 and 3.2 kB; now 1.5 and 3.1 kB (the reduction's map held as a
4-byte index of K's entry where an entry of TᵀKT is one entry of K, 12–16 bytes an entry before, and
no zero values of its pattern; scikit-fem's mapping of every cell and facet dropped once the forms
are assembled, 350 bytes a cell). The bounds below sit between: 2.0 kB held (the cell matrices'
2.3 kB, or the reduction's whole map with the mapping, could not come back unnoticed) and 3.5 kB
at the peak.
"""
import gc
import tracemalloc
import weakref
from pathlib import Path

import numpy as np
import yaml

from wcs.contact import iterative
from wcs.model.evaluation import Evaluator
from wcs.fem.affine import CellMatrices
from wcs.study import load_study

ROOT = Path(__file__).resolve().parents[2]


def patch():
    doc = yaml.safe_load((ROOT / "studies" / "validation" / "block-on-block-3d.yaml").read_text())
    doc["scene"]["mesh"]["size"] = 0.1
    doc["solver"] = {"method": "iterative"}
    return load_study(doc)


def test_the_model_holds_no_cell_matrices_and_builds_lean():
    study = patch()
    tracemalloc.start()
    try:
        ev = Evaluator(study)
        held, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    cells = ev.smesh.mesh.t.shape[1]
    assert isinstance(ev.model.K.local, CellMatrices)         # made from the gradients, chunk by chunk
    assert ev.model.K.local.g.nbytes + ev.model.K.local.measure.nbytes == cells * (4 * 3 + 1) * 8
    assert held / cells < 2000, held / cells
    assert peak / cells < 3500, peak / cells
    assert "_cached_mapping" not in vars(ev.smesh.mesh)        # skfem's mapping, made again by a later basis
    red = ev.model.reduce
    assert red.source.nbytes == 4 * red.nnz and red.M.shape[0] == red.rest.size < 0.1 * red.nnz


def test_the_anchor_keeps_its_hierarchy_without_an_operator():
    """After the nominal solve, the anchor's GAMG hierarchy is kept for the data sets started from
    its answer without any matrix of K's size: neither the operator it was built for nor its last
    Newton step's is held (the KSP and the finest level hold a diagonal; each solve sets its own
    operator before its CG)."""
    ev = Evaluator(patch())
    assert ev.evaluate({}).status == 0
    krylov = iterative._ANCHOR[ev.model][1]
    held, pre = krylov.ksp.getOperators()
    pc, level = krylov.fine
    assert krylov.P is None and held.handle == pre.handle == pc.getMGSmoother(level).getOperators()[0].handle
    assert held.getInfo()["nz_used"] == held.getSize()[0]


def test_the_strain_operator_is_applied_from_the_gradients_the_stiffness_holds():
    """No matrix of the 3D strain operator (432 bytes a cell, 0.78 GB at 1e6 unknowns): G u and
    Gᵀ e are made from elasticity's gradients, the same array (bitwise the matrix's products:
    tests/geometry/test_tet.py)."""
    from wcs.geometry.tet import StrainOperator
    model = Evaluator(patch()).model
    assert isinstance(model.G, StrainOperator) and model.G.g is model.K.local.g


def test_a_contact_solve_holds_no_unreduced_stiffness_and_the_adjoint_assembles_none(monkeypatch):
    """While the contact is solved, no K(c) is alive beside the reduced K the solve works on (the
    model kept the last one: 0.5 GB at 1e6 unknowns); the adjoint takes K U0, kept from the
    reduction, so an evaluation with gradients still assembles K(c) once."""
    ev = Evaluator(patch())
    assembled, alive = [], []
    operator = type(ev.model.K)
    assemble, solve = operator.__call__, iterative.solve_contact_iterative

    def spy_assemble(self, coefficients):
        K = assemble(self, coefficients)
        assembled.append(weakref.ref(K))
        return K

    def spy_solve(*args, **kw):
        gc.collect()
        alive.append(sum(ref() is not None for ref in assembled))
        return solve(*args, **kw)
    monkeypatch.setattr(operator, "__call__", spy_assemble)
    monkeypatch.setattr(iterative, "solve_contact_iterative", spy_solve)
    out = ev.evaluate({}, gradients=True)
    assert out.status == 0, out.message
    assert all(np.all(np.isfinite(g)) for g in out.grad.values())
    assert alive == [0] and len(assembled) == 1


def test_release_frees_the_solves_caches_and_the_next_solve_gives_the_same_bits():
    """`Model.release` (what `wcs solve` calls before it writes its files) lets go of the anchor's
    GAMG hierarchy and the cached K U0; the next evaluation starts cold and gives the same bits as
    the first (a solve's answer never depends on the caches: `Model.solve`)."""
    ev = Evaluator(patch())
    first = ev.evaluate({})
    assert first.status == 0 and ev.model in iterative._ANCHOR and ev.model._cache.support is not None
    krylov = iterative._ANCHOR[ev.model][1]
    ev.model.release()
    assert ev.model not in iterative._ANCHOR and krylov.ksp is None
    assert ev.model._cache.support is None and ev.model._cache.anchor is None
    again = ev.evaluate({})
    assert again.status == 0
    assert np.array_equal(again.state.u, first.state.u) and again.phi == first.phi


def test_the_mesh_files_arrays_are_not_kept_beside_the_mesh_made_of_them(tmp_path):
    """A mesh file is read once for the study's check and its mesh (`meshfile.load_raw`'s cache),
    and the cache lets go of the file's arrays once the mesh is made (8 MB at 1e5 unknowns)."""
    from tests.scene.test_meshfile_3d import FILE, write_block_msh
    from wcs.scene import meshfile
    write_block_msh(tmp_path / "block.msh")
    (tmp_path / "study.yaml").write_text(FILE)
    study = load_study(tmp_path / "study.yaml")
    assert len(meshfile._CACHE) == 1
    Evaluator(study)
    assert meshfile._CACHE == {}
