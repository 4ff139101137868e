"""wcs against Kratos Multiphysics 10.4.4 on the same gmsh file, whole processes, one thread each.

Cases (tests/bench/kratos_mesh.py writes the .msh, MSH 2.2 ASCII, which both codes read):
- the 3D block-on-block patch (studies/validation/block-on-block-3d.yaml), its contact band
  meshed at each face size of WCS_BENCH_KRATOS_FACES (default "0.04 0.02 0.01"), the rest at 0.2;
- the 3D Hertz quarter model (studies/validation/hertz-3d.yaml) meshed at WCS_BENCH_KRATOS_HERTZ
  (default a/24 = 0.00417 near the contact point; a/8 = 0.0125 runs in minutes).

wcs runs `wcs solve` of the validation study with `mesh: {file: ...}` (the file's groups for its
boundaries; the box region of interest and its criterion left out: a box cannot be cut from a
file's cells) once for each method of WCS_BENCH_KRATOS_METHODS (default "auto iterative":
`auto` the method wcs picks itself; `monolithic` may be added). Kratos runs
tests/bench/kratos_patch.py under the interpreter in WCS_KRATOS_PYTHON (a venv with
KratosMultiphysics and its Structural-, ContactStructural- and LinearSolvers- applications):
mortar ALM frictionless contact, AMGCL, the Hertz load in 5 load steps. Without WCS_KRATOS_PYTHON the Kratos row says "absent".

The cases run alternately (wcs method 1, method 2, Kratos, method 1, ...), WCS_BENCH_KRATOS_REPEAT
rounds (default 3), with OMP/OPENBLAS/MKL_NUM_THREADS=1 and wcs' bytecode compiled first (as an
installed package has it). Each process is measured by the getrusage of the finished child
(`common.run_measured`: started from a small launcher, so that the peak is the child's own and not
the pytest process' it would inherit): CPU time (user + system), wall time and peak resident set. On a shared machine the wall time
depends on the load: compare CPU times and peaks, and medians over the rounds.

Each answer is read back and checked after the table is written: the contact pressure at the
contact node nearest the face's centre (Hertz: the axis), the extreme ones, the lowest
z-displacement of the loaded face (Kratos also reports its Newton iterations). The patch's
exact answer: pressure 2 MPa, the top lowered by 0.5·2e6/5e9 + 0.5·2e6/2e10 = 2.5e-4 m
(uniaxial stress, sides free); a row counts only with the displacement to 0.1 % and the centre
pressure to 5 % (Hertz: the axis pressure to 5 % of p0). Kratos' nodal multipliers
(|LAGRANGE_MULTIPLIER_CONTACT_PRESSURE| x SCALE_FACTOR) drift from 2 MPa as the face is refined,
most at the face's edges: the table's p_min and p_max show by how much. A method that refuses
(wcs monolithic where its memory estimate is too large: exit 2 with the estimate) keeps its
refusal in the failure column.

Tables (CSV, results/bench/): bench_kratos_face{FACE}.csv, one a face (a face may be run alone:
the finer faces under the memory lock), and bench_kratos_hertz{H}.csv, one a mesh size; the columns are HEADER
(cpu_median_s, peak_gb, ... per code and method).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from common import ROOT, run_measured, write_table
from kratos_mesh import write_hertz_msh, write_patch_msh

PATCH = ROOT / "studies" / "validation" / "block-on-block-3d.yaml"
DRIVER = Path(__file__).with_name("kratos_patch.py")
HERTZ = ROOT / "studies" / "validation" / "hertz-3d.yaml"
HERTZ_P0 = 6.99e9               # its header: p0 = 3P / (2πa²)
PRESSURE = 2.0e6
TOP_UZ = 0.5 * PRESSURE / 5.0e9 + 0.5 * PRESSURE / 2.0e10
ONE_THREAD = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


def file_study(path: Path, msh: Path, bodies: list[str], method: str, drop_roi: str) -> dict:
    """A validation study on the file mesh: the file's groups replace the geometric boundaries,
    each body one region of its material; the box region of interest (a box cannot be cut from
    a file's cells) and its criterion are left out."""
    d = yaml.safe_load(path.read_text())
    s = d["scene"]
    materials = {b: s["bodies"][b]["regions"][0]["material"] for b in bodies}
    s["mesh"] = {"file": msh.name}
    s["bodies"] = {b: {"regions": [{"material": materials[b]}]} for b in bodies}
    s.pop("boundaries")
    s["regions_of_interest"].pop(drop_roi)
    d["criteria"] = [c for c in d["criteria"] if c["kind"] == "contact_pressure"]
    d["solver"] = {"method": method}
    return d


def child_env() -> dict:
    """The children's environment: one thread each, and Python free to keep its bytecode (with
    PYTHONDONTWRITEBYTECODE set, every `wcs solve` compiled wcs' modules again: CPU time that an
    installed wcs never spends; Kratos' site-packages are compiled at install)."""
    env = {**os.environ, **ONE_THREAD}
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def compile_wcs() -> None:
    """wcs' bytecode written before the first timed run, as an installed package has it."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(ROOT / "wcs")], env=child_env(), check=True)


def wcs_case(work: Path, study: dict, method: str) -> list[str]:
    path = work / f"{study['study']}-{method}.yaml"
    path.write_text(yaml.safe_dump(study))
    return [sys.executable, "-m", "wcs.cli", "solve", "-q", "-o", str(work / f"{method}.nc"), str(path)]


def wcs_answer(nc: Path, top_z: float, centre: tuple) -> dict:
    """Unknowns, contact nodes, the contact pressure at the contact node nearest the centre (x, y),
    the extreme ones, and the lowest z-displacement of the loaded face z = top_z."""
    with xr.open_dataset(nc) as ds:
        p = ds["contact_pressure"].values
        top = np.abs(ds["coords"].values[:, 2] - top_z) < 1e-9
        xy = ds["contact_coords"].values[:, :2]
        at = np.argmin(((xy - np.asarray(centre)) ** 2).sum(axis=1))
        return {"unknowns": 3 * ds.sizes["node"], "contact_nodes": ds.sizes["contact_node"],
                "p_centre": float(p[at]), "p_max": float(p.max()), "p_min": float(p.min()),
                "top_uz_min": float(ds["displacement"].values[top, 2].min())}


def json_line(text: str) -> dict:
    """The driver's answer: its last stdout line that is a JSON object."""
    return json.loads([line for line in text.splitlines() if line.startswith("{")][-1])


def check_patch(answer: dict) -> str:
    """The patch test's exact answer (module docstring): what is off, or ''."""
    return "; ".join(msg for ok, msg in [
        (answer["top_uz_min"] == pytest.approx(-TOP_UZ, rel=1e-3), f"top u_z {answer['top_uz_min']:.6g} != {-TOP_UZ}"),
        (answer["p_centre"] == pytest.approx(PRESSURE, rel=5e-2), f"centre pressure {answer['p_centre']:.6g}")]
        if not ok)


def check_hertz(answer: dict) -> str:
    """Hertz's peak pressure p0 on the axis to 5 % (tests/contact/test_mortar_hertz_3d.py: wcs within 3 % at a/24)."""
    ok = answer["p_centre"] == pytest.approx(HERTZ_P0, rel=5e-2)
    return "" if ok else f"axis pressure {answer['p_centre']:.6g} != p0 {HERTZ_P0:.4g} (5 %)"


HEADER = ["mesh", "code", "unknowns", "contact_nodes", "ok_runs", "runs", "cpu_median_s", "cpu_min_s", "cpu_max_s",
          "wall_median_s", "wall_min_s", "wall_max_s", "peak_gb", "p_centre", "p_min", "p_max", "top_uz_min", "newton", "failure"]


def compare(work: Path, mesh: float, studies: dict, kratos: list | None, check, top_z: float, centre) -> list:
    """Rows of HEADER: the wcs studies and the Kratos command run in turn, REPEAT rounds."""
    msh = work / "mesh.msh"
    cases = {m: wcs_case(work, d, m) for m, d in studies.items()}
    if kratos:
        cases["kratos"] = kratos
    runs = {k: [] for k in cases}
    compile_wcs()
    for _ in range(int(os.environ.get("WCS_BENCH_KRATOS_REPEAT", "3"))):
        for name, cmd in cases.items():          # alternating: A B C A B C ...
            r = run_measured(cmd, work, child_env())
            wall, cpu, peak, code, out, err = r["wall"], r["cpu"], r["peak_gb"], r["code"], r["stdout"], r["stderr"]
            answer, wrong = None, ""
            if code == 0:
                answer = json_line(out) if name == "kratos" else wcs_answer(work / f"{name}.nc", top_z, centre)
                wrong = check(answer)
            runs[name].append((wall, cpu, peak, answer, (err.strip() or f"exit {code}").splitlines()[-1][:200], wrong))
    rows = []
    for name, rs in runs.items():
        ok = [r for r in rs if r[3] is not None]
        if not ok:
            rows.append([mesh, name, "", "", 0, len(rs), "failed"] + [""] * 11 + [rs[-1][4]])
            continue
        walls, cpus, a = [r[0] for r in ok], [r[1] for r in ok], ok[-1][3]
        notes = {r[5] for r in ok if r[5]} | ({"Newton not converged"} if not all(
            r[3].get("converged", True) for r in ok) else set())
        rows.append([mesh, name, a["unknowns"], a["contact_nodes"], len(ok), len(rs),
                     round(float(np.median(cpus)), 2), round(min(cpus), 2), round(max(cpus), 2),
                     round(float(np.median(walls)), 2), round(min(walls), 2), round(max(walls), 2),
                     round(max(r[2] for r in ok), 4), f"{a['p_centre']:.6g}", f"{a['p_min']:.6g}",
                     f"{a['p_max']:.6g}", f"{a['top_uz_min']:.6g}", a.get("newton", ""), "; ".join(sorted(notes))])
        print(rows[-1], flush=True)
    return rows


def assert_fair(rows: list) -> None:
    """Every answer given is right (the failure column of a row that ran says only that Kratos'
    Newton stopped unconverged) and wcs' iterative method solved every round. The monolithic
    method may refuse (exit 2 with its memory and time estimate, far beyond this machine at the
    finest default face): that is its result, kept in the table."""
    wrong = [r for r in rows if r[4] and r[-1] not in ("", "Newton not converged")]
    assert not wrong, f"an answer is off (the failure column): {wrong}"
    assert all(r[4] == r[5] for r in rows if r[1] == "iterative"), "wcs' iterative method failed: see the table"


def kratos_python() -> str | None:
    kratos = os.environ.get("WCS_KRATOS_PYTHON")
    if not kratos:
        print("Kratos absent: set WCS_KRATOS_PYTHON to the python of a venv with KratosMultiphysics")
    return kratos


def methods() -> list[str]:
    """wcs' methods to run: WCS_BENCH_KRATOS_METHODS (default "auto iterative"; iterative
    alone keeps a large face's runs off the memory lock: the table's peaks)."""
    return os.environ.get("WCS_BENCH_KRATOS_METHODS", "auto iterative").split()


def absent_row(kratos) -> list:
    return [] if kratos else [["", "kratos", "", "", 0, 0, "absent (WCS_KRATOS_PYTHON unset)"] + [""] * 12]


@pytest.mark.bench
def test_bench_kratos_patch(tmp_path):
    faces = [float(f) for f in os.environ.get("WCS_BENCH_KRATOS_FACES", "0.04 0.02 0.01").split()]
    kratos = kratos_python()
    rows = []
    for face in faces:                  # a table per face, with its own stamp: a face may be run alone
        work = tmp_path / f"face{face}"
        work.mkdir()
        write_patch_msh(work / "mesh.msh", face)
        studies = {m: file_study(PATCH, work / "mesh.msh", ["base", "block"], m, "core") for m in methods()}
        cmd = kratos and [kratos, str(DRIVER), "patch", str(work / "mesh.msh"), str(work / "kratos")]
        found = compare(work, face, studies, cmd, check_patch, 0.5, (0.5, 0.5))
        print(write_table(f"bench_kratos_face{face}", HEADER, found + absent_row(kratos)).read_text())
        rows += found
    assert_fair(rows)


@pytest.mark.bench
def test_bench_kratos_hertz(tmp_path):
    """The 3D Hertz quarter model (studies/validation/hertz-3d.yaml) from a .msh meshed at
    WCS_BENCH_KRATOS_HERTZ (default a/24 = 0.00417 within 0.13 of the contact point: ≈ 9.5e4
    unknowns; a/8 = 0.0125 runs in minutes); wcs takes the dual mortar (nonmatching faces),
    Kratos its mortar ALM in 5 load steps.
    Table: results/bench/bench_kratos_hertz{H}.csv (H the mesh size: a size may be run alone)."""
    h = float(os.environ.get("WCS_BENCH_KRATOS_HERTZ", "0.00417"))
    kratos = kratos_python()
    write_hertz_msh(tmp_path / "mesh.msh", h)
    studies = {m: file_study(HERTZ, tmp_path / "mesh.msh", ["sphere", "block"], m, "below") for m in methods()}
    cmd = kratos and [kratos, str(DRIVER), "hertz", str(tmp_path / "mesh.msh"), str(tmp_path / "kratos")]
    rows = compare(tmp_path, h, studies, cmd, check_hertz, 1.0, (0.0, 0.0))
    print(write_table(f"bench_kratos_hertz{h:g}", HEADER, rows + absent_row(kratos)).read_text())
    assert_fair(rows)
