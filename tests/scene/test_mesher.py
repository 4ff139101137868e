"""Geometry, meshing and selectors (wcs.scene)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.support.scenes import typed_scene
from wcs.errors import StudyError
from wcs.scene import mesher2d as mesher
from wcs.scene import selectors
from wcs.geometry.facets import facet_lengths, facet_normals, nodal_normals
from wcs.scene.selectors import Selection
from wcs.scene.spec import Boundary, RegionOfInterest

ROOT = Path(__file__).resolve().parents[2]


def build_mesh(sc, *args, **kw):
    """The mesh of a test's scene mapping, typed as the loader hands it on."""
    return mesher.build_mesh(typed_scene(sc), *args, **kw)


def select_region(sm, spec, path, **kw):
    return selectors.select_region(sm, RegionOfInterest.model_validate(spec), path, **kw)


def select_boundary(sm, spec, path, **kw):
    return selectors.select_boundary(sm, Boundary.model_validate(spec), path, **kw)


def scene(bodies, size=0.25, boundaries=None, refine=None):
    mesh = {"size": size}
    if refine:
        mesh["refine"] = refine
    return {"dimension": 2, "plane": "strain", "mesh": mesh, "bodies": bodies,
            "boundaries": boundaries or {}}


def one(shape, **kw):
    return scene({"b": {"regions": [{"material": "m", "shape": shape}]}}, **kw)


def signed_areas(m):
    p, t = m.p, m.t
    d1 = p[:, t[1]] - p[:, t[0]]
    d2 = p[:, t[2]] - p[:, t[0]]
    return 0.5 * (d1[0] * d2[1] - d1[1] * d2[0])


def polygon_area_of_circle(r, n):
    return 0.5 * n * r * r * math.sin(2 * math.pi / n)


@pytest.fixture(scope="module")
def demo():
    sc = yaml.safe_load((ROOT / "studies" / "two-blocks-demo.yaml").read_text())["scene"]
    return sc, build_mesh(sc)


# --------------------------------------------------------------------------- shapes

DISC = {"disc": {"center": [0.0, 0.0], "radius": 1.0}}


@pytest.mark.parametrize("shape, area, rtol", [
    ({"rectangle": [0.0, 0.0, 2.0, 1.0]}, 2.0, 1e-12),
    ({"polygon": [[0, 0], [2, 0], [2, 1], [1, 2], [0, 1]]}, 3.0, 1e-12),
    (DISC, math.pi, 0.02),
    ({"rectangle": [-2, -2, 2, 2], "minus": [DISC]}, 16 - math.pi, 0.005),          # tunnel
    ({**DISC, "intersect": [{"rectangle": [-2, 0, 2, 2]}]}, math.pi / 2, 0.02),      # half-cylinder
    ({"rectangle": [0, 0, 3, 1], "minus": [{"rectangle": [1, -1, 2, 0.5]},
                                          {"rectangle": [0, 0.5, 0.5, 1]}]}, 2.25, 1e-12),
    ({"rectangle": [-1, -1, 1, 1],                                                   # nested booleans
      "intersect": [{**DISC, "minus": [{"disc": {"center": [0, 0], "radius": 0.5}}]}]},
     0.75 * math.pi, 0.03),
])
def test_shapes(shape, area, rtol):
    sm = build_mesh(one(shape))
    a = signed_areas(sm.mesh)
    assert (a > 0).all(), "cells must be counter-clockwise"
    assert a.sum() == pytest.approx(area, rel=rtol)
    # every node is used by a cell, numbering compact
    assert np.array_equal(np.unique(sm.mesh.t), np.arange(sm.mesh.p.shape[1]))
    assert sm.bodies == ["b"] and sm.regions == [("b", "b_0")]
    assert (sm.cell_body == 0).all() and (sm.cell_region == 0).all()


