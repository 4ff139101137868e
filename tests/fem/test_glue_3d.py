"""Glued interfaces in 3D (the 2D format's `glue:` with 3D selectors); a region's own mesh size
is tests/scene/test_region_size_3d.py's.

Tolerances: uniform stress and free thermal expansion are affine displacements; on a flat
interface both traces of an affine field are that field, so it satisfies every glue row and
lies in the glued P1 space: the Galerkin solution is it, up to round-off (1e-8 relative leaves
orders of magnitude for a few thousand unknowns). The two materials of the stack have the same
ν/E, so under a uniaxial stress their lateral strains agree (the uniform stress is the solution
of the glued problem). On matching faces the glue rows are node-to-node ties, so the glued
pair is the one-body problem in other variables: 1e-10 relative.
"""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from wcs.geometry.mortar3d import mortar_integrals3d
from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs import load_study

from tests.model.test_model_3d import solve

ROOT = Path(__file__).resolve().parents[2]
P = 2.0e6                                   # the traction on the top [Pa]
MATERIALS = {"stiff": {"E": 2.0e10, "nu": 0.3, "expansion": 1.0e-5, "conductivity": 3.0},
             "soft": {"E": 1.0e10, "nu": 0.15, "expansion": 1.0e-5, "conductivity": 1.0}}   # same ν/E
ROLLERS = {"bottom": {"u": [None, None, 0.0]}, "x0": {"u": [0.0, None, None]}, "y0": {"normal": 0.0}}


def plane(point, normal, body=None):
    out = {"plane": {"point": point, "normal": normal}}
    return out if body is None else {"body": body, **out}


def stack(base=0.25, block=None, **scene) -> dict:
    """A soft block [0,1]² × [0, 0.25] glued on a stiff base [0,1]² × [−0.25, 0] (slave: the block's
    bottom). `block`: the block's own size (the bodies meshed apart: a nonmatching interface)."""
    bodies = {"base": {"regions": [{"material": "stiff", "shape": {"box": [0, 0, -0.25, 1, 1, 0]}}]},
              "block": {"regions": [{"material": "soft", "shape": {"box": [0, 0, 0, 1, 1, 0.25]}}]}}
    if block is not None:
        bodies["base"]["mesh"], bodies["block"]["mesh"] = {"size": base}, {"size": block}
    d = {"study": "glue-3d",
         "scene": {"dimension": 3, "mesh": {"size": base}, "materials": MATERIALS, "bodies": bodies,
                   "boundaries": {"bottom": plane([0, 0, -0.25], [0, 0, 1]), "top": plane([0, 0, 0.25], [0, 0, 1]),
                                  "x0": plane([0, 0, 0], [1, 0, 0]), "y0": plane([0, 0, 0], [0, 1, 0]),
                                  "base_top": plane([0, 0, 0], [0, 0, 1], "base"),
                                  "block_bottom": plane([0, 0, 0], [0, 0, 1], "block")},
                   "supports": ROLLERS, "loads": {"top": {"traction": [0.0, 0.0, -P]}},
                   "glue": {"joint": {"slave": "block_bottom", "master": "base_top"}}},
         "solver": {"method": "monolithic"}}
    d["scene"].update(scene)
    return d


def strain(material: str, tau: np.ndarray) -> np.ndarray:
    E, nu = MATERIALS[material]["E"], MATERIALS[material]["nu"]
    return (tau - nu * (tau.sum() - tau)) / E


def test_a_nonmatching_glued_interface_passes_the_uniform_stress():
    """Block meshed 3× finer than the base: τ_zz = −P in both, every other component 0, and the
    displacement is the closed form u = ε x (ε of each material, u_z continuous at z = 0). The
    slave nodes on the rollers x = 0, y = 0 are excluded and their dual functions merged."""
    ev, res = solve(stack(0.25, 0.25 / 3))
    assert all(m.shape[1] == 0 for m in ev.model.free_modes.values())   # the block held through the glue
    g = ev.model.glue[0].rows
    x = ev.smesh.mesh.p
    on_rollers = np.isclose(x[0, g.dropped], 0.0) | np.isclose(x[1, g.dropped], 0.0)
    assert g.dropped.size and on_rollers.all()                      # the supported slave nodes
    assert np.isin(g.C.indices, g.dropped).any()                    # their merged terms in kept rows
    assert g.slave.size > 3 * np.unique(ev.smesh.boundary_nodes("base_top")).size   # nonmatching, 1:3
    s = res.state.stress
    assert np.abs(s[2] + P).max() < 1e-8 * P
    assert np.abs(np.delete(s, 2, axis=0)).max() < 1e-8 * P
    tau = np.array([0.0, 0.0, -P])
    u = res.state.u.reshape(-1, 3).T
    body = ev.smesh.node_body
    for b, mat in enumerate(("stiff", "soft")):
        eps = strain(mat, tau)
        exact = eps[:, None] * (x - [[0.0], [0.0], [-0.25]]) if mat == "stiff" else \
            eps[:, None] * x + [[0.0], [0.0], [0.25 * strain("stiff", tau)[2]]]
        assert np.abs(u[:, body == b] - exact[:, body == b]).max() < 1e-8 * np.abs(exact).max()


