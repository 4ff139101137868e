"""Where study input comes from: YAML files read safely (a regular file of bounded size, no
duplicate keys, `1e7` a number, bounded nesting and alias expansion), a study given as a
mapping read as the file with its text would be, files located relative to the file that names
them (or among the shipped material libraries), and `_Source`: the file and key path a piece of
input lives at, which turns a fault into a `StudyError` naming both."""
from __future__ import annotations

import os
import re
import stat
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from pydantic import TypeAdapter, ValidationError

from ..errors import StudyError
from ..scene.spec import MAX_NAME
from .includes import SHIPPED

LIBRARIES = SHIPPED                                             # shipped material libraries: configs/
MAPPING = Path("<mapping>")                                       # the file name of a study given as a mapping
MAX_NESTING = 50                                   # levels of a study file (shapes nest)
MAX_NODES = 1_000_000                              # values of a study file, aliases expanded


class _Loader(yaml.SafeLoader):
    """SafeLoader that rejects duplicate keys and reads `1e7` as a number (as YAML 1.2 does)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                if key_node.value in seen:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key '{key_node.value}'", key_node.start_mark)
                seen.add(key_node.value)
        return super().construct_mapping(node, deep)


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


MAX_FILE_BYTES = 4 * 2**20     # a study, scene or material file: a few hundred lines at most


def _read_yaml(path: Path) -> tuple[Any, str]:
    """The parsed content and the text of a YAML file; StudyError if it is not a regular file
    (a device or a FIFO never ends), is larger than MAX_FILE_BYTES, is unreadable or is not YAML."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)        # a FIFO: no wait for a writer
        _check_regular(fd, path)
        with os.fdopen(fd, "rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
        if len(data) > MAX_FILE_BYTES:                        # grew while read
            raise StudyError(f"the file has more than the {MAX_FILE_BYTES} bytes a study, scene or material "
                             "file may have", file=str(path))
        text = data.decode("utf-8")
    except FileNotFoundError:
        raise StudyError("file not found", file=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise StudyError(f"cannot read the file: {exc}", file=str(path)) from None
    return _parse_yaml(text, path), text


def _check_regular(fd: int, path: Path) -> None:
    """StudyError (`fd` closed) unless `fd` is a regular file of at most MAX_FILE_BYTES."""
    info = os.fstat(fd)
    fault = None
    if not stat.S_ISREG(info.st_mode):
        kind = ("a directory" if stat.S_ISDIR(info.st_mode) else "a FIFO" if stat.S_ISFIFO(info.st_mode)
                else "a device" if stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode) else "a socket")
        fault = f"not a regular file ({kind}): study, scene and material files are YAML files"
    elif info.st_size > MAX_FILE_BYTES:
        fault = (f"the file has {info.st_size} bytes, more than the {MAX_FILE_BYTES} a study, scene or material "
                 "file may have")
    if fault is not None:
        os.close(fd)
        raise StudyError(fault, file=str(path))


def _parse_yaml(text: str, path: Path) -> Any:
    """The parsed content of YAML text read from `path`; StudyError naming `path` if not YAML."""
    try:
        doc = yaml.load(text, Loader=_Loader)
    except RecursionError:                          # the parser recurses per level
        raise StudyError(f"the file nests deeper than {MAX_NESTING} levels", file=str(path)) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise StudyError(f"YAML syntax error{where}: {exc.problem or exc.context}",
                         file=str(path)) from None
    except yaml.YAMLError as exc:
        raise StudyError(f"YAML syntax error: {exc}", file=str(path)) from None
    if _depth(doc) > MAX_NESTING:
        raise StudyError(f"the file nests deeper than {MAX_NESTING} levels", file=str(path))
    if _expanded_size(doc) > MAX_NODES:
        raise StudyError(f"the file holds more than {MAX_NODES} values once its aliases (*name) are expanded",
                         file=str(path))
    return doc


def _mapping_yaml(mapping: Mapping) -> tuple[Any, str]:
    """A study given as a mapping, as YAML text and parsed back from it: it loads exactly
    as the file with that text would, and the text is what the results record."""
    file = str(MAPPING)
    if _depth(mapping) > MAX_NESTING:
        raise StudyError(f"the mapping nests deeper than {MAX_NESTING} levels", file=file)
    try:
        text = yaml.safe_dump(mapping, sort_keys=False, allow_unicode=True)
    except yaml.YAMLError as exc:
        raise StudyError(f"not YAML data (numbers, strings, booleans, null, lists, mappings): {exc}",
                         file=file) from None
    return _parse_yaml(text, MAPPING), text


def _depth(doc) -> int:
    """Levels of nested mappings and lists (a scalar is level 0), without recursion."""
    deepest, stack, seen = 0, [(doc, 0)], set()
    while stack:
        node, level = stack.pop()
        if isinstance(node, (dict, list)) and (id(node), level) not in seen:   # aliases: once
            seen.add((id(node), level))
            deepest = max(deepest, level + 1)
            if level + 1 > MAX_NESTING:
                break
            stack += [(child, level + 1) for child in (node.values() if isinstance(node, dict) else node)]
    return deepest


def _expanded_size(doc) -> int:
    """Values (scalars, lists, mappings) of the document with every alias expanded: an alias
    repeats its anchor's whole subtree, so a few lines can stand for 1e7 shapes. Each distinct
    node is counted once and its count reused (bounded time, depth checked by `_depth` first)."""
    sizes: dict[int, int] = {}

    def size(node) -> int:
        if not isinstance(node, (dict, list)):
            return 1
        if id(node) not in sizes:
            sizes[id(node)] = 1 + sum(map(size, node.values() if isinstance(node, dict) else node))
        return sizes[id(node)]
    return size(doc)


def _locate(name: str, src: _Source, key: str, shipped: bool = False) -> Path:
    """A file named at `key`: relative to the referencing file's folder, then (`shipped`)
    among the package's material libraries."""
    places = (src.base / name,) + ((LIBRARIES / name,) if shipped else ())
    for candidate in places:
        if candidate.exists():                  # not a regular file: `_read_yaml` says what it is
            return candidate
    raise src.error((key,), f"file '{name}' not found (looked for {' and '.join(map(str, places))})")


def _fault(err: dict) -> str:
    """A pydantic error in plain words, with the offending value when it is short."""
    if err["type"] == "missing":
        return "required key is missing"
    message = err["msg"].removeprefix("Value error, ").replace("Input should be", "must be")
    message = re.sub(r"^(List|Dictionary) should have (.*) after validation", r"must have \2", message)
    message = re.sub(r" or instance of \w+$", "", message)
    value = err.get("input")
    if (err["type"] != "unknown_key" and isinstance(value, (bool, int, float, str, type(None)))
            and len(repr(value)) <= 80 and f"got {value!r}" not in message):
        message += f" (got {value!r})"
    return message


def _shown_key(key) -> str:
    """A key or name as a message shows it: a control character or a lone surrogate escaped
    (`\x00`), past MAX_NAME characters cut (the fault itself is reported at its own key)."""
    text = str(key)
    if not text.isprintable():
        text = ascii(text)[1:-1]
    return text if len(text) <= MAX_NAME else f"{text[:MAX_NAME]}... ({len(text)} characters)"


@dataclass(frozen=True)
class _Source:
    """Where a piece of input lives: the file to name, the key path of the piece in it, and
    the folder the names it gives are relative to (default: the file's folder)."""

    file: Path
    prefix: tuple = ()
    folder: Path | None = None

    @property
    def base(self) -> Path:
        return self.file.parent if self.folder is None else self.folder

    def error(self, path, message: str) -> StudyError:
        keys = self.prefix + tuple(path)
        return StudyError(message, file=str(self.file), path=".".join(map(_shown_key, keys)) or None)

    def validate(self, schema: TypeAdapter, data, path=()):
        """`data` checked and converted by `schema`; the first fault as a StudyError."""
        try:
            return schema.validate_python(data)
        except ValidationError as exc:
            errors = exc.errors()
            first = errors[0]
            loc = [k for k in first["loc"] if k != "[key]"]
            if first["type"] == "unknown_key":
                loc.append(first["ctx"]["key"])
            more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
            raise self.error(tuple(path) + tuple(loc), _fault(first) + more) from None
