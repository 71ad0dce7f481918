"""Docs and docstrings name only files the repository has: every path like
`docs/joints.md`, `examples/rsup.yaml` or `fccgen/viz/scene.py` in a doc, a source file
or a test exists, every relative Markdown link of docs/ resolves, and nothing cites a
design document outside the repository (the design is docs/design.md)."""
from __future__ import annotations

import re
from pathlib import Path

from conftest import ROOT

TOP = ("docs", "examples", "tests", "fccgen", "benchmarks", "templates")
SUFFIXES = ("md", "py", "yaml", "pyx", "pxd", "jinja", "ipynb", "csv", "png", "svg", "h",
            "c", "txt", "toml", "json")
PATH = re.compile(rf"(?<![\w/.-])((?:{'|'.join(TOP)})/[\w./-]*?\.(?:{'|'.join(SUFFIXES)}))"
                  r"(?![\w-])")
LINK = re.compile(r"\]\(([^)#\s]+\.(?:md|png|svg|ipynb|csv|py|yaml))(?:#[^)]*)?\)")
# Generated or user-chosen names that docs show as examples of output, not as files
# of the repository.
OUTPUTS = ("docs/figures/", "docs/accuracy/", "docs/performance/", "benchmarks/out/")


def texts():
    """(path, text) of every doc, source file, template and test."""
    files = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")),
             *sorted((ROOT / "docs").glob("*.ipynb")), *sorted((ROOT / "examples").glob("*")),
             *sorted((ROOT / "fccgen").rglob("*.py")), *sorted((ROOT / "fccgen").rglob("*.pyx")),
             *sorted((ROOT / "fccgen").rglob("*.pxd")), *sorted((ROOT / "templates").glob("*")),
             *sorted((ROOT / "tests").glob("*.py")), *sorted((ROOT / "benchmarks").rglob("*.py")),
             ROOT / "setup.py", ROOT / "pyproject.toml"]
    for path in files:
        if path.is_file() and path.suffix in {f".{s}" for s in SUFFIXES} | {".jinja"}:
            yield path, path.read_text(encoding="utf-8", errors="replace")


def test_every_named_repository_file_exists():
    missing = []
    for path, text in texts():
        for name in PATH.findall(text):
            name = name.rstrip(".")
            if not name.startswith(OUTPUTS) and not (ROOT / name).exists():
                missing.append(f"{path.relative_to(ROOT)}: {name}")
    assert not missing, "named but missing:\n" + "\n".join(missing)


def test_every_relative_link_of_the_docs_resolves():
    broken = []
    for doc in [ROOT / "README.md", ROOT / "examples" / "README.md",
                *sorted((ROOT / "docs").glob("*.md"))]:
        for target in LINK.findall(doc.read_text(encoding="utf-8")):
            if "://" not in target and not (doc.parent / target).exists():
                broken.append(f"{doc.relative_to(ROOT)}: {target}")
    assert not broken, "\n".join(broken)


def test_no_reference_to_a_design_document_outside_the_repository():
    stale = [f"{path.relative_to(ROOT)}:{k + 1}" for path, text in texts()
             for k, line in enumerate(text.splitlines())
             if re.search(r"\bDESIGN\b", line) and path.name != Path(__file__).name]
    assert not stale, "cite docs/design.md instead:\n" + "\n".join(stale)
