"""Validation scenes for tests: load one (optionally edited) and solve it at its nominal data."""
from pathlib import Path

import yaml

import wcs

VALIDATION = Path(__file__).resolve().parents[1] / "studies" / "validation"


def load(name, tmp_path, edit=None):
    doc = yaml.safe_load((VALIDATION / f"{name}.yaml").read_text())
    if edit:
        edit(doc)
    path = tmp_path / f"{name}-{abs(hash(yaml.safe_dump(doc))) % 10**8}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return wcs.load_study(path)


def solve(name, tmp_path, edit=None):
    study = load(name, tmp_path, edit)
    ev = study.evaluate(study.nominal())
    assert ev.status == 0, ev.message
    return study, ev
