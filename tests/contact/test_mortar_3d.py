"""The 3D segment-based dual mortar operator: geometry alone, no solver.

Flat nonmatching sides (structured and rotated, sizes 1:3 both ways, gmsh blocks with their own
sizes, an inclined fault plane): partition of unity Σ_l M_jl = D_j, linear fields reproduced
(M x = D x_slave), clipped areas summing to the slave area, rigid motions without a jump. A
curved pair (a ball in a socket, nonmatching): D totals the slave triangulation's area and
that converges as O(h²) to the cap's. Matching sides reduce to node-to-node rows."""
import numpy as np
import pytest

from wcs.contact.mortar3d import jump_rows, mortar_sides3d
from wcs.geometry.facets import _clip
from wcs.geometry.mortar3d import _clip_many, _pairs, mortar_integrals3d, oriented_facets, triangle_normals
from wcs.contact.pairs import tangents
from wcs.errors import StudyError
from wcs.scene.mesher3d import build_mesh3d
from wcs.study import load_scene


def grid(n, side=1.0, centre=(0.5, 0.5), angle=0.0, outward=+1):
    """A square of side `side` at z = 0 cut into 2n² triangles, rotated by `angle` about its centre,
    oriented with the outward normal ±e_z."""
    s = np.linspace(-side / 2, side / 2, n + 1)
    u, v = (a.ravel() for a in np.meshgrid(s, s, indexing="ij"))
    c, si = np.cos(angle), np.sin(angle)
    x = np.column_stack([c * u - si * v + centre[0], si * u + c * v + centre[1], np.zeros(u.size)])
    k = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, cc, d = k[:-1, :-1].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel(), k[:-1, 1:].ravel()
    tri = np.concatenate([np.stack([a, b, cc], 1), np.stack([a, cc, d], 1)])
    return x, (tri if outward > 0 else tri[:, [0, 2, 1]])


def cap(n, half=0.5, angle=0.0, outward=+1):
    """The unit sphere's patch over the square [−half, half]² of the plane z = 1 (central
    projection), 2n² triangles, rotated by `angle` about e_z; outward +1: the ball's normal."""
    x, tri = grid(n, 2 * half, (0.0, 0.0), angle, outward)
    x[:, 2] = 1.0
    return x / np.linalg.norm(x, axis=1)[:, None], tri


def join(slave, master):
    (xs, ts), (xm, tm) = slave, master
    return np.vstack([xs, xm]), ts, tm + len(xs)


def check_flat(x, ts, tm, covered_area):
    mi = mortar_integrals3d(x, ts, tm)
    _, area = triangle_normals(x, ts)
    assert mi.covered.sum() == pytest.approx(covered_area, abs=1e-12)
    # partition of unity: dual basis and master shape functions both sum to one on the covered part
    assert np.abs(np.asarray(mi.M.sum(axis=1)).ravel() - mi.D).max() < 1e-14
    # linear fields reproduced on coplanar sides: ∫ψ_j x = D_j x_j
    assert np.abs(mi.M @ x - mi.D[:, None] * x[mi.slave]).max() < 1e-14
    assert mi.D.sum() == pytest.approx(mi.covered.sum(), abs=1e-13)
    assert np.abs(mi.normal - [0, 0, 1]).max() < 1e-14
    return mi, area


@pytest.mark.parametrize("ns, nm", [(3, 9), (9, 3)])
def test_flat_nonmatching_rotated(ns, nm):
    """Slave [0, 1]² (outward +e_z) under a master square of side 1.5 rotated by 30° (outward −e_z,
    covers it), meshes 1:3 and 3:1: every slave triangle is fully covered, D_j = ∫φ_j."""
    x, ts, tm = join(grid(ns), grid(nm, 1.5, angle=np.radians(30), outward=-1))
    mi, area = check_flat(x, ts, tm, 1.0)
    assert np.abs(mi.covered - area).max() < 1e-15
    trib = np.bincount(np.searchsorted(mi.slave, ts).ravel(), np.repeat(area / 3, 3))
    assert np.abs(mi.D - trib).max() < 1e-15                   # D_jj = ∫φ_j: a third of each triangle
    assert mi.dropped.size == 0


def test_flat_partly_covered():
    """A master square of side 0.5 rotated by 20° inside the slave [0, 1]²: the clipped areas sum
    to the master's area, the dual basis built on the covered parts keeps Σ M = D and M x = D x."""
    x, ts, tm = join(grid(6), grid(5, 0.5, angle=np.radians(20), outward=-1))
    mi, _ = check_flat(x, ts, tm, 0.25)
    assert 0 < mi.slave.size < 49 and mi.dropped.size == 49 - mi.slave.size


