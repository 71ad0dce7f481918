"""docs/reliability.md names the test of each guard as ``FILE::test_name`` (FILE a
test module under tests/); each such test exists, a function of that name defined in
that file, so that the list cannot point at a test that was renamed or removed."""
from __future__ import annotations

import ast
import re

from conftest import ROOT

NAMED = re.compile(r"(tests/test_\w+\.py)::(test_\w+)")


def _defined_tests(path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {node.name for node in ast.walk(tree)
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            and node.name.startswith("test_")}


def test_every_test_the_reliability_page_names_exists():
    text = (ROOT / "docs" / "reliability.md").read_text(encoding="utf-8")
    named = NAMED.findall(text)
    assert len(named) >= 40            # the guard list is there, not only prose
    defined, missing = {}, []
    for file, name in named:
        path = ROOT / file
        if file not in defined:
            defined[file] = _defined_tests(path) if path.is_file() else set()
        if name not in defined[file]:
            missing.append(f"{file}::{name}")
    assert not missing, "named in docs/reliability.md but not defined:\n" + "\n".join(
        missing)
