"""Validation scenes for tests: load one (optionally edited) and solve it at its nominal data."""
from pathlib import Path

import yaml

import wcs

VALIDATION = Path(__file__).resolve().parents[1] / "studies" / "validation"


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