def test_coarse_disc_is_round():
    # size 0.5, the coarsest the loader allows on a disc of diameter 2, gives ~13 edges; the
    # curvature rule gives the circle its 24
    sc = one(DISC, size=0.5, boundaries={"rim": {"circle": {"center": [0, 0], "radius": 1.0}}})
    sm = build_mesh(sc)
    n = len(sm.boundaries["rim"])
    assert n >= 24
    assert signed_areas(sm.mesh).sum() >= polygon_area_of_circle(1.0, 24) * (1 - 1e-12)


def test_tunnel_circle_boundary_length():
    r = 0.3
    sc = one({"rectangle": [0, 0, 2, 2], "minus": [{"disc": {"center": [1, 1], "radius": r}}]},
             size=0.1, boundaries={"tunnel": {"circle": {"center": [1, 1], "radius": r}}})
    sm = build_mesh(sc)
    f = sm.boundaries["tunnel"]
    assert facet_lengths(sm.mesh, f).sum() == pytest.approx(2 * math.pi * r, rel=0.01)
    # outward normals of the tunnel wall point into the hole (towards the centre)
    m = sm.mesh
    mid = m.p[:, m.facets[:, f]].mean(axis=1)
    radial = (mid - np.array([[1.0], [1.0]])) / r
    assert np.all(np.einsum("ij,ji->i", facet_normals(m, f), radial) < -0.99)


def test_regions_share_nodes():
    zone = {"disc": {"center": [1.0, 0.5], "radius": 0.3}}
    sc = scene({"rock": {"regions": [
        {"material": "m", "shape": {"rectangle": [0, 0, 2, 1], "minus": [zone]}},
        {"material": "w", "name": "weak", "shape": zone}]}}, size=0.1)
    sm = build_mesh(sc)
    assert sm.regions == [("rock", "rock_0"), ("rock", "weak")]
    m = sm.mesh
    a = signed_areas(m)
    assert a.sum() == pytest.approx(2.0, rel=1e-12)
    c = m.p[:, m.t].mean(axis=1)
    inside = np.hypot(c[0] - 1.0, c[1] - 0.5) < 0.3
    assert np.array_equal(inside, sm.cell_region == 1)
    assert a[sm.cell_region == 1].sum() == pytest.approx(math.pi * 0.09, rel=0.02)
    # glued: no duplicated coordinates inside one body
    assert np.unique(m.p.T, axis=0).shape[0] == m.p.shape[1]
    assert sm.region_index("weak") == 1


# --------------------------------------------------------------------------- demo scene


def test_demo_bodies_and_duplicated_interface(demo):
    sc, sm = demo
    m = sm.mesh
    assert sm.bodies == ["base", "pad"]
    assert sm.regions == [("base", "base_0"), ("pad", "pad_0")]
    assert set(np.unique(sm.cell_body)) == {0, 1}
    assert np.all(np.diff(sm.cell_body) >= 0)
    nb = sm.node_body
    assert (nb >= 0).all()
    top, bot = sm.boundary_nodes("base_top"), sm.boundary_nodes("pad_bottom")
    assert (nb[top] == 0).all() and (nb[bot] == 1).all()
    assert not set(top) & set(bot)
    # same coordinates, different ids
    order_t = np.lexsort(m.p[:, top])
    order_b = np.lexsort(m.p[:, bot])
    assert np.array_equal(m.p[:, top][:, order_t], m.p[:, bot][:, order_b])
    # no cell of one body uses a node of another
    assert np.all(nb[m.t] == sm.cell_body[None, :])
    # the two bodies do not share facets: interface facets are boundary facets
    bf = set(m.boundary_facets())
    assert set(sm.boundaries["base_top"]) <= bf and set(sm.boundaries["pad_bottom"]) <= bf
    assert (signed_areas(m) > 0).all()
    assert signed_areas(m).sum() == pytest.approx(2.5, rel=1e-12)


