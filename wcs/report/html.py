"""The report as one self-contained HTML page (inline CSS, images as data: URIs).

Over 500 lines for one page: `Report` renders the sections of one HTML page in their order, a method
a section.
"""
from __future__ import annotations

import base64
import datetime as _dt
import html
import math
import re
import sys
import traceback

import numpy as np

from ..model.criteria import in_words
from ..results.drivers import IDLE, NO_EXTREME, idle
from ..results.extremes import pairs
from ..progress import phase
from ..model.validity import MAX_DISPLACEMENT, MAX_GRADIENT
from ..results.verdict import CLOSE
from . import plots, plots3d, timeline, view3d
from .data import KIND_LABEL, Results, uniform_value

SECTIONS = [
    ("summary", "Summary"),
    ("limits", "Limits"),
    ("histories", "Each criterion against time at its worst data"),
    ("membership", "Membership function of each criterion (fuzzy data)"),
    ("scene", "The scene and mesh"),
    ("view3d", "The model in 3D (interactive)"),
    ("mesh-check", "The mesh's share"),
    ("worst-data", "Worst data set per criterion"),
    ("drivers", "What drives the extremes"),
    ("worst-fields", "Deformed shape and stresses at the worst case"),
    ("contact", "Contact pressure and slip"),
    ("criteria-vs-parameters", "Criteria against the parameters"),
    ("best-so-far", "Best so far against solves"),
    ("failures", "Failures"),
    ("provenance", "Provenance"),
]

CSS = """
body{font-family:-apple-system,'Segoe UI',Roboto,'DejaVu Sans',Arial,sans-serif;margin:0;color:#1b1f24;background:#fff;line-height:1.4}
main{max-width:1240px;margin:0 auto;padding:16px 28px 48px}
header{background:#1f3a5f;color:#fff;padding:18px 28px}
header h1{margin:0 0 4px;font-size:24px}
header p{margin:0;opacity:.85}
nav{background:#eef2f7;padding:8px 28px;font-size:13px;border-bottom:1px solid #d0d7de}
nav a{margin-right:14px;color:#1f3a5f;text-decoration:none}
h2{border-bottom:2px solid #1f3a5f;padding-bottom:3px;margin-top:34px;font-size:19px}
h3{font-size:15px;margin:18px 0 6px}
table{border-collapse:collapse;margin:8px 0 14px;font-size:13px}
th,td{border:1px solid #d0d7de;padding:4px 8px;text-align:left;vertical-align:middle}
th{background:#f3f5f8}
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
.pass{background:#dff5e3;color:#11612a;font-weight:bold}
.fail{background:#d1242f;color:#fff;font-weight:bold}
.none{color:#57606a}
.verdict{display:inline-block;font-size:22px;font-weight:bold;padding:6px 18px;border-radius:6px;margin:6px 0}
.verdict.pass{border:2px solid #11612a}
.verdict.fail{border:2px solid #82071e}
.verdict.none{background:#eef2f7;border:2px solid #8c959f}
.bar{position:relative;width:160px;height:12px;background:#e6ebf1;border:1px solid #aab4bf;border-radius:2px}
.bar .mark{position:absolute;top:-3px;width:4px;height:16px;margin-left:-2px;background:#1f3a5f}
.bar .mark.bound{background:#d1242f}
.atbound{color:#d1242f;font-weight:bold}
img{max-width:100%;height:auto;border:1px solid #e1e4e8;margin:6px 0}
.note{color:#57606a;font-size:13px}
.warn{background:#fff8c5;border:1px solid #d4a72c;padding:6px 10px;font-size:13px}
details{margin:8px 0}
summary{cursor:pointer;color:#1f3a5f;font-weight:bold}
pre{background:#f6f8fa;border:1px solid #d0d7de;padding:10px;font-size:12px;overflow-x:auto;white-space:pre}
dl.kv{display:grid;grid-template-columns:max-content auto;gap:2px 16px;font-size:13px}
dl.kv dt{font-weight:bold}
dl.kv dd{margin:0;font-family:monospace;word-break:break-all}
.wide{overflow-x:auto;max-width:100%}
.view3d-controls{font-size:13px;margin:6px 0}
.view3d-controls label{margin-right:12px}
"""

NOT_SEARCHED = "Its maximum is not searched (sense: min): see its minimum under Limits."

SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")

PARAM_UNITS = [
    (r"^materials\.[^.]+\.(E|lambda|mu)$", "Pa"), (r"^materials\.[^.]+\.nu$", "–"),
    (r"^materials\.[^.]+\.density_weight$", "N/m³"), (r"^materials\.[^.]+\.expansion$", "1/K"),
    (r"^materials\.[^.]+\.conductivity$", "W/(m·K)"), (r"^loads\.[^.]+\.(pressure|traction)", "Pa"),
    (r"^body_forces\.", "N/m³"), (r"^supports\.[^.]+\.(u|normal)", "m"),
    (r"friction\.slip_limit", "Pa"), (r"friction\.coefficient", "–"),
    (r"^thermal\.(temperature|reference)", "K"), (r"^thermal\.sources", "W/m³"),
]


def param_units(path: str) -> str:
    for pattern, u in PARAM_UNITS:
        if re.search(pattern, path):
            return u
    return "–"


