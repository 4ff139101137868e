"""Criterion values in 3D against independent computations: volume and face means over regions
of interest embedded in the tetrahedra, the normal from the face, the stress densities and their
derivatives with six components, and the contact pressure Φ6 on the slave triangles.

Tolerances: the regions are embedded in the mesh, so a box's volume and a face's area are exact
to round-off (1e-12 relative); a mean is a ratio of sums of a few thousand terms (1e-12
relative); derivatives against central differences of step 1e-6 relative (truncation ~1e-12,
round-off ~1e-10 of the value): 1e-7."""
from types import SimpleNamespace

import numpy as np
import pytest

import wcs
from tests.model.test_adjoint_3d import two_region_block
from wcs.model import criteria, regions
from wcs.errors import StudyError
from wcs.geometry import tet
from wcs.scene.mesher3d import build_mesh3d
from wcs.scene.selectors import Selection
from wcs.study import load_scene


@pytest.fixture(scope="module")
def block():
    study = wcs.load_study(two_region_block())
    ev = study.evaluate(study.nominal())
    assert ev.status == 0
    return study, ev


def test_volume_and_face_means_are_the_exact_means_over_the_embedded_regions(block):
    """T_vol over the box [0.8, 1.2]×[0.3, 0.7]×[0.6, 0.9] (and the ball): Σ|T| T̄_T / Σ|T| with
    the cells whose centroid is in the box, |T| from numpy's determinant; T_face over the top
    face z = 1 (area 2): Σ |F| T̄_F / Σ |F|; 'lift' is the mean of u_z over the top (the outward
    normal of the top face is +z), 'settle' the mean of u_z over the ball (X_r on the top)."""
    study, ev = block
    sm, state = ev.evaluator.smesh, ev.state
    p, t = sm.mesh.p, sm.mesh.t
    x = p[:, t]                                                        # (3, 4, ncells)
    vol = np.abs(np.linalg.det(np.moveaxis(x[:, 1:] - x[:, :1], -1, 0))) / 6.0
    c = x.mean(axis=1)
    box = np.all((c.T > [0.8, 0.3, 0.6]) & (c.T < [1.2, 0.7, 0.9]), axis=1)
    assert abs(vol[box].sum() - 0.4 * 0.4 * 0.3) <= 1e-12
    Tbar = state.T[t].mean(axis=0)
    ball = np.linalg.norm(c.T - [1.4, 0.5, 0.85], axis=1) < 0.15
    assert 0.95 < vol[ball].sum() / (4 / 3 * np.pi * 0.15**3) < 1.0          # an inscribed polyhedron
    means = [vol[s] @ Tbar[s] / vol[s].sum() for s in (box, ball)]
    assert ev.phi["T_vol"] == pytest.approx(max(means), rel=1e-12)
    top = sm.boundaries["top"]
    f = p[:, sm.mesh.facets[:, top]]                                   # (3, 3, n)
    area = 0.5 * np.linalg.norm(np.cross(f[:, 1] - f[:, 0], f[:, 2] - f[:, 0], axis=0), axis=0)
    assert abs(area.sum() - 2.0) <= 1e-12
    nodes = sm.mesh.facets[:, top]
    assert ev.phi["T_face"] == pytest.approx(area @ state.T[nodes].mean(axis=0) / area.sum(), rel=1e-12)
    uz = state.u[2::3]
    assert ev.phi["lift"] == pytest.approx(area @ uz[nodes].mean(axis=0) / area.sum(), rel=1e-12)
    assert ev.phi["settle"] == pytest.approx(vol[ball] @ uz[t[:, ball]].mean(axis=0) / vol[ball].sum(), rel=1e-12)
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    un = np.stack([state.u[i::3] for i in range(3)]).T @ d
    cells = ev.evaluator.criteria[4].selections[0].index          # the cylinder's cells
    assert ev.phi["shift"] == pytest.approx(vol[cells] @ un[t[:, cells]].mean(axis=0) / vol[cells].sum(), rel=1e-12)


