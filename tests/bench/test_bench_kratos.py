"""wcs against Kratos Multiphysics 10.4.4 (issue 25, "Ahead of the peer"): the 3D block-on-block
patch (studies/validation/block-on-block-3d.yaml) read by both codes from ONE gmsh file
(tests/bench/kratos_mesh.py: contact band meshed at `face`, the rest at 0.2), frictionless,
one thread each (OMP/OPENBLAS/MKL_NUM_THREADS=1), whole processes run alternately
(wcs iterative, wcs monolithic, Kratos, ...; WCS_BENCH_KRATOS_REPEAT rounds, default 3), each
timed by wall clock and its peak resident set (getrusage of the finished child).

- wcs: `wcs solve` of the patch study with `mesh: {file: ...}` and `solver.method` iterative,
  then monolithic; the answer read back is the largest contact pressure (the patch test's
  exact value is the applied 2 MPa at every contact node).
- Kratos: tests/bench/kratos_patch.py run by the interpreter in WCS_KRATOS_PYTHON (Kratos in
  its own venv: KratosMultiphysics, -StructuralMechanics-, -ContactStructuralMechanics-,
  -LinearSolversApplication 10.4.4 from PyPI); mortar ALM frictionless contact, AMGCL. Its
  answer is the largest and smallest normal contact pressure on the slave face.
The patch test's exact answer: contact pressure 2 MPa, the top lowered by
0.5·2e6/5e9 + 0.5·2e6/2e10 = 2.5e-4 m (uniaxial stress, sides free). Both codes must give the
top displacement to 0.1 % and the contact pressure at the face's centre to 1 % for the
comparison to count (asserted per successful run; wcs gives both to 1e-7, Kratos the
displacement to 4e-4 and its nodal multipliers scatter by ≈ 0.5 % inside the face, up to 2.5 %
at the face's edges); the extreme pressures are reported beside. Without WCS_KRATOS_PYTHON the Kratos
rows say "absent". WCS_BENCH_KRATOS_FACES picks the face sizes (default "0.04 0.02 0.01").
Table: results/bench/bench_kratos.csv.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from common import ROOT, write_table
from kratos_mesh import write_patch_msh

PATCH = ROOT / "studies" / "validation" / "block-on-block-3d.yaml"
DRIVER = Path(__file__).with_name("kratos_patch.py")
PRESSURE = 2.0e6
TOP_UZ = 0.5 * PRESSURE / 5.0e9 + 0.5 * PRESSURE / 2.0e10
ONE_THREAD = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


def patch_study(msh: Path, method: str) -> dict:
    """The patch study on the file mesh: the file's groups replace the geometric boundaries."""
    d = yaml.safe_load(PATCH.read_text())
    s = d["scene"]
    s["mesh"] = {"file": msh.name}
    s["bodies"] = {"base": {"regions": [{"material": "stiff"}]}, "block": {"regions": [{"material": "soft"}]}}
    s.pop("boundaries")
    s["regions_of_interest"].pop("core")              # a box cannot be cut from a file's cells
    d["criteria"] = [c for c in d["criteria"] if c["name"] == "pressure"]
    d["solver"] = {"method": method}
    return d


def run(cmd: list[str], cwd: Path) -> tuple[float, float, int, str, str]:
    """Wall seconds, peak resident set (GB, the child's own rusage), exit code, stdout, stderr."""
    out, err = cwd / "stdout.txt", cwd / "stderr.txt"
    with out.open("w") as fo, err.open("w") as fe:
        t = time.perf_counter()
        p = subprocess.Popen(cmd, cwd=cwd, env={**os.environ, **ONE_THREAD}, stdout=fo, stderr=fe)
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t
    return wall, usage.ru_maxrss / 1e6, os.waitstatus_to_exitcode(status), out.read_text(), err.read_text()


def wcs_case(work: Path, msh: Path, method: str) -> list[str]:
    study = work / f"patch-{method}.yaml"
    study.write_text(yaml.safe_dump(patch_study(msh, method)))
    return [sys.executable, "-m", "wcs.cli", "solve", "-q", "-o", str(work / f"{method}.nc"), str(study)]


