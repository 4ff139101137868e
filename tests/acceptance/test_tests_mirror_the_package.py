"""The tests mirror the package: every test file sits under the folder of the part of wcs it
tests (a subpackage, wcs/contact/ -> tests/contact/, or a top-level module, wcs/cli.py ->
tests/cli/), or under acceptance/ (cross-cutting contract and trust checks), bench/
(benchmarks) or support/ (helpers the tests share). A maintainer finds the tests of a module
by its part's name."""
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
PACKAGE = TESTS.parent / "wcs"
OWN = {"acceptance", "bench", "support"}       # folders named for a kind of test, not for a part


def parts(package: Path) -> set[str]:
    """The parts of a package: its subpackages and its top-level modules."""
    return ({d.name for d in package.iterdir() if (d / "__init__.py").is_file()}
            | {p.stem for p in package.glob("*.py") if p.stem != "__init__"})


def misplaced(tests: Path, allowed: set[str]) -> list[str]:
    """The Python files of `tests` outside a folder named in `allowed` (the folder's own
    __init__.py and conftest.py excepted)."""
    return sorted(str(p.relative_to(tests)) for p in tests.rglob("*.py")
                  if p.parent == tests and p.name not in ("__init__.py", "conftest.py")
                  or p.parent != tests and p.relative_to(tests).parts[0] not in allowed)


def test_every_test_file_sits_under_a_part_of_the_package_or_a_kind_of_test():
    assert misplaced(TESTS, parts(PACKAGE) | OWN) == []


def test_every_folder_of_tests_but_bench_is_a_package():
    """Test modules are `tests.<part>.<name>`, so two parts may each hold a test file of one
    name; bench/ runs its scripts by their own names (`from common import ...`)."""
    folders = {p.parent for p in TESTS.rglob("*.py")} - {TESTS / "bench"}
    assert sorted(str(d.relative_to(TESTS.parent)) for d in folders if not (d / "__init__.py").is_file()) == []


def test_the_rule_finds_a_flat_test_file_and_a_folder_named_for_nothing(tmp_path):
    """The rule on a tree of its own: the flat layout of before, a folder for no part of the
    package, and the files it allows."""
    package = tmp_path / "wcs"
    (package / "contact").mkdir(parents=True)
    for name in ("__init__.py", "cli.py", "contact/__init__.py"):
        (package / name).write_text("")
    tests = tmp_path / "tests"
    for name in ("__init__.py", "conftest.py", "test_cli.py", "scenes.py", "contact/test_solver.py",
                 "cli/test_cli.py", "support/scenes.py", "acceptance/test_closed_forms.py",
                 "issue15/test_trust.py", "contact/data/make_mesh.py"):
        (tests / name).parent.mkdir(parents=True, exist_ok=True)
        (tests / name).write_text("")
    assert parts(package) == {"cli", "contact"}
    assert misplaced(tests, parts(package) | OWN) == ["issue15/test_trust.py", "scenes.py", "test_cli.py"]