def test_demo_boundaries(demo):
    sc, sm = demo
    m = sm.mesh
    for name, spec in sc["boundaries"].items():
        f = sm.boundaries[name]
        assert f.size > 0 and np.all(np.diff(f) > 0)
        (x0, y0), (x1, y1) = spec["segment"]
        L = math.hypot(x1 - x0, y1 - y0)
        assert facet_lengths(m, f).sum() == pytest.approx(L, rel=1e-12)
        assert len(f) >= round(L / sc["mesh"]["size"])          # at least one edge per size
        body = sm.bodies.index(spec["body"])
        assert np.all(sm.cell_body[m.f2t[0, f]] == body)
    # refine box [0.4, 0.9, 1.6, 1.1] at 0.01 covers the interface
    assert len(sm.boundaries["base_top"]) >= 90
    assert len(sm.boundaries["base_bottom"]) <= 2 * 2.0 / sc["mesh"]["size"]


def test_refine_box_increases_density():
    base = one({"rectangle": [0, 0, 2, 1]}, size=0.1)
    ref = one({"rectangle": [0, 0, 2, 1]}, size=0.1,
              refine=[{"box": [0.8, 0.3, 1.2, 0.7], "size": 0.02}])
    m0, m1 = build_mesh(base).mesh, build_mesh(ref).mesh

    def count_in_box(m):
        c = m.p[:, m.t].mean(axis=1)
        return int(np.sum((c[0] > 0.8) & (c[0] < 1.2) & (c[1] > 0.3) & (c[1] < 0.7)))

    n0, n1 = count_in_box(m0), count_in_box(m1)
    assert n1 > 10 * n0
    # size inside the box ~ 0.02: box area 0.16 / (sqrt(3)/4 * 0.02**2) ~ 920 cells
    assert 500 < n1 < 2000
    # far away the mesh stays coarse
    a1 = signed_areas(m1)
    c = m1.p[:, m1.t].mean(axis=1)
    far = c[0] < 0.2
    assert np.median(a1[far]) > 0.5 * np.median(signed_areas(m0))


def test_refine_near_boundary():
    sc = one({"rectangle": [0, 0, 2, 1]}, size=0.2,
             boundaries={"top": {"segment": [[0, 1], [2, 1]]}, "bottom": {"segment": [[0, 0], [2, 0]]}},
             refine=[{"boundary": "top", "size": 0.02}])
    sm = build_mesh(sc)
    assert len(sm.boundaries["top"]) >= 90
    assert len(sm.boundaries["bottom"]) <= 20


def test_deterministic(demo):
    sc, sm = demo
    sm2 = build_mesh(sc)
    assert np.array_equal(sm.mesh.p, sm2.mesh.p)
    assert np.array_equal(sm.mesh.t, sm2.mesh.t)
    assert np.array_equal(sm.cell_region, sm2.cell_region)
    for k in sm.boundaries:
        assert np.array_equal(sm.boundaries[k], sm2.boundaries[k])


# --------------------------------------------------------------------------- errors


def test_overlapping_bodies():
    sc = scene({"a": {"regions": [{"material": "m", "shape": {"rectangle": [0, 0, 1, 1]}}]},
                "b": {"regions": [{"material": "m", "shape": {"rectangle": [0.5, 0.5, 2, 2]}}]}})
    with pytest.raises(StudyError) as e:
        build_mesh(sc)
    assert e.value.path == "scene.bodies.b"


def test_overlapping_regions_of_a_body():
    """A later region inside an earlier one of the same body would take the common area by the
    order of the file (the earlier region's data silently lost there): refused at the later one."""
    sc = scene({"a": {"regions": [{"material": "m", "shape": {"rectangle": [0, 0, 2, 1]}},
                                  {"material": "m", "shape": {"rectangle": [0.5, 0.25, 1.5, 0.75]}}]}})
    with pytest.raises(StudyError, match=r"overlaps region 'a_0' of body 'a' \(common area 0.5\)") as e:
        build_mesh(sc)
    assert e.value.path == "scene.bodies.a.regions.1"


