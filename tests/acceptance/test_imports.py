"""Dependencies point one way: the modules of wcs import each other without a cycle, counting
the imports inside functions too (a function-level import that dodges a cycle is still one), and
no module imports from a layer above its own (the layers as the `wcs/__init__.py` docstring
lists them, bottom up); `search/` imports from the lowest layer alone, below the study."""
import ast
import re
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
            if target and target != name and (target == "wcs" or not name.startswith(target + ".")):
                # a package's own __init__ is left out, but for the root's (the top layer)
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


def layers() -> list[list[str]]:
    """The layers the `wcs/__init__.py` docstring declares, bottom up: per layer its modules or
    packages as dotted names (`wcs.geometry`); the package's own __init__ (`wcs`) is on top."""
    doc = ast.get_docstring(ast.parse((PACKAGE / "__init__.py").read_text()))
    found = re.findall(r"^\s+\d+\. ([\w, ]+?)(?: \(.*?\))?:", doc, flags=re.M)
    out = [[f"wcs.{name.strip()}" for name in line.split(",")] for line in found]
    out[-1].append("wcs")
    return out


def layer_of(module: str, order: list[list[str]]) -> int:
    """The index of the layer that holds `module` (its longest declared prefix; `wcs`, the
    package's own __init__, holds itself alone)."""
    best = max(((len(p), i) for i, layer in enumerate(order) for p in layer
                if module == p or (p != "wcs" and module.startswith(p + "."))), default=None)
    assert best is not None, f"{module} is in no layer of the wcs/__init__.py docstring"
    return best[1]


def upward(g: dict[str, set[str]], order: list[list[str]]) -> list[str]:
    """Every import of a module from a layer above its own, as 'a (layer i) -> b (layer j)'."""
    return [f"{a} (layer {layer_of(a, order) + 1}) -> {b} (layer {layer_of(b, order) + 1})"
            for a in sorted(g) for b in sorted(g[a]) if layer_of(b, order) > layer_of(a, order)]


def test_the_finder_sees_a_cycle_and_a_function_level_import():
    assert cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert cycle({"a": {"b"}, "b": set()}) is None
    g = graph()
    assert "wcs.model.model" in g["wcs.model.evaluation"]      # module level
    assert "wcs.model.evaluation" in g["wcs.app.evaluable"]    # inside EvaluableStudy._evaluator
    assert "wcs.dd.solver" in g["wcs.model.model"]             # inside Model._solve_dd


def test_no_import_cycle():
    found = cycle(graph())
    assert found is None, " -> ".join(found)


def test_the_layers_are_read_and_an_upward_import_is_seen():
    order = layers()
    assert order[0][:2] == ["wcs.errors", "wcs.status"] and order[-1] == ["wcs.cli", "wcs"]
    assert layer_of("wcs.contact.solver", order) < layer_of("wcs.dd.solver", order)
    with pytest.raises(AssertionError, match="in no layer"):
        layer_of("wcs.undeclared", order)
    assert upward({"wcs.fem.gluing": {"wcs.contact.mortar"}}, order) == [
        f"wcs.fem.gluing (layer {layer_of('wcs.fem', order) + 1}) -> wcs.contact.mortar "
        f"(layer {layer_of('wcs.contact', order) + 1})"]


def test_no_module_imports_from_a_layer_above():
    found = upward(graph(), layers())
    assert not found, "\n".join(found)


def test_search_imports_only_from_the_lowest_layer():
    """The strategies see a `Problem` and the `search` options (`wcs.options`), not the study."""
    order, g = layers(), graph()
    found = [f"{a} -> {b}" for a in sorted(g) if a.startswith("wcs.search")
             for b in sorted(g[a]) if not b.startswith("wcs.search") and layer_of(b, order) > 0]
    assert not found, "\n".join(found)
    assert layer_of("wcs.search", order) < layer_of("wcs.study", order)


@pytest.mark.parametrize("module", ["wcs.model.model", "wcs.dd.solver", "wcs.model.evaluation"])
def test_the_solvers_do_not_import_the_study_loader(module):
    """The options live below the loader (`wcs.options`), so the solvers need no study file."""
    assert not any(m.startswith("wcs.study") for m in graph()[module])
