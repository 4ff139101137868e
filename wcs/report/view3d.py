"""The report's interactive 3D view: the outer surface of the tetrahedral mesh drawn by plotly.js
(embedded once, so the page stays one file that works offline), turned and zoomed with the mouse.

What it holds (`view_data`, plain JSON): one `Mesh3d` per region (its cells' outer triangles, so
hiding a region shows its neighbours closed), one per contact surface (the slave side) and per
region of interest, `Scatter3d` outlines of the supported and loaded faces with arrows along the
loads; per case (the worst data set of each criterion, one per distinct data set) the fields
|u| and the displacement at the vertices, von Mises and the principal stresses σ₁, σ₃ of the cell
under each triangle, contact pressure and slip |s| at the contact surface's vertices. Arrays are
float32/int32, base64 (plotly's typed-array form `{dtype, bdata}`): 4 bytes a number.

The face sets of supports, loads and contacts are found as the solver finds them
(`wcs.scene.mesher3d.surface_distance` within the selector's tolerance, on the named body); a
set that cannot be drawn is named in `missing`, not left out silently.
"""
from __future__ import annotations

import base64
import json

import numpy as np

from .data import Results
from .plots import CONTACT_COLORS, distinct_cases, length_scale, magnification, stress_scale
from .plots3d import _von_mises, face_normals, outer_faces, outline, roi_cells, roi_frame, selected_faces

PALETTE = ["#a6cee3", "#b2df8a", "#fdbf6f", "#cab2d6", "#fb9a99", "#ffff99", "#8dd3c7", "#bebada", "#80b1d3"]
SUPPORT_COLOR, LOAD_COLOR, ROI_COLOR = "#1f5fbf", "#e08000", "#202020"
ARROWS = 12          # load arrows drawn per loaded face set


def typed(a, dtype: str = "f4") -> dict:
    """An array in plotly's typed-array form (little-endian float32 or int32, base64)."""
    a = np.ascontiguousarray(a, dtype={"f4": "<f4", "i4": "<i4"}[dtype]).ravel()
    return {"dtype": dtype, "bdata": base64.b64encode(a.tobytes()).decode()}