@pytest.mark.slow
def test_a_coarse_slave_side_passes_the_uniform_stress_too():
    """The same patch with the roles swapped (slave: the base's coarse top, 3× coarser than its
    master): the dual mortar patch test holds whichever side is the slave."""
    ev, res = solve(stack(0.25, 0.25 / 3, glue={"joint": {"slave": "base_top", "master": "block_bottom"}}))
    assert ev.model.glue[0].rows.slave.size < np.unique(ev.smesh.boundary_nodes("block_bottom")).size / 3
    s = res.state.stress
    assert np.abs(s[2] + P).max() < 1e-8 * P
    assert np.abs(np.delete(s, 2, axis=0)).max() < 1e-8 * P


def test_a_glue_on_matching_faces_is_the_one_body_problem():
    """Faces matching (one gmsh fragment), two materials of different ν, a clamped bottom (no
    slave node excluded) and a shear traction: the glued pair's displacement equals that of one
    body with the two regions, node by node."""
    loads = {"top": {"traction": [0.7 * P, -0.3 * P, -P]}}
    clamp = {"bottom": {"u": [0.0, 0.0, 0.0]}}
    glued = stack(supports=clamp, loads=loads)
    glued["scene"]["materials"] = {**MATERIALS, "soft": {**MATERIALS["soft"], "nu": 0.4}}
    one = yaml.safe_load(yaml.safe_dump(glued))
    sc = one["scene"]
    sc["bodies"] = {"stack": {"regions": [dict(sc["bodies"]["base"]["regions"][0], name="base"),
                                          dict(sc["bodies"]["block"]["regions"][0], name="block")]}}
    del sc["glue"], sc["boundaries"]["base_top"], sc["boundaries"]["block_bottom"]
    ev1, r1 = solve(glued)
    ev2, r2 = solve(one)
    assert ev1.model.glue[0].rows.dropped.size == 0
    assert ev1.model.glue[0].rows.C.nnz == 2 * ev1.model.glue[0].rows.slave.size    # node-to-node ties
    x1, x2 = np.round(ev1.smesh.mesh.p.T, 12), np.round(ev2.smesh.mesh.p.T, 12)
    nodes, of = np.unique(x1, axis=0, return_inverse=True)         # a glued node -> its place
    order = np.lexsort(x2.T[::-1])                                  # the one body's nodes, in that order
    assert len(nodes) == len(x2) and np.array_equal(nodes, x2[order])
    u1, u2 = r1.state.u.reshape(-1, 3), r2.state.u.reshape(-1, 3)[order]
    assert np.abs(u1 - u2[of.ravel()]).max() < 1e-10 * np.abs(u2).max()    # both copies of interface nodes


def test_a_glued_stack_under_uniform_heating_expands_freely():
    """The temperature held on the block's top only: heat passes the nonmatching glue (T uniform
    in both bodies), and the stack on rollers expands freely, u = αΔT (x − x_0), no stress."""
    dT = 40.0
    ev, res = solve(stack(0.25, 0.125, loads={},
                          thermal={"reference": 290.0, "temperature": {"top": 290.0 + dT}}))
    assert np.abs(res.state.T - (290.0 + dT)).max() < 1e-8 * dT
    alpha = MATERIALS["stiff"]["expansion"]
    u = res.state.u.reshape(-1, 3).T
    exact = alpha * dT * (ev.smesh.mesh.p - [[0.0], [0.0], [-0.25]])
    assert np.abs(u - exact).max() < 1e-8 * np.abs(exact).max()
    beta = MATERIALS["stiff"]["E"] / (1 - 2 * MATERIALS["stiff"]["nu"]) * alpha      # (3λ + 2μ) α
    assert np.abs(res.state.stress).max() < 1e-8 * beta * dT


