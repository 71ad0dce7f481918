"""fccgen export --fmu FILE.fmu --sensitivities KEYS (docs/export.md, "Sensitivities in
the FMU"): the FMU's outputs d(COLUMN)/d(KEY), run by FMPy (an independent FMI
importer), against simulate(sensitivities=...) on the sparse path, the C engine's path.

* FMPy's validation of the FMU reports no problem; its outputs are the columns' (but
  constraint_error's) derivatives and the latest event's time's, key by key.
* The coordinates' and speeds' derivatives are the same engine's arithmetic on the same
  numbers: equal to 1e-12 of each column's largest magnitude (measured: bit for bit).
  The other columns' are Richardson central differences of the output functions in
  both programs, each with the step it picks from the magnitudes it sees (the reason
  test_export_sens.py compares them to 1e-9; measured 5e-11 here).
* d(events.last.time)/d(KEY) is 0 before the first latch, then each latch's
  d(time)/d(KEY) from its time on: equal to 1e-12 (measured: bit for bit).
* Refusals with a sentence, nothing written: a key the model does not have, and a
  list of keys with --c.
"""
from __future__ import annotations

import shutil
import sys

import numpy as np
import pytest

from conftest import EXAMPLES

from fccgen.export.c_project import ExportError
from fccgen.export.fmu import export_fmu

fmpy = pytest.importorskip("fmpy")

CC = shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(CC is None or not sys.platform.startswith("linux"),
                                reason="needs a C compiler (Linux)")
KEYS = ["loads[0].stiffness", "bodies.panel2.mass"]


@pytest.fixture(scope="session")
def solar_fmu(build_dir, tmp_path_factory):
    return export_fmu(EXAMPLES / "solar_array.yaml",
                      tmp_path_factory.mktemp("fmu_sens") / "solar_array.fmu", build_dir,
                      sensitivities=",".join(KEYS))


def test_the_fmu_outputs_each_keys_derivatives(solar_fmu):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(solar_fmu)) == []
    description = fmpy.read_model_description(str(solar_fmu))
    outputs = [v.name for v in description.modelVariables if v.causality == "output"]
    plain = [n for n in outputs if not n.startswith("d(") and not n.startswith("events.")]
    sens = [n for n in outputs if n.startswith("d(")]
    per_key = [f"d({c})" for c in plain if c != "constraint_error"] + ["d(events.last.time)"]
    assert sens == [f"{d}/d({key})" for key in KEYS for d in per_key]


def test_the_fmu_sensitivities_equal_simulate(solar_fmu, compiled_sparse):
    solver = compiled_sparse("solar_array")
    description = fmpy.read_model_description(str(solar_fmu))
    sens = [v.name for v in description.modelVariables if v.name.startswith("d(")]
    rows = fmpy.simulate_fmu(str(solar_fmu), output=sens, stop_time=3.0,
                             output_interval=0.01)
    result = solver.simulate(t_end=3.0, output_dt=0.01, reactions=False,
                             sensitivities=KEYS)
    assert np.array_equal(rows["time"], result.t)
    state = {f"{n}.{x}" for n, _ in solver.plan.triples
             for x in ("x", "y", "z", "vx", "vy", "vz")}
    assert [e["name"] for e in result.events] == ["panel_latch", "root_latch"]
    derived = 0
    for name in sens:
        column = name[2:name.index(")/d(")]
        if column == "events.last.time":
            key = name[name.index(")/d(") + 4:-1]
            want = np.zeros_like(result.t)
            for event in result.events:
                want[result.t >= event["t"]] = event[f"d(time)/d({key})"]
            assert np.any(want != 0)
            rel = 1e-12
        else:
            want = result[name]
            rel = 1e-12 if column in state else 1e-9
            derived += column not in state
        scale = max(float(np.max(np.abs(want))), 1e-300)
        assert np.max(np.abs(rows[name] - want)) <= rel * scale, name
    assert derived > 0


def test_requests_the_fmu_cannot_answer_are_refused(build_dir, tmp_path):
    from fccgen.cli import main
    target = tmp_path / "dp.fmu"
    with pytest.raises(ExportError, match="'bodies.nope.mass' is not a parameter of the "
                                          "model; the keys with one: "):
        export_fmu(EXAMPLES / "double_pendulum.yaml", target, build_dir,
                   sensitivities="bodies.nope.mass")
    assert not target.exists() and not list(tmp_path.iterdir())
    code = main(["export", str(EXAMPLES / "double_pendulum.yaml"), "--c",
                 str(tmp_path / "c"), "--sensitivities", "gravity[1]", "--build-dir",
                 str(build_dir), "-q"])
    assert code != 0 and not (tmp_path / "c").exists()


def test_a_driven_model_s_fmu_has_its_motor_torque_but_not_its_derivative(
        build_dir, tmp_path, compiled_sparse):
    """four_bar_driven exports its motor's torque (a second solve at each read), which
    has no sensitivity, as in simulate: the FMU outputs motor.torque and the other
    columns' derivatives, not d(motor.torque)/d(KEY); FMPy runs it, and the torque
    equals simulate's to 1e-10 of its largest (the multipliers' accuracy,
    tests/test_export_c.py)."""
    from fmpy.validation import validate_fmu
    key = "bodies.coupler.mass"
    path = export_fmu(EXAMPLES / "four_bar_driven.yaml", tmp_path / "fbd.fmu", build_dir,
                      sensitivities=key)
    assert validate_fmu(str(path)) == []
    description = fmpy.read_model_description(str(path))
    outputs = [v.name for v in description.modelVariables if v.causality == "output"]
    assert "motor.torque" in outputs and "d(O.angle)/d(bodies.coupler.mass)" in outputs
    assert not any(n.startswith("d(motor.torque)") for n in outputs)
    rows = fmpy.simulate_fmu(str(path), output=["motor.torque"], stop_time=0.5,
                             output_interval=0.01)
    result = compiled_sparse("four_bar_driven").simulate(t_end=0.5, output_dt=0.01,
                                                        reactions=False)
    want = result["motor.torque"]
    assert np.abs(rows["motor.torque"] - want).max() <= 1e-10 * np.abs(want).max()
