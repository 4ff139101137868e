"""Refinement zones and grading of 3D meshes (`mesh.refine`, `mesh.grading`): the size is
min(size, size_r + grading · dist_r(x)) as in 2D, so cells inside a zone are no larger than its
size (gmsh's 3D Delaunay meshes edges of 1.2–1.45× the target size on average, at every size:
the bound below is 1.5×), cells far from it keep the scene size, and the
estimate the resource guard uses is an upper bound of the cells meshed."""
import numpy as np
import pytest

from tests.scene.test_mesher_3d import BLOCK, FAULT, build_mesh3d, fault_scene
from wcs.errors import StudyError
from wcs.scene.estimate import estimate_cells3d, plane_box_area
from wcs.study import load_scene


def mean_edges(mesh):
    p, t = mesh.p, mesh.t
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    return np.mean([np.linalg.norm(p[:, t[a]] - p[:, t[b]], axis=0) for a, b in pairs], axis=0)


def centroids(mesh):
    return mesh.p[:, mesh.t].mean(axis=1)


ZONES = {
    "ball": {"ball": {"center": [0.5, 0.5, 0.5], "radius": 0.15}},
    "box": {"box": [0.3, 0.3, 0.3, 0.7, 0.7, 0.7]},
    "cylinder": {"cylinder": {"start": [0.5, 0.5, 0.0], "end": [0.5, 0.5, 1.0], "radius": 0.1}},
    "boundary": {"boundary": "fault_h"},
}


@pytest.mark.parametrize("kind", ZONES)
def test_cells_in_a_refine_zone_meet_its_size_and_far_cells_the_scene_size(kind):
    scene = fault_scene(size=0.3)
    scene["mesh"] = {"size": 0.3, "grading": 0.5, "refine": [{**ZONES[kind], "size": 0.06}]}
    coarse = build_mesh3d(fault_scene(size=0.3)).mesh
    fine = build_mesh3d(scene).mesh
    assert fine.t.shape[1] > 2 * coarse.t.shape[1]
    c, h = centroids(fine), mean_edges(fine)
    if kind == "boundary":                                 # the fault plane x − z = 0.5
        n = np.array(FAULT["normal"]) / np.linalg.norm(FAULT["normal"])
        d = np.abs(n @ (c - np.reshape(FAULT["point"], (3, 1))))
    elif kind == "box":
        d = np.linalg.norm(np.maximum(np.maximum(0.3 - c, c - 0.7), 0.0), axis=0)
    elif kind == "ball":
        d = np.maximum(np.linalg.norm(c - 0.5, axis=0) - 0.15, 0.0)
    else:
        d = np.maximum(np.hypot(c[0] - 0.5, c[1] - 0.5) - 0.1, 0.0)
    near = d < 0.02
    assert near.sum() > 20
    assert 0.06 <= np.median(h[near]) <= 0.06 * 1.5              # the zone's size, as meshed
    far = d > 0.6                                             # 0.06 + 0.5 · 0.6 > 0.3: the scene size
    if far.any():
        assert np.median(h[far]) > 0.2
    typed = load_scene({"dimension": 3, "materials": {"m": {"E": 1.0, "nu": 0.3}}, **{
        k: v for k, v in scene.items() if k != "bodies"},
        "bodies": {b: {**s, "regions": [{**r, "material": "m"} for r in s["regions"]]}
                   for b, s in scene["bodies"].items()}})
    estimate, path = estimate_cells3d(typed, 0.3)
    assert fine.t.shape[1] <= estimate <= 15 * fine.t.shape[1]   # an upper estimate, not a wild one


def test_grading_zero_jumps_and_larger_grading_spreads_less():
    cells = []
    for g in (0.2, 1.0):
        scene = fault_scene(size=0.3)
        scene["mesh"] = {"size": 0.3, "grading": g, "refine": [{**ZONES["ball"], "size": 0.05}]}
        cells.append(build_mesh3d(scene).mesh.t.shape[1])
    assert cells[0] > 1.3 * cells[1]                         # slower growth: more fine cells


def test_an_unknown_refine_boundary_is_a_study_error_at_its_path():
    scene = fault_scene()
    scene["mesh"] = {"size": 0.3, "refine": [{"boundary": "nowhere", "size": 0.1}]}
    with pytest.raises(StudyError) as e:
        build_mesh3d(scene)
    assert "scene.mesh.refine.0.boundary" in str(e.value) and "unknown boundary" in str(e.value)


@pytest.mark.parametrize("point, normal, box, area", [
    ([0, 0, 0.5], [0, 0, 1], [0, 0, 0, 2, 1, 1], 2.0),                          # across z
    ([1, 1, 1], [1, 1, 1], [0, 0, 0, 2, 2, 2], 3 * np.sqrt(3.0)),               # a regular hexagon of side √2
    ([0, 0, 0], [-2, 3, 0], [-60, -60, 0, 60, 60, 4], 4 * np.hypot(120, 80)),   # the tunnel's fault
    ([0, 0, 5], [0, 0, 1], [0, 0, 0, 1, 1, 1], 0.0),                            # misses the box
])
def test_the_area_of_a_plane_in_a_box_the_estimate_uses(point, normal, box, area):
    assert plane_box_area(point, normal, box) == pytest.approx(area, rel=1e-12, abs=1e-12)


def test_a_refine_cylinder_across_two_bodies_is_estimated_once():
    """The 3D tunnel's ring r < 7 m (a `mesh.refine` cylinder without `body`) lies in both the
    hanging wall and the footwall; it is meshed once and now estimated once: at 0.3 m the
    estimate was 1.32e6 (the default mesh.max_cells 1e6 refused a 1.9e5-cell mesh), now 6.8e5,
    still above the cells gmsh makes."""
    from pathlib import Path

    import yaml
    doc = yaml.safe_load((Path(__file__).parents[2] / "studies" / "tunnel-fault-3d.yaml").read_text())
    doc["scene"]["mesh"]["refine"][0]["size"] = 0.3
    scene = load_scene(doc["scene"])
    estimate, path = estimate_cells3d(scene, scene.mesh.size)
    assert path == "mesh.refine.0.size"
    assert 1.93e5 <= estimate <= 1.0e6          # meshed: 193065 tetrahedra (`wcs check`)