def test_a_body_glued_to_its_partner_moves_with_the_cluster():
    """The block has no support of its own: glued, it takes the cluster's joint rigid modes. With
    the base on the bottom roller only, the x and y translations and the rotation about z of
    both bodies together (listed under the base): rigid for the whole pair (K R = 0) and
    satisfying the glue rows (held by the rollers, the pair solves: the patch test above)."""
    ev = Evaluator(load_study(stack(0.25, 0.125, supports={"bottom": ROLLERS["bottom"]})))
    m = ev.model
    R = m.free_modes["base"]
    assert m.free_modes["block"].shape[1] == 0 and R.shape[1] == 3
    block = np.flatnonzero(ev.smesh.node_body == 1)
    assert np.linalg.matrix_rank(R.reshape(-1, 3, 3)[block].reshape(-1, 3)) == 3     # the block moves too
    K = m.K(m.stiffness_coefficients(m.nominal))
    assert np.abs(K @ R).max() < 1e-9 * abs(K).max() * np.abs(R).max()
    g = m.glue[0].rows
    for k in range(3):
        assert np.abs(g.C @ R[k::3]).max() < 1e-12 * np.abs(R).max()   # no jump across the glue
    with pytest.raises(StudyError, match="body 'base' is not held: three rigid motions are free"):
        ev.evaluate(ev.study.nominal())


def test_excluded_slave_nodes_keep_the_rows_affine():
    """Two nonmatching triangulations of the unit square z = 0 facing each other: excluding the
    slave nodes on the edge x = 0 (a support there) merges their dual functions into the
    neighbours'; the rows still reproduce every affine field (C x = 0, C 1 = 0), the excluded
    nodes have no row and appear in their neighbours' rows."""
    rng = np.random.default_rng(3)

    def grid(n):                                   # counter-clockwise about +z
        t = np.linspace(0.0, 1.0, n)
        X, Y = np.meshgrid(t, t, indexing="ij")
        idx = np.arange(n * n).reshape(n, n)
        tri = [[idx[i, j], idx[i + 1, j], idx[i + 1, j + 1]] for i in range(n - 1) for j in range(n - 1)]
        tri += [[idx[i, j], idx[i + 1, j + 1], idx[i, j + 1]] for i in range(n - 1) for j in range(n - 1)]
        return np.column_stack([X.ravel(), Y.ravel(), np.zeros(n * n)]), np.array(tri)
    xs, ts = grid(7)
    xm, tm = grid(3)
    inner = (xs[:, :2] > 0) & (xs[:, :2] < 1)
    xs[:, :2] += 0.03 * rng.standard_normal((len(xs), 2)) * inner
    x = np.vstack([xs, xm])
    ts, tm = ts[:, [0, 2, 1]], tm + len(xs)        # the slave side faces −z, the master +z
    exclude = np.flatnonzero(xs[:, 0] == 0.0)
    mi = mortar_integrals3d(x, ts, tm, exclude=exclude)
    plain = mortar_integrals3d(x, ts, tm)
    assert plain.slave.size == len(xs) and mi.slave.size == len(xs) - exclude.size
    assert not np.isin(mi.slave, exclude).any() and np.isin(exclude, mi.dropped).all()
    assert np.isin(mi.C.indices, exclude).any()
    assert np.abs(mi.C @ x).max() < 1e-13 and np.abs(mi.C @ np.ones(len(x))).max() < 1e-13



def test_wcs_check_runs_a_3d_study_with_glue_and_a_region_size(tmp_path):
    """A glued stack whose block has a finer core region: `wcs check` accepts it (exit 0) and
    solves the nominal case."""
    d = stack(0.25, 0.125)
    d["scene"]["bodies"]["base"]["regions"] = [
        {"material": "stiff", "shape": {"box": [0, 0, -0.25, 1, 1, 0],
                                        "minus": [{"box": [0.25, 0.25, -0.2, 0.75, 0.75, -0.05]}]}},
        {"material": "soft", "name": "core", "shape": {"box": [0.25, 0.25, -0.2, 0.75, 0.75, -0.05]},
         "mesh": {"size": 0.1}}]
    d["uncertain"] = {"loads.top.traction.2": [-3.0e6, -1.0e6]}
    d["scene"]["regions_of_interest"] = {"core": {"box": [0.25, 0.25, -0.2, 0.75, 0.75, -0.05], "body": "base"}}
    d["criteria"] = [{"name": "stress", "kind": "von_mises", "regions": ["core"]}]
    study = tmp_path / "glued.yaml"
    study.write_text(yaml.safe_dump(d))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-m", "wcs.cli", "check", str(study)], capture_output=True, text=True,
                         env=env, cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "Traceback" not in out.stderr


def test_a_slave_side_held_everywhere_is_refused_by_name():
    """A support on the interface plane (both faces) holds every slave node: nothing is left to
    glue, exit 2 at the glue's slave key."""
    d = stack(supports={**ROLLERS, "mid": {"u": [None, None, 0.0]}})
    d["scene"]["boundaries"]["mid"] = plane([0, 0, 0], [0, 0, 1])
    with pytest.raises(StudyError, match="scene.glue.joint.slave: every node of the slave side carries a support"):
        Evaluator(load_study(d))
