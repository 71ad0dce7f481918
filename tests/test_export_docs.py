"""docs/export.md works as written: its shell lines run in a fresh folder after
`fccgen examples` (make included), its Python snippet runs there and prints a
difference at rounding level, the example's CSV equals simulate's, and every C API
function the page shows exists in the exported header."""
from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, run_python

DOC = (ROOT / "docs" / "export.md").read_text(encoding="utf-8")
CC = shutil.which("cc") or shutil.which("gcc")

pytestmark = pytest.mark.skipif(CC is None or shutil.which("make") is None
                                or not sys.platform.startswith("linux"),
                                reason="needs a C compiler and make (Linux)")


def blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", DOC, flags=re.S)


@pytest.fixture(scope="module")
def folder(tmp_path_factory, compiled, build_dir):
    """A user's folder: the session's build of rsup as its ./generated, then the
    page's shell lines (but the first block's, which show the forms)."""
    import fccgen
    work = tmp_path_factory.mktemp("export-user")
    for name in ("rsup", "solar_array", "solar_array_input"):   # the session's builds
        fccgen.load(ROOT / "examples" / f"{name}.yaml", build_dir, linear_solver="sparse")
        for entry in (name, f"{name}_events", f"{name}_dp"):
            if (build_dir / entry).is_dir():
                shutil.copytree(build_dir / entry, work / "generated" / entry)
    bin_dir = Path(sys.executable).parent
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}",
           "PYTHONPATH": str(Path(fccgen.__file__).resolve().parent.parent)}
    for block in blocks("bash")[1:]:
        done = subprocess.run(["bash", "-e", "-c", block], cwd=work, env=env,
                              capture_output=True, text=True)
        assert done.returncode == 0, f"{block}\n{done.stdout}\n{done.stderr}"
    return work


def test_the_shell_lines_write_what_the_page_says(folder):
    assert (folder / "rsup_c" / "rsup_example").is_file()
    assert (folder / "rsup.fmu").is_file()
    c = np.genfromtxt(folder / "rsup_c" / "rsup.csv", delimiter=",", names=True)
    py = np.genfromtxt(folder / "rsup_py.csv", delimiter=",", names=True)
    assert len(c) == len(py)
    for name in c.dtype.names:
        scale = max(float(np.max(np.abs(py[name]))), 1e-300)
        assert np.max(np.abs(c[name] - py[name])) <= 1e-12 * scale, name


def test_the_python_snippet_prints_a_rounding_difference(folder):
    pytest.importorskip("fmpy")
    done = run_python(blocks("python")[0], folder, check=False)
    assert done.returncode == 0, done.stderr
    assert float(done.stdout.split()[-1]) < 1e-10


def test_the_c_lines_name_functions_of_the_header(folder):
    header = (folder / "rsup_c" / "rsup.h").read_text()
    for call in set(re.findall(r"\b(rsup_[a-z_]+)\(", blocks("c")[0])):
        assert f"{call}(" in header, call


def test_the_inputs_section_works_as_written(folder):
    """The inputs section's FMU, driven from FMPy, equals simulate(inputs=...) to
    rounding, and its C lines compile and run against the panel's C project."""
    pytest.importorskip("fmpy")
    done = run_python(blocks("python")[1], folder, check=False)
    assert done.returncode == 0, done.stderr
    assert float(done.stdout.split()[-1]) < 1e-10
    from fccgen.export import export_c
    project = export_c(folder / "examples" / "panel_input.yaml", folder / "panel_c",
                       folder / "generated")
    body = blocks("c")[1].replace("\n", "\n    ")
    (project / "snippet.c").write_text('#include <stdio.h>\n#include "panel_input.h"\n'
                                       f"int main(void)\n{{\n    {body}\n"
                                       '    printf("%.17g\\n", angle);\n    return 0;\n}\n')
    for cmd in (["make", "-s"], [CC, "-std=c99", "-Wall", "-Werror", "-I.", "snippet.c",
                                 "libpanel_input.a", "-lm", "-o", "snippet"],
                ["./snippet"]):
        done = subprocess.run(cmd, cwd=project, capture_output=True, text=True)
        assert done.returncode == 0, f"{cmd}: {done.stdout}\n{done.stderr}"
    assert 0 < float(done.stdout) < 1


