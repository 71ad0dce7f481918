"""The README is the truth: its Python snippet runs as written in a folder outside
the repository, its `examples/...` lines work there after `fccgen examples`, and every
command line it shows parses with fccgen's own parser."""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT, run_python
from test_viz_scene import by_name, page_data

README = (ROOT / "README.md").read_text(encoding="utf-8")


def blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", README, flags=re.S)


def command_lines() -> list[str]:
    """Every `fccgen ...` command of the README's bash blocks, comments dropped, the
    set-up's commands split at &&."""
    lines = []
    for block in blocks("bash"):
        for line in block.splitlines():
            for part in line.split("#")[0].split("&&"):
                if part.strip().startswith("fccgen"):
                    lines.append(part.strip())
    return lines


def cli(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """The fccgen command of this test session, run in ``cwd``."""
    import fccgen
    parent = str(Path(fccgen.__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": parent}
    return subprocess.run([sys.executable, "-m", "fccgen.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True)


@pytest.fixture(scope="module")
def user_folder(tmp_path_factory, compiled, build_dir):
    """A folder outside the repository where `fccgen examples` has run; its
    ./generated holds the session's builds (the cache a second run would find)."""
    import shutil
    folder = tmp_path_factory.mktemp("new-user")
    for name in ("double_pendulum", "solar_array"):
        compiled(name)
        shutil.copytree(build_dir / name, folder / "generated" / name)
    done = cli(["examples"], folder)
    assert done.returncode == 0, done.stderr
    assert (folder / "examples" / "double_pendulum.yaml").is_file()
    return folder


def test_the_python_snippet_runs_in_another_folder(user_folder):
    (snippet,) = [b for b in blocks("python") if "import fccgen" in b]
    done = run_python(snippet, cwd=user_folder, check=False)
    assert done.returncode == 0, done.stderr
    assert "['t', 'P1.x'" in done.stdout
    assert (user_folder / "double_pendulum.h5").is_file()
    assert (user_folder / "double_pendulum.png").stat().st_size > 10_000
    check = run_python("import pandas, fccgen; f = fccgen.Result.load("
                       "'double_pendulum.h5').to_pandas(); print(f.index.name, "
                       "len(f), f['P2.x'].iloc[-1] == f['P2.x'].values[-1])",
                       cwd=user_folder)
    assert check.stdout.split() == ["t", "201", "True"]


def test_the_set_up_run_and_the_solar_array_page_work_there(user_folder):
    first = command_lines()[0]
    assert first == ("fccgen simulate examples/double_pendulum.yaml --out "
                     "double_pendulum.csv")
    done = cli(shlex.split(first)[1:], user_folder)
    assert done.returncode == 0, done.stderr
    assert "501 rows" in done.stdout
    (animate,) = [c for c in command_lines() if "examples/solar_array.yaml" in c]
    done = cli(shlex.split(animate)[1:] + ["-q"], user_folder)
    assert done.returncode == 0, done.stderr
    data = page_data((user_folder / "solar_array.html").read_text(encoding="utf-8"))
    assert by_name(data, "bodies (mass centres)")["text"] == ["bus", "panel1", "panel2"]
    assert {"panel1", "panel2"} <= set(by_name(data, "bodies (inertia boxes)")["hovertext"])


def test_every_command_line_parses_and_names_a_shipped_example():
    import fccgen
    from fccgen.cli import COMMANDS, _parser
    shipped = set(fccgen.example_names())
    lines = command_lines()
    assert len(lines) >= 15
    for line in lines:
        args = shlex.split(line)[1:]
        if args[0] not in COMMANDS:
            args.insert(0, "generate")
        _parser().parse_args(args)              # SystemExit on an unknown option
        for name in re.findall(r"examples/(\w+)\.yaml", line):
            assert name in shipped, line


def test_examples_are_found_by_name_and_copied_without_overwriting(tmp_path):
    import fccgen
    from fccgen.example_models import copy_examples
    assert fccgen.example_path("rsup") == fccgen.example_path("rsup.yaml")
    assert fccgen.example_path("rsup").read_text() == (ROOT / "examples" / "rsup.yaml"
                                                       ).read_text()
    with pytest.raises(ValueError, match="no example named 'nope'; the examples are "
                                         "a01_pendulum, "):
        fccgen.example_path("nope")
    written = copy_examples(tmp_path / "ex")
    assert {p.name for p in written} >= {"README.md", "make_n_four_bar.py", "rsup.yaml"}
    (tmp_path / "ex" / "rsup.yaml").write_text("mine")
    assert copy_examples(tmp_path / "ex") == []                  # nothing replaced
    assert (tmp_path / "ex" / "rsup.yaml").read_text() == "mine"
    assert len(copy_examples(tmp_path / "ex", overwrite=True)) == len(written)
