"""The list of slow tests (tests/slow_tests.txt, read by tests/conftest.py) names real tests, and
the marker reaches what it lists: a renamed or deleted test must leave the list with it, or the
fast subset would quietly grow."""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

from tests.conftest import PROJECT_ROOT, is_slow, slow_tests


@cache
def _test_names(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {node.name for node in ast.walk(tree)
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            and node.name.startswith("test")}


def test_every_listed_slow_test_exists() -> None:
    listed = slow_tests()
    assert listed, "tests/slow_tests.txt lists nothing"
    assert len(set(listed)) == len(listed), "an entry is listed twice"
    missing = []
    for entry in listed:
        file, _, name = entry.partition("::")
        path = PROJECT_ROOT / file
        if not (file.startswith("tests/") and path.is_file()):
            missing.append(f"{entry}: no such test file")
        elif name and name not in _test_names(path):
            missing.append(f"{entry}: no test {name} in {file}")
    assert missing == []


def test_a_listed_file_or_test_marks_its_tests_and_parameters_only() -> None:
    listed = ("tests/a/test_x.py", "tests/b/test_y.py::test_long")
    assert is_slow("tests/a/test_x.py::test_one", listed)
    assert is_slow("tests/b/test_y.py::test_long[case-1]", listed)
    assert is_slow("tests/b/test_y.py::test_long", listed)
    assert not is_slow("tests/b/test_y.py::test_longer", listed)
    assert not is_slow("tests/b/test_y.py::test_short", listed)
    assert not is_slow("tests/a/test_x2.py::test_one", listed)
