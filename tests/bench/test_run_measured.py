"""`common.run_measured` reports a command's own peak resident set, not the launching process':
a child's ru_maxrss starts from the memory map it had before exec, so measured straight from a
large parent every small command would look as large as the parent."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import run_measured  # noqa: E402

GROW = "import sys; b = bytearray(int(sys.argv[1]) * 2**20); b[::4096] = b'x' * len(b[::4096]); print('ok')"


def test_the_peak_is_the_commands_own_not_the_parents(tmp_path):
    ballast = np.ones(60 * 2**20 // 8)          # this process: at least 60 MB more than the command
    ballast[::512] = 2.0
    small = run_measured([sys.executable, "-S", "-c", GROW, "5"], tmp_path)
    large = run_measured([sys.executable, "-S", "-c", GROW, "40"], tmp_path)
    assert small["code"] == 0 and small["stdout"].strip() == "ok"
    # the plain child of this process inherits its high-water mark: the trap the launcher avoids
    p = subprocess.Popen([sys.executable, "-S", "-c", "pass"])
    _, _, usage = os.wait4(p.pid, 0)
    assert usage.ru_maxrss / 1e6 > 0.06
    # a bare interpreter with 5 MB touched stays well under the ballast; 40 MB more shows as ≈ 40 MB more
    assert small["peak_gb"] < 0.04
    assert 0.035 < large["peak_gb"] - small["peak_gb"] < 0.05
    assert small["cpu"] > 0 and small["wall"] > 0


def test_the_exit_code_and_the_streams_come_back(tmp_path):
    r = run_measured([sys.executable, "-S", "-c", "import sys; print('out'); sys.stderr.write('err'); sys.exit(3)"],
                     tmp_path)
    assert (r["code"], r["stdout"].strip(), r["stderr"].strip()) == (3, "out", "err")
