"""Inputs in event functions (docs/model-file.md "inputs", docs/events.md).

The model: examples/panel_input.yaml (a panel on a hinge turned by a constant torque
T = 0.02 N m, angle T t^2 / (2 J)) with a second input, ``latch_angle``, that an event
reads: the hinge locks where its angle reaches the input.

* the threshold as a number: the lock happens at t* = sqrt(2 J theta / T), the closed
  form (RK4 is exact on a motion quadratic in t, so the time is the location's, within
  its tolerance 1e-12 s, plus rounding), and the angle holds at theta after it;
* an input that jumps between steps across the event function (the threshold falls
  below the angle) fires the event at the start of the next step, within the location
  tolerance;
* the compiled run equals the NumPy version with the same inputs: the event times to
  2e-12 s (each locates to 1e-12 s with its own iteration), the columns to 1e-12 of
  their magnitude plus what their rate moves them in those 2e-12 s (a lock at times
  apart holds the angle where each run reached it);
* the exported C program that sets the input between steps equals
  simulate(inputs=...) on the sparse path to 1e-12 (the same engine and steps), and an
  FMU whose input FMPy drives from a table equals simulate(inputs=...) with that
  table to 1e-10 (as tests/test_export_inputs.py states for loads).
"""
from __future__ import annotations

import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import EXAMPLES

import fccgen
from fccgen.export import export_c

CC = shutil.which("cc") or shutil.which("gcc")
MAKE = shutil.which("make")
STRICT = "-std=c99 -Wall -Wextra -pedantic -Werror -O2"
J = 0.1666667 + 2.0 * 0.5 ** 2          # the panel's inertia about the hinge
T = 0.02                                # its torque (the start value of hinge_torque)
TOL = 1e-12                             # simulate's event location tolerance (s)


def latch_text() -> str:
    text = (EXAMPLES / "panel_input.yaml").read_text()
    text = text.replace("name: panel_input", "name: panel_input_latch", 1)
    text = text.replace("inputs: {hinge_torque: 0.02}",
                        "inputs: {hinge_torque: 0.02, latch_angle: 0.03}", 1)
    return text.replace("simulate:", "events:\n  - {name: latch, when: \"hinge.angle >= "
                        "latch_angle\", do: lock, joint: hinge}\nsimulate:", 1)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    path = tmp_path_factory.mktemp("latch") / "panel_input_latch.yaml"
    path.write_text(latch_text())
    return path


@pytest.fixture(scope="module")
def latch(model, build_dir):
    return fccgen.load(model, build_dir)


@pytest.fixture(scope="module")
def sparse(model, build_dir):
    return fccgen.load(model, build_dir, linear_solver="sparse")


def drop(t):
    """The threshold 0.05 until t = 1, then 0.005 (below the angle 0.015 there)."""
    return 0.05 if t < 1.0 - 1e-9 else 0.005


def test_an_input_threshold_locks_at_the_closed_form_time(latch):
    for theta in (0.03, 0.01):
        result = latch.simulate(inputs={"latch_angle": theta}, reactions=False)
        (row,) = result.events
        assert row["name"] == "latch" and row["action"] == "lock"
        assert abs(row["t"] - np.sqrt(2 * J * theta / T)) <= 2 * TOL
        after = result.t > row["t"]
        assert np.all(np.abs(result["hinge.angle"][after] - theta) <= 1e-9)
    # the start value (0.03) when no input is given
    assert latch.simulate(reactions=False).events[0]["t"] == pytest.approx(
        np.sqrt(2 * J * 0.03 / T), abs=2 * TOL)


def test_a_jump_across_the_event_function_fires_at_the_next_step(latch):
    result = latch.simulate(inputs={"latch_angle": drop}, reactions=False)
    (row,) = result.events
    assert 1.0 <= row["t"] <= 1.0 + 2 * TOL
    held = result["hinge.angle"][result.t > 1.0]
    assert np.all(np.abs(held - T / (2 * J)) <= 1e-9)     # the angle at t = 1 holds


