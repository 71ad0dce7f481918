"""Sensitivities on the sparse path and in the exported C project
(docs/export.md "Sensitivities", docs/sensitivities.md).

* simulate(sensitivities=...) on a solver loaded with linear_solver="sparse" (the
  exported engine's path): against Richardson central differences of the same
  fixed-step runs, as the dense path is checked (tests/test_sensitivity_runs.py, its
  docstring says why 1e-7): every supported kind on the double pendulum; the solar
  array's latch times and P.x after both latches (test_sensitivity_events.py's check).
* fccgen export --c DIR --sensitivities, built under -std=c99 -Wall -Wextra -pedantic
  -Werror: the example's FILE_sens.csv and the d(time) columns of its event log equal
  simulate(sensitivities=...) on the sparse path, on the double pendulum and on the
  solar array through both latches. The coordinates' and speeds' derivatives and the
  event times' are the same engine's arithmetic on the same numbers (dP and the start's
  derivative written exactly): 1e-12 of each column's largest magnitude (measured
  1e-15). The other columns (mass centres, angular velocities, energy, joint angles)
  are Richardson central differences of the output functions in both programs, with a
  step each picks from the magnitudes it sees (simulate over the whole run, the C API
  at each read): each estimate's error is about 1e-12 of the column's scale plus
  rounding over the step, eps |column| / h, which is largest for the energy (a small
  derivative of a sum of larger terms, measured 1e-10); compared to 1e-9.
* The selftest replays every key's sensitivities and fails on a wrong golden value.
* Refusals with a sentence: an unknown key, a project exported without
  sensitivities, a model with bounces (the FMU's sensitivities:
  test_export_fmu_sens.py).
"""
from __future__ import annotations

import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import EXAMPLES

from fccgen.export import export_c
from test_sensitivity_runs import CASES, check_against_differences, state_columns

CC = shutil.which("cc") or shutil.which("gcc")
MAKE = shutil.which("make")
STRICT = "-std=c99 -Wall -Wextra -pedantic -Werror -O2"
KEYS = {"double_pendulum": ["bodies.rod1.mass", "gravity[1]"],
        "solar_array": ["loads[0].stiffness", "bodies.panel2.mass"]}

needs_cc = pytest.mark.skipif(CC is None or MAKE is None
                              or not sys.platform.startswith("linux"),
                              reason="needs a C compiler, make and GNU ld (Linux)")


def run(cmd, cwd, code=0):
    done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    assert done.returncode == code, f"{cmd}: {done.stdout}\n{done.stderr}"
    return done


def test_sparse_path_sensitivities_match_central_differences(compiled_sparse):
    solver = compiled_sparse("double_pendulum")
    run_ = dict(t_end=0.3, dt=1e-3, method="rk4")
    keys = CASES["double_pendulum"]
    result = solver.simulate(**run_, reactions=False, sensitivities=keys)
    assert result.info["sensitivities"] == keys
    columns = state_columns(result, keys[0])
    for key in keys:
        assert check_against_differences(result, solver, key, columns, run_,
                                         label="sparse") >= 1


def test_sparse_path_carries_the_solar_array_latches(compiled_sparse):
    from test_sensitivity_events import check_solar_array
    check_solar_array(compiled_sparse("solar_array"))


@pytest.fixture(scope="session")
def sens_project(build_dir, tmp_path_factory):
    root = tmp_path_factory.mktemp("export_sens")
    cache = {}

    def get(name):
        if name not in cache:
            folder = export_c(EXAMPLES / f"{name}.yaml", root / name, build_dir,
                              sensitivities=True)
            run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
            cache[name] = folder
        return cache[name]
    return get


