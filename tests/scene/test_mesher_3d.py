"""3D scenes meshed with gmsh (OpenCASCADE): matching faces with duplicated nodes where bodies
touch, face and region selectors, solids, determinism, and bad input at its key path.

Planar solids are meshed exactly (volumes and face areas to round-off); curved surfaces are
inscribed polyhedra (nodes on the surface, areas and volumes a little smaller)."""
import numpy as np
import pytest

from wcs.errors import StudyError
from wcs.geometry.tet import volumes
from wcs.scene import selectors
from wcs.scene.mesher3d import build_mesh3d as mesh_typed
from wcs.scene.spec import RegionOfInterest
from wcs.study import load_scene

FAULT = {"point": [1.0, 0.0, 0.5], "normal": [1.0, 0.0, -1.0]}    # the plane x − z = 0.5
BLOCK = [0.0, 0.0, 0.0, 2.0, 1.0, 1.0]


def fault_scene(size=0.3):
    return {
        "bodies": {
            "hanging": {"regions": [{"shape": {"box": BLOCK, "intersect": [{"halfspace": FAULT}]}}]},
            "foot": {"regions": [{"shape": {"box": BLOCK, "minus": [{"halfspace": FAULT}]}}]},
        },
        "boundaries": {
            "fault_h": {"plane": FAULT, "body": "hanging"},
            "fault_f": {"plane": FAULT, "body": "foot"},
            "bottom": {"plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}},
            "bottom_foot": {"plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}, "body": "foot"},
            "right": {"box": [2, -1, -1, 2, 2, 2]},
        },
        "mesh": {"size": size},
    }


def build_mesh3d(scene):
    """The scene (geometry only) as a study's 3D scene block, loaded by the study loader and meshed."""
    bodies = {b: {**spec, "regions": [{**r, "material": "m"} for r in spec["regions"]]}
              for b, spec in scene["bodies"].items()}
    return mesh_typed(load_scene({**scene, "dimension": 3, "bodies": bodies,
                                  "materials": {"m": {"E": 1e9, "nu": 0.3}}}))


def facet_areas(mesh, facets):
    x = mesh.p[:, mesh.facets[:, facets]]
    return 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], axis=0), axis=0)


@pytest.fixture(scope="module")
def fault():
    return build_mesh3d(fault_scene())


def test_fault_block_has_matching_faces_with_duplicated_nodes(fault):
    m = fault.mesh
    h, f = fault.boundaries["fault_h"], fault.boundaries["fault_f"]
    nh, nf = np.unique(m.facets[:, h]), np.unique(m.facets[:, f])
    assert np.intersect1d(nh, nf).size == 0                           # each body its own nodes
    assert (fault.node_body[nh] == 0).all() and (fault.node_body[nf] == 1).all()
    # the same points on both sides, and the same triangles
    xh, xf = m.p[:, nh].T, m.p[:, nf].T
    assert xh.shape == xf.shape
    assert np.array_equal(xh[np.lexsort(xh.T)], xf[np.lexsort(xf.T)])
    tri = lambda fs: sorted(tuple(sorted(map(tuple, m.p[:, m.facets[:, k]].T))) for k in fs)
    assert tri(h) == tri(f)
    # the fault is the rectangle √2 × 1; each body has volume 1 (x ≤ z + 1/2 and its complement)
    assert facet_areas(m, h).sum() == pytest.approx(np.sqrt(2.0), rel=1e-12)
    vol = volumes(m.p, m.t)
    assert vol.min() > 0
    assert np.bincount(fault.cell_body, weights=vol) == pytest.approx([1.0, 1.0], rel=1e-12)


def test_face_selectors_pick_the_right_faces(fault):
    m = fault.mesh
    bottom = fault.boundaries["bottom"]
    assert facet_areas(m, bottom).sum() == pytest.approx(2.0, rel=1e-12)
    # the foot's part of z = 0: x from 0.5 to 2
    assert facet_areas(m, fault.boundaries["bottom_foot"]).sum() == pytest.approx(1.5, rel=1e-12)
    assert np.allclose(m.p[2, m.facets[:, bottom]], 0.0, atol=1e-12)
    r = fault.boundaries["right"]
    assert facet_areas(m, r).sum() == pytest.approx(1.0, rel=1e-12)
    assert np.allclose(m.p[0, m.facets[:, r]], 2.0, atol=1e-12)
    assert (fault.node_body[m.facets[0, r]] == 1).all()               # x = 2 is the foot's
    # a boundary as a region of interest, restricted to a body (the 2D selector, unchanged)
    sel = selectors.select_region(fault, RegionOfInterest.model_validate({"boundary": "bottom", "body": "foot"}), "roi")
    assert sel.kind == "facets" and np.array_equal(sel.index, fault.boundaries["bottom_foot"])


