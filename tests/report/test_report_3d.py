"""The geometry behind the 3D report figures, checked against exact measures: the outer faces
of a tetrahedral mesh cover its surface exactly (areas of a meshed box to round-off), a plane
cut of the tetrahedra covers the body's cross-section exactly, and a surface's own frame spans
its plane."""
from pathlib import Path

import numpy as np
import pytest

from tests.scene.test_mesher_3d import BLOCK, FAULT, build_mesh3d, fault_scene
from wcs.contact.frame import surface_frame
from wcs.report.plots3d import outer_faces, plane_section, plane_axes


@pytest.fixture(scope="module")
def fault_sm():
    return build_mesh3d(fault_scene(size=0.25))


@pytest.fixture(scope="module")
def fault(fault_sm):
    return fault_sm.mesh


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
  boundaries:
    fault_h: {plane: {point: [1.0, 0.0, 0.5], normal: [1.0, 0.0, -1.0]}, body: hanging}
    fault_f: {plane: {point: [1.0, 0.0, 0.5], normal: [1.0, 0.0, -1.0]}, body: foot}
    bottom: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}
    right: {box: [2, -1, -1, 2, 2, 2]}
  supports:
    bottom: {u: [0, 0, 0]}
  loads:
    right: {pressure: 1.0e6}
  contacts:
    fault: {slave: fault_h, master: fault_f}
  regions_of_interest:
    core: {ball: {center: [1.0, 0.5, 0.5], radius: 0.3}}
    near_fault: {cylinder: {start: [0.5, 0.0, 0.0], end: [0.5, 1.0, 0.0], radius: 0.3}, body: foot}
criteria:
  - {name: stress, kind: von_mises, regions: [core, near_fault]}
"""


def synthetic_solve3d(mesh, sm=None) -> "xr.Dataset":
    """A `wcs solve` file in the 3D layout (coords (node, 3), cells (cell, 4), six stress
    components, contact fields with a tangent dimension of 2) from an analytic displacement:
    only the report's reading and drawing are tested here, not a solve."""
    import xarray as xr
    from wcs.geometry.tet import principal, strain_operator, stresses, von_mises
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
    if sm is not None:                   # the bodies, as `wcs.model.fields` writes them
        ds["cell_body"] = ("cell", sm.cell_body.astype(np.int32))
        ds = ds.assign_coords(body=sm.bodies)
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
    assert html.count("plotly.js v") == 1 and 'id="view3d-plot"' in html and 'href="#view3d"' in html
    assert 'id="membership"' not in html and 'href="#membership"' not in html          # a crisp study


# ---------------------------------------------------------------- what the assessor sees in 3D

def report3d(fault_sm, tmp_path, full: bool = True):
    """The report of the synthetic 3D solve file (with its bodies), or only its interactive view's
    section in a page (`full` False: fast), and the loaded results."""
    from wcs.report.data import load
    from wcs.report.view3d import view_html
    from wcs.cli import main
    nc, out = tmp_path / "solve3d.nc", tmp_path / "report.html"
    synthetic_solve3d(fault_sm.mesh, fault_sm).to_netcdf(nc, engine="h5netcdf")
    if full:
        assert main(["report", str(nc), "-o", str(out), "--quiet"]) == 0
    else:
        out.write_text(f"<!DOCTYPE html><html><body>{view_html(load(nc))}</body></html>", encoding="utf-8")
    return out, load(nc)


def view_json(html: str) -> dict:
    import json
    start = html.index('<script type="application/json" id="view3d-data">') + len(
        '<script type="application/json" id="view3d-data">')
    return json.loads(html[start:html.index("</script>", start)].replace("<\\/", "</"))


def decode(spec) -> np.ndarray:
    import base64
    return np.frombuffer(base64.b64decode(spec["bdata"]), {"f4": "<f4", "i4": "<i4"}[spec["dtype"]])