def compact(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The nodes a triangle set uses and the triangles renumbered into them."""
    nodes, local = np.unique(faces, return_inverse=True)
    return nodes, local.reshape(faces.shape)


def _lines(x: np.ndarray, pairs: np.ndarray, digits: float) -> tuple[list, list, list]:
    """Polyline coordinates (None between segments), rounded to `digits` (a length)."""
    out = [[], [], []]
    for a, b in pairs:
        for k in range(3):
            out[k] += [round(float(x[a, k]) / digits) * digits, round(float(x[b, k]) / digits) * digits, None]
    return tuple(out)


def _round(v: float, step: float) -> float:
    return round(v / step) * step


def view_data(res: Results) -> dict:
    """The figure (plotly traces and layout) and the cases and fields the page switches between."""
    mesh = res.mesh
    x = mesh.coords
    scale = float(np.ptp(x, axis=0).max()) or 1.0
    step = 1e-5 * scale
    faces, owner = outer_faces(mesh.cells, x)
    traces, missing = [], []
    parts, contacts = [], []              # (trace index, nodes, triangles, owner cells)

    # ------------------------------------------------ one surface per region (or body)
    if mesh.cell_region is not None and mesh.regions:
        groups = [(f"{r}", mesh.cell_region == k) for k, r in enumerate(mesh.regions)]
    elif mesh.cell_body is not None and mesh.bodies:
        groups = [(f"{b}", mesh.cell_body == k) for k, b in enumerate(mesh.bodies)]
    else:
        groups = [("mesh", np.ones(len(mesh.cells), bool))]
    for k, (name, mask) in enumerate(groups):
        cells = np.flatnonzero(mask)
        if not cells.size:
            continue
        f, o = outer_faces(mesh.cells[cells], x)
        nodes, tri = compact(f)
        body = (mesh.bodies[int(np.bincount(mesh.cell_body[cells]).argmax())]
                if mesh.cell_body is not None and mesh.bodies else "")
        traces.append(dict(
            type="mesh3d", name=name, legendgroup=f"body {body}" if body else "mesh",
            legendgrouptitle={"text": f"body {body}" if body else "mesh"}, showlegend=True,
            x=typed(x[nodes, 0]), y=typed(x[nodes, 1]), z=typed(x[nodes, 2]),
            i=typed(tri[:, 0], "i4"), j=typed(tri[:, 1], "i4"), k=typed(tri[:, 2], "i4"),
            color=PALETTE[k % len(PALETTE)], flatshading=True,
            lighting={"ambient": 0.45, "diffuse": 0.75, "specular": 0.0, "roughness": 1.0, "fresnel": 0.0,
                      "facenormalsepsilon": 0, "vertexnormalsepsilon": 0},
            lightposition={"x": 1e5, "y": -2e5, "z": 3e5}))
        parts.append((len(traces) - 1, nodes, tri, cells[o]))

    # ------------------------------------------------ contact surfaces (slave side)
    for c, (pair, spec) in enumerate((res.scene.get("contacts") or {}).items()):
        sel = selected_faces(res, (spec or {}).get("slave", ""), faces, owner)
        if sel is None or not sel.any():
            missing.append(f"contact surface {pair}")
            continue
        nodes, tri = compact(faces[sel])
        traces.append(dict(
            type="mesh3d", name=f"contact {pair}", legendgroup="contact", legendgrouptitle={"text": "contacts"},
            x=typed(x[nodes, 0]), y=typed(x[nodes, 1]), z=typed(x[nodes, 2]),
            i=typed(tri[:, 0], "i4"), j=typed(tri[:, 1], "i4"), k=typed(tri[:, 2], "i4"),
            color=CONTACT_COLORS[c % len(CONTACT_COLORS)], flatshading=True, showlegend=True))
        contacts.append((len(traces) - 1, pair, nodes))

    # ------------------------------------------------ regions of interest
    for name in res.scene.get("regions_of_interest") or {}:
        roi = (res.scene["regions_of_interest"][name]) or {}
        if "boundary" in roi:
            sel = selected_faces(res, roi["boundary"], faces, owner)
            f = faces[sel] if sel is not None else np.zeros((0, 3), int)
        else:
            cells = roi_cells(res, name)
            f = outer_faces(mesh.cells[cells], x)[0] if cells is not None and cells.any() else np.zeros((0, 3), int)
        if not len(f):
            missing.append(f"region of interest {name}")
            continue
        nodes, tri = compact(f)
        traces.append(dict(
            type="mesh3d", name=name, legendgroup="roi", legendgrouptitle={"text": "regions of interest"},
            x=typed(x[nodes, 0]), y=typed(x[nodes, 1]), z=typed(x[nodes, 2]),
            i=typed(tri[:, 0], "i4"), j=typed(tri[:, 1], "i4"), k=typed(tri[:, 2], "i4"),
            color=ROI_COLOR, opacity=0.45, flatshading=True, showlegend=True, visible="legendonly"))

    # ------------------------------------------------ supports and loads: outlines, load arrows
    for what, colour in (("supports", SUPPORT_COLOR), ("loads", LOAD_COLOR)):
        for name, spec in (res.scene.get(what) or {}).items():
            sel = selected_faces(res, name, faces, owner)
            if sel is None or not sel.any():
                missing.append(f"{what[:-1]} on {name}")
                continue
            lx, ly, lz = _lines(x, outline(faces[sel]), step)
            label = f"{'support' if what == 'supports' else 'load'} {name}"
            if what == "loads":
                pick = np.flatnonzero(sel)[np.linspace(0, sel.sum() - 1, min(ARROWS, sel.sum())).astype(int)]
                centre = x[faces[pick]].mean(axis=1)
                if "traction" in (spec or {}):
                    d = np.broadcast_to(np.asarray(spec["traction"], float), centre.shape)
                else:
                    d = -face_normals(x, faces[pick]) * np.sign(float((spec or {}).get("pressure", 1.0)) or 1.0)
                d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300) * 0.06 * scale
                for p, v in zip(centre, d):          # an arrow onto the face: shaft and two barbs
                    side = np.cross(v, [0, 0, 1.0] if abs(v[2]) < 0.9 * np.linalg.norm(v) else [1.0, 0, 0])
                    side *= 0.25 * np.linalg.norm(v) / np.linalg.norm(side)
                    for a, b in ((p - v, p), (p - 0.3 * v + side, p), (p - 0.3 * v - side, p)):
                        for k, out in enumerate((lx, ly, lz)):
                            out += [_round(float(a[k]), step), _round(float(b[k]), step), None]
            traces.append(dict(type="scatter3d", mode="lines", name=label, x=lx, y=ly, z=lz,
                               line={"color": colour, "width": 5}, legendgroup=what,
                               legendgrouptitle={"text": what}, hoverinfo="name", showlegend=True))

    # ------------------------------------------------ the cases and their fields
    cases = distinct_cases(res)
    fs = [res.worst_fields[j] for j, _ in cases]
    us = [f.displacement for f in fs if f.displacement is not None]
    mag = magnification(mesh, max(us, key=lambda u: float(np.nanmax(np.abs(u))))) if us else 1.0
    fields = []

    def add(key, label, on, mode, per_case, scaler, colorscale):
        vals = [np.asarray(a, float) for v in per_case if v is not None for a in v if a is not None]
        if not vals:
            return
        allv = np.concatenate(vals)
        sc, units = scaler(allv)
        finite = allv[np.isfinite(allv)] * sc
        if not finite.size:
            return
        lo = float(np.min(finite))
        lo = 0.0 if lo >= 0 else lo
        hi = float(np.percentile(finite, 99.5))
        fields.append({"key": key, "label": f"{label} [{units}]", "on": on, "mode": mode, "units": units,
                       "cmin": lo, "cmax": hi if hi > lo else lo + 1.0, "colorscale": colorscale})
        for case, v in zip(case_data, per_case):
            case["values"][key] = None if v is None else [None if a is None else typed(np.asarray(a) * sc)
                                                          for a in v]

    case_data = [{"label": label, "values": {}, "displacement": None} for _, label in cases]
    for case, f in zip(case_data, fs):
        if f.displacement is not None:
            case["displacement"] = [[typed(f.displacement[nodes, k]) for k in range(3)] for _, nodes, _, _ in parts]

    def per_part(values, at_nodes: bool):
        return None if values is None else [values[nodes] if at_nodes else values[cells]
                                            for _, nodes, _, cells in parts]
    add("u", "displacement |u|", "body", "vertex",
        [per_part(None if f.displacement is None else np.linalg.norm(f.displacement, axis=1), True) for f in fs],
        length_scale, "Viridis")
    add("von_mises", "von Mises stress", "body", "cell", [per_part(_von_mises(f), False) for f in fs],
        stress_scale, "Viridis")
    add("s1", "largest principal stress σ₁", "body", "cell",
        [per_part(None if f.principal_stress is None else f.principal_stress[:, 0], False) for f in fs],
        stress_scale, "RdBu_r")
    add("s3", "smallest principal stress σ₃", "body", "cell",
        [per_part(None if f.principal_stress is None else f.principal_stress[:, -1], False) for f in fs],
        stress_scale, "RdBu_r")
    add("contact_pressure", "contact pressure −τₙ", "contact", "vertex",
        [_contact_values(f, contacts, x, "contact_pressure") for f in fs], stress_scale, "Hot_r")
    add("contact_slip", "slip |s|", "contact", "vertex",
        [_contact_values(f, contacts, x, "contact_slip") for f in fs], length_scale, "Cividis")

    pad = 0.08 * scale                    # the axis box clips: the faces and load arrows lie inside
    lo, hi = x.min(axis=0) - pad, x.max(axis=0) + pad
    layout = {
        "scene": {"aspectmode": "data", **{f"{a}axis": {"title": {"text": f"{a} [m]"}, "showspikes": False}
                                           for a in "xyz"},
                  "camera": {"eye": {"x": 1.2, "y": -1.6, "z": 0.9}, "up": {"x": 0, "y": 0, "z": 1}}},
        "legend": {"groupclick": "toggleitem", "itemsizing": "constant", "x": 0, "xanchor": "left", "y": 1,
                   "bgcolor": "rgba(255,255,255,0.7)"},
        "margin": {"l": 0, "r": 0, "t": 10, "b": 0}, "uirevision": "view", "height": 640}
    frame = roi_frame(res)
    return {"traces": traces, "layout": layout, "parts": [p[0] for p in parts], "contacts": [c[0] for c in contacts],
            "fields": fields, "cases": case_data, "magnification": mag, "missing": missing,
            "frames": {"whole model": [lo.tolist(), hi.tolist()], **({"regions of interest": [
                (frame[0] - 0.02 * np.ptp(frame, axis=0).max()).tolist(),
                (frame[1] + 0.02 * np.ptp(frame, axis=0).max()).tolist()]} if frame else {})}}


def _contact_values(f, contacts, x: np.ndarray, name: str):
    """The contact field `name` at each contact surface's vertices, matched to the file's contact
    nodes of its pair by position (None for a surface whose vertices are not all among them)."""
    from scipy.spatial import cKDTree
    if f is None or f.contact_coords is None or name not in f.contact:
        return None
    v = f.contact[name]
    v = np.linalg.norm(v, axis=1) if v.ndim == 2 else v
    out = []
    for _, pair, nodes in contacts:
        idx = np.flatnonzero(f.contact_pair == pair)
        if not idx.size:
            out.append(None)
            continue
        d, k = cKDTree(f.contact_coords[idx]).query(x[nodes])
        tol = 1e-9 * float(np.ptp(x, axis=0).max())
        out.append(v[idx[k]] if np.all(d <= tol) else None)
    return out if any(o is not None for o in out) else None


CONTROLLER = r"""
(function () {
  var D = JSON.parse(document.getElementById('view3d-data').textContent);
  var gd = document.getElementById('view3d-plot');
  var caseSel = document.getElementById('view3d-case'), fieldSel = document.getElementById('view3d-field');
  var frameSel = document.getElementById('view3d-frame');
  var deformed = document.getElementById('view3d-deformed'), through = document.getElementById('view3d-through');
  function decode(s) {
    var b = atob(s.bdata), u = new Uint8Array(b.length);
    for (var i = 0; i < b.length; i++) u[i] = b.charCodeAt(i);
    return s.dtype === 'f4' ? new Float32Array(u.buffer) : new Int32Array(u.buffer);
  }
  var base = D.traces.map(function (t) {
    var c = {};
    for (var k in t) c[k] = (t[k] && t[k].bdata) ? decode(t[k]) : t[k];
    return c;
  });
  function traces() {
    var f = D.fields[+fieldSel.value], c = D.cases[+caseSel.value], out = base.map(function (t, i) {
      var o = Object.assign({}, t);
      if (gd.data) o.visible = gd.data[i].visible;
      return o;
    });
    var first = {body: true, contact: true};
    function paint(o, v, k) {
      o.intensity = decode(v); o.intensitymode = f.mode; o.colorscale = f.colorscale;
      o.cmin = f.cmin; o.cmax = f.cmax; o.showscale = first[k]; first[k] = false;
      o.colorbar = {title: {text: f.label, side: 'right'}, len: 0.8};
      o.hovertemplate = f.label.split(' [')[0] + ': %{intensity:.4g} ' + f.units + '<extra>%{fullData.name}</extra>';
    }
    D.parts.forEach(function (ti, p) {
      var o = out[ti];
      if (f && c && f.on === 'body' && c.values[f.key] && c.values[f.key][p]) paint(o, c.values[f.key][p], 'body');
      else if (f && f.on === 'contact') { o.color = '#c8c8c8'; o.opacity = 0.18; }
      if (through.checked) o.opacity = 0.25;
      if (deformed.checked && c && c.displacement) {
        var u = c.displacement[p], m = D.magnification;
        ['x', 'y', 'z'].forEach(function (a, k) {
          var d = decode(u[k]), x0 = base[ti][a], xs = new Float32Array(x0.length);
          for (var n = 0; n < x0.length; n++) xs[n] = x0[n] + m * d[n];
          o[a] = xs;
        });
      }
    });
    D.contacts.forEach(function (ti, p) {
      if (f && c && f.on === 'contact' && c.values[f.key] && c.values[f.key][p]) paint(out[ti], c.values[f.key][p], 'contact');
    });
    return out;
  }
  function frame() {
    var b = D.frames[frameSel.value], lo = b[0], hi = b[1], s = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    var sc = Object.assign({}, D.layout.scene, {aspectmode: 'manual',
      aspectratio: {x: (hi[0] - lo[0]) / s, y: (hi[1] - lo[1]) / s, z: (hi[2] - lo[2]) / s}});
    ['x', 'y', 'z'].forEach(function (a, k) { sc[a + 'axis'] = Object.assign({}, sc[a + 'axis'], {range: [lo[k], hi[k]]}); });
    return Object.assign({}, D.layout, {scene: sc, uirevision: frameSel.value});
  }
  function draw() { return Plotly.react(gd, traces(), frame(), {responsive: true, displaylogo: false}); }
  [caseSel, fieldSel, frameSel, deformed, through].forEach(function (e) { e.addEventListener('change', draw); });
  window.wcsView3d = {draw: draw, plot: gd};
  window.wcsView3dReady = draw().then(function () { gd.setAttribute('data-ready', '1'); });
})();
"""


def view_html(res: Results, plotly_js: str | None = None) -> str:
    """The section's HTML: the controls, the plot's <div>, plotly.js, the data and the controller."""
    import html
    if plotly_js is None:
        from plotly.offline import get_plotlyjs
        plotly_js = get_plotlyjs()
    d = view_data(res)
    esc = html.escape
    options = "".join(f'<option value="{k}">{esc(c["label"])}</option>' for k, c in enumerate(d["cases"]))
    fields = "".join(f'<option value="{k}">{esc(f["label"])}</option>' for k, f in enumerate(d["fields"])) + \
        '<option value="-1">none: the regions in their colours</option>'
    frames = "".join(f'<option value="{esc(k)}">{esc(k)}</option>' for k in d["frames"])
    data = json.dumps(d, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    note = (f'<p class="warn" id="view3d-missing">Not drawn: {esc(", ".join(d["missing"]))} (not a geometric '
            'face selector of the scene, or it selects no outer face).</p>' if d["missing"] else "")
    return (
        '<p>Drag to turn, scroll to zoom, right-drag to move. Click a legend entry to hide or show a region, '
        'a contact surface, a region of interest (hidden at first), the supports (blue outlines) or the loads '
        '(orange outlines, arrows along the load); click a group title for the whole group. '
        'Hover a face for its value.</p>' + note +
        '<div class="view3d-controls">'
        f'<label>case <select id="view3d-case">{options}</select></label> '
        f'<label>field <select id="view3d-field">{fields}</select></label> '
        f'<label>frame <select id="view3d-frame">{frames}</select></label> '
        f'<label><input type="checkbox" id="view3d-deformed"> deformed (displacement × {d["magnification"]:g})</label> '
        '<label><input type="checkbox" id="view3d-through"> see-through</label></div>'
        '<div id="view3d-plot" style="width:100%;height:640px"></div>'
        f'<script>{plotly_js}</script>'
        f'<script type="application/json" id="view3d-data">{data}</script>'
        f'<script>{CONTROLLER}</script>')
