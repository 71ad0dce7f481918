"""Imports point down (docs/architecture.md): no module imports one that imports it
back, directly or around a circle, and the stages (the packages and top-level modules of
fccgen) form no circle either. Lazy imports inside functions count: a circle through
them is still a circle when the function runs."""
import ast
import graphlib
import re
from collections import defaultdict
from pathlib import Path

import fccgen

PACKAGE = Path(fccgen.__file__).parent
DOC = Path(__file__).parents[1] / "docs" / "architecture.md"
# data shipped as packages, not stages: the example models (their generator scripts
# are Python) and the Jinja2 templates, where an installed fccgen keeps them
DATA = {"examples", "templates"}


def module_name(path: Path) -> tuple[str, bool]:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    is_package = parts[-1] == "__init__"
    if is_package:
        parts = parts[:-1]
    return ".".join(parts), is_package


def modules() -> dict[str, tuple[list[Path], bool]]:
    """Every module of fccgen: its Python files and its Cython ones (.pyx, .pxd: one
    module may have both)."""
    out = {}
    for path in [*PACKAGE.rglob("*.py"), *PACKAGE.rglob("*.pyx"), *PACKAGE.rglob("*.pxd")]:
        name, is_package = module_name(path)
        out.setdefault(name, ([], is_package))[0].append(path)
    return out


def imported(name: str, is_package: bool, tree: ast.AST, known) -> set[str]:
    """The fccgen modules that module ``name`` imports, anywhere in its body."""
    def existing(target: str) -> str | None:
        while target and target not in known:
            target = target.rpartition(".")[0]
        return target or None

    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(filter(None, (existing(a.name) for a in node.names)))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[:len(base) - node.level + 1]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            for alias in node.names:
                target = existing(f"{base}.{alias.name}") or existing(base)
                if target:
                    found.add(target)
    found.discard(name)
    return {m for m in found if m.startswith("fccgen")}


def cython_imports(text: str) -> ast.AST:
    """The import statements of a Cython module as a Python tree (its other lines are
    not Python): ``from X cimport a, b`` counts as ``from X import a, b``, with the
    names on the statement's first line (enough to see a submodule imported by name)."""
    lines = []
    for line in text.splitlines():
        m = re.match(r"\s*from\s+(\S+)\s+c?import\s+(.*)", line)
        if m:
            names = [n for n in re.findall(r"\w+", m.group(2).split(" as ")[0])]
            lines.append(f"from {m.group(1)} import {', '.join(names) or '_'}")
            continue
        m = re.match(r"\s*c?import\s+([\w.]+)", line)
        if m:
            lines.append(f"import {m.group(1)}")
    return ast.parse("\n".join(lines))


def graph() -> dict[str, set[str]]:
    known = modules()
    return {name: set().union(*(
                imported(name, is_package, cython_imports(path.read_text())
                         if path.suffix in (".pyx", ".pxd") else ast.parse(path.read_text()),
                         known) for path in paths))
            for name, (paths, is_package) in known.items()}


def stage(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def test_no_module_imports_itself_around_a_circle():
    edges = graph()
    # a package's __init__ may gather its children; a child importing its own package
    # then sees the package half-made only if the package imports that child: counted
    graphlib.TopologicalSorter(edges).prepare()      # raises CycleError naming the circle


def test_the_stages_form_no_circle():
    stages = defaultdict(set)
    for a, targets in graph().items():
        for b in targets:
            if stage(a) != stage(b):
                stages[stage(a)].add(stage(b))
    graphlib.TopologicalSorter(stages).prepare()


def test_the_architecture_doc_names_every_stage():
    """Every package and top-level module of fccgen appears in docs/architecture.md's
    table or its paragraph on the top level, so the doc says where each one sits."""
    text = DOC.read_text()
    named = set(re.findall(r"`([a-z_]+)`", text))
    stages = {stage(m) for m in modules()} - {"__init__", "__main__"} - DATA
    assert stages <= named, f"not in docs/architecture.md: {sorted(stages - named)}"


def test_the_scan_sees_relative_and_lazy_imports():
    """The checks above can fail: the scan finds a module-level relative import
    (runtime.solver -> runs.energy_check), one of a submodule by name
    (runtime.solver -> rank) and a lazy one inside a function (api -> analysis.inverse),
    and a made-up circle is refused."""
    edges = graph()
    assert {"fccgen.runs.energy_check", "fccgen.rank"} <= edges["fccgen.runtime.solver"]
    assert "fccgen.analysis.inverse" in edges["fccgen.api"]
    edges["fccgen.rank"] = edges["fccgen.rank"] | {"fccgen.runtime.solver"}
    try:
        graphlib.TopologicalSorter(edges).prepare()
    except graphlib.CycleError:
        return
    raise AssertionError("a circle through rank and runtime.solver was not found")
