"""The report's figures (matplotlib, Agg), each returned as PNG bytes.

Over 500 lines: the report's 2D figures, one function a figure, over the units, scales and mesh
geometry of its first sections.
"""
from __future__ import annotations

import io
import math

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.path import Path as MplPath  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.tri import Triangulation  # noqa: E402

from .data import Contact, Mesh, Results, order_along, uniform_value  # noqa: E402
from .timeline import Histories, defining_level, output_index  # noqa: E402

DPI = 100
plt.rcParams.update({"font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9,
                     "legend.fontsize": 8, "figure.dpi": DPI})
CONTACT_COLORS = ["#d62728", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf"]
ROI_COLOR = "#000000"
SOURCE_COLOR = "#ffd700"
LABEL_OFFSETS = ((0, 0), (0, 12), (0, -12), (28, 0), (-28, 0), (28, 12), (-28, -12), (28, -12), (-28, 12))   # points


def png(fig, tight: bool = True) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, bbox_inches="tight" if tight else None)
    plt.close(fig)
    return buf.getvalue()


# ---------------------------------------------------------------- units and scales

def stress_scale(values) -> tuple[float, str]:
    m = float(np.nanmax(np.abs(values))) if np.size(values) and np.isfinite(values).any() else 0.0
    if m >= 1e6:
        return 1e-6, "MPa"
    if m >= 1e3:
        return 1e-3, "kPa"
    return 1.0, "Pa"


def length_scale(values) -> tuple[float, str]:
    m = float(np.nanmax(np.abs(values))) if np.size(values) and np.isfinite(values).any() else 0.0
    if m >= 1.0:
        return 1.0, "m"
    if m >= 1e-3:
        return 1e3, "mm"
    return 1e6, "µm"


def nice(v: float) -> float:
    """1, 2 or 5 times a power of ten, not above v."""
    if not np.isfinite(v) or v <= 0:
        return 1.0
    e = math.floor(math.log10(v))
    for m in (5, 2, 1):
        if m * 10 ** e <= v:
            return float(m * 10 ** e)
    return float(10 ** e)


def unit_label(units: str) -> str:
    return units.replace("^2", "²").replace("^3", "³") if units else "–"


# ---------------------------------------------------------------- mesh geometry

