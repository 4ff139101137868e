"""`load_study(path_or_mapping)`: a study file read, checked with its typed models and
cross-reference rules, and returned as the plain `Study`; `load_scene(mapping)`: the scene block
alone, resolved and checked the same way."""
from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from pathlib import Path

from ..dynamics.spec import check_dynamics
from ..scene.spec import Scene
from .criteria import _check_criteria, _split_limits
from .fuzzy import _levels
from .resources import NO_CRITERIA, _check_mesh, _locking_warnings
from .scene import _check_contacts, _check_references, _check_regions, _check_thermal, _load_scene
from .schema import _STUDY
from .includes import resolve_includes
from .source import LIBRARIES, MAPPING, _mapping_yaml, _read_yaml, _Source
from .study import Study
from .uncertain import _check_lame_sweep, _check_sweep, _parameters, _parse_uncertain

def _recorded_text(base: Path, text: str, extra: list[tuple[Path, str]]) -> str:
    """The study text followed by each file it pulled in (named relative to `base`; a shipped
    library by its name, so the record does not depend on where wcs is installed), as
    further YAML documents."""
    for path, more in extra:
        shipped = path.resolve().parent == LIBRARIES.resolve()
        name = f"shipped library {path.name}" if shipped else os.path.relpath(path, base)
        text = f"{text.rstrip()}\n---\n# {name}\n{more}"
    return text


def _checked_scene(raw, src: _Source, method: str = "auto") -> tuple[Scene, list[tuple[Path, str]], list[str], float | None]:
    """The scene of a study (inline, or a file name relative to `src`), resolved and checked;
    the files it came from, the notes on it and its estimated cell count."""
    scene, scene_src, extra, notes = _load_scene(raw, src)
    _check_regions(scene, scene_src)
    _check_references(scene, scene_src)
    _check_contacts(scene, scene_src)
    notes = notes + _check_thermal(scene, scene_src)
    return scene, extra, notes, _check_mesh(scene, scene_src, method)


def load_scene(mapping: Mapping, base_dir=None) -> Scene:
    """The `scene:` block of a study given as the mapping its YAML parses to, resolved and
    checked as `load_study` does (file names relative to `base_dir`, default the current
    directory); StudyError names `<mapping>` and the key path (`scene.…`)."""
    doc, _ = _mapping_yaml(mapping)
    return _checked_scene(doc, _Source(MAPPING, (), Path.cwd() if base_dir is None else Path(base_dir)))[0]


def load_study(path_or_mapping, base_dir=None) -> Study:
    """Read and validate a study file, or a study given as the mapping its YAML parses to;
    StudyError names the file (`<mapping>`), key path and fault. The files the study names
    are relative to `base_dir` (default: the study file's folder; for a mapping, the current
    directory)."""
    if isinstance(path_or_mapping, Mapping):
        file, folder = MAPPING, Path.cwd()
        doc, text = _mapping_yaml(path_or_mapping)
    else:
        file = Path(path_or_mapping)
        folder = file.parent
        doc, text = _read_yaml(file)
    src = _Source(file, (), folder if base_dir is None else Path(base_dir))
    doc, included = resolve_includes(doc, file, src.base, _read_yaml)   # `include:` presets (wcs/study/includes.py)
    if not isinstance(doc, dict):
        got = "an empty file" if doc is None else type(doc).__name__
        raise src.error((), f"a study file is a mapping of keys (got {got})")
    top = src.validate(_STUDY, doc)
    scene, extra, notes, cells = _checked_scene(top.scene, src, top.solver.method)
    uncertain = _parse_uncertain(top.uncertain, scene, src)
    criteria = top.criteria
    _check_criteria(criteria, scene, src)
    upper_limits, lower_limits = _split_limits(top.limits, criteria, src)
    sweep = top.sweep
    _check_sweep(sweep, scene, src)
    _check_lame_sweep(sweep, uncertain, scene, src)
    check_dynamics(top.dynamics, scene, uncertain, criteria, top.solver, src.error)
    name = top.study or ("study" if file is MAPPING else file.stem)
    text = _recorded_text(src.base, text, included + extra)
    return Study(
        name=name, file=file, text=text, sha256=hashlib.sha256(text.encode()).hexdigest(),
        scene=scene, uncertain=uncertain, criteria=criteria, limits=upper_limits,
        search=top.search, solver=top.solver, sweep=sweep,
        output=top.output or f"results/{name}.nc", parameters=_parameters(uncertain), notes=notes,
        warnings=_locking_warnings(scene, uncertain) + ([] if criteria else [NO_CRITERIA]), estimated_cells=cells,
        lower_limits=lower_limits, levels=_levels(top, uncertain), dynamics=top.dynamics,
    )