def test_the_3d_report_holds_an_offline_interactive_view_of_the_files_fields(fault_sm, tmp_path):
    """The page embeds plotly.js once (no URL to fetch), one surface per body whose triangles are
    exactly the body's outer faces, the contact surface, regions of interest, supports and loads,
    and per case the fields: von Mises of the cell under each triangle and the contact pressure at
    the contact surface's vertices equal the file's (float32: relative 1e-6)."""
    import re
    from wcs.report.plots import stress_scale
    out, res = report3d(fault_sm, tmp_path, full=False)
    html = out.read_text()
    assert html.count("plotly.js v") == 1 and 'id="view3d-plot"' in html
    tags = re.sub(r"<script[^>]*>.*?</script>", "", html, flags=re.S)        # plotly.js's own text aside
    assert "<script src" not in html and not re.search(r'(src|href)\s*=\s*["\']?(https?:)?//', tags)
    d = view_json(html)
    assert d["missing"] == []
    names = [t["name"] for t in d["traces"]]
    assert names[:2] == ["hanging", "foot"] and "contact fault" in names
    assert {"core", "near_fault", "support bottom", "load right"} <= set(names)
    assert [f["key"] for f in d["fields"]] == ["u", "von_mises", "s1", "s3", "contact_pressure", "contact_slip"]
    mesh, vm = res.mesh, res.worst_fields[0].von_mises
    area = 0.0
    for k, ti in enumerate(d["parts"]):
        t = d["traces"][ti]
        x = np.column_stack([decode(t[a]) for a in "xyz"])
        tri = np.column_stack([decode(t[a]) for a in "ijk"])
        area += 0.5 * np.linalg.norm(np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]]), axis=1).sum()
        # the von Mises values drawn are those of the cells under the triangles: find each by its centroid
        body = mesh.cell_body == k
        from wcs.report.plots3d import outer_faces
        faces, owner = outer_faces(mesh.cells[body], mesh.coords)
        sc, _ = stress_scale(vm)
        want = vm[np.flatnonzero(body)[owner]] * sc
        got = decode(d["cases"][0]["values"]["von_mises"][k])
        order = np.lexsort(np.round(mesh.coords[faces].mean(axis=1), 9).T)
        order_got = np.lexsort(np.round(x[tri].mean(axis=1), 6).T)
        assert got[order_got] == pytest.approx(want[order], rel=1e-6)
    assert area == pytest.approx(10.0 + 2 * np.sqrt(2.0), rel=1e-6)         # both bodies closed
    ci = d["contacts"][0]
    xc = np.column_stack([decode(d["traces"][ci][a]) for a in "xyz"])
    p = decode(d["cases"][0]["values"]["contact_pressure"][0])
    assert abs(xc[:, 0] - xc[:, 2] - 0.5).max() < 1e-6                       # on the fault plane x − z = 0.5
    assert p == pytest.approx(1.0 * (1 + xc[:, 1]), rel=1e-6)                # 1e6 (1 + y) Pa in MPa


def test_the_view_selects_the_faces_the_solver_selects(fault_sm):
    """The supported, loaded and contact faces drawn are the solver's facets of each boundary,
    a body's restriction included."""
    import xarray as xr
    from wcs.report.data import from_dataset
    from wcs.report.plots3d import outer_faces, selected_faces
    res = from_dataset(synthetic_solve3d(fault_sm.mesh, fault_sm))
    faces, owner = outer_faces(res.mesh.cells, res.mesh.coords)
    key = {tuple(f) for f in np.sort(faces, axis=1).tolist()}
    for name in ("fault_h", "fault_f", "bottom", "right"):
        sel = selected_faces(res, name, faces, owner)
        want = np.sort(fault_sm.mesh.facets[:, fault_sm.boundaries[name]].T, axis=1)
        assert {tuple(f) for f in want.tolist()} <= key
        assert sorted(map(tuple, np.sort(faces[sel], axis=1).tolist())) == sorted(map(tuple, want.tolist())), name


def test_outer_faces_point_outward_whatever_the_vertex_order(fault):
    """With the coordinates, every outer face points away from its cell even when half the
    tetrahedra are numbered negatively (a mesh file may; before, their faces pointed inward and
    drew dark patches)."""
    cells = fault.t.T.copy()
    cells[::2] = cells[::2][:, [1, 0, 2, 3]]
    faces, owner = outer_faces(cells, fault.p.T)
    x = fault.p.T[faces]
    outward = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    inward = fault.p.T[cells[owner]].mean(axis=1) - x.mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", outward, inward) < 0)