def boundary_edges(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Edges used by one cell only (outer boundary, holes, both sides of a contact),
    and the cell of each."""
    t = mesh.cells
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    owner = np.tile(np.arange(len(t)), 3)
    key = np.sort(e, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    once = cnt[inv.ravel()] == 1
    return e[once], owner[once]


def subset_outline(mesh: Mesh, cells: np.ndarray) -> np.ndarray:
    """The boundary edges (n, 2) of a subset of cells, as node pairs."""
    t = mesh.cells[cells]
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[cnt[inv.ravel()] == 1]


def _inside(spec: dict, pts: np.ndarray, tol: float) -> np.ndarray:
    """Points selected by a region selector (area: box/disc/polygon) or a boundary
    selector (segment/circle/box)."""
    if "box" in spec:
        x0, y0, x1, y1 = spec["box"]
        return (pts[:, 0] >= x0 - tol) & (pts[:, 0] <= x1 + tol) & (pts[:, 1] >= y0 - tol) & (pts[:, 1] <= y1 + tol)
    if "disc" in spec:
        c, r = np.asarray(spec["disc"]["center"], float), float(spec["disc"]["radius"])
        return np.linalg.norm(pts - c, axis=1) <= r + tol
    if "polygon" in spec:
        return MplPath(np.asarray(spec["polygon"], float)).contains_points(pts, radius=tol) | \
            MplPath(np.asarray(spec["polygon"], float)).contains_points(pts, radius=-tol)
    if "segment" in spec:
        a, b = (np.asarray(p, float) for p in spec["segment"])
        d = b - a
        s = np.clip(((pts - a) @ d) / max(d @ d, 1e-300), 0, 1)
        return np.linalg.norm(pts - (a + s[:, None] * d), axis=1) <= tol
    if "circle" in spec:
        c, r = np.asarray(spec["circle"]["center"], float), float(spec["circle"]["radius"])
        return np.abs(np.linalg.norm(pts - c, axis=1) - r) <= tol + 1e-3 * r
    return np.zeros(len(pts), bool)


def roi_geometry(res: Results, name: str):
    """("cells", index) or ("edges", (n, 2) node pairs) for a region of interest, or None."""
    mesh = res.mesh
    spec = (res.scene.get("regions_of_interest") or {}).get(name)
    if mesh is None or not isinstance(spec, dict):
        return None
    p = mesh.coords
    extent = float(np.ptp(p, axis=0).max()) or 1.0
    tol = 1e-6 * extent
    body = spec.get("body")
    body_ok = np.ones(len(mesh.cells), bool)
    if body and mesh.cell_body is not None and body in mesh.bodies:
        body_ok = mesh.cell_body == mesh.bodies.index(body)
    if "boundary" in spec:
        bspec = (res.scene.get("boundaries") or {}).get(spec["boundary"])
        if not isinstance(bspec, dict):
            return None
        edges, owner = boundary_edges(mesh)
        ok = _inside(bspec, p[edges[:, 0]], tol) & _inside(bspec, p[edges[:, 1]], tol) & body_ok[owner]
        b2 = bspec.get("body")
        if b2 and mesh.cell_body is not None and b2 in mesh.bodies:
            ok &= mesh.cell_body[owner] == mesh.bodies.index(b2)
        return ("edges", edges[ok]) if ok.any() else None
    cent = p[mesh.cells].mean(axis=1)
    sel = np.flatnonzero(_inside(spec, cent, tol) & body_ok)
    return ("cells", sel) if sel.size else None


def roi_box(res: Results, names) -> tuple[float, float, float, float] | None:
    """Bounding box (x0, x1, y0, y1) of some regions of interest, when it is small
    enough against the domain to deserve a zoomed view."""
    mesh = res.mesh
    pts = []
    for n in names:
        g = roi_geometry(res, n)
        if g is None:
            continue
        nodes = mesh.cells[g[1]].ravel() if g[0] == "cells" else g[1].ravel()
        pts.append(mesh.coords[nodes])
    if not pts:
        return None
    pts = np.concatenate(pts)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    dlo, dhi = mesh.coords.min(axis=0), mesh.coords.max(axis=0)
    c, half = (lo + hi) / 2, max((hi - lo).max() * 0.8, 1e-9)
    if 2 * half > 0.5 * (dhi - dlo).max():
        return None
    return (c[0] - half, c[0] + half, c[1] - half, c[1] + half)


def contacts_of(res: Results) -> list[Contact]:
    f = next((f for f in res.worst_fields if f is not None and f.contact_coords is not None), None)
    if f is None:
        return []
    out = []
    for pair in dict.fromkeys(f.contact_pair.tolist()):
        idx = np.flatnonzero(f.contact_pair == pair)
        pts = f.contact_coords[idx]
        o = order_along(pts)
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts[o], axis=0), axis=1))])
        out.append(Contact(pair, pts[o], arc, idx[o]))
    return out


def _axes_m(ax, title=""):
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if title:
        ax.set_title(title)


def _zoom(ax, box):
    if box is not None:
        ax.set_xlim(box[0], box[1])
        ax.set_ylim(box[2], box[3])


# ---------------------------------------------------------------- the scene

def point_sources(res: Results) -> list[tuple[str, float, float]]:
    """(name, x, y) of the scene's point sources (`scene.sources`) at their nominal points."""
    out = []
    for name, src in (res.scene.get("sources") or {}).items():
        point = src.get("point") if isinstance(src, dict) else None
        if isinstance(point, (list, tuple)) and len(point) == 2 and all(isinstance(v, (int, float)) for v in point):
            out.append((str(name), float(point[0]), float(point[1])))
    return out


def place_labels(ax, labels: list[tuple[str, float, float]], beside: int = 0) -> list[str]:
    """Each label at its point or, where its box would overlap one already placed, at the first
    of LABEL_OFFSETS where it does not (the first `beside` labels never on their point: it holds
    a marker); a label whose point is outside the axes' view, or that
    overlaps at every offset, is left out. Returns the names left out for overlapping. Call it
    once the figure's layout is final (the boxes are measured in display units)."""
    renderer = ax.figure.canvas.get_renderer()
    (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
    placed, left_out = [], []
    for i, (name, x, y) in enumerate(labels):
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            continue
        for dx, dy in LABEL_OFFSETS[1:] if i < beside else LABEL_OFFSETS:
            text = ax.annotate(name, (x, y), xytext=(dx, dy), textcoords="offset points", fontsize=7,
                               ha="center", va="center", zorder=9, annotation_clip=False,
                               bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.75))
            box = text.get_window_extent(renderer).expanded(1.05, 1.1)
            if not any(box.overlaps(other) for other in placed):
                placed.append(box)
                break
            text.remove()
        else:
            left_out.append(name)
    return left_out


def scene_figure(res: Results) -> bytes:
    return png(scene_plot(res))


def scene_plot(res: Results):
    """The scene figure: bodies or regions, the mesh, contacts, regions of interest and point
    sources; with regions of interest a zoom on them beside it; labels that would overlap
    placed beside each other or left out and named in the axes' note (`place_labels`)."""
    mesh = res.mesh
    tri = Triangulation(mesh.coords[:, 0], mesh.coords[:, 1], mesh.cells)
    rois = list((res.scene.get("regions_of_interest") or {}).keys())
    box = roi_box(res, rois)
    n_ax = 2 if box is not None else 1
    fig, axes = plt.subplots(1, n_ax, figsize=(6.2 * n_ax, 5.6), squeeze=False)
    contacts = contacts_of(res)
    if mesh.cell_region is not None and len(mesh.regions) > 1:
        labels, colour_of = mesh.regions, mesh.cell_region
    elif mesh.cell_body is not None and mesh.bodies:
        labels, colour_of = mesh.bodies, mesh.cell_body
    else:
        labels, colour_of = ["mesh"], np.zeros(len(mesh.cells), int)
    cmap = plt.get_cmap("Pastel1" if len(labels) <= 9 else "tab20")
    colours = [cmap(i % cmap.N) for i in range(len(labels))]
    lw_mesh = 0.15 if len(mesh.cells) > 3000 else 0.3
    sources = point_sources(res)
    names = [[] for _ in range(n_ax)]          # (name, x, y) to label, per axes
    for k, ax in enumerate(axes[0]):
        ax.tripcolor(tri, facecolors=colour_of.astype(float), cmap=matplotlib.colors.ListedColormap(colours),
                     vmin=-0.5, vmax=len(labels) - 0.5, edgecolors="none")
        ax.triplot(tri, color="0.35", lw=lw_mesh if k == 0 else 0.3)
        for i, c in enumerate(contacts):
            ax.plot(c.coords[:, 0], c.coords[:, 1], "-", color=CONTACT_COLORS[i % len(CONTACT_COLORS)],
                    lw=3.0, solid_capstyle="round", zorder=5)
        for i, name in enumerate(rois):
            g = roi_geometry(res, name)
            if g is None:
                continue
            segs = subset_outline(mesh, g[1]) if g[0] == "cells" else g[1]
            lc = LineCollection(mesh.coords[segs], colors=ROI_COLOR, linewidths=1.6 if g[0] == "cells" else 2.6,
                                linestyles="--" if g[0] == "cells" else "-", zorder=6)
            ax.add_collection(lc)
            if k == n_ax - 1:
                cx, cy = mesh.coords[segs.ravel()].mean(axis=0)
                names[k].append((name, float(cx), float(cy)))
        for name, x, y in sources:                  # labelled first: a source's name is never left out for a region's
            ax.plot([x], [y], marker="*", ms=13, color=SOURCE_COLOR, mec="k", mew=0.8, ls="none", zorder=8)
        names[k] = [*sources, *names[k]]
        _axes_m(ax, "the scene and its mesh" if k == 0 else "zoom: regions of interest")
        if k == 1:
            _zoom(ax, box)
    handles = [Patch(facecolor=colours[i], edgecolor="0.4", label=f"{'region' if labels is mesh.regions else 'body'} {l}")
               for i, l in enumerate(labels)]
    handles += [matplotlib.lines.Line2D([], [], color=CONTACT_COLORS[i % len(CONTACT_COLORS)], lw=3,
                                        label=f"contact {c.pair} (slave side)") for i, c in enumerate(contacts)]
    if rois:
        handles += [matplotlib.lines.Line2D([], [], color=ROI_COLOR, lw=1.6, ls="--", label="region of interest (area)"),
                    matplotlib.lines.Line2D([], [], color=ROI_COLOR, lw=2.6, label="region of interest (boundary piece)")]
    if sources:
        handles += [matplotlib.lines.Line2D([], [], marker="*", ms=11, color=SOURCE_COLOR, mec="k", ls="none",
                                            label="point source (its nominal point)")]
    fig.legend(handles=handles, loc="lower center", ncol=min(4, len(handles)),
               bbox_to_anchor=(0.5, -0.02), frameon=False)
    fig.tight_layout(rect=(0, 0.08 + 0.03 * (len(handles) // 4), 1, 1))
    for ax, items in zip(axes[0], names):
        left_out = place_labels(ax, items, beside=len(sources))
        if left_out:
            ax.text(0.01, 0.01, f"not labelled (overlapping): {', '.join(left_out)}", transform=ax.transAxes,
                    fontsize=6.5, ha="left", va="bottom", zorder=10,
                    bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="0.6", alpha=0.85))
    return fig


# ---------------------------------------------------------------- the worst case

def magnification(mesh: Mesh, u: np.ndarray) -> float:
    umax = float(np.nanmax(np.linalg.norm(u, axis=1))) if u is not None and len(u) else 0.0
    extent = float(np.ptp(mesh.coords, axis=0).max())
    if umax <= 0 or not np.isfinite(umax):
        return 1.0
    return nice(0.06 * extent / umax)


def worst_case_figure(res: Results, j: int) -> tuple[bytes, float]:
    """Deformed mesh with von Mises; von Mises and principal stress directions zoomed on
    the criterion's regions of interest; the temperature when there is one."""
    mesh, f = res.mesh, res.worst_fields[j]
    crit = res.criteria[j]
    u = f.displacement if f.displacement is not None else np.zeros_like(mesh.coords)
    mag = magnification(mesh, u)
    tri0 = Triangulation(mesh.coords[:, 0], mesh.coords[:, 1], mesh.cells)
    pd = mesh.coords + mag * u
    tri = Triangulation(pd[:, 0], pd[:, 1], mesh.cells)
    box = roi_box(res, crit.regions or list((res.scene.get("regions_of_interest") or {}).keys()))
    vm = f.von_mises
    if vm is None and f.stress is not None:
        s = f.stress
        vm = np.sqrt(0.5 * ((s[:, 0] - s[:, 1]) ** 2 + (s[:, 1] - s[:, 2]) ** 2 + (s[:, 2] - s[:, 0]) ** 2)
                     + 3 * s[:, 3] ** 2)
    panels = ["deformed"] + (["vm-zoom"] if box is not None and vm is not None else []) + ["directions"] \
        + (["T"] if f.temperature is not None else [])
    if len(panels) == 4:
        fig, axes = plt.subplots(2, 2, figsize=(11.0, 9.4))
        axes = axes.ravel()
    else:
        fig, axes = plt.subplots(1, len(panels), figsize=(5.0 * len(panels), 4.5), squeeze=False)
        axes = axes[0]
    edges, _ = boundary_edges(mesh)
    lo, hi = mesh.coords.min(axis=0), mesh.coords.max(axis=0)
    view = box if box is not None else (lo[0], hi[0], lo[1], hi[1])
    cent = mesh.coords[mesh.cells].mean(axis=1)
    for ax, panel in zip(axes, panels):
        if panel == "deformed":
            ax.add_collection(LineCollection(mesh.coords[edges], colors="0.55", linewidths=0.6, linestyles=":"))
            if vm is not None:
                sc, su = stress_scale(vm)
                top = float(np.nanpercentile(vm, 99.5))
                pc = ax.tripcolor(tri, facecolors=vm * sc, cmap="viridis", edgecolors="none", vmin=0, vmax=top * sc)
                fig.colorbar(pc, ax=ax, shrink=0.85, extend="max" if np.nanmax(vm) > top else "neither",
                             label=f"von Mises stress [{su}]")
            else:
                ax.triplot(tri, color="0.3", lw=0.2)
            ax.add_collection(LineCollection(pd[edges], colors="k", linewidths=0.5))
            ax.autoscale_view()
            _axes_m(ax, f"deformed shape (displacement × {mag:g}), von Mises")
        elif panel == "vm-zoom":
            inview = (cent[:, 0] >= view[0]) & (cent[:, 0] <= view[1]) & (cent[:, 1] >= view[2]) & (cent[:, 1] <= view[3])
            sc, su = stress_scale(vm[inview] if inview.any() else vm)
            top = float(np.nanmax(vm[inview])) if inview.any() else float(np.nanmax(vm))
            pc = ax.tripcolor(tri0, facecolors=vm * sc, cmap="viridis", edgecolors="none", vmin=0, vmax=top * sc)
            fig.colorbar(pc, ax=ax, shrink=0.85, label=f"von Mises stress [{su}]")
            ax.add_collection(LineCollection(mesh.coords[edges], colors="w", linewidths=0.8))
            _axes_m(ax, "von Mises near the regions of interest (undeformed)")
            _zoom(ax, view)
        elif panel == "directions":
            ax.add_collection(LineCollection(mesh.coords[edges], colors="k", linewidths=0.8))
            if f.stress is not None:
                _principal_crosses(ax, mesh, f.stress, view)
            _axes_m(ax, "principal stress directions" + (" (zoom)" if box is not None else ""))
            _zoom(ax, view)
        else:
            temperature_panel(fig, ax, tri0, f.temperature)
    fig.tight_layout()
    return png(fig), mag


def temperature_panel(fig, ax, tri: Triangulation, temperature: np.ndarray) -> None:
    """The temperature on the undeformed mesh with its colour bar; a field uniform up to round-off
    (`uniform_value`) in one colour, its value in the title and no colour bar."""
    flat = uniform_value(temperature)
    if flat is None:
        pc = ax.tripcolor(tri, temperature, shading="gouraud", cmap="inferno")
        fig.colorbar(pc, ax=ax, shrink=0.85, label="temperature [K]")
        _axes_m(ax, "temperature")
        return
    ax.tripcolor(tri, np.full(len(temperature), flat), shading="gouraud", cmap="inferno", vmin=flat - 1.0,
                 vmax=flat + 1.0)
    _axes_m(ax, f"temperature: uniform, {flat:.6g} K")


def _principal_crosses(ax, mesh: Mesh, stress: np.ndarray, view, n=22):
    """A cross per sampled cell: both principal directions, length ∝ |σ|, red tension, blue compression."""
    x0, x1, y0, y1 = view
    cent = mesh.coords[mesh.cells].mean(axis=1)
    inview = np.flatnonzero((cent[:, 0] >= x0) & (cent[:, 0] <= x1) & (cent[:, 1] >= y0) & (cent[:, 1] <= y1))
    if inview.size == 0:
        return
    h = max(x1 - x0, y1 - y0) / n
    key = np.floor((cent[inview] - [x0, y0]) / h).astype(int)
    _, first = np.unique(key, axis=0, return_index=True)
    cells = inview[first]
    sxx, syy, sxy = stress[cells, 0], stress[cells, 1], stress[cells, 3]
    c, r = (sxx + syy) / 2, np.sqrt(((sxx - syy) / 2) ** 2 + sxy ** 2)
    th = 0.5 * np.arctan2(2 * sxy, sxx - syy)
    s1, s2 = c + r, c - r
    smax = float(np.max(np.abs(np.concatenate([s1, s2])))) or 1.0
    segs, cols = [], []
    for s, ang in ((s1, th), (s2, th + np.pi / 2)):
        half = 0.45 * h * np.abs(s) / smax
        d = np.column_stack([np.cos(ang), np.sin(ang)]) * half[:, None]
        p = cent[cells]
        segs += list(np.stack([p - d, p + d], axis=1))
        cols += ["#d62728" if v > 0 else "#1f4fd6" for v in s]
    ax.add_collection(LineCollection(segs, colors=cols, linewidths=1.3))
    sc, su = stress_scale(smax)
    ax.plot([], [], color="#d62728", label="tension")
    ax.plot([], [], color="#1f4fd6", label="compression")
    ax.legend(loc="upper right", title=f"longest = {smax * sc:.3g} {su}", title_fontsize=7)


# ---------------------------------------------------------------- contacts

def contact_figure(res: Results) -> bytes | None:
    contacts = contacts_of(res)
    if not contacts:
        return None
    cases = distinct_cases(res)
    quantities = [q for q in ("contact_pressure", "contact_slip") if any(q in res.worst_fields[j].contact for j, _ in cases)]
    if not quantities:
        return None
    fig, axes = plt.subplots(len(quantities), len(contacts), figsize=(max(4.6 * len(contacts), 6), 2.9 * len(quantities)),
                             squeeze=False)
    for ci, c in enumerate(contacts):
        for qi, q in enumerate(quantities):
            ax = axes[qi, ci]
            allv = np.concatenate([res.worst_fields[j].contact[q][c.order] for j, _ in cases if q in res.worst_fields[j].contact])
            sc, su = stress_scale(allv) if q == "contact_pressure" else length_scale(allv)
            for k, (j, label) in enumerate(cases):
                v = res.worst_fields[j].contact.get(q)
                if v is not None:
                    ax.plot(c.arc, v[c.order] * sc, "-", lw=1.4, color=f"C{k}", label=label)
            ax.set_xlabel(f"arc position s [m] from ({c.coords[0, 0]:.3g}, {c.coords[0, 1]:.3g})")
            ax.set_ylabel(("contact pressure" if q == "contact_pressure" else "tangential slip") + f" [{su}]")
            ax.set_title(f"{c.pair}: {'pressure −τₙ' if q == 'contact_pressure' else 'slip'}")
            ax.grid(alpha=0.3)
            if qi == 0 and ci == 0:
                ax.legend(loc="best")
    fig.tight_layout()
    return png(fig)


def distinct_cases(res: Results) -> list[tuple[int, str]]:
    """(criterion index, label) of the worst cases with fields, one per distinct data set — in a
    dynamic study per data set and output time, the fields' time in the label (two criteria
    worst at the same data but at different times are two cases)."""
    out, seen = [], []
    for j, c in enumerate(res.criteria):
        f = res.worst_fields[j]
        if f is None:
            continue
        if res.kind == "solve":
            return [(j, "nominal data")]
        at = _output_time(res, j)
        dup = next((k for k, x, t in seen if np.array_equal(x, c.worst_x, equal_nan=True) and t == at), None)
        if dup is not None:
            out[dup] = (out[dup][0], out[dup][1] + [c.name])
            continue
        seen.append((len(out), c.worst_x, at))
        out.append((j, [c.name]))
    return [(j, f"worst {', '.join(names)}" + ("" if seen[k][2] is None else f" at t = {seen[k][2]:.4g} s"))
            for k, (j, names) in enumerate(out)]


def _output_time(res: Results, j: int) -> float | None:
    """The output time criterion j's worst-case fields are at (None: a static study's)."""
    h = res.histories
    if h is None or h.output_time is None:
        return None
    return float(h.output_time[output_index(h, j)])


# ---------------------------------------------------------------- evaluations

def scatter_figure(res: Results, j: int, units: list[str]) -> bytes:
    """Criterion j against each parameter over all evaluations."""
    crit = res.criteria[j]
    n = len(res.params)
    ncol = min(6, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(2.15 * ncol, 1.85 * nrow + 0.3), squeeze=False, sharey=True)
    ok, bad = ~res.failed, res.failed
    y = res.phi[:, j]
    good = ok & np.isfinite(y)
    for k in range(nrow * ncol):
        ax = axes.flat[k]
        if k >= n:
            ax.set_visible(False)
            continue
        x = res.x[:, k]
        ax.plot(x[good], y[good], "o", ms=3, color="C0", alpha=0.7, label="solved")
        if bad.any():
            ax.plot(x[bad], np.zeros(bad.sum()), "x", ms=5, color="#d62728",
                    transform=matplotlib.transforms.blended_transform_factory(ax.transData, ax.transAxes),
                    clip_on=False, label="failed")
        if crit.worst_eval is not None:
            ax.plot(x[crit.worst_eval], y[crit.worst_eval], "*", ms=10, color="#d62728", mec="k", mew=0.5, label="worst")
        lo, hi = res.lower[k], res.upper[k]
        if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
            pad = 0.05 * (hi - lo)
            ax.set_xlim(lo - pad, hi + pad)
            ax.axvspan(lo, hi, color="0.93", zorder=0)
        ax.set_xlabel(_short(res.params[k]) + f" [{units[k]}]", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(4))
        ax.yaxis.set_major_locator(matplotlib.ticker.MaxNLocator(5))
        ax.xaxis.get_offset_text().set_fontsize(6)
        ax.yaxis.get_offset_text().set_fontsize(6)
        if k % ncol == 0:
            ax.set_ylabel(f"{crit.name} [{unit_label(crit.units)}]", fontsize=8)
    note = _limit_line(axes.flat[0], crit.limit, y[good], all_axes=list(axes.flat[:n]))
    handles, labels = axes.flat[0].get_legend_handles_labels()
    if np.isfinite(crit.limit):
        handles.append(matplotlib.lines.Line2D([], [], color="#d62728", ls="--"))
        labels.append(f"limit {crit.limit:.4g} {unit_label(crit.units)}" + (f" ({note})" if note else ""))
    fig.legend(handles, labels, loc="upper center", ncol=len(labels), frameon=False, bbox_to_anchor=(0.5, 1.0))
    height = 1.85 * nrow + 0.3           # fixed margins: tight_layout is slow on a big grid
    fig.subplots_adjust(left=0.75 / (2.15 * ncol), right=0.99, bottom=0.5 / height, top=1 - 0.4 / height,
                        wspace=0.12, hspace=0.55)
    return png(fig, tight=False)


def _short(path: str) -> str:
    """A dotted path without its section (and `friction.`): `fault_west.slip_limit[0]`."""
    parts = [p for p in path.split(".") if p != "friction"]
    return ".".join(parts[1:]) if len(parts) > 2 else path


def _limit_line(ax, limit, values, all_axes=None) -> str:
    """The limit as a dashed line when it is near the data; otherwise a note of where it is."""
    if not np.isfinite(limit):
        return ""
    finite = values[np.isfinite(values)]
    if finite.size:
        lo, hi = float(finite.min()), float(finite.max())
        span = max(hi - lo, 1e-12 * max(abs(hi), 1.0))
        near = lo - 1.5 * span <= limit <= hi + 1.5 * span
    else:
        near = True
    if near:
        for a in all_axes or [ax]:
            a.axhline(limit, color="#d62728", ls="--", lw=1)
        return ""
    return "above the plotted range" if limit > finite.max() else "below the plotted range"


def best_so_far_figure(res: Results) -> bytes:
    m = len(res.criteria)
    ncol = min(3, m)
    nrow = math.ceil(m / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.3 * ncol, 3.0 * nrow), squeeze=False)
    idx = np.arange(1, res.n_eval + 1)
    stages = list(dict.fromkeys(res.stage))
    for j, crit in enumerate(res.criteria):
        ax = axes.flat[j]
        y = np.where(res.failed, np.nan, res.phi[:, j])
        best = np.fmax.accumulate(np.where(np.isfinite(y), y, -np.inf))
        best[~np.isfinite(best)] = np.nan
        for k, st in enumerate(stages):
            sel = np.array([s == st for s in res.stage]) & np.isfinite(y)
            ax.plot(idx[sel], y[sel], "o", ms=3, alpha=0.6, color=f"C{k}", label=f"{st}")
        ax.step(idx, best, where="post", color="k", lw=1.5, label="best so far")
        if res.failed.any():
            ax.plot(idx[res.failed], np.zeros(res.failed.sum()), "x", color="#d62728", ms=5, clip_on=False,
                    transform=matplotlib.transforms.blended_transform_factory(ax.transData, ax.transAxes),
                    label="failed")
        note = _limit_line(ax, crit.limit, y)
        if np.isfinite(crit.limit):
            ax.plot([], [], color="#d62728", ls="--", label=f"limit {crit.limit:.3g}" + (f"\n({note})" if note else ""))
        ax.set_xlabel("forward solves")
        ax.set_ylabel(f"{crit.name} [{unit_label(crit.units)}]")
        ax.set_title(crit.name)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    for k in range(m, nrow * ncol):
        axes.flat[k].set_visible(False)
    fig.tight_layout()
    return png(fig)


def failures_figure(res: Results) -> bytes:
    """Where in the box the evaluations failed: each data set as a line over the
    parameters scaled to the box (0 = lower, 1 = upper)."""
    n = len(res.params)
    width = np.where(res.upper > res.lower, res.upper - res.lower, 1.0)
    z = (res.x - res.lower) / width
    fig, ax = plt.subplots(figsize=(max(6.0, 0.42 * n + 2), 3.4))
    k = np.arange(n)
    ok = ~res.failed
    for row in z[ok]:
        ax.plot(k, row, "-", color="0.6", lw=0.6, alpha=0.5)
    codes = sorted(set(res.status[res.failed].tolist()))
    for ci, code in enumerate(codes):
        for r, row in enumerate(z[res.status == code]):
            ax.plot(k, row, "-o", ms=3, lw=1.2, color=CONTACT_COLORS[ci % len(CONTACT_COLORS)],
                    label=f"status {code}: {res.status_meanings.get(code, '?')}" if r == 0 else None)
    ax.plot([], [], "-", color="0.6", label="solved")
    ax.set_xticks(k)
    ax.set_xticklabels([_short(p) for p in res.params], rotation=60, ha="right", fontsize=7)
    ax.set_ylim(-0.05, 1.05)
    ax.set_yticks([0, 0.5, 1])
    ax.set_yticklabels(["lower", "mid", "upper"])
    ax.set_ylabel("position in the box [–]")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.01), ncol=3, frameon=False)
    fig.tight_layout()
    return png(fig)