def test_compiled_equals_numeric_with_inputs_in_events(latch, model):
    numeric = fccgen.load_numeric(model)
    for inputs in ({"latch_angle": 0.01}, {"latch_angle": drop}):
        a = latch.simulate(inputs=inputs, output_dt=0.05, reactions=False)
        b = numeric.simulate(inputs=inputs, output_dt=0.05, reactions=False)
        assert [r["name"] for r in a.events] == [r["name"] for r in b.events]
        for ra, rb in zip(a.events, b.events):
            assert abs(ra["t"] - rb["t"]) <= 2 * TOL
        for name in ("hinge.angle", "hinge.rate", "panel.cx", "panel.cy", "energy"):
            scale = max(float(np.max(np.abs(a[name]))), 1e-300)
            # a lock 2e-12 s apart holds each column where its rate took it by then
            rate = float(np.max(np.abs(np.diff(a[name])))) / 0.05
            bound = 1e-12 * scale + 2 * TOL * rate
            assert np.max(np.abs(a[name] - b[name])) <= bound, name


PROGRAM = r"""
#include <stdio.h>
#include "panel_input_latch.h"

int main(void)
{
    panel_input_latch_sim *sim = panel_input_latch_create();
    int k = panel_input_latch_output_index("hinge.angle");
    int r = panel_input_latch_output_index("hinge.rate");
    if (sim == NULL || k < 0 || r < 0 || panel_input_latch_input_index("latch_angle") != 1)
        return 1;
    if (panel_input_latch_set_input(sim, "latch_angle", 0.05) != 0
            || panel_input_latch_start(sim, 2.0) != 0 || panel_input_latch_step_to(sim, 1.0) != 0)
        return 2;
    printf("%.17g %.17g\n", panel_input_latch_output(sim, k), panel_input_latch_output(sim, r));
    if (panel_input_latch_set_input(sim, "latch_angle", 0.005) != 0
            || panel_input_latch_step_to(sim, 2.0) != 0)
        return 3;
    printf("%.17g %.17g\n", panel_input_latch_output(sim, k), panel_input_latch_output(sim, r));
    panel_input_latch_destroy(sim);
    return 0;
}
"""


@pytest.mark.skipif(CC is None or MAKE is None or not sys.platform.startswith("linux"),
                    reason="needs a C compiler and make (Linux)")
def test_an_exported_program_setting_the_input_equals_simulate(model, build_dir, tmp_path,
                                                               sparse):
    folder = export_c(model, tmp_path / "latch", build_dir)
    (folder / "latch.c").write_text(PROGRAM)

    def run(cmd):
        done = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
        assert done.returncode == 0, f"{cmd}: {done.stdout}\n{done.stderr}"
        return done.stdout
    run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"])
    run([CC, *STRICT.split(), "-I.", "latch.c", "libpanel_input_latch.a", "-lm", "-o", "latch"])
    got = np.array([[float(x) for x in line.split()]
                    for line in run(["./latch"]).splitlines()])
    result = sparse.simulate(inputs={"latch_angle": drop}, output_dt=1.0, reactions=False)
    assert len(result.events) == 1                  # the lock happened (at t = 1)
    want = np.array([[result["hinge.angle"][j], result["hinge.rate"][j]] for j in (1, 2)])
    scale = np.max(np.abs(want), axis=0)
    assert np.all(np.abs(got - want) <= 1e-12 * scale)
    assert abs(got[1, 1]) <= 1e-9                    # locked: at rest


def test_an_fmu_input_driving_an_event_equals_simulate(model, build_dir, tmp_path, sparse):
    fmpy = pytest.importorskip("fmpy")
    if CC is None or not sys.platform.startswith("linux"):
        pytest.skip("needs a C compiler (Linux)")
    from fccgen.export.fmu import export_fmu
    fmu = export_fmu(model, tmp_path / "panel_input_latch.fmu", build_dir)
    # the threshold falls from 0.05 to 0 over [0.6, 1.2]: it meets the angle
    # 0.015 t^2 on the way (held between communication points, as in simulate)
    times, values = np.array([0.0, 0.6, 1.2, 2.0]), np.array([0.05, 0.05, 0.0, 0.0])
    signal = np.array(list(zip(times, values)),
                      dtype=[("time", np.float64), ("latch_angle", np.float64)])
    rows = fmpy.simulate_fmu(str(fmu), stop_time=2.0, output_interval=0.01, input=signal)
    result = sparse.simulate(inputs={"latch_angle": (times, values)}, output_dt=0.01,
                             reactions=False)
    assert len(result.events) == 1 and 0.6 < result.events[0]["t"] < 1.2
    for name in ("hinge.angle", "hinge.rate", "panel.cx", "energy"):
        want = result[name]
        assert np.max(np.abs(rows[name] - want)) <= 1e-10 * np.max(np.abs(want)), name
