"""docs/benchmarks.md is built from the benchmarks' CSV files (tests/bench/page.py): every
table with its stamp, its writer and its rows as written, a long one cut with a note."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import write_table  # noqa: E402
import common  # noqa: E402
import page  # noqa: E402


def test_the_page_holds_every_table_with_its_stamp_and_writer(tmp_path, monkeypatch):
    monkeypatch.setattr(common, "OUT", tmp_path)             # write_table's folder
    forward, search = "forward_hertz", "search_convergence"          # names the benchmarks write
    write_table(forward, ["method", "seconds"], [["monolithic", 0.25], ["dd|4", 1.5]])
    write_table(search, ["solves", "rel_error"], [[i, 1.0 / (i + 1)] for i in range(page.MAX_ROWS + 5)])
    target = page.write(tmp_path, tmp_path / "benchmarks.md")
    text = target.read_text()
    stamp = (tmp_path / "forward_hertz.csv").read_text().splitlines()[0].removeprefix("# ")
    assert text.index("## forward_hertz") < text.index("## search_convergence")
    assert f"`{stamp}` — written by `tests/bench/test_bench_forward.py`" in text
    assert "written by `tests/bench/test_bench_search.py`" in text
    assert "| method | seconds |\n| --- | --- |\n| monolithic | 0.25 |\n| dd\\|4 | 1.5 |\n" in text
    assert f"| {page.MAX_ROWS - 1} | {1.0 / page.MAX_ROWS} |" in text and f"| {page.MAX_ROWS} |" not in text
    assert f"(the first {page.MAX_ROWS} of {page.MAX_ROWS + 5} rows" in text


def test_without_tables_the_page_says_how_to_make_them(tmp_path):
    assert "`make bench` writes them" in page.page([])