# ---------------------------------------------------------------- both ends, membership

def _limits(ax, crit) -> None:
    """The criterion's limits as vertical red lines (upper dashed, lower dotted)."""
    for value, label, ls in ((crit.limit, "upper limit", "--"), (crit.limit_lower, "lower limit", ":")):
        if np.isfinite(value):
            ax.axvline(value, color="#d62728", ls=ls, lw=1.2, label=label)


def range_figure(res: Results) -> bytes:
    """Per criterion the interval [min, max] found (a bar; a dot for an end alone) against its
    limits (red lines), one row each (criteria have their own units)."""
    m = len(res.criteria)
    fig, axes = plt.subplots(m, 1, figsize=(7.5, 0.9 + 0.75 * m), squeeze=False)
    for j, c in enumerate(res.criteria):
        ax = axes[j, 0]
        ends = [v for v in (c.best, c.worst) if np.isfinite(v)]
        if len(ends) == 2:
            ax.plot([c.best, c.worst], [0, 0], color="#1f3a5f", lw=6, solid_capstyle="butt", label="[min, max]")
        ax.plot(ends, [0] * len(ends), "o", color="#1f3a5f", ms=5)
        _limits(ax, c)
        ax.set_yticks([])
        ax.set_ylabel(c.name, rotation=0, ha="right", va="center")
        ax.set_xlabel(f"[{unit_label(c.units)}]", fontsize=8)
        ax.grid(alpha=0.3, axis="x")
    labelled = {}
    for ax in axes.flat:
        for h, label in zip(*ax.get_legend_handles_labels()):
            labelled.setdefault(label, h)
    if labelled:
        axes[0, 0].legend(list(labelled.values()), list(labelled), fontsize=7, loc="upper left",
                          bbox_to_anchor=(1.0, 1.2))
    fig.tight_layout()
    return png(fig)


