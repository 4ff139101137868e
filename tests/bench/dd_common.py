"""Helpers of the DD benchmarks: build a model from a study (edited), and run DD vs monolithic."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import yaml

import wcs
from wcs.dd import solver as dds
from wcs.model.model import Model
from wcs.scene.mesher2d import build_mesh

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "studies"
OUT = ROOT / "results" / "bench"


def build(name: str, tmpdir: Path, edit=None):
    src = STUDIES / name
    doc = yaml.safe_load(src.read_text())
    if edit:
        edit(doc)
    for f in src.parent.glob("materials*.yaml"):
        (tmpdir / f.name).write_text(f.read_text())
    path = tmpdir / src.name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    study = wcs.load_study(path)
    return study, Model(study.scene, build_mesh(study.scene), {"method": "monolithic"})


def run(study, model, options, compare=True):
    """(DDResult, dict of measured numbers)."""
    scene = study.scene
    c = model.coefficients(scene)
    _, Kr, rhs, u0 = model.reduced_system(c, model.solve_heat(c) if model.thermal else None)
    t = time.perf_counter()
    res = dds.solve_dd(model, scene, Kr, rhs, u0, options, coefficients=c)
    out = {"status": res.status.value, "time_dd": time.perf_counter() - t,
           "pcg1": res.info.get("pcg1"), "successive": res.info.get("successive"), "pcg2": res.info.get("pcg2"),
           "contraction": res.info.get("contraction"), "ndof": Kr.shape[0],
           "subdomains": res.info.get("subdomains"), "interface_dofs": res.info.get("interface_dofs"),
           "floating_units": res.info.get("floating_units"), "contact_nodes": model.zone.gap.size}
    if compare and res.u is not None:
        t = time.perf_counter()
        mono = model.solve(c)
        out["time_mono"] = time.perf_counter() - t
        out["err_u"] = float(np.linalg.norm(res.u - mono.u) / np.linalg.norm(mono.u))
        out["err_lam_n"] = float(np.linalg.norm(res.lam_n - mono.contact.force_n)
                                 / max(np.linalg.norm(mono.contact.force_n), 1e-300))
    return res, out
