"""The model's inputs in the exports (docs/export.md, "Inputs"), on
examples/panel_input.yaml (a hinge torque set from outside):

* a compiled C program sets the input by name before the start and by index between
  steps, and its outputs equal simulate(inputs=...) with the same values held over
  the same steps, to 1e-12 of the column's magnitude (the same engine and steps);
* the FMU declares the input (causality input, its start value) and passes FMPy's
  validation;
* an FMU run whose input FMPy drives from a table (simulate_fmu's input=) equals
  simulate(inputs=...) with that table to 1e-10: FMPy sets the table's value at each
  communication point, interpolated linearly, and it holds over the communication
  step; simulate samples the same table at the same output times and holds it.
"""
from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from conftest import EXAMPLES

import fccgen
from fccgen.export import export_c
from fccgen.export.fmu import export_fmu

CC = shutil.which("cc") or shutil.which("gcc")
MAKE = shutil.which("make")
STRICT = "-std=c99 -Wall -Wextra -pedantic -Werror -O2"
MODEL = EXAMPLES / "panel_input.yaml"
pytestmark = pytest.mark.skipif(CC is None or MAKE is None
                                or not sys.platform.startswith("linux"),
                                reason="needs a C compiler and make (Linux)")

PROGRAM = r"""
#include <stdio.h>
#include "panel_input.h"

int main(void)
{
    panel_input_sim *sim = panel_input_create();
    int k = panel_input_output_index("hinge.angle");
    int r = panel_input_output_index("hinge.rate");
    if (sim == NULL || k < 0 || r < 0 || panel_input_input_count() != 1
            || panel_input_input_index("hinge_torque") != 0
            || panel_input_set_input(sim, "no_such", 1.0) == 0
            || panel_input_set_input_index(sim, 1, 1.0) == 0)
        return 1;
    if (panel_input_set_input(sim, "hinge_torque", 0.05) != 0
            || panel_input_start(sim, 2.0) != 0
            || panel_input_step_to(sim, 1.0) != 0)
        return 2;
    printf("%.17g %.17g\n", panel_input_output(sim, k), panel_input_output(sim, r));
    if (panel_input_set_input_index(sim, 0, -0.03) != 0
            || panel_input_step_to(sim, 2.0) != 0)
        return 3;
    printf("%.17g %.17g\n", panel_input_output(sim, k), panel_input_output(sim, r));
    panel_input_destroy(sim);
    return 0;
}
"""


@pytest.fixture(scope="module")
def sparse(build_dir):
    return fccgen.load(MODEL, build_dir, linear_solver="sparse")


def test_set_input_in_a_compiled_c_program(build_dir, tmp_path, sparse):
    folder = export_c(MODEL, tmp_path / "panel", build_dir)
    (folder / "inputs.c").write_text(PROGRAM)

    def run(cmd):
        done = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
        assert done.returncode == 0, f"{cmd}: {done.stdout}\n{done.stderr}"
        return done.stdout
    run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"])
    run([CC, *STRICT.split(), "-I.", "inputs.c", "libpanel_input.a", "-lm", "-o",
         "inputs"])
    got = np.array([[float(x) for x in line.split()]
                    for line in run(["./inputs"]).splitlines()])
    # 0.05 from the start, -0.03 from t = 1: held over the steps after each output
    result = sparse.simulate(inputs={"hinge_torque": lambda t: 0.05 if t < 1 - 1e-9
                                     else -0.03}, output_dt=1.0, reactions=False)
    want = np.array([[result["hinge.angle"][j], result["hinge.rate"][j]] for j in (1, 2)])
    assert np.all(np.abs(got - want) <= 1e-12 * np.max(np.abs(want), axis=0))
    assert "panel_input_set_input_index" in (folder / "README.md").read_text()


@pytest.fixture(scope="module")
def fmu(build_dir, tmp_path_factory):
    return export_fmu(MODEL, tmp_path_factory.mktemp("fmu") / "panel_input.fmu",
                      build_dir)


def test_the_fmu_declares_the_input_and_fmpy_validates_it(fmu):
    fmpy = pytest.importorskip("fmpy")
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(fmu)) == []
    with zipfile.ZipFile(fmu) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    var = [v for v in root.iter("ScalarVariable") if v.get("name") == "hinge_torque"]
    assert len(var) == 1 and var[0].get("causality") == "input"
    assert float(var[0].find("Real").get("start")) == 0.02
    assert fmpy.read_model_description(str(fmu)).modelVariables


def test_an_input_driven_from_fmpy_equals_simulate_inputs(fmu, sparse):
    fmpy = pytest.importorskip("fmpy")
    times = np.array([0.0, 0.3, 0.8, 1.4, 2.0])
    values = np.array([0.0, 0.06, -0.02, 0.03, 0.0])
    signal = np.array(list(zip(times, values)),
                      dtype=[("time", np.float64), ("hinge_torque", np.float64)])
    rows = fmpy.simulate_fmu(str(fmu), stop_time=2.0, output_interval=0.01,
                             input=signal)
    result = sparse.simulate(inputs={"hinge_torque": (times, values)}, output_dt=0.01,
                             reactions=False)
    assert np.array_equal(rows["time"], result.t)
    for name in ("hinge.angle", "hinge.rate", "panel.cx", "panel.cy", "energy"):
        want = result[name]
        assert np.max(np.abs(rows[name] - want)) <= 1e-10 * np.max(np.abs(want)), name
    # the input acted: the run differs from the start value's
    plain = sparse.simulate(output_dt=0.01, reactions=False)
    assert np.max(np.abs(plain["hinge.angle"] - result["hinge.angle"])) > 1e-3