def membership_figure(res: Results, j: int) -> bytes:
    """The membership function of criterion j: at each α-level the interval [min, max] of the
    criterion over the α-cut (a horizontal bar at height α), the ends joined, and the limits."""
    lv, c = res.levels, res.criteria[j]
    fig, ax = plt.subplots(figsize=(5.6, 3.2))
    lo, hi = lv.best[:, j], lv.worst[:, j]
    for a, b, w in zip(lv.alpha, lo, hi):
        if np.isfinite(b) and np.isfinite(w):
            ax.plot([b, w], [a, a], color="#1f3a5f", lw=3, alpha=0.6)
    for ends, label in ((hi, "max over the α-cut"), (lo, "min over the α-cut")):
        ok = np.isfinite(ends)
        if ok.any():
            ax.plot(ends[ok], lv.alpha[ok], "o-", color="#1f3a5f" if label.startswith("max") else "#2ca02c",
                    ms=4, label=label)
    _limits(ax, c)
    ax.set_ylim(-0.05, 1.05)
    ax.set_ylabel("membership α")
    ax.set_xlabel(f"{c.name} [{unit_label(c.units)}]")
    ax.set_title(f"{c.name}: membership function")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    return png(fig)


# ---------------------------------------------------------------- after the search: what drives an extreme