def test_matching_sides_are_node_to_node():
    """Coincident meshes: D⁻¹M is the identity on the coincident nodes (C = 1 on the slave node,
    −1 on its master twin)."""
    x, ts, tm = join(grid(4), grid(4, outward=-1))
    mi = mortar_integrals3d(x, ts, tm)
    C = mi.C.toarray()
    assert np.abs(C[np.arange(25), mi.slave] - 1).max() < 1e-13
    assert np.abs(C[np.arange(25), mi.slave + 25] + 1).max() < 1e-13
    assert np.abs(C).sum() == pytest.approx(50, abs=1e-11)


def test_curved_pair_area_converges():
    """A ball (slave, outward) in a socket (master: the same sphere, outward towards the centre,
    meshed 1:3 finer, rotated 20°, wider): every slave triangle is covered, so ΣD is the area of
    the slave triangulation to round-off, and that tends to the patch's area Ω = 4 asin(a²/(1+a²))
    (a = 1/2) as h²: the error falls by 4 (± 5 %) per halving of h."""
    omega = 4 * np.arcsin(0.25 / 1.25)
    errors = []
    for n in (4, 8):
        x, ts, tm = join(cap(n), cap(3 * n, 0.8, np.radians(20), outward=-1))
        mi = mortar_integrals3d(x, ts, tm)
        _, area = triangle_normals(x, ts)
        assert np.abs(mi.covered - area).max() < 1e-15
        assert mi.D.sum() == pytest.approx(area.sum(), abs=1e-13)
        assert np.abs(np.asarray(mi.M.sum(axis=1)).ravel() - mi.D).max() < 1e-14
        errors.append(omega - mi.D.sum())
    assert errors[0] > 0 and errors[0] / errors[1] == pytest.approx(4.0, rel=0.05)
    assert abs(errors[1]) / omega < 4e-3


def test_two_master_layers_refused():
    """A master side folded over itself (two layers facing one slave triangle) is refused."""
    x, ts, tm = join(grid(2), grid(2, 1.5, outward=-1))
    _, tm2 = grid(2, 1.5, outward=-1)
    with pytest.raises(StudyError, match="overlaps itself"):
        mortar_integrals3d(np.vstack([x, x[9:] + [0, 0, 0.1]]), ts, np.vstack([tm, tm2 + len(x)]))


def tangent_frame_ok(n, t):
    assert np.abs(np.einsum("mkd,md->mk", t, n)).max() < 1e-15
    assert np.abs(np.linalg.norm(t, axis=2) - 1).max() < 1e-15
    assert np.abs(np.cross(t[:, 0], t[:, 1]) - n).max() < 1e-15