@needs_cc
@pytest.mark.parametrize("name", ["double_pendulum", "solar_array"])
def test_the_exported_sensitivities_equal_simulate(name, sens_project, compiled_sparse):
    folder = sens_project(name)
    keys = KEYS[name]
    run([f"./{name}_example", "out.csv", "--sensitivities", ",".join(keys)], folder)
    lines = (folder / "out_sens.csv").read_text().splitlines()
    names = lines[0].split(",")
    rows = np.loadtxt(folder / "out_sens.csv", delimiter=",", skiprows=1, ndmin=2)
    result = compiled_sparse(name).simulate(reactions=False, sensitivities=keys)
    assert rows.shape == (len(result.t), len(names))
    state = {f"{n}.{x}" for n, _ in compiled_sparse(name).plan.triples
             for x in ("x", "y", "z", "vx", "vy", "vz")}
    derived = 0
    for k, column in enumerate(names):
        want = result.t if column == "t" else result[column]
        scale = max(float(np.max(np.abs(want))), 1e-300)
        base = column[2:column.index(")/d(")] if column != "t" else "t"
        rel = 1e-12 if base in state or base == "t" else 1e-9
        derived += rel == 1e-9
        assert np.max(np.abs(rows[:, k] - want)) <= rel * scale, column
    assert derived > 0
    assert len(names) - 1 == len(keys) * (len([c for c in result.names
                                               if not c.startswith("d(")]) - 2)
    if name == "solar_array":          # d(time)/d(key) of both latches
        events = (folder / "out_events.csv").read_text().splitlines()
        header = events[0].split(",")
        assert [e["name"] for e in result.events] == ["panel_latch", "root_latch"]
        assert len(events) == 1 + len(result.events)
        for i, e in enumerate(result.events):
            got = dict(zip(header, events[1 + i].split(",")))
            for key in keys:
                column = f"d(time)/d({key})"
                assert float(got[column]) == pytest.approx(e[column], rel=1e-12, abs=0)
    assert run([f"./{name}_selftest"], folder).stdout.strip() == "selftest passed"


@needs_cc
def test_the_selftest_fails_on_a_wrong_sensitivity(sens_project, tmp_path):
    folder = tmp_path / "dp"
    shutil.copytree(sens_project("double_pendulum"), folder)
    golden = folder / "double_pendulum_golden.h"
    text = golden.read_text()
    start = text.index("GOLDEN_SENS[] = {") + len("GOLDEN_SENS[] = {\n    ")
    golden.write_text(text[:start] + "0x1.0p+0" + text[text.index(",", start):])
    run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
    done = run(["./double_pendulum_selftest"], folder, code=1)
    assert "golden 1\n" in done.stdout and "selftest failed: 1 values differ" in done.stdout


@needs_cc
def test_requests_the_export_cannot_answer_are_refused(sens_project, build_dir, tmp_path):
    folder = sens_project("double_pendulum")
    done = run(["./double_pendulum_example", "x.csv", "--sensitivities", "bodies.nope.mass"],
               folder, code=2)
    assert "--sensitivities: no parameter of this name" in done.stderr
    plain = export_c(EXAMPLES / "double_pendulum.yaml", tmp_path / "plain", build_dir)
    assert not (plain / "dp_kernels.c").exists()
    run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], plain)
    done = run(["./double_pendulum_example", "x.csv", "--sensitivities", "gravity[1]"],
               plain, code=2)
    assert "exported without sensitivities (fccgen export MODEL.yaml --c DIR " \
           "--sensitivities)" in done.stderr


def test_models_and_targets_without_sensitivities_are_refused(build_dir, tmp_path):
    from fccgen.cli import main
    from fccgen.export.c_project import ExportError
    with pytest.raises(ExportError,
                       match="through a bounce .a joint limit. on the dense path only"):
        export_c(EXAMPLES / "pendulum_limit.yaml", tmp_path / "pl", build_dir,
                 sensitivities=True)
    assert not (tmp_path / "pl").exists()
    code = main(["export", str(EXAMPLES / "pendulum_limit.yaml"), "--fmu",
                 str(tmp_path / "x.fmu"), "--sensitivities", "--build-dir", str(build_dir),
                 "-q"])
    assert code != 0 and not (tmp_path / "x.fmu").exists()