DRIVER_BARS = 15            # bars shown per criterion; the rest are summed into one


def drivers_figure(params: list[str], drivers: np.ndarray, signs: np.ndarray, units: str, title: str) -> bytes:
    """Ranked horizontal bars |dΦ/dx_i|(u_i − l_i), largest on top; red: Φ grows with x_i, blue: it falls.
    Beyond DRIVER_BARS the rest is one grey bar ("k others")."""
    order = np.argsort(-drivers, kind="stable")
    shown = order[:DRIVER_BARS]
    labels = [_short(params[i]) for i in shown]
    values = list(drivers[shown])
    colors = ["#d62728" if signs[i] > 0 else "#1f77b4" for i in shown]
    if order.size > DRIVER_BARS:
        labels.append(f"{order.size - DRIVER_BARS} others (sum)")
        values.append(float(drivers[order[DRIVER_BARS:]].sum()))
        colors.append("0.6")
    fig, ax = plt.subplots(figsize=(6.4, 0.28 * len(values) + 1.2))
    y = np.arange(len(values))[::-1]
    ax.barh(y, values, color=colors)
    ax.set_yticks(y)
    ax.set_yticklabels(labels, fontsize=7)
    ax.set_xlabel(f"|∂Φ/∂xᵢ| · (uᵢ − lᵢ) [{unit_label(units)}]")
    ax.set_title(title)
    ax.grid(axis="x", alpha=0.3)
    ax.legend(handles=[Patch(color="#d62728", label="grows with xᵢ"), Patch(color="#1f77b4", label="falls with xᵢ")],
              fontsize=7, loc="lower right")
    fig.tight_layout()
    return png(fig)


def history_figure(hist: Histories, j: int, name: str, units: str, limit: float) -> bytes:
    """Criterion j against time at its worst data, the defining level marked (the peak for max)
    and the limit drawn where there is one."""
    fig, ax = plt.subplots(figsize=(6.4, 2.6))
    h = hist.values[j]
    ax.plot(hist.time, h, color="#1f3a5f", lw=1.4, label=name)
    n = defining_level(h, hist.over[j])
    if n is not None:
        ax.plot([hist.time[n]], [h[n]], "o", color="#d1242f", ms=7, zorder=3,
                label=f"{ {'max': 'peak', 'min': 'least', 'final': 'end'}[hist.over[j]]} {h[n]:.4g} at t = {hist.time[n]:.4g} s")
    elif np.isfinite(h).any():
        ax.axhline(np.nanmean(h), color="#d1242f", ls=":", label=f"mean {np.nanmean(h):.4g}")
    if np.isfinite(limit):
        ax.axhline(limit, color="#82071e", ls="--", lw=1, label=f"limit {limit:.4g}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"{name} [{unit_label(units)}]")
    ax.grid(alpha=.3)
    ax.legend(loc="best")
    return png(fig)