def test_regions_of_a_body_may_touch():
    sc = scene({"a": {"regions": [{"material": "m", "shape": {"rectangle": [0, 0, 1, 1]}},
                                  {"material": "m", "shape": {"rectangle": [1, 0, 2, 1]}}]}})
    assert build_mesh(sc).regions == [("a", "a_0"), ("a", "a_1")]


def test_touching_bodies_are_fine():
    sc = scene({"a": {"regions": [{"material": "m", "shape": {"rectangle": [0, 0, 1, 1]}}]},
                "b": {"regions": [{"material": "m", "shape": {"rectangle": [1, 0.5, 2, 2]}}]}})
    sm = build_mesh(sc)
    assert sm.bodies == ["a", "b"]


def test_empty_shape():
    sc = one({**DISC, "minus": [{"disc": {"center": [0, 0], "radius": 2.0}}]})
    with pytest.raises(StudyError) as e:
        build_mesh(sc)
    assert e.value.path == "scene.bodies.b.regions.0.shape"


def test_selector_selecting_nothing():
    sc = one({"rectangle": [0, 0, 1, 1]}, boundaries={
        "ok": {"segment": [[0, 0], [1, 0]]},
        "nothing": {"segment": [[0, 0.5], [1, 0.5]]}})      # interior line: no boundary edge
    with pytest.raises(StudyError) as e:
        build_mesh(sc)
    assert e.value.path == "scene.boundaries.nothing"


# --------------------------------------------------------------------------- selectors and normals


def test_region_selectors(demo):
    """Box and polygon regions cut the cells exactly (the cut area is the region's), a
    disc needs the mesh to embed it, a boundary region is its facets."""
    sc, sm = demo
    s = select_region(sm, {"box": [0.93, 0.91, 1.07, 1.0]}, "scene.regions_of_interest.under_pad")
    assert s.kind == "cells" and len(s) > 0
    assert np.all(sm.cell_body[s.index] == 0)
    assert s.cell_moments(sm.mesh).sum() == pytest.approx(0.14 * 0.09, rel=1e-12)
    s3 = select_region(sm, {"polygon": [[0, 0], [2, 0], [0, 1]]}, "x")
    assert s3.cell_moments(sm.mesh).sum() == pytest.approx(1.0, rel=1e-12)
    with pytest.raises(StudyError, match="disc cannot be cut") as e:
        select_region(sm, {"disc": {"center": [1.0, 1.0], "radius": 0.1}, "body": "pad"}, "x")
    assert e.value.path == "x.disc"
    s4 = select_region(sm, {"boundary": "pad_left"}, "x")
    assert isinstance(s4, Selection) and s4.kind == "facets"
    assert np.array_equal(s4.index, sm.boundaries["pad_left"])
    with pytest.raises(StudyError) as e:
        select_region(sm, {"box": [5, 5, 6, 6]}, "scene.regions_of_interest.far")
    assert e.value.path == "scene.regions_of_interest.far"
    with pytest.raises(StudyError):
        select_region(sm, {"box": [0.9, 0.9, 1.1, 1.0], "body": "pad"}, "x")


