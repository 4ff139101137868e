"""Dependencies point one way: the modules of wcs import each other without a cycle, counting
the imports inside functions too (a function-level import that dodges a cycle is still one)."""
import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "wcs"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, modules: set[str]) -> set[str]:
    """The wcs modules `path` imports anywhere in its body (a name imported from a package
    counts as its submodule when it is one)."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([node.module] if node.module else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        else:
            continue
        for target in targets:
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != name and not name.startswith(target + "."):   # a package's own __init__
                out.add(target)
    return out


def graph() -> dict[str, set[str]]:
    files = sorted(PACKAGE.rglob("*.py"))
    modules = {module_name(f) for f in files}
    return {module_name(f): imports(f, modules) for f in files}


def cycle(g: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of the graph (as a closed path), or None."""
    state, path = {}, []

    def visit(v):
        state[v] = "open"
        path.append(v)
        for w in sorted(g[v]):
            if state.get(w) == "open":
                return path[path.index(w):] + [w]
            if w not in state and (found := visit(w)):
                return found
        state[v] = "done"
        path.pop()
        return None

    for v in sorted(g):
        if v not in state and (found := visit(v)):
            return found
    return None


def test_the_finder_sees_a_cycle_and_a_function_level_import():
    assert cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert cycle({"a": {"b"}, "b": set()}) is None
    g = graph()
    assert "wcs.model" in g["wcs.evaluation"]           # module level
    assert "wcs.evaluation" in g["wcs.study"]           # inside Study.evaluate
    assert "wcs.dd.solver" in g["wcs.model"]            # inside Model._solve_dd


def test_no_import_cycle():
    found = cycle(graph())
    assert found is None, " -> ".join(found)


@pytest.mark.parametrize("module", ["wcs.model", "wcs.dd.solver", "wcs.evaluation"])
def test_the_solvers_do_not_import_the_study_loader(module):
    """The options live below the loader (`wcs.options`), so the solvers need no study file."""
    assert "wcs.study" not in graph()[module]