def wcs_answer(nc: Path) -> dict:
    """Unknowns, contact nodes and the extreme contact pressures of the nominal solve."""
    with xr.open_dataset(nc) as ds:
        p = ds["contact_pressure"].values
        top = ds["coords"].values[:, 2] > 0.5 - 1e-9
        xy = ds["contact_coords"].values[:, :2]
        centre = np.argmin(((xy - 0.5) ** 2).sum(axis=1))
        return {"unknowns": 3 * ds.sizes["node"], "contact_nodes": ds.sizes["contact_node"],
                "p_centre": float(p[centre]), "p_max": float(p.max()), "p_min": float(p.min()),
                "top_uz_min": float(ds["displacement"].values[top, 2].min())}


def json_line(text: str) -> dict:
    """The driver's answer: its last stdout line that is a JSON object."""
    return json.loads([line for line in text.splitlines() if line.startswith("{")][-1])


def check(answer: dict) -> None:
    """The patch test's exact answer (module docstring), so that both codes solved the same problem."""
    assert answer["top_uz_min"] == pytest.approx(-TOP_UZ, rel=1e-3), answer
    assert answer["p_centre"] == pytest.approx(PRESSURE, rel=1e-2), answer


@pytest.mark.bench
def test_bench_kratos_patch(tmp_path):
    faces = [float(f) for f in os.environ.get("WCS_BENCH_KRATOS_FACES", "0.04 0.02 0.01").split()]
    repeat = int(os.environ.get("WCS_BENCH_KRATOS_REPEAT", "3"))
    kratos = os.environ.get("WCS_KRATOS_PYTHON")
    if not kratos:
        print("Kratos absent: set WCS_KRATOS_PYTHON to the python of a venv with KratosMultiphysics")
    rows = []
    for face in faces:
        work = tmp_path / f"face{face}"
        work.mkdir()
        msh = work / "patch.msh"
        write_patch_msh(msh, face)
        cases = {m: wcs_case(work, msh, m) for m in ("iterative", "monolithic")}
        if kratos:
            cases["kratos"] = [kratos, str(DRIVER), "patch", str(msh), str(work / "kratos")]
        runs = {k: [] for k in cases}
        for _ in range(repeat):
            for name, cmd in cases.items():          # alternating: A B C A B C ...
                wall, peak, code, out, err = run(cmd, work)
                answer = None
                if code == 0:
                    answer = json_line(out) if name == "kratos" else wcs_answer(work / f"{name}.nc")
                    check(answer)
                runs[name].append((wall, peak, answer, (err.strip() or f"exit {code}").splitlines()[-1][:200]))
        for name, rs in runs.items():
            ok = [r for r in rs if r[2] is not None]
            walls, peaks = [r[0] for r in ok], [r[1] for r in ok]
            a = ok[-1][2] if ok else {}
            rows.append([face, name, a.get("unknowns", ""), a.get("contact_nodes", ""), len(ok), len(rs),
                         round(float(np.median(walls)), 2) if ok else "failed",
                         round(min(walls), 2) if ok else "", round(max(walls), 2) if ok else "",
                         round(max(peaks), 3) if ok else "",
                         f"{a['p_centre']:.6g}" if ok else "", f"{a['p_min']:.6g}" if ok else "", f"{a['p_max']:.6g}" if ok else "",
                         f"{a['top_uz_min']:.6g}" if ok else "", "" if ok else rs[-1][3]])
            print(rows[-1], flush=True)
    if not kratos:
        rows.append(["", "kratos", "", "", 0, 0, "absent (WCS_KRATOS_PYTHON unset)", "", "", "", "", "", "", "", ""])
    path = write_table("bench_kratos", ["face", "code", "unknowns", "contact_nodes", "ok_runs", "runs",
                                        "wall_median_s", "wall_min_s", "wall_max_s", "peak_gb", "p_centre", "p_min", "p_max",
                                        "top_uz_min", "failure"], rows)
    print(path.read_text())
