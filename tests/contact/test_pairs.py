"""Contact pairing (wcs.contact.pairs)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import skfem
import yaml

from wcs.contact.pairs import (normal_jump_matrix, pair_contact, pair_sides,
                               tangent_jump_matrix)
from wcs.errors import StudyError
from tests.support.scenes import typed_scene
from wcs.scene.mesher2d import build_mesh
from wcs.scene.selectors import select_boundary
from wcs.scene.spec import Boundary, Contact

ROOT = Path(__file__).resolve().parents[2]
R = 1.0


@pytest.fixture(scope="module")
def demo():
    sc = yaml.safe_load((ROOT / "studies" / "two-blocks-demo.yaml").read_text())["scene"]
    return build_mesh(typed_scene(sc))


@pytest.fixture(scope="module")
def hertz():
    sc = {"mesh": {"size": 0.2, "refine": [{"box": [-0.3, -0.05, 0.3, 0.05], "size": 0.01}]},
          "bodies": {"disc": {"regions": [{"material": "m", "shape": {"disc": {"center": [0, R], "radius": R}}}]},
                     "block": {"regions": [{"material": "m", "shape": {"rectangle": [-1.5, -1, 1.5, 0]}}]}},
          "boundaries": {"rim": {"body": "disc", "box": [-0.5, -0.01, 0.5, 0.3]},
                         "top": {"body": "block", "segment": [[-1.5, 0], [1.5, 0]]}}}
    return build_mesh(typed_scene(sc))


def vector_basis(mesh):
    return skfem.Basis(mesh, skfem.ElementVector(skfem.ElementTriP1()))


def test_coincident_sides(demo):
    sm = demo
    pr = pair_contact(sm, Contact(**{"slave": "pad_bottom", "master": "base_top"}), "scene.contacts.interface")
    p = sm.mesh.p
    slave_nodes = sm.boundary_nodes("pad_bottom")
    assert np.array_equal(pr.slave, slave_nodes) and pr.dropped.size == 0
    assert np.all(sm.node_body[pr.slave] == 1) and np.all(sm.node_body[pr.master_nodes] == 0)
    # node to node
    assert np.array_equal(p[:, pr.slave], p[:, pr.master_nodes[:, 0]])
    assert np.array_equal(pr.master_weights, np.tile([1.0, 0.0], (len(pr), 1)))
    assert np.array_equal(pr.gap, np.zeros(len(pr)))
    assert pr.weight.sum() == pytest.approx(1.0, rel=1e-12)
    assert np.array_equal(pr.normal, np.tile([0.0, -1.0], (len(pr), 1)))
    assert np.array_equal(pr.tangent, np.tile([1.0, 0.0], (len(pr), 1)))
    # the ends get half a facet
    h = np.diff(np.sort(p[0, pr.slave]))
    assert pr.weight[np.argmin(p[0, pr.slave])] == pytest.approx(h[0] / 2)


def test_hertz_gaps(hertz):
    sm = hertz
    pr = pair_contact(sm, Contact(**{"slave": "rim", "master": "top"}), "scene.contacts.c")
    x = sm.mesh.p[:, pr.slave]
    assert len(pr) > 50 and pr.dropped.size == 0
    expected = R - np.sqrt(R**2 - x[0] ** 2)
    assert np.abs(pr.gap - expected).max() < 1e-3 * R
    assert np.allclose(pr.gap, x[1], atol=1e-12 * R)          # projection onto y = 0 is vertical
    assert np.all(pr.gap >= 0)
    assert np.allclose(pr.normal, [0.0, -1.0])
    assert np.allclose(pr.master_weights.sum(axis=1), 1.0)
    assert np.all(pr.master_weights >= 0)
    # the projection reproduces the slave x coordinate
    xm = np.einsum("ij,kij->ki", pr.master_weights, sm.mesh.p[:, pr.master_nodes])
    assert np.allclose(xm[0], x[0], atol=1e-14) and np.allclose(xm[1], 0.0)
    # the touching node: gap 0, weights (1, 0)
    i = np.argmin(np.abs(x[0]))
    assert pr.gap[i] == 0.0 and np.array_equal(pr.master_weights[i], [1.0, 0.0])


def test_jumps_rigid_translation(hertz):
    sm = hertz
    pr = pair_contact(sm, Contact(**{"slave": "rim", "master": "top"}), "c")
    mesh = sm.mesh
    nd = vector_basis(mesh).nodal_dofs
    nn = mesh.p.shape[1]
    Bn = normal_jump_matrix(pr, nn, nodal_dofs=nd)
    Bt = tangent_jump_matrix(pr, nn, nodal_dofs=nd)
    # default DOF order == skfem's
    assert (normal_jump_matrix(pr, nn) != Bn).nnz == 0
    assert Bn.shape == (len(pr), 2 * nn)

    def field(c, body):
        u = np.zeros(2 * nn)
        on = sm.node_body == sm.bodies.index(body) if body else np.ones(nn, bool)
        u[nd[0, on]] = c[0]
        u[nd[1, on]] = c[1]
        return u

    # everything translated: no jump
    u = field([0.3, -0.7], None)
    assert np.allclose(Bn @ u, 0.0, atol=1e-14) and np.allclose(Bt @ u, 0.0, atol=1e-14)
    # slave body moved towards the master by d: normal jump d, no slip
    d = 1e-3
    u = field([0.0, -d], "disc")
    assert np.allclose(Bn @ u, d) and np.allclose(Bt @ u, 0.0)
    # the deformed gap is gap - B_n u: the touching node penetrates
    assert np.min(pr.gap - Bn @ u) == pytest.approx(-d)
    # master moved towards the slave: same normal jump
    u = field([0.0, d], "block")
    assert np.allclose(Bn @ u, d) and np.allclose(Bt @ u, 0.0)
    # slave slid along the tangent
    u = field([0.02, 0.0], "disc")
    assert np.allclose(Bn @ u, 0.0) and np.allclose(Bt @ u, 0.02)


def test_initial_gap_closes():
    sc = {"mesh": {"size": 0.1},
          "bodies": {"base": {"regions": [{"material": "m", "shape": {"rectangle": [0, 0, 2, 1]}}]},
                     "pad": {"regions": [{"material": "m", "shape": {"rectangle": [0.5, 1.01, 1.5, 1.5]}}]}},
          "boundaries": {"base_top": {"body": "base", "segment": [[0, 1], [2, 1]]},
                         "pad_bottom": {"body": "pad", "segment": [[0.5, 1.01], [1.5, 1.01]]}}}
    sm = build_mesh(typed_scene(sc))
    pr = pair_contact(sm, Contact(**{"slave": "pad_bottom", "master": "base_top"}), "c")
    assert np.allclose(pr.gap, 0.01, rtol=1e-9)
    nn = sm.mesh.p.shape[1]
    u = np.zeros(2 * nn)
    u[1::2][sm.node_body == 1] = -0.01                  # pad down by the gap
    assert np.allclose(pr.gap - normal_jump_matrix(pr, nn) @ u, 0.0, atol=1e-15)


def test_projection_outside_master_is_dropped(demo):
    sm = demo
    master = select_boundary(sm, Boundary(body="base", segment=[[0.8, 1.0], [1.2, 1.0]]), "m")
    xs = sm.mesh.p[0, np.unique(sm.mesh.facets[:, master])]
    pr = pair_sides(sm.mesh, sm.boundaries["pad_bottom"], master, "c")
    assert pr.dropped.size > 0
    x = sm.mesh.p[0, pr.slave]
    assert x.min() >= xs.min() - 1e-12 and x.max() <= xs.max() + 1e-12
    assert len(pr) + pr.dropped.size == sm.boundary_nodes("pad_bottom").size


def test_sides_not_facing(demo):
    sm = demo
    with pytest.raises(StudyError) as e:
        pair_contact(sm, Contact(**{"slave": "pad_left", "master": "base_top"}), "scene.contacts.bad")
    assert e.value.path == "scene.contacts.bad"
    with pytest.raises(StudyError) as e:
        pair_contact(sm, Contact(**{"slave": "pad_top", "master": "base_bottom"}), "scene.contacts.far")
    assert e.value.path == "scene.contacts.far"
    with pytest.raises(StudyError):
        pair_contact(sm, Contact(**{"slave": "base_top", "master": "base_bottom"}), "scene.contacts.same")


def test_sides_sharing_nodes(demo):
    with pytest.raises(StudyError, match="share nodes") as e:
        pair_contact(demo, Contact(**{"slave": "pad_left", "master": "pad_bottom"}), "scene.contacts.x")
    assert e.value.path == "scene.contacts.x"
