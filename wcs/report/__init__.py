"""`wcs report OUT.nc -o REPORT.html`: one self-contained HTML page (images embedded
as base64 PNG, no external CSS/JS) that an assessor reads without wcs.

API:
    from wcs.report import write_report, render_report
    write_report("results/tunnel-fault.nc", "results/tunnel-fault.html")  # -> Path
    html_text = render_report(xarray_dataset_or_path)                     # -> str
"""
from __future__ import annotations

import sys
from pathlib import Path

from ..errors import StudyError

__all__ = ["cmd_report", "render_report", "write_report", "SECTION_IDS"]


# the sections of every report; besides them "membership" (a fuzzy study), "view3d" (a 3D mesh) and
# "histories" (a dynamic study)
SECTION_IDS = ["summary", "limits", "scene", "mesh-check", "worst-data", "drivers", "worst-fields", "contact",
               "criteria-vs-parameters", "best-so-far", "failures", "provenance"]


def render_report(results, source: str = "", strict: bool = False) -> str:
    """The report's HTML for a results file path, an xarray.Dataset in the layout of
    a wcs results file (run, sweep or solve file) or a loaded `data.Results`. StudyError for a bad file."""
    import xarray as xr

    from . import data, html
    if isinstance(results, data.Results):
        res, source = results, source or results.source
    elif isinstance(results, xr.Dataset):
        res = data.from_dataset(results, source or "dataset")
    else:
        res = data.load(results)
        source = source or str(results)
    return html.render(res, source=source, strict=strict)


def write_report(results, output=None, strict: bool = False) -> Path:
    """Write the report of a results file; default output beside it (.html)."""
    if output is None:
        if not isinstance(results, (str, Path)):
            raise ValueError("an output path is needed for a dataset")
        output = Path(results).with_suffix(".html")
    output = Path(output)
    text = render_report(results, strict=strict)
    output.parent.mkdir(parents=True, exist_ok=True)
    tmp = output.with_name(output.name + ".part")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(output)
    return output


def cmd_report(args) -> int:
    results = Path(args.results)
    if not results.exists():
        print(f"error: {results}: no such results file", file=sys.stderr)
        return 2
    out = Path(args.output) if args.output else results.with_suffix(".html")
    if out.suffix.lower() not in (".html", ".htm"):
        print(f"error: {out}: the report is an HTML file (use a .html name)", file=sys.stderr)
        return 2
    from .data import load
    try:
        res = load(results)
        path = write_report(res, out, strict=getattr(args, "verbose", False))
    except StudyError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"error: {out}: cannot write the report ({e.strerror or e})", file=sys.stderr)
        return 2
    if res.incomplete:
        print(f"warning: {results}: {res.incomplete}", file=sys.stderr)
    if not getattr(args, "quiet", False):
        size = path.stat().st_size
        print(f"wrote {path} ({size / 1e6:.2f} MB)")
    return 0