def test_mesh_is_deterministic(fault):
    again = build_mesh3d(fault_scene())
    assert np.array_equal(again.mesh.p, fault.mesh.p) and np.array_equal(again.mesh.t, fault.mesh.t)
    assert all(np.array_equal(again.boundaries[k], v) for k, v in fault.boundaries.items())


def test_tunnel_wall_nodes_lie_on_the_cylinder_and_ball_region_is_embedded():
    r, length = 0.5, 3.0
    scene = {
        "bodies": {"rock": {"regions": [{"shape": {
            "box": [-2, 0, -2, 2, length, 2],
            "minus": [{"cylinder": {"start": [0, -1, 0], "end": [0, length + 1, 0], "radius": r}}]}}]}},
        "boundaries": {"wall": {"cylinder": {"start": [0, 0, 0], "end": [0, length, 0], "radius": r}}},
        "regions_of_interest": {"near": {"ball": {"center": [1.0, 1.5, 0.0], "radius": 0.4}}},
        "mesh": {"size": 0.8},
    }
    sm = build_mesh3d(scene)
    m = sm.mesh
    wall = sm.boundaries["wall"]
    x = m.p[:, np.unique(m.facets[:, wall])]
    assert np.abs(np.hypot(x[0], x[2]) - r).max() < 1e-9 * r
    assert x[1].min() == pytest.approx(0.0, abs=1e-12) and x[1].max() == pytest.approx(length, rel=1e-12)
    # an inscribed polyhedron of ≥ 24 segments per turn: area within (2π/24)²/6 ≈ 1.2 % below 2πrL
    ratio = facet_areas(m, wall).sum() / (2 * np.pi * r * length)
    assert 0.985 < ratio < 1.0
    # the whole tunnel wall: no other boundary facet has its nodes on the cylinder
    others = np.setdiff1d(m.boundary_facets(), wall)
    y = m.p[:, m.facets[:, others]]
    assert (np.abs(np.hypot(y[0], y[2]) - r) > 1e-6).any(axis=0).all()
    # the ball is embedded: its cells fill an inscribed polyhedron of the ball, nothing outside it
    cells = sm.roi_cells["near"]
    vol = volumes(m.p, m.t[:, cells]).sum()
    assert 0.9 < vol / (4 / 3 * np.pi * 0.4**3) < 1.0
    c = m.p[:, m.t[:, cells]]
    assert (np.linalg.norm(c - np.array([1.0, 1.5, 0.0])[:, None, None], axis=0) <= 0.4 * (1 + 1e-9)).all()
    assert volumes(m.p, m.t).sum() == pytest.approx(16 * length - np.pi * r**2 * length, rel=0.01)


