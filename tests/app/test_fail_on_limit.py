"""`wcs run --fail-on-limit`: exit 3 when a worst value breaks its limit, 0 when all hold;
the report of the broken run says FAIL.

heated-plate's heave limit 1e-4 m is broken by every data set (the nominal heave is
~5.6e-4 m); a copy with the limit at 1 m holds. A budget of 6 solves keeps this fast.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import yaml

from wcs.cli import main

ROOT = Path(__file__).resolve().parents[2]
PLATE = ROOT / "studies" / "heated-plate.yaml"


def _copy(tmp_path: Path, limits: dict | None = None, budget: int = 6) -> Path:
    doc = yaml.safe_load(PLATE.read_text())
    doc["search"] = {**(doc.get("search") or {}), "budget": budget}
    if limits is not None:
        doc["limits"] = limits
    out = tmp_path / "plate.yaml"
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


def _wcs(*args, cwd):
    exe = Path(sys.executable).with_name("wcs")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "wcs.cli"]
    return subprocess.run([*cmd, *args], capture_output=True, text=True, cwd=cwd, timeout=600)


def test_broken_limit_exits_3_and_the_report_says_fail(tmp_path):
    from tests.report.test_report import Page

    study, nc = _copy(tmp_path), tmp_path / "broken.nc"
    proc = _wcs("run", str(study), "-o", str(nc), "--fail-on-limit", cwd=tmp_path)
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "limit broken: heave" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert nc.is_file()                                  # the results are written all the same
    html = tmp_path / "broken.html"
    assert main(["report", str(nc), "-o", str(html), "--quiet"]) == 0
    text = html.read_text()
    page = Page(text)
    heave = page.limit_row("heave")
    assert heave["verdict"]["text"] == "FAIL" and "fail" in heave["verdict"]["class"]
    assert heave["margin"]["text"].startswith("−")
    assert 'id="verdict">FAIL<' in text


def test_broken_limit_without_the_flag_exits_0(tmp_path):
    study = _copy(tmp_path)
    assert main(["run", str(study), "-o", str(tmp_path / "r.nc"), "--quiet"]) == 0


def test_limits_that_hold_exit_0(tmp_path, capsys):
    study, nc = _copy(tmp_path, limits={"heave": 1.0}), tmp_path / "fine.nc"
    assert main(["run", str(study), "-o", str(nc), "--fail-on-limit"]) == 0
    out = capsys.readouterr()
    assert "limit broken" not in out.err
    html = tmp_path / "fine.html"
    assert main(["report", str(nc), "-o", str(html), "--quiet"]) == 0
    from tests.report.test_report import Page
    page = Page(html.read_text())
    assert page.limit_row("heave")["verdict"]["text"] == "PASS"
