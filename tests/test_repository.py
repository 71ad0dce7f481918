"""Promises the repository makes to a new user: the README's commands are the ones CI
runs, and build output stays out of version control."""
from __future__ import annotations

import re
import shutil
import subprocess

import pytest

from conftest import ROOT


def readme_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    return re.findall(r"```bash\n(.+?)\n```", text, flags=re.S)[:2]


def test_readme_starts_with_the_two_commands():
    example, tests = readme_commands()
    assert "pip install ." in example and "fccgen simulate examples/" in example
    assert 'pip install ".[test]"' in tests and tests.rstrip().endswith("pytest")
    model = re.search(r"fccgen simulate (\S+\.yaml)", example).group(1)
    assert (ROOT / model).is_file()


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    _, tests = readme_commands()
    assert tests.strip() in ci


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(),
                    reason="not a git checkout")
def test_generated_output_is_not_tracked():
    tracked = subprocess.run(["git", "ls-files", "generated"], cwd=ROOT, capture_output=True,
                             text=True, check=True).stdout.split()
    assert tracked == ["generated/README.md"]
    probe = subprocess.run(["git", "check-ignore", "-q", "generated/x/x.c"], cwd=ROOT)
    assert probe.returncode == 0, "generated/ must be ignored by git"


def test_every_package_is_installed():
    """A package folder missing from pyproject's list works from the source tree and
    is absent from the installed copy that CI tests."""
    import tomllib
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
                 ["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts)
             for p in (ROOT / "fccgen").rglob("__init__.py")}
    assert found <= listed, sorted(found - listed)