def _what(c) -> str:
    """A criterion in words: its reduction over its regions (`wcs.model.criteria.in_words`; its kind's
    label where the file does not name its regions), "—" where the kind is unknown."""
    return in_words(c.kind, c.regions) if c.kind in KIND_LABEL else (c.kind or "—")


def number(v, units: str = "", digits: int = 4, difference: bool = False) -> str:
    """A number for people: 4 significant digits, ×10ⁿ for large and small ones, units; a
    temperature in K also in °C, unless it is a `difference` (a margin, an error)."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    v = float(v)
    u = plots.unit_label(units) if units and units != "–" else ""
    if v == 0:
        s = "0"
    else:
        e = math.floor(math.log10(abs(v)))
        if -3 <= e < 5:
            s = f"{v:.{max(digits - 1 - e, 0)}f}" if e < digits else f"{v:.0f}"
        else:
            m = v / 10 ** e
            if round(abs(m), digits - 1) >= 10:
                m, e = m / 10, e + 1
            s = f"{m:.{digits - 1}f} × 10{str(e).translate(SUPERSCRIPT)}"
    s = s.replace("-", "−")
    out = f"{s} {u}".strip()
    if units == "K" and not difference:
        out += f" ({v - 273.15:.1f} °C)"
    return out


def esc(s) -> str:
    return html.escape(str(s))


def img(data: bytes, alt: str) -> str:
    return f'<img alt="{esc(alt)}" src="data:image/png;base64,{base64.b64encode(data).decode()}">'


class Report:
    def __init__(self, res: Results, source: str = "", strict: bool = False):
        self.res = res
        self.source = source
        self.strict = strict
        self.units = [("" if u == "1" else u) if u else param_units(p) for u, p in   # "1": dimensionless
                      zip(res.param_units or [""] * len(res.params), res.params)]
        self.problems: list[str] = []

    # ------------------------------------------------------------ helpers
    def guarded(self, sid: str, title: str, build) -> str:
        try:
            body = build()
        except Exception as e:  # noqa: BLE001 - one broken figure must not lose the whole report
            if self.strict:
                raise
            self.problems.append(f"{sid}: {type(e).__name__}: {e}")
            print(f"warning: report section {sid!r} could not be drawn: {type(e).__name__}: {e}", file=sys.stderr)
            body = (f'<p class="warn report-error">This section could not be drawn: '
                    f'{esc(type(e).__name__)}: {esc(e)}</p>'
                    f'<details><summary>details</summary><pre>{esc(traceback.format_exc())}</pre></details>')
        return f'<section id="{sid}">\n<h2>{esc(title)}</h2>\n{body}\n</section>\n'

    def verdicts(self):
        """Per criterion: "pass", "fail", "unknown" (a limit without a value to read it against)
        or "none" (no limit); the upper limit against the worst value, the lower against the best."""
        out = []
        for c in self.res.criteria:
            checks = [None if not math.isfinite(v) else ok for v, ok, lim in
                      ((c.worst, c.worst <= c.limit, c.limit), (c.best, c.best >= c.limit_lower, c.limit_lower))
                      if math.isfinite(lim)]
            out.append("none" if not checks else "fail" if False in checks else "unknown" if None in checks
                       else "pass")
        return out

    def mesh_verdicts(self):
        """`verdicts` read with the mesh check: "marginal" where a limit of the criterion lies
        within an extreme ± its estimated mesh error."""
        return ["marginal" if v in ("pass", "fail") and self.marginal(c.name) else v
                for c, v in zip(self.res.criteria, self.verdicts())]

    def marginal(self, criterion: str) -> bool:
        a = self.res.after_search
        return a is not None and "mesh_check_verdict" in a and \
            bool((a["mesh_check_verdict"].sel(criterion=criterion) == "MARGINAL").any())

    def fallbacks(self) -> dict[str, int]:
        """Solved evaluations whose message names a fallback, `solved (B after A ...)`: message -> count."""
        out: dict[str, int] = {}
        for m, st in zip(self.res.messages or [], self.res.status):
            if st == 0 and m.startswith("solved (") and " after " in m:
                out[m] = out.get(m, 0) + 1
        return out

    # ------------------------------------------------------------ sections
    def summary(self) -> str:
        r, a = self.res, self.res.attrs
        n_fail = int(r.failed.sum())
        v = r.verdict
        verdict, why = v.label, "; ".join(v.reasons)
        cls = {"FAIL": "fail", "PASS": "none" if v.unchecked else "pass"}.get(v.word, "none")
        what = {"run": "worst-scenario search", "sweep": "grid sweep", "solve": "single forward solve (nominal data)"}[r.kind]
        rows = [("study", esc(r.study)), ("results file", esc(self.source) or "—"),
                ("created", esc(a.get("created", "—"))), ("kind", what),
                ("evaluations", f"{r.n_eval} ({n_fail} failed)"),
                ("parameters", f"{len(r.params)} uncertain numbers"),
                ("criteria", ", ".join(esc(c.name) for c in r.criteria))]
        if r.small_strain is not None:
            ratio, grad = r.small_strain
            rows.append(("small strains", f"max |∇u| {grad:.3g} (small-strain theory: ≤ {MAX_GRADIENT:g}), "
                         f"max |u| / body size {ratio:.3g} (≤ {MAX_DISPLACEMENT:g}), "
                         f"{'at the solved case' if r.kind == 'solve' else 'over the nominal and the worst cases'}"
                         f"{'' if r.validity else ': within'}"))
        body = ""
        if r.incomplete:
            body += incomplete_banner(r.incomplete)
        body += (f'<div class="verdict {cls}" id="verdict">{esc(verdict)}</div>'
                 f'<p id="verdict-reasons">{esc(why)}.</p>')
        if v.unchecked:
            body += (f'<p class="warn" id="mesh-share-unknown"><b>The mesh\'s share is not estimated</b> for '
                     f'{esc(", ".join(dict.fromkeys(v.unchecked)))}, whose margin is within '
                     f'{CLOSE:.0%} of its limit: this verdict may change on a finer mesh '
                     '(see “The mesh\'s share”).</p>')
        if r.validity:
            body += ('<div class="warn" id="small-strain"><b>Outside the model\'s validity</b> (small strains '
                     'and small slips, see “small strains” below):<ul>'
                     + "".join(f"<li>{esc(w)}</li>" for w in r.validity) + "</ul></div>")
        if r.warnings:
            body += ('<div class="warn" id="study-warnings"><b>Warnings of the study</b> (as `wcs check` '
                     'gives them):<ul>' + "".join(f"<li>{esc(w)}</li>" for w in r.warnings) + "</ul></div>")
        fallbacks = self.fallbacks()
        if fallbacks:
            body += (f'<div class="warn" id="fallbacks"><b>{sum(fallbacks.values())} of {r.n_eval} evaluations '
                     'were solved by a fallback</b> (not the solver method first tried):<ul>'
                     + "".join(f"<li>{n} × {esc(m)}</li>" for m, n in fallbacks.items()) + "</ul></div>")
        body += _kv(rows)
        if r.kind != "run":
            body += ('<p class="note">This file is not a worst-scenario search: the values below are the '
                     'largest found among its evaluations, not a certified maximum over the box.</p>')
        return body

    def limits(self) -> str:
        r = self.res
        ends = any(c.searched_min for c in r.criteria)
        rows = []
        for j, (c, v) in enumerate(zip(r.criteria, self.mesh_verdicts())):
            margin = c.limit - c.worst if math.isfinite(c.limit) and math.isfinite(c.worst) else float("nan")
            pct = 100 * margin / abs(c.limit) if math.isfinite(margin) and c.limit != 0 else float("nan")
            label = {"pass": "PASS", "fail": "FAIL", "marginal": "MARGINAL", "none": "no limit", "unknown": "unknown"}[v]
            cls = {"pass": "pass", "fail": "fail"}.get(v, "none")
            if v in ("pass", "fail") and c.name in r.verdict.unchecked:    # within CLOSE, the mesh's share unknown
                label, cls = label + " (mesh share unknown)", "fail" if v == "fail" else "none"
            if v == "pass" and r.incomplete:                  # the evaluations so far only: no PASS
                label, cls = "holds so far (incomplete run)", "none"
            low = ""
            if ends:
                low = (f'<td class="num">{number(c.limit_lower, c.units) if math.isfinite(c.limit_lower) else "—"}</td>'
                       f'<td class="num best-value">{number(c.best, c.units) if c.searched_min else "not searched"}</td>')
            cert = esc(c.certificate) + (f" (max); {esc(c.best_certificate)} (min)" if c.searched_min else "")
            rows.append(
                f'<tr data-criterion="{esc(c.name)}"><td>{esc(c.name)}</td>'
                f'<td class="criterion-what">{esc(self.what(j, c))}</td>'
                f'<td>{esc(plots.unit_label(c.units))}</td>{low}'
                f'<td class="num">{number(c.worst, c.units) if c.searched_max else "not searched"}</td>'
                f'<td class="num">{number(c.limit, c.units) if math.isfinite(c.limit) else "—"}</td>'
                f'<td class="num">{number(margin, c.units, difference=True) if math.isfinite(margin) else "—"}</td>'
                f'<td class="num">{f"{pct:+.1f} %".replace("-", "−") if math.isfinite(pct) else "—"}</td>'
                f'<td class="{cls} verdict-cell">{label}</td><td>{cert}'
                f'{"<br><span class=note>" + esc(c.certificate_note) + "</span>" if c.certificate_note else ""}</td></tr>')
        head = "<th>lower limit</th><th>best value (min)</th>" if ends else ""
        body = ('<table id="limits-table"><tr><th>criterion</th><th>what it is</th><th>units</th>' + head +
                '<th>worst value</th><th>limit</th><th>margin (limit − worst)</th><th>margin [%]</th><th>verdict</th>'
                '<th>certificate</th></tr>' + "".join(rows) + "</table>"
                '<p class="note">Every criterion is a maximum over its regions of interest' + (
                    ' (in this dynamic study, its history reduced over time as "what it is" says)'
                    if r.histories is not None else '') + '; a limit is broken '
                'when the worst value exceeds it (negative margin)' + (
                    ', a lower limit when the best value (the minimum over the box) falls below it' if ends else '') +
                '. Certificate: <b>corner-kkt</b> — the '
                'maximiser is a vertex of the box satisfying the KKT sign conditions; <b>local-kkt</b> — a '
                'local maximum satisfying the first-order conditions; <b>heuristic</b> — the best value '
                'found, no optimality proof; <b>grid</b> — the maximum over a sweep grid' + (
                    '; the same for the minimum, with the signs of −Φ' if ends else '') + '.</p>')
        if ends:
            body += ('<h3>The range of each criterion against its limits</h3>'
                     + img(plots.range_figure(r), "interval [min, max] per criterion") +
                     '<p class="note" id="range-text">' + "; ".join(
                         f"{esc(c.name)} ∈ [{number(c.best, c.units)}, {number(c.worst, c.units)}]"
                         for c in r.criteria if c.searched_min and c.searched_max) + "</p>")
        return body

    def what(self, j: int, c) -> str:
        """Criterion c (the j-th) in words, with its reduction over time in a dynamic study."""
        h = self.res.histories
        return _what(c) if h is None else timeline.in_time(_what(c), h.over[j])

    def histories(self) -> str:
        """A dynamic study: each criterion's history at its worst data, its defining level marked."""
        r, h = self.res, self.res.histories
        out = [f'<p>Each evaluation is a simulation of {h.time.size - 1} time levels to t = {h.time[-1]:.4g} s; '
               'a criterion\'s value is its history reduced over time (its <code>over_time</code>). Below, '
               'each criterion against time at the data set of its worst value, the level that gives it marked; '
               'the worst-case fields are drawn at the output time nearest that level.</p>']
        for j, c in enumerate(r.criteria):
            if not np.isfinite(h.values[j]).any():
                out.append(f'<h3>{esc(c.name)}</h3><p class="note">No history (no successful evaluation).</p>')
                continue
            out.append(f'<h3>{esc(c.name)}</h3><p class="history-what" data-criterion="{esc(c.name)}">'
                       f'{esc(self.what(j, c))}: {number(c.worst, c.units)}</p>'
                       + img(plots.history_figure(h, j, c.name, c.units, c.limit), f"{c.name} against time"))
        return "".join(out)

    def membership(self) -> str:
        r, lv = self.res, self.res.levels
        if lv is None and r.kind == "solve":
            return ('<p class="note">A single solve at one data set: no range over the admissible set '
                    '(<code>wcs run</code> searches it, at every α-level of a fuzzy study).</p>')
        if lv is None:
            return ('<p class="note">A crisp study: every uncertain number is a box (no '
                    '<code>{support, core}</code>), so each criterion has one range, in the limits above.</p>')
        out = [f'<p>The admissible data form a fuzzy set: the data of membership ≥ α are the α-cut, a box '
               f'(levels {", ".join(f"{a:g}" for a in lv.alpha)}). Each criterion\'s range over the α-cuts is '
               'its membership function; the intervals are nested (larger α, smaller box).</p>']
        for j, c in enumerate(r.criteria):
            rows = "".join(f'<tr><td class="num">{a:g}</td><td class="num">{number(lv.best[i, j], c.units)}</td>'
                           f'<td class="num">{number(lv.worst[i, j], c.units)}</td></tr>'
                           for i, a in enumerate(lv.alpha))
            reading = limit_membership(lv.alpha, lv.best[:, j], lv.worst[:, j], c.limit_lower, c.limit)
            out.append(f'<h3>{esc(c.name)}</h3><p class="membership-reading" data-criterion="{esc(c.name)}">'
                       f'{esc(reading)}</p>' + img(plots.membership_figure(r, j), f"membership function of {c.name}")
                       + '<table class="levels"><tr><th>α</th><th>min over the α-cut</th><th>max over the α-cut</th>'
                       f'</tr>{rows}</table>')
        return "".join(out)

    def scene(self) -> str:
        r = self.res
        if r.mesh is None:
            return '<p class="note">The results file holds no mesh.</p>'
        a = r.attrs
        rois = r.scene.get("regions_of_interest") or {}
        text = (f'<p>{r.mesh.coords.shape[0]} nodes, {r.mesh.cells.shape[0]} '
                f'{"tetrahedra" if r.mesh.dim == 3 else "triangles"}'
                f'{", plane " + esc(a["plane"]) if "plane" in a else ""}; '
                f'bodies: {", ".join(esc(b) for b in r.mesh.bodies) or "—"}; '
                f'regions: {", ".join(esc(x) for x in r.mesh.regions) or "—"}; '
                f'regions of interest: {", ".join(esc(x) for x in rois) or "—"}.</p>')
        figure = plots3d.scene_figure3d(r) if r.mesh.dim == 3 else plots.scene_figure(r)
        return text + img(figure, "scene and mesh")

    def view3d(self) -> str:
        """The interactive 3D view of a 3D mesh (plotly.js embedded once, wcs/report/view3d.py)."""
        return view3d.view_html(self.res)

    def shown(self, sid: str) -> bool:
        """Sections that exist for some files only: the membership functions of a fuzzy study, the
        interactive view of a 3D mesh."""
        if sid == "membership":
            return fuzzy(self.res)
        if sid == "view3d":
            return self.res.mesh is not None and self.res.mesh.dim == 3
        if sid == "histories":
            return self.res.histories is not None
        return True

    def worst_data(self) -> str:
        r = self.res
        out = []
        for c in r.criteria:
            if not c.searched_max:
                out.append(f'<h3>{esc(c.name)}</h3><p class="note">{NOT_SEARCHED}</p>')
                continue
            if not np.isfinite(c.worst):
                out.append(f'<h3>{esc(c.name)}</h3><p class="note">No data set: every evaluation failed.</p>')
                continue
            if not r.params:
                out.append(f'<h3>{esc(c.name)}: worst value {number(c.worst, c.units)}</h3><p class="note">'
                           'The study has no uncertain numbers: its one data set is the nominal data.</p>')
                continue
            rows = []
            for k, p in enumerate(r.params):
                lo, hi, x = r.lower[k], r.upper[k], c.worst_x[k]
                w = hi - lo
                t = (x - lo) / w if w > 0 else 0.5
                tol = 1e-9 * max(abs(w), abs(hi), abs(lo), 1e-300)
                at = "lower" if abs(x - lo) <= tol else "upper" if abs(x - hi) <= tol else ""
                u = self.units[k]
                rows.append(
                    f'<tr><td><code>{esc(p)}</code></td><td class="num">{number(lo, u)}</td>'
                    f'<td class="num">{number(hi, u)}</td>'
                    f'<td class="num{" atbound" if at else ""}">{number(x, u)}</td>'
                    f'<td><div class="bar" title="{100 * t:.0f} % of the box"><div class="mark{" bound" if at else ""}" '
                    f'style="left:{100 * min(max(t, 0), 1):.1f}%"></div></div></td>'
                    f'<td>{"● at " + at + " bound" if at else ""}</td></tr>')
            out.append(
                f'<h3>{esc(c.name)}: worst value {number(c.worst, c.units)}</h3>'
                '<table class="worst-x"><tr><th>parameter</th><th>lower</th><th>upper</th><th>worst data set</th>'
                '<th>position in the box</th><th></th></tr>' + "".join(rows) + "</table>")
        return "".join(out)

    def worst_fields(self) -> str:
        r = self.res
        if r.mesh is None or all(f is None for f in r.worst_fields):
            return '<p class="note">The results file holds no fields of the worst cases.</p>'
        out = []
        done = {}
        for j, c in enumerate(r.criteria):
            f = r.worst_fields[j]
            if not c.searched_max:
                out.append(f'<h3>{esc(c.name)}</h3><p class="note">{NOT_SEARCHED}</p>')
                continue
            if f is None:
                out.append(f'<h3>{esc(c.name)}</h3><p class="note">No fields (no successful evaluation).</p>')
                continue
            at = timeline.when(r.histories, j) if r.histories is not None and r.histories.output_time is not None else ""
            key = ("solve" if r.kind == "solve" else tuple(np.round(c.worst_x, 14)), at)
            if key in done:
                out.append(f'<h3>{esc(c.name)}</h3><p class="note">Same data set as the worst case of '
                           f'{esc(done[key])}: see above.</p>')
                continue
            done[key] = c.name
            data, mag = (plots3d.surface_figure if r.mesh.dim == 3 else plots.worst_case_figure)(r, j)
            cut = plots3d.cut_figure(r, j) if r.mesh.dim == 3 else None
            label = "the nominal data" if r.kind == "solve" else f"the worst case of {esc(c.name)}"
            label += f" {esc(at)}" if at else ""
            extra = []
            if f.von_mises is not None:
                extra.append(f"max von Mises {number(float(np.nanmax(f.von_mises)), 'Pa')}")
            if f.principal_stress is not None:
                extra.append(f"σ₁ max {number(float(np.nanmax(f.principal_stress[:, 0])), 'Pa')}, "
                             f"σ₂ min {number(float(np.nanmin(f.principal_stress[:, -1])), 'Pa')}")
            if f.displacement is not None:
                extra.append(f"max |u| {number(float(np.nanmax(np.linalg.norm(f.displacement, axis=1))), 'm')}")
            flat = None if f.temperature is None else uniform_value(f.temperature)
            if flat is not None:
                extra.append(f"temperature uniform, {number(flat, 'K')}")
            elif f.temperature is not None:
                extra.append(f"temperature {number(float(np.nanmin(f.temperature)), 'K')} … "
                             f"{number(float(np.nanmax(f.temperature)), 'K')}")
            out.append(f'<h3>{esc(c.name)}: {label}</h3>'
                       f'<p>Displacements magnified × {mag:g}. {"; ".join(extra)}.</p>'
                       + img(data, f"worst case of {c.name}")
                       + ("" if cut is None else '<p>Cuts through the regions of interest (undeformed; the '
                          'cells of each region outlined).</p>' + img(cut, f"cuts at the worst case of {c.name}")))
        return "".join(out)

    def contact(self) -> str:
        if self.res.mesh is not None and self.res.mesh.dim == 3:
            return self.contact3d()
        data = plots.contact_figure(self.res)
        if data is None:
            return '<p class="note">No contact in this study (or no contact fields in the file).</p>'
        pairs = [c.pair for c in plots.contacts_of(self.res)]
        return (f'<p>Along each contact ({", ".join(esc(p) for p in pairs)}), on the slave nodes, at the worst '
                'case of each criterion: the contact pressure −τₙ (zero where the contact opens) and the relative '
                'tangential displacement (slip).</p>' + img(data, "contact pressure and slip"))

    def contact3d(self) -> str:
        maps = [(label, plots3d.contact_maps_figure(self.res, j)) for j, label in plots.distinct_cases(self.res)]
        maps = [(label, data) for label, data in maps if data is not None]
        if not maps:
            return '<p class="note">No contact in this study (or no contact fields in the file).</p>'
        return ('<p>On each contact surface, on the slave nodes, in the surface\'s own coordinates (its two '
                'principal directions): the contact pressure −τₙ (zero where the contact opens) and the '
                'tangential slip |s| with its direction.</p>'
                + "".join(f"<h3>{esc(label)}</h3>" + img(data, f"contact maps, {label}") for label, data in maps))

    def scatter(self) -> str:
        r = self.res
        if r.n_eval < 2:
            return f'<p class="note">Only {r.n_eval} evaluation in this file: nothing to plot.</p>'
        out = ['<p>Each point is one evaluation; the shaded band is the box; ★ the worst; '
               '× at the bottom a failed evaluation (no value); dashed red: the limit.</p>']
        for j, c in enumerate(r.criteria):
            out.append(f"<h3>{esc(c.name)} [{esc(plots.unit_label(c.units))}]</h3>"
                       + img(plots.scatter_figure(r, j, self.units), f"{c.name} against the parameters"))
        return "".join(out)

    def best(self) -> str:
        r = self.res
        if r.n_eval < 2:
            return f'<p class="note">Only {r.n_eval} evaluation in this file: nothing to plot.</p>'
        return ("<p>The largest value found after each forward solve (black), and every evaluation "
                "coloured by the search stage that asked for it.</p>" + img(plots.best_so_far_figure(r), "best so far"))

    def failures(self) -> str:
        r = self.res
        codes, counts = np.unique(r.status, return_counts=True)
        rows = "".join(f'<tr><td class="num">{int(c)}</td><td>{esc(r.status_meanings.get(int(c), "unknown code"))}</td>'
                       f'<td class="num">{int(n)}</td></tr>' for c, n in zip(codes, counts))
        n_fail = int(r.failed.sum())
        body = (f'<p>{n_fail} of {r.n_eval} evaluations failed'
                f'{" (the evaluations in this file of an incomplete run)" if r.incomplete else ""}.</p>'
                + "".join(f'<p class="failed-where">{esc(w[0].upper() + w[1:])}.</p>' for w in r.failed_where)
                + '<table id="status-table"><tr><th>status</th><th>meaning</th><th>count</th></tr>' + rows + "</table>")
        if n_fail:
            body += ('<p>Where in the box they happened (each evaluation a line over the parameters scaled to '
                     'the box; grey: solved):</p>' + img(plots.failures_figure(r), "failures in the box"))
            idx = np.flatnonzero(r.failed)[:50]
            head = "".join(f"<th>{esc(plots._short(p))}</th>" for p in r.params)
            msg = r.messages or [""] * r.n_eval
            head = "<th>message</th>" + head
            trs = "".join(f'<tr><td class="num">{i}</td><td>{esc(r.stage[i])}</td><td class="num">{r.status[i]}</td>'
                          f'<td>{esc(msg[i])}</td>'
                          + "".join(f'<td class="num">{number(v, u)}</td>' for v, u in zip(r.x[i], self.units))
                          + "</tr>" for i in idx)
            body += (f'<details><summary>the failed data sets{" (first 50)" if n_fail > 50 else ""}</summary>'
                     f'<div style="overflow-x:auto"><table><tr><th>eval</th><th>stage</th><th>status</th>{head}</tr>'
                     f'{trs}</table></div></details>')
        return body

    def provenance(self) -> str:
        r, a = self.res, self.res.attrs
        wt = r.wall_time[np.isfinite(r.wall_time)]
        it = r.iterations[np.isfinite(r.iterations) & ~r.failed]
        rows = [("study", a.get("study", r.study)), ("study_sha256", a.get("study_sha256", "—")),
                ("wcs_version", a.get("wcs_version", "—")), ("git_commit", a.get("git_commit", "—")),
                ("seed", a.get("seed", "—")), ("solver", a.get("solver", "—")),
                ("plane", a.get("plane", "—")),
                ("mesh", f'{a.get("mesh_nodes", "—")} nodes, {a.get("mesh_cells", "—")} cells'),
                ("created", a.get("created", "—")),
                ("search", f'{a.get("search_method", "—")}, budget {a.get("budget", "—")}, gradients '
                           f'{a.get("gradients", "—")}, complete: {a.get("complete", "—")}'),
                ("compute", f"{wt.sum():.1f} s in {len(wt)} evaluations" + (
                    f" ({np.median(wt):.2f} s median)" if len(wt) else "")),
                ("solver iterations", (f"{int(it.min())}–{int(it.max())} per evaluation" if len(it) else "—")
                 + (f" ({r.iterations_doc})" if r.iterations_doc else "")),
                ("results file", self.source or "—"),
                ("report generated", _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))]
        body = _kv([(k, esc(v)) for k, v in rows])
        if r.study_yaml:
            body += (f'<details><summary>the study file as loaded ({len(r.study_yaml.splitlines())} lines, '
                     f'sha256 {esc(str(a.get("study_sha256", ""))[:12])}…)</summary><pre>{esc(r.study_yaml)}</pre></details>')
        else:
            body += '<p class="note">The results file does not record the study text.</p>'
        return body

    # ------------------------------------------------------------ after the search
    def mesh_check(self) -> str:
        a = self.res.after_search
        said = "" if a is None else a.attrs.get("mesh_check", "")
        if a is None or "mesh_check_value" not in a:
            return (f'<p class="note" id="no-mesh-check">No mesh check in this file'
                    f'{": " + esc(said) if said else " (written without one)"}.</p>')
        units = {c.name: c.units for c in self.res.criteria}
        limits = {(kind, c.name): math.isfinite(lim) for c in self.res.criteria     # a file of before NOT CHECKED
                  for kind, lim in (("worst", c.limit), ("best", c.limit_lower))}
        nodes, seconds = a["mesh_check_nodes"].values, a["mesh_check_time"].values
        split, curve = (("every tetrahedron into eight", "curve or surface") if self.res.mesh is not None
                        and self.res.mesh.dim == 3 else ("every triangle into four", "curve"))
        rows = []
        for kind, c, pick in pairs(a):
            f = a["mesh_check_value"].sel(pick).values
            if not np.isfinite(f[0]):
                continue
            u = units.get(c, "")
            err = float(a["mesh_check_error"].sel(pick))
            pct = f" ({100 * err / abs(f[0]):+.2g} %)".replace("-", "−") if np.isfinite(err) and f[0] else ""
            ver = str(a["mesh_check_verdict"].sel(pick).values)
            cls = {"PASS": "none" if self.res.incomplete else "pass", "FAIL": "fail"}.get(ver, "none")
            rows.append(
                f'<tr data-criterion="{esc(c)}" data-extreme="{esc(kind)}"><td>{esc(c)}</td><td>{esc(kind)}</td>'
                + "".join(f'<td class="num">{number(v, u, 7)}</td>' for v in f)
                + f'<td class="num">{number(float(a["mesh_check_order"].sel(pick)))}</td>'
                f'<td class="num">{number(float(a["mesh_check_extrapolated"].sel(pick)), u, 7)}</td>'
                f'<td class="num">{number(err, u, difference=True)}{pct}</td>'
                f'<td class="{cls} verdict-cell">'
                f'{esc(ver) or ("NOT CHECKED" if limits.get((kind, c)) else "no limit")}</td>'
                f'<td class="note" style="min-width:12em">{esc(a["mesh_check_note"].sel(pick).values)}</td></tr>')
        built = [f"{h} ({nodes[k]} nodes, {seconds[k]:.3g} s)" if nodes[k] >= 0 else f"{h} (not built)"
                 for k, h in ((1, "h/2"), (2, "h/4"))]
        head = "".join(f"<th>{h}</th>" for h in (
            "criterion", "extreme", f"h ({nodes[0]} nodes)", *built, "observed order", "extrapolated",
            "estimated error of the h value", "verdict", "note"))
        return (f'<p>{esc(said)}.</p><div class="wide"><table id="mesh-check-table"><tr>{head}</tr>{"".join(rows)}'
                '</table></div>'
                '<p class="note">Each extreme data set is solved again on the study\'s mesh split once and twice '
                f'({split}, new nodes of curved boundaries on the {curve}: the same geometry, h '
                'halved exactly). With f(h), f(h/2), f(h/4) and r = (f(h/2) − f(h))/(f(h/4) − f(h/2)) &gt; 1 the '
                'observed order is log₂ r and Richardson\'s extrapolation f(h/4) + (f(h/4) − f(h/2))/(r − 1); '
                'the estimated error is the extrapolated value minus the value on the study\'s mesh. The verdict '
                'is MARGINAL when the limit lies within the extreme ± the estimated error (without an '
                'observed order: ± the spread of the three values; when the mesh was split once only, the error '
                'of the two values with the linear elements\' theoretical order 1, 2 (f(h/2) − f(h)), as the note '
                'says); NOT CHECKED where a limit is set but no estimate was made.</p>')

    def drivers(self) -> str:
        a = self.res.after_search
        if a is None or "drivers" not in a:
            return '<p class="note" id="no-drivers">No drivers in this file (written without them).</p>'
        units = {c.name: c.units for c in self.res.criteria}
        params = list(self.res.params)
        body = ('<p>At each extreme data set: the adjoint gradient of the criterion scaled by the box, '
                '|∂Φ/∂xᵢ| · (uᵢ − lᵢ), the first-order change of the criterion when parameter i runs across '
                'its interval, so parameters of different units compare. Red bars: the criterion grows with '
                'the parameter; blue: it falls.</p>')
        value = {(k, c.name): c.worst if k == "worst" else c.best for c in self.res.criteria for k in ("worst", "best")}
        for kind, c, pick in pairs(a):
            d = a["drivers"].sel(pick).values
            note = str(a["drivers_note"].sel(pick).values)
            if note == NO_EXTREME:
                continue
            body += f'<h3 data-criterion="{esc(c)}">{esc(c)}, {esc(kind)} case</h3>'
            if not np.all(np.isfinite(d)):
                body += f'<p class="warn no-gradient">No drivers: {esc(note)}.</p>'
                continue
            phi = value.get((kind, c), float("nan"))
            none = idle(d, phi)
            if none.all():
                body += self._no_effect(c, kind, float(np.max(d, initial=0.0)), phi, units.get(c, ""))
                continue
            body += img(plots.drivers_figure(params, np.where(none, 0.0, d), a["drivers_sign"].sel(pick).values,
                                             units.get(c, ""), f"{c}: what drives its {kind} value"), f"drivers of {c}")
            if note.startswith("one-sided differences"):
                body += self._one_sided(a, pick, params, units.get(c, ""), note)
            still = [p for p, z in zip(params, none) if z]
            body += (f'<p class="idle">Parameters that do not move {esc(c)} (to first order at its {esc(kind)} '
                     f'data set): {", ".join(esc(p) for p in still)}.</p>' if still else
                     f'<p class="idle">Every parameter moves {esc(c)} at its {esc(kind)} data set.</p>')
        return body

    @staticmethod
    def _no_effect(c: str, kind: str, largest: float, phi: float, units: str) -> str:
        """Drivers all below round-off (`wcs.results.drivers.idle`): said in words, no bars."""
        return (f'<p class="idle no-effect">No effect: no parameter moves {esc(c)} beyond round-off at its '
                f'{esc(kind)} data set (the largest |∂Φ/∂xᵢ| · (uᵢ − lᵢ), {number(largest, units, difference=True)}, '
                f'is at most {IDLE:g} of |Φ| = {number(abs(phi), units)}: the solves\' round-off).</p>')

    @staticmethod
    def _one_sided(a, pick, params, units: str, note: str) -> str:
        """The one-sided differences of a criterion not differentiable at its extreme, side by side."""
        back, fwd = a["drivers_backward"].sel(pick).values, a["drivers_forward"].sel(pick).values
        def cell(v):
            return f'<td class="num">{number(v, units, difference=True) if math.isfinite(v) else "—"}</td>'
        rows = "".join(f"<tr><td>{esc(p)}</td>{cell(b)}{cell(f)}</tr>" for p, b, f in zip(params, back, fwd))
        how = note.removeprefix("one-sided differences: ")
        return (f'<p class="note one-sided">These drivers are <b>one-sided differences</b>, not derivatives: '
                f'{esc(how)}.</p><table class="one-sided"><tr><th>parameter</th>'
                '<th>backward (x − h)</th><th>forward (x + h)</th></tr>' + rows + '</table>')

    # ------------------------------------------------------------ page
    def render(self) -> str:
        r = self.res
        builders = {"summary": self.summary, "limits": self.limits, "histories": self.histories,
                    "membership": self.membership,
                    "scene": self.scene, "view3d": self.view3d,
                    "worst-data": self.worst_data, "worst-fields": self.worst_fields, "contact": self.contact,
                    "mesh-check": self.mesh_check, "drivers": self.drivers,
                    "criteria-vs-parameters": self.scatter, "best-so-far": self.best,
                    "failures": self.failures, "provenance": self.provenance}
        shown = [(sid, title) for sid, title in SECTIONS if self.shown(sid)]
        parts = []
        with phase("report", len(shown)) as progress:               # a part: a section
            for sid, title in shown:
                parts.append(self.guarded(sid, title, builders[sid]))
                progress.step()
        sections = "".join(parts)
        nav = "".join(f'<a href="#{sid}">{esc(t)}</a>' for sid, t in shown)
        return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                f"<title>wcs report: {esc(r.study)}</title><style>{CSS}</style></head><body>"
                f"<header><h1>Worst-scenario report: {esc(r.study)}</h1>"
                f"<p>wcs {esc(r.attrs.get('wcs_version', ''))} · {esc(r.attrs.get('created', ''))}</p></header>"
                f"<nav>{nav}</nav><main>{sections}</main></body></html>\n")


