"""docs/sweeps.md works as written: its local sweep command and its Python snippet, run
from a copy of the repository's examples/ (as the page says: from the repository's
folder), with the driven four-bar's module built once for the session copied into the
copy's generated/ folder (the cache is keyed by content, so nothing is compiled)."""
from __future__ import annotations

import csv
import re
import shlex
import shutil

from conftest import EXAMPLES, ROOT
from fccgen.cli import main

PAGE = ROOT / "docs" / "sweeps.md"


def section(title: str) -> str:
    text = PAGE.read_text(encoding="utf-8")
    start = text.index(f"## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else None]


def test_the_local_sweep_of_the_page(compiled, build_dir, tmp_path, monkeypatch, capsys):
    compiled("four_bar_driven")                      # built once per session
    shutil.copytree(EXAMPLES, tmp_path / "examples")
    shutil.copytree(build_dir / "four_bar_driven", tmp_path / "generated" / "four_bar_driven")
    monkeypatch.chdir(tmp_path)
    local = section("A local sweep")
    commands = [line.strip() for line in local.splitlines()
                if line.startswith("    fccgen sweep ")]
    assert len(commands) == 1
    args = shlex.split(commands[0])[1:]
    assert main(args) == 0
    out, err = capsys.readouterr()
    assert re.search(r"sweep: 2 runs \(0 failed\) on a local cluster of \d+ thread", out)
    assert "compiling" not in err
    with open("sweep.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["ok", "ok"]
    # a heavier crank needs more torque to turn at the same speed
    assert float(rows[1]["motor.torque:max"]) > float(rows[0]["motor.torque:max"]) > 0
    assert (tmp_path / "sweep.meta.json").exists()

    (code,) = re.findall(r"```python\n(.*?)```", local, flags=re.S)
    exec(compile(code, str(PAGE), "exec"), {})
    printed = capsys.readouterr().out
    assert "2 runs, 0 failed" in printed
    with open("sweep_py.csv", newline="") as fh:
        again = list(csv.DictReader(fh))
    # the same compiled code and numbers: the same torques to the last bit
    assert [r["motor.torque:max"] for r in again] == [r["motor.torque:max"] for r in rows]


def test_the_simulate_many_snippet_of_the_page(compiled, build_dir, tmp_path, monkeypatch,
                                               capsys):
    """The snippet of "Many runs in one process" runs as written: three masses meet
    the stop, the too-large step is reported in its place."""
    compiled("pendulum_limit")                       # built once per session
    shutil.copytree(EXAMPLES, tmp_path / "examples")
    for folder in build_dir.glob("pendulum_limit*"):
        shutil.copytree(folder, tmp_path / "generated" / folder.name)
    monkeypatch.chdir(tmp_path)
    (code,) = re.findall(r"```python\n(.*?)```", section("Many runs in one process: "
                                                         "`simulate_many`"), flags=re.S)
    exec(compile(code, str(PAGE), "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4 and all("first event: quarter at" in x for x in lines[:3])
    assert "failed:" in lines[3] and "diverged" in lines[3]