def test_stress_criteria_are_volume_means_of_the_six_component_invariants(block):
    """von Mises and σ₁ from numpy's eigenvalues of the 3×3 tensors (not wcs's formulas)."""
    study, ev = block
    sm, s = ev.evaluator.smesh, ev.state.stress
    assert s.shape == (6, sm.mesh.t.shape[1])
    xx, yy, zz, yz, xz, xy = s
    T = np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], -2)
    w = np.linalg.eigvalsh(T)
    dev = T - np.trace(T, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    I2 = np.einsum("cij,cij->c", dev, dev)
    vol = tet.volumes(sm.mesh.p, sm.mesh.t)
    for name, density in (("mises", np.sqrt(1.5 * I2)), ("s1", w[:, 2])):
        crit = next(c for c in ev.evaluator.criteria if c.name == name)
        cells = crit.selections[0].index
        assert ev.phi[name] == pytest.approx(vol[cells] @ density[cells] / vol[cells].sum(), rel=1e-12)
    crit = next(c for c in ev.evaluator.criteria if c.name == "shear")
    means = [vol[sel.index] @ I2[sel.index] / vol[sel.index].sum() for sel in crit.selections]
    assert ev.phi["shear"] == pytest.approx(max(means), rel=1e-12)


def _fd(density, s, h=1e-6):
    """Central differences of density (per column) along each of the six components."""
    scale = np.abs(s).max()
    out = []
    for i in range(6):
        e = np.zeros_like(s)
        e[i] = h * scale
        out.append((density(s + e) - density(s - e)) / (2 * h * scale))
    return np.array(out)


def test_stress_density_derivatives_in_3d():
    """∂I₂²/∂τ, ∂σ_vM/∂τ and ∂σ₁/∂τ (v vᵀ) against central differences on random tensors; at a
    double largest eigenvalue σ₁ has a kink (flagged), a simple one none."""
    rng = np.random.default_rng(1)
    s = rng.standard_normal((6, 20)) * 1e6
    for density, derivative in ((tet.shear_intensity, criteria._dI2), (tet.von_mises, criteria._dvon_mises),
                                (criteria._principal_max, criteria._dprincipal_max)):
        fd, ad = _fd(density, s), derivative(s)
        assert np.abs(ad - fd).max() <= 1e-7 * np.abs(fd).max()
    assert not criteria._principal_kink(s).any()
    double = np.array([[2.0, 1.0], [2.0, 1.0], [-1.0, 3.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]) * 1e6
    assert criteria._principal_kink(double).tolist() == [True, False]
    # at the kink: the mean of the two tied projectors e_x e_xᵀ, e_y e_yᵀ (the one-sided mean)
    assert np.allclose(criteria._dprincipal_max(double)[:, 0], [0.5, 0.5, 0, 0, 0, 0], atol=1e-12)


def test_normal_from_a_point_on_the_face_and_refusals(block):
    """n(X_r) from the face under X_r; X_r off the boundary and X_r on an edge of the block (two
    faces at 90°) are refused at the criterion's `point`, with the distance / the reason."""
    study, ev = block
    sm = ev.evaluator.smesh
    scene = study.scene
    spec = SimpleNamespace(direction=None, point=[1.4, 0.5, 1.0])
    sel = Selection("cells", sm.roi_cells["knot"])
    assert np.allclose(regions._direction(sm, spec, sel, "criteria.2", "knot"), [0, 0, 1], atol=1e-14)
    spec = SimpleNamespace(direction=None, point=[1.0, 0.5, 0.5])          # the centre of the block
    with pytest.raises(StudyError, match="not on the boundary .* nearest boundary face is 0.5 away") as e:
        regions._direction(sm, spec, sel, "criteria.2", "knot")
    assert e.value.path == "criteria.2.point"
    spec = SimpleNamespace(direction=None, point=[2.0, 0.5, 1.0])           # the edge x = 2, z = 1
    with pytest.raises(StudyError, match="differ by more than 30°"):
        regions._direction(sm, spec, sel, "criteria.2", "knot")
    assert scene.dimension == 3
    d = two_region_block()
    d["criteria"][2]["point"] = [1.4, 0.5]
    with pytest.raises(StudyError, match="point needs 3 coordinates in a 3D scene, got 2") as e:
        wcs.load_study(d)
    assert e.value.path == "criteria.2.point"


# ---------------------------------------------------------------- Φ6 on the slave triangles

def _contact_mesh(roi):
    """Two unit blocks touching on z = 1 (matching triangles), the region of interest `roi`."""
    scene = load_scene({
        "dimension": 3, "mesh": {"size": 0.25},
        "materials": {"m": {"E": 1e9, "nu": 0.3}},
        "bodies": {"base": {"regions": [{"material": "m", "shape": {"box": [0, 0, 0, 1, 1, 1]}}]},
                   "pad": {"regions": [{"material": "m", "shape": {"box": [0, 0, 1, 1, 1, 2]}}]}},
        "boundaries": {"pad_bottom": {"plane": {"point": [0, 0, 1], "normal": [0, 0, 1]}, "body": "pad"},
                       "base_top": {"plane": {"point": [0, 0, 1], "normal": [0, 0, 1]}, "body": "base"}},
        "contacts": {"c": {"slave": "pad_bottom", "master": "base_top"}},
        "regions_of_interest": {"r": roi}})
    return scene, build_mesh3d(scene)


def _zone(sm):
    """The node-to-node rows of the slave face as the contact zone holds them: nodes, normal
    (0, 0, −1) out of the slave, zero gaps, tributary areas (a third of each adjacent triangle)."""
    faces = sm.mesh.facets[:, sm.boundaries["pad_bottom"]]
    slave = np.unique(faces)
    x = sm.mesh.p[:, faces]
    area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], axis=0), axis=0)
    weight = np.zeros(sm.mesh.p.shape[1])
    for k in range(3):
        np.add.at(weight, faces[k], area / 3)
    m = slave.size
    return SimpleNamespace(names=["c"], pairs=[_Pairs(slave, np.tile([0.0, 0.0, -1.0], (m, 1)))],
                           coords=sm.mesh.p[:, slave].T.copy(), gap=np.zeros(m), weight=weight[slave])


