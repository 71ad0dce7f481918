"""The README's Python snippet pasted into a Python started in the repository root:
the source folder fccgen/ shadows the installed package and has no compiled runtime,
and the error says so and what to do (not a bare ModuleNotFoundError)."""
from __future__ import annotations

import os
import re
import subprocess
import sys

from conftest import ROOT


def readme_snippet() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    [snippet] = [b for b in blocks if "fccgen.load(" in b]
    return snippet


HIDE = """\
import importlib.abc, sys
class Hide(importlib.abc.MetaPathFinder):          # as in a fresh checkout
    def find_spec(self, name, path, target=None):
        if name == {name!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
sys.meta_path.insert(0, Hide())
"""


def test_a_source_folder_without_its_runtime_says_what_to_do(tmp_path):
    """The snippet fed to a Python started in the repository root, the compiled
    runtime module hidden (a fresh checkout has none in the source folder), and an
    'installed' fccgen further down sys.path."""
    site = tmp_path / "site"
    (site / "fccgen").mkdir(parents=True)
    (site / "fccgen" / "__init__.py").write_text("")
    env = {**os.environ, "PYTHONPATH": str(site), "PYTHONDONTWRITEBYTECODE": "1"}
    code = HIDE.format(name="fccgen.runtime._assemble") + readme_snippet()
    proc = subprocess.run([sys.executable, "-"], input=code, cwd=ROOT, env=env,
                          capture_output=True, text=True)
    assert proc.returncode == 1
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith(f"ImportError: fccgen was imported from {ROOT / 'fccgen'}, a "
                           "source folder, which shadows the installed fccgen in "
                           f"{site / 'fccgen'}"), proc.stderr
    assert "compiled runtime (fccgen.runtime._assemble) is not built there" in last
    assert f"start Python in another folder than {ROOT}" in last
    assert "pip install -e ." in last
    assert "ModuleNotFoundError: No module named 'fccgen.runtime._assemble'" in proc.stderr


def test_other_missing_modules_are_not_reworded(tmp_path):
    """Only the runtime's own compiled modules get the explanation."""
    code = HIDE.format(name="numpy") + "from fccgen.runtime import CompiledSolver\n"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines()[-1] == (
        "ModuleNotFoundError: No module named 'numpy'"), proc.stderr
