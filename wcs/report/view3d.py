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


def _round(v, step: float) -> list[float]:
    """Coordinates rounded to a multiple of `step` (a length): short JSON for the few lines drawn."""
    return [round(float(c) / step) * step for c in v]


def _segments(points: list[tuple[np.ndarray, np.ndarray]], step: float) -> dict:
    """x, y, z of a Scatter3d drawing the segments (a, b), None between them."""
    out = {"x": [], "y": [], "z": []}
    for a, b in points:
        for k, axis in enumerate("xyz"):
            out[axis] += _round([a[k], b[k]], step) + [None]
    return out


def _mesh3d(name: str, x: np.ndarray, faces: np.ndarray, group: str, title: str, **style) -> dict:
    """A Mesh3d trace of the triangles x[faces] (only the nodes they use), in a legend group."""
    nodes, tri = compact(faces)
    return dict(type="mesh3d", name=name, legendgroup=group, legendgrouptitle={"text": title}, showlegend=True,
                x=typed(x[nodes, 0]), y=typed(x[nodes, 1]), z=typed(x[nodes, 2]),
                i=typed(tri[:, 0], "i4"), j=typed(tri[:, 1], "i4"), k=typed(tri[:, 2], "i4"),
                flatshading=True, **style)


def _parts(res: Results) -> list[tuple[str, str, np.ndarray]]:
    """(name, body, cells) of each region, or each body when the mesh has no regions."""
    mesh = res.mesh
    if mesh.cell_region is not None and mesh.regions:
        groups = [(r, mesh.cell_region == k) for k, r in enumerate(mesh.regions)]
    elif mesh.cell_body is not None and mesh.bodies:
        groups = [(b, mesh.cell_body == k) for k, b in enumerate(mesh.bodies)]
    else:
        groups = [("mesh", np.ones(len(mesh.cells), bool))]
    out = []
    for name, mask in groups:
        cells = np.flatnonzero(mask)
        if cells.size:
            body = (mesh.bodies[int(np.bincount(mesh.cell_body[cells]).argmax())]
                    if mesh.cell_body is not None and mesh.bodies else "")
            out.append((name, body, cells))
    return out


def _load_arrows(x: np.ndarray, faces: np.ndarray, spec: dict, length: float) -> list:
    """Segments of up to ARROWS arrows onto the loaded faces (shaft and two barbs, `length` long):
    along a traction, or against the outward normal for a positive pressure."""
    pick = np.linspace(0, len(faces) - 1, min(ARROWS, len(faces))).astype(int)
    centre = x[faces[pick]].mean(axis=1)
    if "traction" in spec:
        d = np.broadcast_to(np.asarray(spec["traction"], float), centre.shape)
    else:
        d = -face_normals(x, faces[pick]) * (np.sign(float(spec.get("pressure", 1.0))) or 1.0)
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300) * length
    out = []
    for p, v in zip(centre, d):
        side = np.cross(v, [0, 0, 1.0] if abs(v[2]) < 0.9 * np.linalg.norm(v) else [1.0, 0, 0])
        side *= 0.25 * np.linalg.norm(v) / np.linalg.norm(side)
        out += [(p - v, p), (p - 0.3 * v + side, p), (p - 0.3 * v - side, p)]
    return out