def limit_membership(alpha, best, worst, lower: float, upper: float) -> str:
    """The limits read against a membership function: the smallest level α* from which on (every
    level ≥ α*) the range [best, worst] over the α-cut keeps within the limits. The cuts are
    nested, so the limits then hold for every data set of membership ≥ α*; between the levels
    nothing was computed."""
    if not (math.isfinite(lower) or math.isfinite(upper)):
        return "No limit is set."
    holds = [(not math.isfinite(upper) or (math.isfinite(w) and w <= upper))
             and (not math.isfinite(lower) or (math.isfinite(b) and b >= lower)) for b, w in zip(best, worst)]
    first = len(holds)
    while first > 0 and holds[first - 1]:
        first -= 1
    what = "the limits hold" if math.isfinite(lower) and math.isfinite(upper) else "the limit holds"
    if first == len(holds):
        return f"The limit is broken even at the highest level searched, membership {alpha[-1]:g}" + \
            (" (the core)." if alpha[-1] == 1 else ".")
    if first == 0:
        return (f"{what.capitalize()} for every admissible data set (membership ≥ 0)." if alpha[0] == 0 else
                f"{what.capitalize()} for every data set of membership ≥ {alpha[0]:g}, the lowest level searched.")
    return (f"{what.capitalize()} for every data set of membership ≥ {alpha[first]:g}; a data set of "
            f"membership ≥ {alpha[first - 1]:g} breaks {'them' if what.endswith('limits hold') else 'it'}.")


def fuzzy(res: Results) -> bool:
    """A fuzzy study (`wcs.study.fuzzy._levels`): its file has α-levels, or its study a `fuzzy:` entry or a
    fuzzy number ({support, core})."""
    doc = res.study_doc or {}
    return res.levels is not None or doc.get("fuzzy") is not None or any(
        isinstance(v, dict) and "core" in v for v in (doc.get("uncertain") or {}).values())


def incomplete_banner(why: str) -> str:
    """The summary's one warning of an incomplete run: `why` (`wcs.results.store.incomplete_run`) said once."""
    why = why.removeprefix("the run is incomplete: ")
    return f'<p class="warn" id="incomplete"><b>This run is incomplete</b>: {esc(why)}.</p>'


def _kv(rows) -> str:
    return '<dl class="kv">' + "".join(f"<dt>{k}</dt><dd>{v}</dd>" for k, v in rows) + "</dl>"


def render(res: Results, source: str = "", strict: bool = False) -> str:
    return Report(res, source, strict).render()