def test_a_cube_seen_from_a_corner_shows_three_shades():
    """The static views are shaded: the three faces of a cube the viewer sees differ in brightness
    by more than 0.1 (before: one flat colour, a cube looked like a hexagon)."""
    from wcs.report.plots3d import VIEWS, shading, view_direction
    for elev, azim in VIEWS:
        d = view_direction(elev, azim)
        seen = [n for n in np.vstack([np.eye(3), -np.eye(3)]) if n @ d > 0]
        b = np.sort(shading(np.array(seen), elev, azim))
        assert len(seen) == 3 and np.diff(b).min() > 0.1, b


def test_regions_of_interest_keep_to_their_body(fault_sm):
    """A region with `body:` is the cells of that body inside its solid (before, the cut's outline
    took both bodies' cells)."""
    from wcs.report.data import from_dataset
    from wcs.report.plots3d import _inside, roi_cells
    res = from_dataset(synthetic_solve3d(fault_sm.mesh, fault_sm))
    cells = roi_cells(res, "near_fault")
    solid = _inside(res.scene["regions_of_interest"]["near_fault"], res.mesh.coords[res.mesh.cells].mean(axis=1))
    foot = res.mesh.cell_body == res.mesh.bodies.index("foot")
    assert cells.any() and np.array_equal(cells, solid & foot) and (solid & ~foot).any()


def test_a_region_smaller_than_its_cells_gets_a_cut_through_it(fault_sm):
    """A region of interest smaller than the cells (a 0.1 m pad on the top face, cells of 0.25 m):
    the cut shows the cells through it (before: "the cut misses the mesh", an empty panel)."""
    from wcs.report.data import from_dataset
    from wcs.report.plots3d import cut_panel
    yaml_text = STUDY3D.replace("core: {ball: {center: [1.0, 0.5, 0.5], radius: 0.3}}",
                                "core: {box: [0.45, 0.45, 0.9, 0.55, 0.55, 1.0]}")
    ds = synthetic_solve3d(fault_sm.mesh, fault_sm)
    ds.attrs["study_yaml"] = yaml_text
    res = from_dataset(ds)
    point, e1, e2, half, flat, owner = cut_panel(res, "core")
    assert len(flat) > 0 and half >= 0.1
    lo = np.min([q.min(axis=0) for q in flat], axis=0)
    hi = np.max([q.max(axis=0) for q in flat], axis=0)
    assert np.all(lo <= -0.05) and np.all(hi >= 0.05)                         # the pad's width, covered


def test_contact_maps_read_as_the_scene_axes():
    """A horizontal contact surface is mapped with x rightwards and y upwards, whatever way its
    nodes spread (before: their principal directions, a map turned against the scene)."""
    from wcs.report.plots3d import map_axes
    rng = np.random.default_rng(1)
    q = rng.uniform(-1, 1, (400, 2)) * [1.0, 0.4]
    turn = np.radians(58.0)
    x = np.column_stack([q @ [np.cos(turn), -np.sin(turn)], q @ [np.sin(turn), np.cos(turn)], np.full(400, 0.2)])
    _, e1, e2 = map_axes(x)
    assert e1 == pytest.approx([1, 0, 0], abs=1e-12) and e2 == pytest.approx([0, 1, 0], abs=1e-12)


