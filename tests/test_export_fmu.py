"""fccgen export --fmu (docs/export.md): the FMI 2.0 co-simulation FMU of a model,
loaded and run by FMPy (a test dependency, an independent FMI importer).

* FMPy's validation of the FMU (modelDescription.xml against the standard's schema
  and rules, the binary's functions) reports no problem;
* fmpy.simulate_fmu over 2 s equals fccgen simulate over 2 s (sparse path, same steps)
  to 1e-10 of each column's largest magnitude: the same engine and steps, only the
  compiler's flags and the communication differ;
* a parameter set through start_values equals with_parameters;
* the FMU's variables are the export's columns (outputs), the with_parameters keys
  (parameters) and the model's inputs, and its sources are inside.
"""
from __future__ import annotations

import shutil
import sys
import zipfile
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from conftest import EXAMPLES

import fccgen
from fccgen.export.fmu import export_fmu

fmpy = pytest.importorskip("fmpy")

CC = shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(CC is None or not sys.platform.startswith("linux"),
                                reason="needs a C compiler (Linux)")


@pytest.fixture(scope="session")
def fmu(build_dir, tmp_path_factory):
    """fmu(name) -> path of the model's FMU, exported once per session."""
    root = tmp_path_factory.mktemp("fmu")
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = export_fmu(EXAMPLES / f"{name}.yaml", root / f"{name}.fmu",
                                     build_dir)
        return cache[name]
    return get


def assert_equal_columns(fmu_rows, result, rtol):
    assert np.array_equal(fmu_rows["time"], result.t)
    for name in fmu_rows.dtype.names[1:]:
        want = result[name]
        scale = max(float(np.max(np.abs(want))), 1e-300)
        assert np.max(np.abs(fmu_rows[name] - want)) <= rtol * scale, name


def test_fmpy_validates_the_fmu(fmu):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(fmu("four_bar_driven"))) == []


def test_the_fmu_holds_its_variables_and_sources(fmu, build_dir):
    path = fmu("four_bar_driven")
    with zipfile.ZipFile(path) as z:
        names = z.namelist()
        root = ET.fromstring(z.read("modelDescription.xml"))
    assert "binaries/linux64/four_bar_driven.so" in names
    assert {"sources/four_bar_driven_fmu.c", "sources/fccgen_fmi2.h", "sources/Makefile",
            "sources/fcc_rk4.c", "sources/kernels.c"} <= set(names)
    variables = root.find("ModelVariables")
    by = {}
    for v in variables:
        by.setdefault(v.get("causality"), []).append(v.get("name"))
    assert "O.angle" in by["output"] and "energy" in by["output"]
    assert "bodies.coupler.mass" in by["parameter"]
    assert "motor.torque" in by["output"]
    assert not any(n.endswith(".fx") for n in by["output"])
    assert root.find("CoSimulation").get("modelIdentifier") == "four_bar_driven"


def test_simulate_fmu_over_2_s_equals_fccgen_simulate(fmu, build_dir):
    """rsup (its model file says 1 s; the FMU runs to the stop time it is given)."""
    rows = fmpy.simulate_fmu(str(fmu("rsup")), stop_time=2.0, output_interval=0.01)
    solver = fccgen.load(EXAMPLES / "rsup.yaml", build_dir, linear_solver="sparse")
    result = solver.simulate(t_end=2.0, output_dt=0.01, reactions=False)
    assert_equal_columns(rows, result, 1e-10)


def test_a_parameter_from_start_values_equals_with_parameters(fmu, build_dir):
    values = {"bodies.coupler.mass": 1.1, "bodies.crank.inertia[0]": 2e-5}
    rows = fmpy.simulate_fmu(str(fmu("four_bar_driven")), stop_time=1.0,
                             output_interval=0.01, start_values=values)
    solver = fccgen.load(EXAMPLES / "four_bar_driven.yaml", build_dir,
                         linear_solver="sparse").with_parameters(values)
    assert_equal_columns(rows, solver.simulate(reactions=False), 1e-10)


def test_a_communication_step_off_the_step_grid_is_refused(fmu):
    with pytest.raises(Exception, match="doStep|status"):
        fmpy.simulate_fmu(str(fmu("four_bar_driven")), stop_time=0.1,
                          output_interval=0.0105)
