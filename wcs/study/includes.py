"""Includes: a study takes the keys of preset files it names, unless it sets them itself.

    include: configs/solver-large-3d.yaml          # or a list: [configs/search-quick.yaml, my-solver.yaml]

A name is looked up, in this order,
1. relative to the folder of the file that names it (for a study given as a mapping, its
   base folder), then
2. among the configs shipped with wcs (the repository's top-level `configs/`, installed in
   the package as `wcs/configs/`), by the name with a leading `configs/` left out — so
   `configs/search-quick.yaml` reads the same in the clone and in an installed wcs.

An included file is a mapping of study keys (`search:`, `solver:`, `scene:` ...) and may
include further files, relative to its own folder. The merge: two mappings merge key by
key, recursively; any other value (a number, a string, null, a list) is taken whole from
the file that wins — the including file over what it includes, a later name of the list
over an earlier one. The two values of a key must be of one kind (both mappings, both lists
or both scalars). A name found nowhere, an include cycle, an included file that is not a
mapping and a key of two kinds are StudyErrors (exit 2) naming the file and the key path.
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import StudyError

PACKAGE = Path(__file__).resolve().parents[__name__.count(".") - 1]   # wcs/, wherever in it this module sits
SHIPPED = PACKAGE / "configs"                # the top-level configs/, shipped in the package (a symlink in the clone)
KEY = "include"

Reader = Callable[[Path], tuple[Any, str]]                 # a file -> (parsed YAML, its text)


def resolve_includes(doc, file: Path, folder: Path, read: Reader) -> tuple[Any, list[tuple[Path, str]]]:
    """The study `doc` (read from `file`, its names relative to `folder`) with its includes
    merged in, and the included files with their texts in the order read; `doc` unchanged
    when it names none. `read` reads a YAML file (the study loader's reader: its size,
    nesting and duplicate-key checks apply to included files too)."""
    if not isinstance(doc, dict) or KEY not in doc:
        return doc, []
    files: list[tuple[Path, str]] = []
    return _expand(doc, file, folder, read, (), files), files


def _expand(doc: dict, file: Path, folder: Path, read: Reader, chain: tuple[Path, ...],
            files: list[tuple[Path, str]]) -> dict:
    """`doc` without its `include` key, merged over the files it names (each expanded first)."""
    names = doc[KEY]
    names = [names] if isinstance(names, str) else names
    if not isinstance(names, list) or not names or not all(isinstance(n, str) and n for n in names):
        raise StudyError("must be a file name or a list of file names", file=str(file), path=KEY)
    merged: dict = {}
    for i, name in enumerate(names):
        where = KEY if isinstance(doc[KEY], str) else f"{KEY}[{i}]"
        path = locate(name, folder, file, where)
        if path.resolve() in chain + (file.resolve(),):
            cycle = " -> ".join(str(p) for p in chain + (file.resolve(), path.resolve()))
            raise StudyError(f"'{name}' includes itself: {cycle}", file=str(file), path=where)
        sub, text = read(path)
        files.append((path, text))
        if not isinstance(sub, dict):
            got = "an empty file" if sub is None else type(sub).__name__
            raise StudyError(f"an included file is a mapping of study keys (got {got})", file=str(path))
        if KEY in sub:
            sub = _expand(sub, path, path.parent, read, chain + (file.resolve(),), files)
        merged = merge(merged, sub, str(path), ", ".join(names[:i]))
    return merge(merged, {k: v for k, v in doc.items() if k != KEY}, str(file), ", ".join(names))


def locate(name: str, folder: Path, file: Path, where: str) -> Path:
    """The file an include names: relative to `folder`, then among the shipped configs."""
    places = (folder / name, SHIPPED / name.removeprefix("configs/"))
    for place in places:
        if place.is_file():
            return place
    shipped = ", ".join(sorted(p.name for p in SHIPPED.glob("*.yaml") if not p.name.startswith("materials-")))
    raise StudyError(f"file '{name}' not found (looked for {places[0]} and {places[1]}); the shipped presets "
                     f"are {shipped}", file=str(file), path=where)


def merge(base: dict, over: dict, file: str, origin: str, prefix: tuple = ()) -> dict:
    """`over` merged onto `base`: mappings key by key, any other value of `over` replacing
    `base`'s; StudyError naming `file` (where `over` comes from), the key path and `origin`
    (where `base` comes from) when a key holds values of two kinds."""
    out = dict(base)
    for key, value in over.items():
        path = prefix + (key,)
        if key not in base:
            out[key] = value
        elif isinstance(value, dict) and isinstance(base[key], dict):
            out[key] = merge(base[key], value, file, origin, path)
        elif _kind(value) != _kind(base[key]):
            raise StudyError(f"is {_kind(value)} here but {_kind(base[key])} in {origin}: the two must be of "
                             "one kind (both mappings, both lists or both scalars)",
                             file=file, path=".".join(map(str, path)))
        else:
            out[key] = value
    return out


def _kind(value) -> str:
    return "a mapping" if isinstance(value, dict) else "a list" if isinstance(value, list) else "a scalar"
