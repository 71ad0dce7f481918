"""No text of a model file or of a path reaches the exported C, Makefile, CMake or XML
unchecked (docs/export.md): each new place is attacked with a comment end, quotes,
a newline, a shell substitution and a parent-folder path."""
from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

from conftest import EXAMPLES

from fccgen.errors import ModelError
from fccgen.export import export_c
from fccgen.export.c_data import c_strings
from fccgen.export.fmu import export_fmu, sens_variable_name, xml_name
from fccgen.export.fmu_events import clash, enumeration_items
from fccgen.export.fmu_sens import SensOutput

ATTACKS = ["a*/b", 'a"b', "a\nb", "$(touch pwned)", "../up", "a'b", "a<b>&c", "a\\b"]
CC = shutil.which("cc") or shutil.which("gcc")
MAKE = shutil.which("make")


@pytest.mark.parametrize("name", ATTACKS)
def test_a_model_name_that_is_no_identifier_is_refused_before_anything_is_written(
        name, tmp_path, build_dir):
    text = (EXAMPLES / "four_bar.yaml").read_text().replace("name: four_bar",
                                                            f"name: {name!r}")
    model = tmp_path / "m.yaml"
    model.write_text(text)
    with pytest.raises(ModelError, match="name"):
        export_c(model, tmp_path / "c", build_dir)
    with pytest.raises(ModelError, match="name"):
        export_fmu(model, tmp_path / "m.fmu", build_dir)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.yaml"]


@pytest.mark.parametrize("name", ATTACKS)
def test_an_fmu_variable_name_is_checked_never_mended(name):
    with pytest.raises(ValueError):
        xml_name(name)
    assert xml_name("bodies.arm.inertia[2]") == "bodies.arm.inertia[2]"


@pytest.mark.parametrize("name", ATTACKS)
def test_a_sensitivity_output_name_is_made_of_checked_names_only(name):
    for column, key in ((name, "bodies.arm.mass"), ("P.x", name)):
        with pytest.raises(ValueError, match="FMU variable name"):
            sens_variable_name(SensOutput(column, key, 0))
    assert sens_variable_name(SensOutput("P.x", "loads[0].stiffness", 3)) == \
        "d(P.x)/d(loads[0].stiffness)"


@pytest.mark.parametrize("name", ATTACKS + ["(none)"])
def test_an_event_name_enters_the_fmus_enumeration_only_as_an_identifier(name):
    with pytest.raises(ValueError, match="EventName"):
        enumeration_items(["latch", name], ("lock",))
    items = enumeration_items(["latch"], ("lock",))
    assert items == {"EventName": [("(none)", 0), ("latch", 1)],
                     "EventAction": [("(none)", 0), ("lock", 1)]}


def test_an_event_output_that_is_already_a_variable_is_found():
    assert clash(["latch"], ["R.x", "events.count"]) == "events.count"
    assert clash(["latch"], ["R.x", "events"]) == ""
    assert clash([], ["events.count"]) == ""           # no events: no event outputs


def test_c_strings_escape_every_attack():
    """Each name is one C string literal on its own line: no raw newline, no quote
    or backslash left unescaped (the comment end is harmless inside a string)."""
    lines = c_strings("NAMES", ATTACKS).splitlines()[1:-1]
    assert len(lines) == len(ATTACKS)
    for line in lines:
        inner = line.strip().rstrip(",")
        assert inner[0] == inner[-1] == '"'
        rest = inner[1:-1].replace("\\\\", "").replace('\\"', "")
        assert '"' not in rest and "\\" not in rest.replace("\\?", "").replace(
            "\\012", "")


@pytest.mark.skipif(CC is None or MAKE is None or not sys.platform.startswith("linux"),
                    reason="needs a C compiler and make")
def test_a_hostile_folder_name_never_enters_the_project(tmp_path, build_dir):
    """The folder's path is written nowhere: make builds and runs inside a folder
    named with a shell substitution, quotes and spaces, and runs nothing else."""
    folder = tmp_path / "x $(touch pwned) \"q\" 'r' ` ;"
    export_c(EXAMPLES / "four_bar.yaml", folder, build_dir)
    for path in folder.iterdir():
        assert "pwned" not in path.read_text()
    done = subprocess.run([MAKE, "-s", "four_bar_selftest"], cwd=folder, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    assert subprocess.run(["./four_bar_selftest"], cwd=folder, capture_output=True,
                          text=True).stdout.strip() == "selftest passed"
    assert not list(tmp_path.rglob("pwned"))