def view_data(res: Results) -> dict:
    """The figure (plotly traces and layout) and the cases and fields the page switches between."""
    mesh = res.mesh
    x = mesh.coords
    scale = float(np.ptp(x, axis=0).max()) or 1.0
    faces, owner = outer_faces(mesh.cells, x)
    traces, missing, parts, contacts = [], [], [], []     # parts: (trace, nodes, owner cells); contacts: (trace, pair, nodes)
    lighting = {"ambient": 0.45, "diffuse": 0.75, "specular": 0.0, "roughness": 1.0, "fresnel": 0.0,
                "facenormalsepsilon": 0, "vertexnormalsepsilon": 0}
    for k, (name, body, cells) in enumerate(_parts(res)):
        f, o = outer_faces(mesh.cells[cells], x)
        group = f"body {body}" if body else "mesh"
        traces.append(_mesh3d(name, x, f, group, group, color=PALETTE[k % len(PALETTE)], lighting=lighting,
                              lightposition={"x": 1e5, "y": -2e5, "z": 3e5}))
        parts.append((len(traces) - 1, compact(f)[0], cells[o]))
    for c, (pair, spec) in enumerate((res.scene.get("contacts") or {}).items()):
        sel = selected_faces(res, (spec or {}).get("slave", ""), faces, owner)
        if sel is not None:
            sel[np.flatnonzero(sel)[~_on_contact_nodes(res, pair, x[faces[sel]])]] = False
        if sel is None or not sel.any():
            missing.append(f"contact surface {pair} (no outer face of its slave boundary holds the file's contact nodes)")
            continue
        traces.append(_mesh3d(f"contact {pair}", x, faces[sel], "contact", "contacts",
                              color=CONTACT_COLORS[c % len(CONTACT_COLORS)]))
        contacts.append((len(traces) - 1, pair, compact(faces[sel])[0]))
    for name, roi in (res.scene.get("regions_of_interest") or {}).items():
        if "boundary" in (roi or {}):
            sel = selected_faces(res, roi["boundary"], faces, owner)
            f = faces[sel] if sel is not None else faces[:0]
        else:
            cells = roi_cells(res, name)
            f = outer_faces(mesh.cells[cells], x)[0] if cells is not None and cells.any() else faces[:0]
        if not len(f):
            missing.append(f"region of interest {name} (no cell or face selected)")
            continue
        traces.append(_mesh3d(name, x, f, "roi", "regions of interest", color=ROI_COLOR, opacity=0.45,
                              visible="legendonly"))
    for what, colour in (("supports", SUPPORT_COLOR), ("loads", LOAD_COLOR)):
        for name, spec in (res.scene.get(what) or {}).items():
            sel = selected_faces(res, name, faces, owner)
            if sel is None or not sel.any():
                missing.append(f"{what[:-1]} on {name} (no outer face selected)")
                continue
            segments = [(x[a], x[b]) for a, b in outline(faces[sel])]
            if what == "loads":
                segments += _load_arrows(x, faces[sel], spec or {}, 0.06 * scale)
            traces.append(dict(type="scatter3d", mode="lines", name=f"{what[:-1]} {name}",
                               **_segments(segments, 1e-5 * scale), line={"color": colour, "width": 5},
                               legendgroup=what, legendgrouptitle={"text": what}, hoverinfo="name", showlegend=True))
    cases, fields, mag = _cases(res, parts, contacts, missing)
    pad = 0.08 * scale                    # the axis box clips: the faces and load arrows lie inside
    lo, hi = x.min(axis=0) - pad, x.max(axis=0) + pad
    frames = {"whole model": [lo.tolist(), hi.tolist()]}
    frame = roi_frame(res)
    if frame is not None:                 # first (shown at first) when small in the model, as in the figures
        margin = 0.02 * float(np.ptp(frame, axis=0).max())
        around = {"regions of interest": [(frame[0] - margin).tolist(), (frame[1] + margin).tolist()]}
        frames = {**around, **frames} if np.ptp(frame, axis=0).max() < 0.5 * scale else {**frames, **around}
    layout = {
        "scene": {"aspectmode": "data", **{f"{a}axis": {"title": {"text": f"{a} [m]"}, "showspikes": False}
                                           for a in "xyz"},
                  "camera": {"eye": {"x": 1.2, "y": -1.6, "z": 0.9}, "up": {"x": 0, "y": 0, "z": 1}}},
        "legend": {"groupclick": "toggleitem", "itemsizing": "constant", "x": 0, "xanchor": "left", "y": 1,
                   "bgcolor": "rgba(255,255,255,0.7)"},
        "margin": {"l": 0, "r": 0, "t": 10, "b": 0}, "uirevision": "view", "height": 640}
    return {"traces": traces, "layout": layout, "parts": [p[0] for p in parts], "contacts": [c[0] for c in contacts],
            "fields": fields, "cases": cases, "magnification": mag, "missing": missing, "frames": frames}


