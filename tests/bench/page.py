"""docs/benchmarks.md from the tables the benchmarks write (results/bench/*.csv, by
`common.write_table`: a `# stamp` line, a header row, the rows): one section a table, with
its stamp (commit, CPU, cores, load, date), the benchmark file that writes it and the table
as written. `make bench` writes the page at the end of its session (tests/bench/conftest.py);

    python tests/bench/page.py          # the page from the CSV files at hand
"""
from __future__ import annotations

import csv
import re
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parent
ROOT = BENCH.parents[1]
OUT = ROOT / "results" / "bench"
PAGE = ROOT / "docs" / "benchmarks.md"
MAX_ROWS = 60           # a longer table (a convergence history) is cut: the CSV holds it whole

HEAD = """# Benchmarks

Written by `make bench` (`tests/bench/page.py`) from the tables the benchmarks write to
`results/bench/*.csv`; do not edit it by hand. Each table carries the stamp of its run (commit,
CPU, cores, load average, date) and names the benchmark that writes it, whose docstring says
what is measured and how. Times are medians of repeats taken in the same run on a shared
machine: read them as ratios within a table. The charts (`*.png`) are beside the CSV files in
`results/bench/`; [methods.md](methods.md) says which choices of `wcs/choose.py` rest on which table.
A table the docs name but this page lacks was not run since the page was last written: `make bench`
(or `pytest tests/bench/FILE -m bench`, FILE the benchmark that writes it) writes it.
"""


def writers(folder: Path = BENCH) -> dict[str, str]:
    """Table name pattern -> the benchmark file whose `write_table("NAME", ...)` writes it
    (an f-string's `{...}` matches any text)."""
    out = {}
    for path in sorted(folder.glob("*.py")):
        for name in re.findall(r"write_table\(\s*f?\"([^\"]+)\"", path.read_text()):
            out[".+".join(map(re.escape, re.split(r"\{[^}]*\}", name)))] = path.name
    return out


def section(path: Path, written_by: dict[str, str]) -> str:
    """One table as Markdown: its name, stamp, writer and rows (at most MAX_ROWS)."""
    lines = path.read_text().splitlines()
    stamp = lines[0].removeprefix("#").strip() if lines and lines[0].startswith("#") else "no stamp"
    rows = list(csv.reader(lines[1:] if lines and lines[0].startswith("#") else lines))
    name = path.stem
    writer = next((f for pattern, f in written_by.items() if re.fullmatch(pattern, name)), None)
    out = [f"## {name}", "", f"`{stamp}`" + (f" — written by `tests/bench/{writer}`" if writer else ""), ""]
    if not rows:
        return "\n".join(out + ["(empty table)", ""])
    header, body = rows[0], rows[1:]
    cell = lambda v: v.replace("|", "\\|")                                    # noqa: E731
    out += ["| " + " | ".join(map(cell, header)) + " |", "|" + " --- |" * len(header)]
    out += ["| " + " | ".join(map(cell, row)) + " |" for row in body[:MAX_ROWS]]
    if len(body) > MAX_ROWS:
        out += ["", f"(the first {MAX_ROWS} of {len(body)} rows; `results/bench/{path.name}` holds them all)"]
    return "\n".join(out + [""])


def page(csvs: list[Path], written_by: dict[str, str] | None = None) -> str:
    """The benchmarks page of these CSV files, in name order."""
    written_by = writers() if written_by is None else written_by
    parts = [HEAD] + [section(p, written_by) for p in sorted(csvs, key=lambda p: p.name)]
    if not csvs:
        parts.append("No table yet: `make bench` writes them.\n")
    return "\n".join(parts)


def write(folder: Path = OUT, target: Path = PAGE) -> Path:
    """The page of every CSV file in `folder`, written to `target`."""
    target.write_text(page(sorted(folder.glob("*.csv"))))
    return target


if __name__ == "__main__":
    print(write(*(Path(a) for a in sys.argv[1:3])))
