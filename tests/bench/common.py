"""Shared helpers of the benchmarks: timing as median and spread over repeats, and tables
and charts under results/bench/ stamped with the commit and the machine."""
from __future__ import annotations

import csv
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "results" / "bench"
STUDIES = ROOT / "studies"


def stamp() -> str:
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                                text=True, timeout=5).stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        commit = "unknown"
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        load = f" | load {os.getloadavg()[0]:.1f}"      # a shared machine: how busy it was
    except OSError:
        load = ""
    return f"wcs {commit} | {cpu} | {os.cpu_count()} cores{load} | {time.strftime('%Y-%m-%d %H:%M')}"


def measure(f, repeat: int = 3):
    """(median seconds, relative spread (max-min)/median, last result)."""
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    med = statistics.median(times)
    return med, (max(times) - min(times)) / med if med > 0 else 0.0, out


def write_table(name: str, header: list[str], rows: list[list]) -> Path:
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{name}.csv"
    with path.open("w", newline="") as fh:
        fh.write(f"# {stamp()}\n")
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    return path


def save_figure(fig, name: str) -> Path:
    OUT.mkdir(parents=True, exist_ok=True)
    fig.text(0.99, -0.01, stamp(), ha="right", va="top", fontsize=6, color="0.4")   # below the axes labels
    path = OUT / f"{name}.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    import matplotlib.pyplot as plt
    plt.close(fig)
    return path


# A child's ru_maxrss is not its own peak when a large process launched it: Linux keeps the
# high-water mark of the memory map the child had before exec (on vfork, the parent's), so a
# command started from a 200 MB pytest reports at least 200 MB. This launcher (python -S, ~10 MB)
# starts the command itself and hands back the command's rusage; its own map is the floor.
_LAUNCHER = """
import json, os, sys
pid = os.posix_spawnp(sys.argv[2], sys.argv[2:], os.environ)
_, status, u = os.wait4(pid, 0)
with open(sys.argv[1], "w") as fh:
    json.dump({"code": os.waitstatus_to_exitcode(status), "cpu": u.ru_utime + u.ru_stime,
               "maxrss_kb": u.ru_maxrss}, fh)
"""


def run_measured(cmd: list[str], cwd: Path, env: dict | None = None) -> dict:
    """Run `cmd` in `cwd` as a whole process; its wall seconds, CPU seconds (user + system),
    peak resident set (GB, the command's own: see `_LAUNCHER`), exit code, stdout and stderr."""
    cwd = Path(cwd)
    usage, out, err = cwd / "rusage.json", cwd / "stdout.txt", cwd / "stderr.txt"
    with out.open("w") as fo, err.open("w") as fe:
        t = time.perf_counter()
        subprocess.run([sys.executable, "-S", "-c", _LAUNCHER, str(usage), *cmd], cwd=cwd, env=env,
                       stdout=fo, stderr=fe, check=True)
        wall = time.perf_counter() - t
    u = json.loads(usage.read_text())
    return {"wall": wall, "cpu": u["cpu"], "peak_gb": u["maxrss_kb"] / 1e6, "code": u["code"],
            "stdout": out.read_text(), "stderr": err.read_text()}