def test_sphere_on_an_extruded_block_two_bodies_and_regions():
    """A sphere resting on a block made by extruding a square: a touching point only, so the
    bodies share no face; two regions of the block (split at z = −0.5) share their nodes."""
    square = {"polygon": [[-1, -1], [1, -1], [1, 1], [-1, 1]]}
    scene = {
        "bodies": {
            "ball": {"regions": [{"shape": {"sphere": {"center": [0, 0, 0.5], "radius": 0.5}}}]},
            "block": {"regions": [
                {"name": "lower", "shape": {"extrude": {"shape": square, "vector": [0, 0, -1]},
                                            "minus": [{"box": [-1, -1, -0.5, 1, 1, 0]}]}},
                {"name": "upper", "shape": {"box": [-1, -1, -0.5, 1, 1, 0]}}]},
        },
        "boundaries": {"surface": {"sphere": {"center": [0, 0, 0.5], "radius": 0.5}, "body": "ball"},
                       "top": {"plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}, "body": "block"}},
        "mesh": {"size": 0.4},
    }
    sm = build_mesh3d(scene)
    m = sm.mesh
    vol = np.bincount(sm.cell_region, weights=volumes(m.p, m.t))
    assert vol[1:] == pytest.approx([2.0, 2.0], rel=1e-12)            # lower z ∈ [−1, −0.5], upper above
    assert 0.95 < vol[0] / (np.pi / 6) < 1.0
    s = np.unique(m.facets[:, sm.boundaries["surface"]])
    assert np.abs(np.linalg.norm(m.p[:, s] - np.array([[0], [0], [0.5]]), axis=0) - 0.5).max() < 1e-9
    ball_faces = m.boundary_facets()[sm.node_body[m.facets[0, m.boundary_facets()]] == 0]
    assert np.array_equal(np.sort(sm.boundaries["surface"]), np.sort(ball_faces))   # the whole surface
    assert facet_areas(m, sm.boundaries["top"]).sum() == pytest.approx(4.0, rel=1e-12)
    lower, upper = (np.unique(m.t[:, sm.cell_region == k]) for k in (1, 2))
    assert np.intersect1d(lower, upper).size > 0                      # regions of a body: one mesh


def test_bodies_with_their_own_sizes_have_nonmatching_faces():
    """A block on a block, sizes 2:1: the common face z = 0 is meshed once per body (different
    nodes), both sides cover it exactly; regions of interest are embedded in each body."""
    scene = {
        "bodies": {"top": {"regions": [{"shape": {"box": [0, 0, 0, 1, 1, 0.5]}}], "mesh": {"size": 0.25}},
                   "base": {"regions": [{"shape": {"box": [-0.5, -0.5, -0.5, 1.5, 1.5, 0]}}]}},
        "boundaries": {"lower": {"plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}, "body": "top"},
                       "upper": {"box": [-1, -1, 0, 2, 2, 0], "body": "base"}},
        "regions_of_interest": {"under": {"box": [0.2, 0.2, -0.2, 0.8, 0.8, 0.0], "body": "base"}},
        "mesh": {"size": 0.125},
    }
    sm = build_mesh3d(scene)
    m = sm.mesh
    lower, upper = (np.unique(m.facets[:, sm.boundaries[k]]) for k in ("lower", "upper"))
    inside = upper[(m.p[:2, upper] >= 0).all(axis=0) & (m.p[:2, upper] <= 1).all(axis=0)]
    assert 2 * lower.size < inside.size                              # a coarser side
    assert facet_areas(m, sm.boundaries["lower"]).sum() == pytest.approx(1.0, rel=1e-12)
    # the base is meshed without the top's imprint: its whole top face, 2 × 2
    assert facet_areas(m, sm.boundaries["upper"]).sum() == pytest.approx(4.0, rel=1e-12)
    vol = volumes(m.p, m.t)
    assert np.bincount(sm.cell_body, weights=vol) == pytest.approx([0.5, 2.0], rel=1e-12)
    assert vol[sm.roi_cells["under"]].sum() == pytest.approx(0.6 * 0.6 * 0.2, rel=1e-12)
    assert (sm.cell_body[sm.roi_cells["under"]] == 1).all()
    again = build_mesh3d(scene)
    assert np.array_equal(again.mesh.p, m.p) and np.array_equal(again.mesh.t, m.t)


@pytest.mark.parametrize("change, path", [
    (lambda s: s["bodies"]["foot"]["regions"][0].update(shape={"box": BLOCK}), "scene.bodies.foot"),
    (lambda s: s["bodies"]["foot"]["regions"][0].update(shape={"halfspace": FAULT}),
     "scene.bodies.foot.regions.0.shape.halfspace"),
    (lambda s: s["boundaries"].update(none={"plane": {"point": [0, 0, 5], "normal": [0, 0, 1]}}),
     "scene.boundaries.none"),
    (lambda s: s["bodies"]["foot"]["regions"][0]["shape"].update(box=[0, 0, 0, 2, 1, -1]),
     "scene.bodies.foot.regions.0.shape.box"),
    (lambda s: s["bodies"]["foot"]["regions"][0].update(
        shape={"box": [3, 0, 0, 4, 1, 1], "minus": [{"box": [3.4, -1, -1, 3.6, 2, 2]}]}), "scene.bodies.foot"),
    (lambda s: s["bodies"]["foot"].update(mesh={"size": -1.0}), "scene.bodies.foot.mesh.size"),
    (lambda s: s["bodies"]["foot"]["regions"].append({"shape": {"box": [1.5, 0.2, 0.2, 1.9, 0.8, 0.4]}}),
     "scene.bodies.foot.regions.1"),                  # a second region inside the first: an overlap
    (lambda s: s["boundaries"].update(c={"cylinder": {"start": [0, 0, 0], "end": [0, 0, 0], "radius": 1}}),
     "scene.boundaries.c.cylinder"),
])
def test_bad_input_is_a_study_error_at_its_path(change, path):
    scene = fault_scene(size=0.5)
    change(scene)
    with pytest.raises(StudyError) as err:
        build_mesh3d(scene)
    assert err.value.path == path