def _cases(res: Results, parts: list, contacts: list, missing: list) -> tuple[list, list, float]:
    """Per distinct worst case its label, the displacement at each part's vertices and the values
    of each field on each part or contact surface (`None` where the case lacks it); the fields
    with their common colour range (0 or the least value to the 99.5th percentile over the cases,
    in the units `stress_scale`/`length_scale` choose); the magnification of the deformed shape."""
    chosen = distinct_cases(res)
    fs = [res.worst_fields[j] for j, _ in chosen]
    us = [f.displacement for f in fs if f.displacement is not None]
    mag = magnification(res.mesh, max(us, key=lambda u: float(np.nanmax(np.abs(u))))) if us else 1.0
    cases = [{"label": label, "values": {}, "displacement": None if f.displacement is None else
              [[typed(f.displacement[nodes, k]) for k in range(3)] for _, nodes, _ in parts]}
             for (_, label), f in zip(chosen, fs)]
    fields = []

    def per_part(values, at_nodes: bool):
        return None if values is None else [values[nodes] if at_nodes else values[cells] for _, nodes, cells in parts]

    def add(key, label, on, mode, per_case, scaler, colorscale):
        vals = [np.asarray(a, float) for v in per_case if v is not None for a in v if a is not None]
        allv = np.concatenate(vals) if vals else np.zeros(0)
        finite = allv[np.isfinite(allv)]
        if not finite.size:
            return
        sc, units = scaler(finite)
        lo, hi = min(float(finite.min()) * sc, 0.0), float(np.percentile(finite, 99.5)) * sc
        fields.append({"key": key, "label": f"{label} [{units}]", "on": on, "mode": mode, "units": units,
                       "cmin": lo, "cmax": hi if hi > lo else lo + 1.0, "colorscale": colorscale})
        for case, v in zip(cases, per_case):
            case["values"][key] = None if v is None else [None if a is None else typed(np.asarray(a) * sc) for a in v]

    add("u", "displacement |u|", "body", "vertex",
        [per_part(None if f.displacement is None else np.linalg.norm(f.displacement, axis=1), True) for f in fs],
        length_scale, "Viridis")
    add("von_mises", "von Mises stress", "body", "cell", [per_part(_von_mises(f), False) for f in fs],
        stress_scale, "Viridis")
    for key, label, col in (("s1", "largest principal stress σ₁", 0), ("s3", "smallest principal stress σ₃", -1)):
        add(key, label, "body", "cell",
            [per_part(None if f.principal_stress is None else f.principal_stress[:, col], False) for f in fs],
            stress_scale, "RdBu_r")
    for key, label, scaler, colorscale in (("contact_pressure", "contact pressure −τₙ", stress_scale, "Hot_r"),
                                           ("contact_slip", "slip |s|", length_scale, "Cividis")):
        per_case = []
        for f in fs:
            values, unmatched = _contact_values(f, contacts, res.mesh.coords, key)
            per_case.append(values)
            missing += [m for m in (f"{label} on contact {pair} (its vertices are not the file's contact nodes)"
                                    for pair in unmatched) if m not in missing]
        add(key, label, "contact", "vertex", per_case, scaler, colorscale)
    return cases, fields, mag


def _on_contact_nodes(res: Results, pair: str, tri: np.ndarray) -> np.ndarray:
    """Mask over the triangles tri (k, 3 vertices, 3): those whose vertices are all among the file's
    contact nodes of `pair` (the candidate zone of the contact solve may be part of its surface);
    all of them when the file has no contact nodes."""
    from scipy.spatial import cKDTree
    f = next((f for f in res.worst_fields if f is not None and f.contact_coords is not None), None)
    known = None if f is None else f.contact_coords[f.contact_pair == pair]
    if known is None or not len(known):
        return np.ones(len(tri), bool)
    d, _ = cKDTree(known).query(tri.reshape(-1, 3))
    return (d.reshape(-1, 3) <= 1e-9 * float(np.ptp(res.mesh.coords, axis=0).max())).all(axis=1)


def _contact_values(f, contacts, x: np.ndarray, name: str) -> tuple[list | None, list[str]]:
    """The contact field `name` (a vector by its length) at each contact surface's vertices, matched
    by position to the file's contact nodes of its pair (None for a surface whose vertices are not
    all among them: such pairs are the second item); (None, []) when the case lacks the field."""
    from scipy.spatial import cKDTree
    if f is None or f.contact_coords is None or name not in f.contact:
        return None, []
    v = f.contact[name]
    v = np.linalg.norm(v, axis=1) if v.ndim == 2 else v
    tol = 1e-9 * float(np.ptp(x, axis=0).max())
    out, unmatched = [], []
    for _, pair, nodes in contacts:
        idx = np.flatnonzero(f.contact_pair == pair)
        d, k = cKDTree(f.contact_coords[idx]).query(x[nodes]) if idx.size else (np.inf, None)
        ok = bool(np.all(d <= tol))
        out.append(v[idx[k]] if ok else None)
        unmatched += [] if ok else [pair]
    return (out if any(o is not None for o in out) else None), unmatched


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
    note = (f'<p class="warn" id="view3d-missing">Not drawn: {esc("; ".join(d["missing"]))}.</p>'
            if d["missing"] else "")
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