def test_tangents_right_handed():
    rng = np.random.default_rng(0)
    n = rng.normal(size=(50, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    tangent_frame_ok(n, tangents(n))
    assert np.array_equal(tangents(np.array([[0.0, 0.0, 1.0]])), [[[1, 0, 0], [0, 1, 0]]])


def mesh3d(scene):
    bodies = {b: {**spec, "regions": [{**r, "material": "m"} for r in spec["regions"]]}
              for b, spec in scene["bodies"].items()}
    return build_mesh3d(load_scene({**scene, "dimension": 3, "bodies": bodies,
                                    "materials": {"m": {"E": 1e9, "nu": 0.3}}}))


@pytest.mark.parametrize("normal", [[0, 0, 1], [1, 0, -1]])
def test_gmsh_blocks_nonmatching(normal):
    """Two gmsh bodies meshed with their own sizes (1:3) touching on a plane (horizontal, or the
    inclined plane x − z = 0.5 of the fault scene): the contact rows have zero gap, the plane's
    normal, Σ weight = the face area, and rigid motions have no jump (Bn, Bt stacked by component)."""
    nrm = np.array(normal, float) / np.linalg.norm(normal)
    plane = {"point": [1.0, 0.0, 0.5], "normal": normal}
    block = [0.0, 0.0, 0.0, 2.0, 1.0, 1.0]
    scene = {"bodies": {"under": {"regions": [{"shape": {"box": block, "minus": [{"halfspace": plane}]}}],
                                  "mesh": {"size": 0.45}},
                        "over": {"regions": [{"shape": {"box": block, "intersect": [{"halfspace": plane}]}}],
                                 "mesh": {"size": 0.15}}},
             "boundaries": {"S": {"plane": plane, "body": "under"}, "M": {"plane": plane, "body": "over"}},
             "mesh": {"size": 0.45}}
    sm = mesh3d(scene)
    mesh = sm.mesh
    x = mesh.p.T
    tri = oriented_facets(mesh, sm.boundaries["S"])
    tn, area = triangle_normals(x, tri)
    assert np.abs(tn + nrm).max() < 1e-12            # "under" lies on the side (p − point)·normal ≥ 0
    pr = mortar_sides3d(mesh, sm.boundaries["S"], sm.boundaries["M"])
    assert np.abs(pr.normal - (-nrm)).max() < 1e-12
    assert np.abs(pr.gap).max() < 1e-12
    assert pr.weight.sum() == pytest.approx(area.sum(), rel=1e-12)
    tangent_frame_ok(pr.normal, pr.tangent)
    Bn, Bt = jump_rows(pr)
    m, nn = len(pr), x.shape[0]
    assert Bn.shape == (m, 3 * nn) and Bt.shape == (2 * m, 3 * nn)
    rng = np.random.default_rng(1)
    omega, c = rng.normal(size=3), rng.normal(size=3)
    u = (np.cross(omega, x) + c).ravel()                  # node-interleaved (3i, 3i+1, 3i+2)
    assert np.abs(Bn @ u).max() < 1e-12 and np.abs(Bt @ u).max() < 1e-12
    # a uniform slave translation along t¹ of node j appears in row m + j only as that tangent
    v = np.zeros((nn, 3))
    v[pr.slave] = pr.tangent[:, 0]
    assert np.abs(Bt @ v.ravel() - np.r_[np.ones(m), np.zeros(m)]).max() < 1e-12
    assert np.abs(Bn @ v.ravel()).max() < 1e-12


def ccw(t):
    """The triangles t (k, 3, 2) ordered counter-clockwise."""
    a, b = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    d = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] < 0
    t[d, 1], t[d, 2] = t[d, 2], t[d, 1].copy()
    return t


def test_clip_many_is_clip_of_each_pair():
    """All pairs clipped at once give, pair by pair, the very polygons (vertex for vertex, bitwise)
    of the one-pair clip: inside, outside, across edges, sharing vertices and edges (a grid's
    triangles against each other), emptied."""
    rng = np.random.default_rng(7)
    poly = ccw(rng.uniform(-1, 2, (400, 3, 2)))
    tri = ccw(rng.uniform(0, 1, (400, 3, 2)))
    x, t = grid(3)
    g = ccw(x[t][:, :, :2].copy())
    i, j = (a.ravel() for a in np.meshgrid(np.arange(len(g)), np.arange(len(g))))
    poly, tri = np.concatenate([poly, g[i], tri[:50] * 0.3]), np.concatenate([tri, g[j], tri[:50]])
    clipped, count = _clip_many(poly, np.full(len(poly), 3), tri)
    expect = [_clip(p, q) for p, q in zip(poly, tri)]
    assert {0, 3, 4, 5, 6} <= set(count.tolist())
    assert count.tolist() == [len(e) for e in expect]
    assert all(np.array_equal(c[:n], e) for c, n, e in zip(clipped, count, expect))


def test_pairs_hold_every_laterally_near_facing_pair():
    """The candidate pairs (slave, master) of the curved, rotated pair hold every pair that the
    per-triangle test takes (the master faces the slave, centroids within the sum of the bounding
    radii along the slave's plane), sorted by slave then master; the margin adds only pairs whose
    clipped polygon is empty."""
    x, ts, tm = join(cap(6, outward=-1), cap(5, angle=0.4))
    x = x + [0.0, 0.0, -0.2]
    sn, _ = triangle_normals(x, ts)
    mnu, _ = triangle_normals(x, tm)
    mc = x[tm].mean(axis=1)
    mrad = np.linalg.norm(x[tm] - mc[:, None], axis=2).max(axis=1)
    e, f = _pairs(x, ts, sn, mnu, mc, mrad)
    assert np.all(np.diff(e * len(tm) + f) > 0)
    expect = set()
    for k, t in enumerate(ts):
        sc = x[t].mean(axis=0)
        srad = np.linalg.norm(x[t] - sc, axis=1).max()
        d = mc - sc
        lateral = np.linalg.norm(d - (d @ sn[k])[:, None] * sn[k], axis=1)
        expect |= {(k, m) for m in np.flatnonzero((mnu @ sn[k] < -1e-3) & (lateral <= srad + mrad))}
    found = set(zip(e.tolist(), f.tolist()))
    assert expect <= found and len(expect) > len(ts)
    for k, m in found - expect:                 # extra: the projected triangles do not overlap
        mi = mortar_integrals3d(x, ts[[k]], tm[[m]])
        assert mi.covered[0] == 0.0
