"""A 3D contact surface's own coordinates and the grid of a Lipschitz slip limit on it: the
frame spans the surface's plane with its long side first, the bilinear grid weights are a
partition of unity that interpolates the grid values and reproduces every bilinear function
exactly; the study format takes `points: [nu, nv]` in 3D only and names the values `[i,j]`."""
import copy

import numpy as np
import pytest
import yaml

from tests.study.test_study_3d import STUDY, run, write
from wcs.contact.frame import grid_weights, surface_frame, surface_grid
from wcs import load_study


def rotated_rectangle(n=(31, 13), sides=(3.0, 1.2), seed=0):
    """A regular grid of points on a rectangle (symmetric: its principal axes are the sides), turned in space."""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.linspace(0, 1, n[0]), np.linspace(0, 1, n[1]), indexing="ij")
    uv = np.column_stack([u.ravel(), v.ravel()]) * sides
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return uv, np.array([2.0, -1.0, 0.5]) + uv @ q[:, :2].T, q


def test_the_surface_grid_is_the_rectangle_in_the_surfaces_own_frame():
    uv, x, q = rotated_rectangle()
    origin, e1, e2 = surface_frame(x)
    n = np.cross(q[:, 0], q[:, 1])
    assert abs(e1 @ n) < 1e-12 and abs(e2 @ n) < 1e-12 and abs(e1 @ e2) < 1e-12
    grid, lengths = surface_grid(x)
    assert lengths == pytest.approx([3.0, 1.2], rel=1e-12)
    assert grid.min() == pytest.approx(0.0, abs=1e-12) and grid.max() == pytest.approx(1.0, abs=1e-12)
    # the grid coordinates are the rectangle's, up to the side's orientation
    for k in range(2):
        s = uv[:, k] / [3.0, 1.2][k]
        assert min(np.abs(grid[:, k] - s).max(), np.abs(grid[:, k] - (1 - s)).max()) < 1e-12


def test_grid_weights_interpolate_and_reproduce_bilinear_functions():
    rng = np.random.default_rng(1)
    nu, nv = 4, 3
    pts = rng.uniform(0, 1, (200, 2))
    W = grid_weights(pts, (nu, nv))
    assert W.shape == (200, nu * nv) and np.all(W >= 0)
    assert np.allclose(W.sum(axis=1), 1.0, atol=1e-14)
    u, v = np.meshgrid(np.linspace(0, 1, nu), np.linspace(0, 1, nv), indexing="ij")
    f = lambda a, b: 2.0 - 3.0 * a + 0.5 * b + 4.0 * a * b        # noqa: E731 - bilinear
    assert np.allclose(W @ f(u, v).ravel(), f(pts[:, 0], pts[:, 1]), atol=1e-13)
    nodes = np.column_stack([u.ravel(), v.ravel()])
    assert np.allclose(grid_weights(nodes, (nu, nv)), np.eye(nu * nv), atol=1e-14)   # index i·nv + j


def study_doc(points):
    d = yaml.safe_load(STUDY)
    d["uncertain"] = {"contacts.interface.friction.slip_limit": {"range": [5e4, 1.5e5], "lipschitz": 1e5,
                                                                 "points": points}}
    return d


def test_a_3d_slip_limit_on_a_grid_is_named_by_its_grid_index():
    study = load_study(study_doc([3, 2]))
    names = study.parameters.names
    assert names == [f"contacts.interface.friction.slip_limit[{i},{j}]" for i in range(3) for j in range(2)]
    assert study.nominal() == pytest.approx([1e5] * 6)


@pytest.mark.parametrize("points, words", [(4, "points: [nu, nv]"), ([1, 3], "at least 2 values"),
                                           ([2, 3, 4], "an integer (2D) or [nu, nv]"),
                                           ([2, 2.5], "an integer (2D) or [nu, nv]")])
def test_bad_3d_grid_points_are_exit_2_at_their_path(tmp_path, points, words):
    code, _, err = run(["check", str(write(tmp_path, study_doc(points)))])
    assert code == 2 and "uncertain.contacts.interface.friction.slip_limit" in err and words in err, err


def test_the_surface_grid_is_the_face_however_its_nodes_crowd():
    """Nodes crowded into one corner of a 3 × 1.2 rectangle (a mesh refined
    there) turned the principal directions off its sides and laid the grid on a 3.08 × 1.43
    rectangle; the smallest enclosing rectangle is the face itself."""
    uv, x, q = rotated_rectangle()
    crowd = np.random.default_rng(3).uniform(0, 1, (400, 2)) ** 3 * [3.0, 1.2]
    uv, x = np.vstack([uv, crowd]), np.vstack([x, np.array([2.0, -1.0, 0.5]) + crowd @ q[:, :2].T])
    grid, lengths = surface_grid(x)
    assert lengths == pytest.approx([3.0, 1.2], rel=1e-12)
    for k in range(2):
        s = uv[:, k] / [3.0, 1.2][k]
        assert min(np.abs(grid[:, k] - s).max(), np.abs(grid[:, k] - (1 - s)).max()) < 1e-12


def test_a_slip_limit_at_its_lipschitz_bound_has_exactly_the_studys_slope():
    """A 2 × 1 m contact face meshed finer in one corner, the slip limit on a [5, 2] grid with
    C = 1e5 Pa/m: the constraints bound neighbours by C·0.5 m along the face and C·1 m across
    it (its true sides), and the grid values rising by exactly those steps give every contact
    node g0 + C (x + y): the Lipschitz constant across the face is the study's C, no more."""
    from wcs.model.evaluation import Evaluator
    from wcs.app.problem import lipschitz_constraints
    d = yaml.safe_load(STUDY)
    scene, C, g0 = d["scene"], 1e5, 5e4
    scene["mesh"]["refine"] = [{"box": [0, 0, -0.2, 0.5, 0.4, 0.2], "size": 0.06}]
    scene["bodies"]["base"]["regions"][0]["shape"]["box"] = [0, 0, -0.5, 2, 1, 0]
    scene["bodies"]["block"]["regions"][0]["shape"]["box"] = [0, 0, 0, 2, 1, 0.5]
    scene["boundaries"]["base_top"]["box"] = [0, 0, 0, 2, 1, 0]
    d["uncertain"] = {"contacts.interface.friction.slip_limit": {"range": [g0, 4e5], "lipschitz": C,
                                                                 "points": [5, 2]}}
    study = load_study(d)
    ev = Evaluator(study)
    _, b = lipschitz_constraints(study, ev)
    assert sorted(set(np.round(b / C, 12))) == [0.5, 1.0]
    i, j = np.meshgrid(np.arange(5), np.arange(2), indexing="ij")
    x = (g0 + C * (0.5 * i + 1.0 * j)).ravel()
    slip = ev.map.coefficients(*study.data_set(x)).slip
    nodes = ev.model.zone.coords
    assert np.abs(slip - (g0 + C * (nodes[:, 0] + nodes[:, 1]))).max() < 1e-9 * g0
