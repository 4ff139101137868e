"""Contact solve performance, as ratios measured in one run on ~1e5 unknowns with a
short contact (≤ 200 nodes), against one SuperLU factorization-and-solve of the
same reduced stiffness (tuned: diag_pivot_thresh=0, SymmetricMode):
- the first Tresca solve, assembly included, at most 3x;
- a re-solve with new material and load data on the same mesh at most 0.5x.
Each time is the best of a few repeats (the machine is shared and noisy)."""
import time
from pathlib import Path

import pytest
import scipy.sparse.linalg as spla
import yaml

import wcs
from wcs.model.coefficients import ParameterMap
from wcs.model.model import Model
from wcs.scene.mesher2d import build_mesh

PAD = Path(__file__).resolve().parents[2] / "studies" / "validation" / "tresca-pad.yaml"


def best(f, n):
    times = []
    for _ in range(n):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


@pytest.mark.bench
def test_first_solve_and_resolve_against_one_superlu_solve(tmp_path):
    doc = yaml.safe_load(PAD.read_text())
    doc["scene"]["mesh"] = {"size": 0.0075}
    path = tmp_path / "pad.yaml"
    path.write_text(yaml.safe_dump(doc))
    study = wcs.load_study(path)
    smesh = build_mesh(study.scene)
    unknowns = 2 * smesh.mesh.p.shape[1]

    def first():
        model = Model(study.scene, smesh, study.solver)
        return model, model.solve(model.nominal)
    t_first, (model, state) = best(first, 2)
    m = model.zone.gap.size
    assert 0.9e5 <= unknowns <= 1.2e5 and m <= 200
    c = model.coefficients(study.scene)
    K = model.K(model.stiffness_coefficients(c))
    Kr = (model.Tt @ K @ model.elim.T).tocsc()
    rhs = model.Tt @ model.mechanical_load(c, None)
    t_lu, _ = best(lambda: spla.splu(Kr, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                     options={"SymmetricMode": True}).solve(rhs), 2)

    names = study.parameters.names
    pmap = ParameterMap(model, study.scene, study.uncertain)
    data = []
    for k in range(3):
        x = study.nominal().copy()
        x[names.index("contacts.interface.friction.slip_limit")] *= 1.0 + 0.1 * k
        x[names.index("loads.pad_top.traction.0")] *= 0.9 + 0.05 * k
        E = study.scene.materials["rubber"].E * (1.1 + 0.05 * k)   # new material data too
        data.append(pmap.coefficients(x, {"materials.rubber.E": E}))
    times, iters = [], []
    for s in data:
        t = time.perf_counter()
        st = model.solve(s)
        times.append(time.perf_counter() - t)
        iters.append(st.iterations)
    t_re = min(times)
    print(f"\n{unknowns} unknowns, {m} contact nodes: SuperLU {t_lu:.2f} s; first Tresca solve "
          f"(assembly included) {t_first:.2f} s = {t_first / t_lu:.2f}x; re-solve {t_re:.3f} s = "
          f"{t_re / t_lu:.2f}x; Newton iterations first {state.iterations}, re-solves {iters}")
    assert t_first <= 3.0 * t_lu
    assert t_re <= 0.5 * t_lu