@pytest.mark.slow
def test_the_3d_view_turns_and_switches_fields_in_chromium(fault_sm, tmp_path):
    """Headless Chromium loads the 3D report: no console error, no request leaves the file, the
    page is not wider than the window; a mouse drag turns the model (the camera moves, the picture
    changes), the field list recolours it (von Mises per cell, then the contact pressure on the
    contact surface with the bodies see-through). Screenshots stay in tmp_path for a reviewer."""
    from PIL import Image
    from tests.support.cdp import Browser
    from tests.report.test_report import ensure_chromium
    out, res = report3d(fault_sm, tmp_path)
    d = view_json(out.read_text())
    keys = [f["key"] for f in d["fields"]]

    def pick(b, field):
        b.evaluate(f"(() => {{ const s = document.getElementById('view3d-field'); s.value = '{keys.index(field)}';"
                   "s.dispatchEvent(new Event('change')); return 1; })()")
        return b.evaluate("wcsView3d.draw().then(() => 1)")

    with Browser(ensure_chromium(), tmp_path, width=1280, height=1000) as b:
        b.call("Network.enable", session=True)
        b.open(out)
        assert b.evaluate("window.wcsView3dReady.then(() => document.getElementById('view3d-plot').dataset.ready)") == "1"
        assert b.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
        x, y, w, h = b.evaluate("(() => { const e = document.getElementById('view3d-plot'); e.scrollIntoView();"
                                "const r = e.getBoundingClientRect(); return [r.x, r.y, r.width, r.height]; })()")
        clip = {"x": x, "y": y + b.evaluate("window.scrollY"), "width": w, "height": h}
        shots = {"start": b.screenshot(tmp_path / "view-start.png", clip)}
        eye = "JSON.stringify(wcsView3d.plot._fullLayout.scene._scene.getCamera().eye)"
        before = b.evaluate(eye)
        b.drag(x + 0.5 * w, y + 0.5 * h, x + 0.5 * w + 220, y + 0.5 * h + 80)
        assert b.evaluate(eye) != before
        shots["turned"] = b.screenshot(tmp_path / "view-turned.png", clip)
        pick(b, "von_mises")
        part = d["parts"][0]
        assert b.evaluate(f"wcsView3d.plot.data[{part}].intensitymode") == "cell"
        assert b.evaluate(f"wcsView3d.plot.data[{part}].intensity.length") == len(decode(d["traces"][part]["i"]))
        assert b.evaluate(f"wcsView3d.plot._fullData[{part}].colorbar.title.text").startswith("von Mises stress")
        shots["von Mises"] = b.screenshot(tmp_path / "view-von-mises.png", clip)
        pick(b, "contact_pressure")
        contact = d["contacts"][0]
        assert b.evaluate(f"wcsView3d.plot.data[{contact}].intensity.length") == len(decode(d["traces"][contact]["x"]))
        assert b.evaluate(f"wcsView3d.plot.data[{part}].opacity") < 0.5
        shots["contact pressure"] = b.screenshot(tmp_path / "view-contact-pressure.png", clip)
        requests = [m["params"]["request"]["url"] for m in b.events if m.get("method") == "Network.requestWillBeSent"]
        assert b.errors == []
    assert all(u.startswith(("file:", "data:", "blob:")) for u in requests), requests
    pixels = {k: np.asarray(Image.open(p).convert("RGB")).astype(int) for k, p in shots.items()}
    for k, a in pixels.items():
        assert len(np.unique(a[::4, ::4].reshape(-1, 3), axis=0)) > 100, f"{k}: a blank picture"
    for a, b_ in (("start", "turned"), ("turned", "von Mises"), ("von Mises", "contact pressure")):
        assert np.abs(pixels[a] - pixels[b_]).sum(axis=2).astype(bool).mean() > 0.02, (a, b_)


def test_the_scene_figure_outlines_every_support_load_contact_and_region(fault_sm):
    """Each support, load, contact surface and region of interest of the scene is outlined in the
    static scene figure (`scene_sets`), none left out (before: none drawn)."""
    from wcs.report.data import from_dataset
    from wcs.report.plots3d import outer_faces, scene_sets
    res = from_dataset(synthetic_solve3d(fault_sm.mesh, fault_sm))
    faces, owner = outer_faces(res.mesh.cells, res.mesh.coords)
    sets, missing = scene_sets(res, faces, owner)
    assert missing == [] and [(k, n) for k, n, _ in sets] == [
        ("support", "bottom"), ("load", "right"), ("contact", "fault"),
        ("region of interest", "core"), ("region of interest", "near_fault")]
    assert all(mask.any() for _, _, mask in sets)


def test_a_thin_axis_shows_its_ends_instead_of_crowded_ticks():
    """The 3D tunnel's 120 x 10 x 120 m slice: the 10 m axis gets no ticks, its two ends in its
    label (before: its tick labels ran into each other and into the next axis's); the others at
    most five ticks."""
    from wcs.report.plots import plt
    from wcs.report.plots3d import _axes_ticks
    fig = plt.figure()
    ax = fig.add_subplot(projection="3d")
    lo, hi = np.array([-60.0, 0.0, -60.0]), np.array([60.0, 10.0, 60.0])
    ax.set_xlim(lo[0], hi[0]), ax.set_ylim(lo[1], hi[1]), ax.set_zlim(lo[2], hi[2])
    _axes_ticks(ax, lo, hi)
    assert list(ax.get_yticks()) == [] and ax.get_ylabel() == "y 0 … 10 m"
    assert 2 <= len(ax.get_xticks()) <= 5 and 2 <= len(ax.get_zticks()) <= 5
    plt.close(fig)