@pytest.mark.parametrize("own_size", [None, {"size": 0.2}])
def test_regions_of_interest_are_embedded(own_size):
    """A box, disc and polygon region of interest are unions of cells: their area is the
    shape's (the disc: the mesh's polygon, as for a disc body); a body restricts them. Also
    when a body has its own mesh size (bodies meshed one by one)."""
    sc = scene({"a": {"regions": [{"material": "m", "shape": {"rectangle": [0, 0, 2, 1]}}]},
                "b": {"regions": [{"material": "m", "shape": {"rectangle": [0, 1, 2, 2]}}]}}, size=0.3)
    if own_size:
        sc["bodies"]["b"]["mesh"] = own_size
    sc["regions_of_interest"] = {
        "box": {"box": [0.37, 0.21, 1.53, 1.62]},
        "box_a": {"box": [0.37, 0.21, 1.53, 1.62], "body": "a"},
        "poly": {"polygon": [[0.1, 0.1], [1.9, 0.3], [0.4, 0.8]]},
        "disc": {"disc": {"center": [1.0, 1.0], "radius": 0.45}},
        "outside": {"box": [1.5, 1.5, 3.0, 3.0]}}
    sm = build_mesh(sc)
    area = lambda name: signed_areas(sm.mesh)[sm.roi_cells[name]].sum()  # noqa: E731
    assert area("box") == pytest.approx(1.16 * 1.41, rel=1e-12)
    assert area("box_a") == pytest.approx(1.16 * 0.79, rel=1e-12)
    assert area("poly") == pytest.approx(0.5 * abs(1.8 * 0.7 - 0.2 * 0.3), rel=1e-12)
    assert area("outside") == pytest.approx(0.5 * 0.5, rel=1e-12)        # only its part in the scene
    r = np.hypot(*(sm.mesh.p[:, np.unique(sm.mesh.t[:, sm.roi_cells["disc"]])] - 1.0))
    assert r.max() == pytest.approx(0.45, rel=1e-9)                       # inscribed in the circle
    assert math.pi * 0.45 ** 2 * 0.97 < area("disc") < math.pi * 0.45 ** 2
    assert signed_areas(sm.mesh).sum() == pytest.approx(4.0, rel=1e-12)   # nothing outside the bodies


def test_boundary_selector_box_and_body(demo):
    sc, sm = demo
    both = select_boundary(sm, {"segment": [[0.5, 1.0], [1.5, 1.0]]}, "x")
    assert np.array_equal(both, np.union1d(sm.boundaries["base_top"], sm.boundaries["pad_bottom"]))
    box = select_boundary(sm, {"box": [-0.1, -0.1, 2.1, 0.01], "body": "base"}, "x")
    assert np.array_equal(box, sm.boundaries["base_bottom"])


def test_rectangle_normals(demo):
    sc, sm = demo
    n = facet_normals(sm.mesh, sm.boundaries["base_bottom"])
    assert np.allclose(n, [0.0, -1.0], atol=1e-14)
    n = facet_normals(sm.mesh, sm.boundaries["pad_bottom"])
    assert np.allclose(n, [0.0, -1.0], atol=1e-14)
    n = facet_normals(sm.mesh, sm.boundaries["base_top"])
    assert np.allclose(n, [0.0, 1.0], atol=1e-14)


def test_inclined_boundary_nodal_normals():
    # trapezoid with an inclined right side from (2, 0) to (1, 1)
    sc = one({"polygon": [[0, 0], [2, 0], [1, 1], [0, 1]]}, size=0.1,
             boundaries={"slope": {"segment": [[2, 0], [1, 1]]}})
    sm = build_mesh(sc)
    f = sm.boundaries["slope"]
    assert facet_lengths(sm.mesh, f).sum() == pytest.approx(math.sqrt(2), rel=1e-12)
    nodes, nn = nodal_normals(sm.mesh, f)
    assert len(nodes) == len(f) + 1
    expected = np.array([1.0, 1.0]) / math.sqrt(2)
    assert np.allclose(nn, expected, atol=1e-12)
    assert np.allclose(facet_normals(sm.mesh, f), expected, atol=1e-12)


def test_nodal_normals_on_circle():
    sc = one(DISC, size=0.1, boundaries={"rim": {"circle": {"center": [0, 0], "radius": 1.0}}})
    sm = build_mesh(sc)
    nodes, nn = nodal_normals(sm.mesh, sm.boundaries["rim"])
    radial = sm.mesh.p[:, nodes].T
    assert np.allclose(np.linalg.norm(nn, axis=1), 1.0)
    assert np.all(np.einsum("ij,ij->i", nn, radial) > 1 - 1e-3)
