"""The package explains itself: its docstrings, comments and messages cite the seed (the thesis and
the papers it collects, keyed in wcs/__init__.py), never design notes the repository does not ship."""
import ast
import re
from pathlib import Path

import wcs

PACKAGE = Path(wcs.__file__).parent
NOTES = re.compile(r"physics\.md|architecture\.md|study-format|performance\.md|dd-algorithm|shared/")
# a seed citation after a space or "(": "[21]", "[21, §4]", "[21, (4.32)]", "[21, Remark 2.1]";
# not an index like iparm[35] or f(x)[0], nor a list literal like [0] * n
CITATION = re.compile(r"(?:^|(?<=[\s(]))\[(\d+)(?:\](?!\s*[*+])|, [§(A-Z])", re.M)


def _texts():
    for path in sorted(PACKAGE.rglob("*")):
        if path.is_file() and path.suffix in (".py", ".yaml", ".yml", ".md", ".txt", ".cfg", ".toml"):
            yield path, path.read_text(encoding="utf-8")


def test_no_file_under_wcs_cites_a_design_note():
    hits = [f"{p.relative_to(PACKAGE.parent)}:{n}: {line.strip()}"
            for p, text in _texts() for n, line in enumerate(text.splitlines(), 1) if NOTES.search(line)]
    assert hits == []


def test_every_cited_seed_paper_is_in_the_key():
    key = {int(m) for m in CITATION.findall(wcs.__doc__)}
    assert key == {17, 19, 21, 28, 33, 68, 101}
    cited = {(int(m), str(p.relative_to(PACKAGE.parent))) for p, text in _texts() for m in CITATION.findall(text)}
    assert {m for m, _ in cited} >= {21, 68, 101}       # the solver, criteria and mortar cite their papers
    assert sorted(c for c in cited if c[0] not in key) == []


def _strings(tree):
    """(line, text) of every string literal of a module but its docstrings: what a user may read
    (an f-string's holes as {})."""
    docs = {id(n.body[0].value) for n in ast.walk(tree)
            if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and n.body and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            yield node.lineno, "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
            yield node.lineno, node.value


def test_messages_explain_in_words_and_cite_the_seed_after():
    """A message a user reads says what is wrong in words; a citation follows them as
    "(...; seed [21, Remark 2.1])", never standing in for them ("fails ([21, Remark 2.1])")."""
    hits = [f"{p.relative_to(PACKAGE.parent)}:{line}: {text.strip()[:120]}"
            for p, source in _texts() if p.suffix == ".py"
            for line, text in _strings(ast.parse(source))
            for m in CITATION.finditer(text) if not text[:m.start()].endswith("seed ")]
    assert hits == []