class _Pairs(SimpleNamespace):
    """A contact's rows: slave nodes and normals (`len` the number of rows)."""
    def __init__(self, slave, normal):
        super().__init__(slave=slave, normal=normal)

    def __len__(self):
        return self.slave.size


@pytest.mark.parametrize("roi, centre, area", [
    ({"box": [0.2, 0.3, 0.5, 0.7, 0.8, 1.5]}, [0.45, 0.55], 0.25),
    ({"box": [0.5, 0.5, 0.9, 1.0, 1.0, 1.0]}, [0.75, 0.75], 0.25),        # the master side only, its top face on Γc
    ({"boundary": "base_top"}, [0.5, 0.5], 1.0)])
def test_contact_pressure_is_the_exact_mean_of_the_p1_pressure(roi, centre, area):
    """λ_i = p(x_i) w_i with p affine: ℓ_r · λ is the mean of p over Γc ∩ G_r, which for an
    affine p is p at the centroid of the (rectangular) part, exactly (round-off)."""
    scene, sm = _contact_mesh(roi)
    zone = _zone(sm)
    sel = (Selection("facets", sm.boundaries["base_top"]) if "boundary" in roi
           else Selection("cells", sm.roi_cells["r"]))
    ell, meas = regions._pressure_functional(sm, scene, zone, "r", sel, "scene.regions_of_interest.r")
    assert meas == pytest.approx(area, rel=1e-12)
    p = 3.0e6 + 1.0e6 * zone.coords[:, 0] - 2.0e6 * zone.coords[:, 1]
    assert ell @ (p * zone.weight) == pytest.approx(3.0e6 + 1.0e6 * centre[0] - 2.0e6 * centre[1], rel=1e-12)


def test_a_boundary_region_measures_each_slave_node_once(monkeypatch):
    """Φ6 over a boundary G_r: the distances to G_r's faces are taken once for each slave node and
    triangle centroid, not once for each triangle's corner (~6 triangles share a node; the
    patch's face 0.02: 0.41 s for 4 points a triangle, 0.17 s now, the functional bitwise the same)."""
    scene, sm = _contact_mesh({"boundary": "base_top"})
    zone, sel = _zone(sm), Selection("facets", sm.boundaries["base_top"])
    points, distance = [], regions._distance_to_facets
    monkeypatch.setattr(regions, "_distance_to_facets", lambda mesh, facets, x, cap: points.append(len(x)) or
                        distance(mesh, facets, x, cap))
    ell, meas = regions._pressure_functional(sm, scene, zone, "r", sel, "scene.regions_of_interest.r")
    triangles = len(regions.slave_segments(zone, scene, sm))
    assert points == [zone.gap.size + triangles] * 2       # the slave side and its master projection
    assert meas == pytest.approx(1.0, rel=1e-12)            # the whole face (its values: the test above)