def test_the_events_section_works_as_written(folder):
    """The solar array's C example equals simulate's CSV to rounding and writes both
    latches to its event CSV, the event log's C lines name functions of the header,
    the copy built elsewhere runs, and the FMU with a heavier panel and a driven bus torque equals
    with_parameters and simulate(inputs=...) through both latches, its event outputs
    telling the same latches."""
    c = np.genfromtxt(folder / "solar_array_c" / "sa.csv", delimiter=",", names=True)
    py = np.genfromtxt(folder / "sa_py.csv", delimiter=",", names=True)
    assert len(c) == len(py) == 3001
    for name in c.dtype.names:
        scale = max(float(np.max(np.abs(py[name]))), 1e-300)
        assert np.max(np.abs(c[name] - py[name])) <= 1e-12 * scale, name
    assert (folder / "elsewhere" / "solar_array_c" / "solar_array.csv").is_file()
    events = (folder / "solar_array_c" / "sa_events.csv").read_text().splitlines()
    assert [line.split(",")[1] for line in events[1:]] == ["panel_latch", "root_latch"]
    header = (folder / "solar_array_c" / "solar_array.h").read_text()
    for call in set(re.findall(r"\b(solar_array_[a-z_]+)\(", blocks("c")[2])):
        assert f"{call}(" in header, call
    pytest.importorskip("fmpy")
    done = run_python(blocks("python")[2], folder, check=False)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.split("\n")
    assert "panel_latch" in lines[0] and "root_latch" in lines[0]
    assert lines[1] == lines[0]                   # the FMU's event outputs tell the same
    assert float(done.stdout.split()[-1]) < 1e-10


def test_the_sensitivities_section_works_as_written(folder):
    """The exported example's sensitivities (sa_sens.csv, the d(time) columns of
    sa_events.csv) are the numbers the section's Python lines print (1e-12: the same
    engine), and its C lines compile and run against the project."""
    done = run_python(blocks("python")[3], folder, check=False)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    project = folder / "solar_array_sens"
    sens = np.genfromtxt(project / "sa_sens.csv", delimiter=",", names=True,
                         deletechars="")
    want = float(lines[0])
    assert abs(sens["d(P.x)/d(loads[0].stiffness)"][-1] - want) <= 1e-12 * abs(want)
    events = [line.split(",") for line in
              (project / "sa_events.csv").read_text().splitlines()]
    column = events[0].index("d(time)/d(loads[0].stiffness)")
    for row, (name, value) in zip(events[1:], ast.literal_eval(lines[1])):
        assert row[1] == name and abs(float(row[column]) - value) <= 1e-12 * abs(value)
    body = blocks("c")[3].replace("\n", "\n    ")
    (project / "snippet.c").write_text('#include <stdio.h>\n#include "solar_array.h"\n'
                                       f"int main(void)\n{{\n    {body}\n"
                                       '    printf("%.17g %.17g\\n", dx, dt_latch);\n'
                                       "    return 0;\n}\n")
    for cmd in ([CC, "-std=c99", "-Wall", "-Werror", "-I.", "snippet.c",
                 "libsolar_array.a", "-lm", "-o", "snippet"], ["./snippet"]):
        done = subprocess.run(cmd, cwd=project, capture_output=True, text=True)
        assert done.returncode == 0, f"{cmd}: {done.stdout}\n{done.stderr}"
    dx, dt_latch = (float(x) for x in done.stdout.split())
    assert np.isfinite(dx)
    assert dt_latch == pytest.approx(float(events[1][column]), rel=1e-12)


def test_the_fmu_sensitivities_section_works_as_written(folder):
    """The FMU's d(events.last.time)/d(key) at the end, as the section's Python lines
    print it, is the root latch's d(time)/d(key) of the C project's event log (the same
    engine: 1e-12)."""
    pytest.importorskip("fmpy")
    done = run_python(blocks("python")[4], folder, check=False)
    assert done.returncode == 0, done.stderr
    events = [line.split(",") for line in
              (folder / "solar_array_sens" / "sa_events.csv").read_text().splitlines()]
    column = events[0].index("d(time)/d(loads[0].stiffness)")
    assert events[-1][1] == "root_latch"
    want = float(events[-1][column])
    assert float(done.stdout.split()[-1]) == pytest.approx(want, rel=1e-12)