def test_the_contact_surface_drawn_is_where_the_file_has_contact_nodes(fault_sm):
    """A contact solved on a candidate zone, part of its slave surface (the 3D Hertz sphere): the
    view draws the slave faces whose nodes the file holds, coloured by their values, and names
    nothing as missing (before the fix: the whole surface, its field not drawn)."""
    from wcs.report.data import from_dataset
    from wcs.report.view3d import view_data
    ds = synthetic_solve3d(fault_sm.mesh, fault_sm)
    ds = ds.isel(contact_node=np.flatnonzero(ds["contact_coords"].values[:, 1] <= 0.5))
    d = view_data(from_dataset(ds))
    ci = d["contacts"][0]
    xc = np.column_stack([decode(d["traces"][ci][a]) for a in "xyz"])
    assert d["missing"] == [] and len(xc) > 10 and xc[:, 1].max() <= 0.5 + 1e-6
    assert decode(d["cases"][0]["values"]["contact_pressure"][0]) == pytest.approx(1 + xc[:, 1], rel=1e-6)


def drive_view(html: Path, folder: Path) -> dict:
    """Headless Chromium on a report's 3D view, as an assessor uses it: the page loads with no
    console error and no request leaving the file, a mouse drag turns the model, the field list
    recolours it (von Mises, then the contact pressure where the file has contact); each state's
    screenshot (kept in `folder` for a reviewer) shows a picture, and each differs from the last.
    Returns the screenshots' paths."""
    from PIL import Image
    from tests.support.cdp import Browser
    from tests.report.test_report import ensure_chromium
    keys = [f["key"] for f in view_json(html.read_text())["fields"]]
    with Browser(ensure_chromium(), folder, width=1280, height=1000) as b:
        b.call("Network.enable", session=True)
        b.open(html)
        assert b.evaluate("window.wcsView3dReady.then(() => document.getElementById('view3d-plot').dataset.ready)") == "1"
        x, y, w, h = b.evaluate("(() => { const e = document.getElementById('view3d-plot'); e.scrollIntoView();"
                                "const r = e.getBoundingClientRect(); return [r.x, r.y, r.width, r.height]; })()")
        clip = {"x": x, "y": y + b.evaluate("window.scrollY"), "width": w, "height": h}
        shots = {"start": b.screenshot(folder / f"{html.stem}-start.png", clip)}
        eye = "JSON.stringify(wcsView3d.plot._fullLayout.scene._scene.getCamera().eye)"
        before = b.evaluate(eye)
        b.drag(x + 0.5 * w, y + 0.5 * h, x + 0.5 * w + 220, y + 0.5 * h + 80)
        assert b.evaluate(eye) != before
        shots["turned"] = b.screenshot(folder / f"{html.stem}-turned.png", clip)
        for field in ("von_mises", "contact_pressure"):
            if field in keys:
                b.evaluate(f"(() => {{ const s = document.getElementById('view3d-field'); s.value = '{keys.index(field)}';"
                           "s.dispatchEvent(new Event('change')); return 1; })()")
                b.evaluate("wcsView3d.draw().then(() => 1)")
                shots[field] = b.screenshot(folder / f"{html.stem}-{field}.png", clip)
        requests = [m["params"]["request"]["url"] for m in b.events if m.get("method") == "Network.requestWillBeSent"]
        assert b.errors == []
    assert all(u.startswith(("file:", "data:", "blob:")) for u in requests), requests
    pixels = [np.asarray(Image.open(p).convert("RGB")).astype(int) for p in shots.values()]
    for name, a in zip(shots, pixels):
        assert len(np.unique(a[::4, ::4].reshape(-1, 3), axis=0)) > 100, f"{name}: a blank picture"
    for (name, a), b_ in zip(list(zip(shots, pixels))[1:], pixels):
        assert np.abs(a - b_).sum(axis=2).astype(bool).mean() > 0.02, f"{name}: the picture did not change"
    return shots