def test_contact_pressure_refuses_a_region_that_cuts_slave_triangles():
    """A ball not embedded in the mesh (the mesh was built with another region) cuts slave
    triangles: refused, by the region's path, never integrated approximately."""
    scene, sm = _contact_mesh({"box": [0.2, 0.3, 0.5, 0.7, 0.8, 1.5]})
    other = load_scene({**scene.model_dump(exclude_none=True),
                        "regions_of_interest": {"r": {"ball": {"center": [0.5, 0.5, 1.0], "radius": 0.33}}}})
    with pytest.raises(StudyError, match="cuts .* slave triangles") as e:
        regions._pressure_functional(sm, other, _zone(sm), "r", Selection("cells", np.zeros(0, int)),
                                      "scene.regions_of_interest.r")
    assert e.value.path == "scene.regions_of_interest.r"


@pytest.mark.parametrize("roi, exact", [
    ({"ball": {"center": [0.5, 0.5, 1.0], "radius": 0.3}}, np.pi * 0.3**2),
    ({"cylinder": {"start": [0.5, 0.5, 0.8], "end": [0.5, 0.5, 1.2], "radius": 0.3}}, np.pi * 0.3**2),
    ({"cylinder": {"start": [0.2, 0.5, 1.0], "end": [0.8, 0.5, 1.0], "radius": 0.2}}, 0.6 * 0.4)])
def test_contact_pressure_over_an_embedded_ball_or_cylinder(roi, exact):
    """A ball or cylinder embedded in the mesh meets the contact face in the mesh's polygon
    inscribed in its trace (a disc, or a 0.6 × 0.4 rectangle for the lying cylinder): no slave
    triangle is cut, Γc ∩ G_r is that polygon (its area just below the disc's, the rectangle's
    exactly) and a uniform pressure has that mean exactly."""
    scene, sm = _contact_mesh(roi)
    zone = _zone(sm)
    ell, meas = regions._pressure_functional(sm, scene, zone, "r", Selection("cells", sm.roi_cells["r"]),
                                              "scene.regions_of_interest.r")
    assert 0.97 * exact < meas <= exact * (1 + 1e-12)
    assert ell @ (2.5e6 * zone.weight) == pytest.approx(2.5e6, rel=1e-12)
    inside = ell > 0
    c = zone.coords[inside]
    level = regions._region_level(scene.regions_of_interest["r"], c)
    assert level.max() <= 1e-9                         # every node carrying the mean is in G_r


def test_the_distance_to_facets_is_the_minimum_over_every_triangle():
    """The candidates near each point (`_distance_to_facets`'s centroids within its cap and a
    triangle's reach) give the same minimum, to the bit, as the distance to every triangle, where
    it is within the cap (half, exactly or twice the minimum; inf elsewhere): random triangles of
    all sizes, points inside and around their cloud."""
    from types import SimpleNamespace
    from wcs.model.regions import _distance_to_facets, _triangle_distances
    rng = np.random.default_rng(0)
    tri = rng.random((300, 3, 3)) * rng.choice([0.01, 0.1, 1.0], (300, 1, 1)) + rng.random((300, 1, 3))
    x = rng.random((200, 3)) * 3 - 1
    every = np.array([_triangle_distances(np.repeat(p[None], len(tri), 0), tri).min() for p in x])
    mesh = SimpleNamespace(p=tri.reshape(-1, 3).T, facets=np.arange(900).reshape(300, 3).T)
    cap = every * rng.choice([0.5, 1.0, 2.0], len(x))
    expected = np.where(cap >= every, every, np.inf)
    assert np.isfinite(expected).sum() > 100 and np.isinf(expected).sum() > 30
    assert np.array_equal(_distance_to_facets(mesh, np.arange(300), x, cap), expected)
