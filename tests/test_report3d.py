"""The geometry behind the 3D report figures, checked against exact measures: the outer faces
of a tetrahedral mesh cover its surface exactly (areas of a meshed box to round-off), a plane
cut of the tetrahedra covers the body's cross-section exactly, and a surface's own frame spans
its plane."""
import numpy as np
import pytest

from test_mesher3d import BLOCK, FAULT, build_mesh3d, fault_scene
from wcs.contact.frame import surface_frame
from wcs.report.plots3d import outer_faces, plane_section, plane_axes


@pytest.fixture(scope="module")
def fault():
    return build_mesh3d(fault_scene(size=0.25)).mesh


def tri_area(x):
    return 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)


def polygon_area(p, e1, e2):
    """Signed area of a planar polygon (k, 3) in the plane's coordinates (e1, e2): the shoelace formula."""
    x, y = p @ e1, p @ e2
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def test_outer_faces_cover_the_surface_of_each_body_exactly(fault):
    faces, owner = outer_faces(fault.t.T)
    x = fault.p.T[faces]
    # two bodies of the block [0,2]x[0,1]x[0,1] cut by the fault x − z = 0.5: the outer box
    # surface 10 plus both sides of the fault, a 1 x sqrt(2) rectangle
    assert tri_area(x).sum() == pytest.approx(10.0 + 2 * np.sqrt(2.0), rel=1e-12)
    centroid = x.mean(axis=1)
    inward = fault.p.T[fault.t.T[owner]].mean(axis=1) - centroid        # towards the cell
    outward = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    assert np.all(np.einsum("ij,ij->i", outward, inward) < 0)            # oriented outward


@pytest.mark.parametrize("point, normal, area", [
    ([1.0, 0.5, 0.37], [0, 0, 1], 2.0),                                   # across z: the whole 2 x 1
    ([0.7, 0.5, 0.5], [1, 0, 0], 1.0),                                    # across x
    ([1.0, 0.5, 0.5], [0, 1, 1], np.sqrt(2.0) * 2.0),                     # inclined: 2 x sqrt(2)
])
def test_a_plane_cut_covers_the_cross_section_exactly(fault, point, normal, area):
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    polygons, owner = plane_section(fault.p.T, fault.t.T, point, n)
    assert len(polygons) == owner.size > 50
    e1, e2 = plane_axes(n)
    assert np.allclose([e1 @ n, e2 @ n, e1 @ e2], 0) and np.allclose([e1 @ e1, e2 @ e2], 1)
    areas = np.array([polygon_area(p, e1, e2) for p in polygons])
    assert np.all(areas > 0)                                              # ordered counter-clockwise
    assert areas.sum() == pytest.approx(area, rel=1e-10)
    for p in polygons:
        assert np.abs((p - point) @ n).max() < 1e-12


def test_the_surface_frame_spans_a_plane_face(fault):
    n = np.asarray(FAULT["normal"], float) / np.linalg.norm(FAULT["normal"])
    rng = np.random.default_rng(0)
    uv = rng.uniform(-1, 1, (200, 2)) * [1.0, 0.3]
    a, b = plane_axes(n)
    x = np.asarray(FAULT["point"]) + uv[:, :1] * a + uv[:, 1:] * b
    origin, e1, e2 = surface_frame(x)
    assert abs(e1 @ n) < 1e-12 and abs(e2 @ n) < 1e-12
    assert abs(abs(e1 @ a) - 1) < 0.05                                    # the long direction first


# ---------------------------------------------------------------- the report of a 3D file

STUDY3D = """study: fault-block-3d
scene:
  dimension: 3
  mesh: {size: 0.25}
  regions_of_interest:
    core: {ball: {center: [1.0, 0.5, 0.5], radius: 0.3}}
    near_fault: {cylinder: {start: [0.5, 0.0, 0.0], end: [0.5, 1.0, 0.0], radius: 0.3}, body: foot}
criteria:
  - {name: stress, kind: von_mises, regions: [core, near_fault]}
"""


def synthetic_solve3d(mesh) -> "xr.Dataset":
    """A `wcs solve` file in the 3D layout (coords (node, 3), cells (cell, 4), six stress
    components, contact fields with a tangent dimension of 2) from an analytic displacement:
    only the report's reading and drawing are tested here, not a solve."""
    import xarray as xr
    from wcs.fem.tet import principal, strain_operator, stresses, von_mises
    p, t = mesh.p, mesh.t
    u = np.column_stack([1e-3 * p[0] * p[2], -2e-4 * p[1], 5e-4 * p[2] ** 2 - 1e-4 * p[0]])
    e = (strain_operator(p, t) @ u.ravel()).reshape(6, -1)
    nc = t.shape[1]
    s = stresses(e, np.full(nc, 1e9), np.full(nc, 5e8), np.zeros(nc), np.zeros(nc))
    faces, _ = outer_faces(t.T)
    fault_nodes = np.unique(faces[np.abs(p[0, faces] - p[2, faces] - 0.5).max(axis=1) < 1e-9])
    x = p[:, fault_nodes].T
    n = np.array(FAULT["normal"]) / np.linalg.norm(FAULT["normal"])
    t1, t2 = plane_axes(n)
    ds = xr.Dataset(coords={"param": np.array([], dtype=object), "criterion": ["stress"]})
    ds["phi"] = ("criterion", [float(von_mises(s).max())])
    ds["x"] = ("param", np.zeros(0))
    ds["coords"] = (("node", "dim"), p.T)
    ds["cells"] = (("cell", "vertex"), t.T)
    ds["displacement"] = (("node", "dim"), u)
    ds["stress"] = (("cell", "component"), s.T)
    ds["von_mises"] = ("cell", von_mises(s))
    ds["principal_stress"] = (("cell", "principal"), principal(s))
    ds["contact_coords"] = (("contact_node", "dim"), x)
    ds["contact_pair"] = ("contact_node", np.array(["fault"] * len(x), dtype=object))
    ds["contact_pressure"] = ("contact_node", 1e6 * (1 + x[:, 1]))
    ds["contact_slip"] = (("contact_node", "tangent"), np.column_stack([1e-4 * x[:, 1], 2e-5 * np.ones(len(x))]))
    ds["contact_tangents"] = (("contact_node", "tangent", "dim"), np.broadcast_to([t1, t2], (len(x), 2, 3)).copy())
    ds.attrs.update(study="fault-block-3d", study_yaml=STUDY3D)
    return ds


def test_the_report_of_a_3d_file_draws_the_surface_cuts_and_contact_maps(fault, tmp_path):
    from wcs.cli import main
    nc, out = tmp_path / "solve3d.nc", tmp_path / "report.html"
    synthetic_solve3d(fault).to_netcdf(nc, engine="h5netcdf")
    assert main(["report", str(nc), "-o", str(out), "--quiet"]) == 0
    html = out.read_text()
    assert f"{fault.t.shape[1]} tetrahedra" in html
    for alt in ("scene and mesh", "worst case of stress", "cuts at the worst case of stress", "contact maps"):
        assert f'alt="{alt}' in html, alt
    assert html.count("data:image/png;base64,") >= 4
