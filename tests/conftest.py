"""Shared fixtures: each example is generated and compiled once per test session."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
REFERENCE = Path(__file__).resolve().parent / "reference"
sys.path.insert(0, str(Path(__file__).resolve().parent))   # tests/minimal.py


def example_module(name: str):
    """The script examples/<name>.py as a module (the model generators and plot
    scripts are scripts, not a package)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def build_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("generated")


@pytest.fixture(scope="session")
def compiled(build_dir):
    """compiled(name) -> CompiledSolver of examples/<name>.yaml, built once."""
    import fccgen
    cache = {}

    def get(name: str):
        if name not in cache:
            cache[name] = fccgen.load(EXAMPLES / f"{name}.yaml", build_dir)
        return cache[name]
    return get


@pytest.fixture(scope="session")
def compiled_sparse(build_dir):
    """compiled_sparse(name) -> CompiledSolver of examples/<name>.yaml on the sparse
    path (the path the C export takes), built once."""
    import fccgen
    cache = {}

    def get(name: str):
        if name not in cache:
            cache[name] = fccgen.load(EXAMPLES / f"{name}.yaml", build_dir,
                                      linear_solver="sparse")
        return cache[name]
    return get


@pytest.fixture(scope="session")
def numeric():
    """numeric(name) -> NumericSolver of examples/<name>.yaml."""
    import fccgen
    cache = {}

    def get(name: str):
        if name not in cache:
            cache[name] = fccgen.load_numeric(EXAMPLES / f"{name}.yaml")
        return cache[name]
    return get


def run_python(code: str, cwd: Path, check: bool = True):
    """Run ``python -c code`` in a fresh interpreter that imports the same fccgen as
    this test session (source tree or installed), from ``cwd`` -- never from the
    repository root, whose source package would shadow an installed one."""
    import os
    import subprocess

    import fccgen
    package_parent = str(Path(fccgen.__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [package_parent, *filter(None, [os.environ.get("PYTHONPATH")])])}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env,
                          capture_output=True, text=True, check=check)
