"""Validation scenes for tests: load one (optionally edited) and solve it at its nominal data."""
from pathlib import Path

import yaml

import wcs
from wcs.study import load_scene

VALIDATION = Path(__file__).resolve().parents[2] / "studies" / "validation"


def load(name, edit=None):
    doc = yaml.safe_load((VALIDATION / f"{name}.yaml").read_text())
    if edit:
        edit(doc)
    return wcs.load_study(doc)


def solve(name, edit=None):
    study = load(name, edit)
    ev = study.evaluate(study.nominal())
    assert ev.status == 0, ev.message
    return study, ev


def typed_scene(scene: dict, base_dir=None):
    """A test's scene mapping as the loader hands it on (`wcs.study.load_scene`: validated,
    checked, regions named); a scene without `materials` gets one (steel-like) for each name
    its regions use."""
    used = {r["material"] for body in scene["bodies"].values() for r in body["regions"]}
    return load_scene({"materials": {m: {"E": 2.0e11, "nu": 0.3} for m in sorted(used)}} | scene, base_dir)
