"""fccgen export of the model's other simulate: methods (docs/export.md, "What the
export runs"): baumgarte and dopri5.

Each model file is an example with its simulate: method changed, exported once per
session, built with make under -std=c99 -Wall -Wextra -pedantic -Werror, and run:

* the example's CSV equals fccgen simulate of the same file on the sparse path to
  1e-12 of each column's largest magnitude: the same C engine with the same steps,
  only the compiler's flags differ (dopri5: the same accepted steps, its records by
  the same dense output at the same times);
* the FMU, run by FMPy, equals simulate to 1e-10 (as tests/test_export_fmu.py);
* what simulate refuses with a method (events with baumgarte) the export refuses
  with the same reason, and sensitivities are refused for a method other than rk4.
"""
from __future__ import annotations

import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import EXAMPLES

import fccgen
from fccgen.errors import FccgenError
from fccgen.export import ExportError, export_c
from test_export_c import CC, MAKE, STRICT, assert_columns_equal, read_csv, run

pytestmark = pytest.mark.skipif(CC is None or MAKE is None or not sys.platform.startswith("linux"),
                                reason="needs a C compiler, make and GNU ld (Linux)")
HERE = Path(__file__).resolve().parent


def with_method(example: str, method: str, folder: Path) -> Path:
    """examples/<example>.yaml with simulate: method set to method, in folder (with
    the examples' tables, which model files name by a relative path)."""
    for table in EXAMPLES.glob("*.csv"):
        shutil.copy(table, folder / table.name)
    text = (EXAMPLES / f"{example}.yaml").read_text()
    line = re.search(r"^simulate: \{(.*)\}$", text, re.M)
    settings = re.sub(r",?\s*method: \w+", "", line.group(1))
    path = folder / f"{example}_{method}.yaml"
    path.write_text(text.replace(line.group(0),
                                 f"simulate: {{{settings}, method: {method}}}"))
    return path


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    folder = tmp_path_factory.mktemp("methods")
    return lambda example, method: with_method(example, method, folder)


@pytest.fixture(scope="module")
def exported(models, build_dir, tmp_path_factory):
    """exported(example, method) -> (folder, header, rows of the example's CSV)."""
    root = tmp_path_factory.mktemp("export_methods")
    cache = {}

    def get(example, method):
        if (example, method) not in cache:
            folder = export_c(models(example, method), root / f"{example}_{method}",
                              build_dir)
            run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
            assert run([f"./{example}_selftest"], folder).strip() == "selftest passed"
            run([f"./{example}_example", "out.csv"], folder)
            cache[example, method] = (folder, *read_csv(folder / "out.csv"))
        return cache[example, method]
    return get


def simulated(models, build_dir, example, method, **kw):
    solver = fccgen.load(models(example, method), build_dir, linear_solver="sparse")
    return solver, solver.simulate(reactions=False, **kw)


@pytest.mark.parametrize("example", ["four_bar", "four_bar_driven"])
def test_baumgarte_example_equals_simulate(example, exported, models, build_dir):
    _, names, rows = exported(example, "baumgarte")
    solver, result = simulated(models, build_dir, example, "baumgarte")
    assert result.info["method"] == "baumgarte" and rows.shape[0] == len(result.t)
    assert_columns_equal(names, rows, result, 1e-12)
    # the run is not rk4's: the constraints drift (no projection), damped
    rk4 = solver.simulate(method="rk4", reactions=False)
    assert np.max(np.abs(rk4["constraint_error"])) < 1e-9
    assert np.max(np.abs(result["constraint_error"])) > 1e3 * np.max(
        np.abs(rk4["constraint_error"]))


def test_baumgarte_counts_turns_as_simulate(exported, models, build_dir):
    """tape_spring_table: its hinge's moment is a table of the joint angle counted over
    turns (the angle passes -pi), re-based after every step as in simulate."""
    _, names, rows = exported("tape_spring_table", "baumgarte")
    _, result = simulated(models, build_dir, "tape_spring_table", "baumgarte")
    assert np.min(result["H.angle"]) < -np.pi - 0.5
    assert_columns_equal(names, rows, result, 1e-12)


def test_baumgarte_with_events_is_refused_as_simulate_refuses_it(models, build_dir,
                                                                 tmp_path):
    path = models("solar_array", "baumgarte")
    with pytest.raises(FccgenError) as by_simulate:
        fccgen.load(path, build_dir, linear_solver="sparse")
    with pytest.raises(FccgenError) as by_export:
        export_c(path, tmp_path / "sa", build_dir)
    assert str(by_export.value) == str(by_simulate.value)
    assert "rk4, dopri5 in a model with events" in str(by_export.value)
    assert not (tmp_path / "sa").exists()


def test_sensitivities_are_refused_for_another_method(models, build_dir, tmp_path):
    with pytest.raises(ExportError, match="method is baumgarte.*sensitivities through "
                                          "rk4 runs only"):
        export_c(models("four_bar", "baumgarte"), tmp_path / "fb", build_dir,
                 sensitivities=True)
    assert not (tmp_path / "fb").exists()


@pytest.mark.parametrize("example", ["four_bar", "four_bar_driven"])
def test_dopri5_example_equals_simulate(example, exported, models, build_dir):
    """The records at simulate's output times, from the same accepted steps and dense
    output: the example asks for them one at a time, simulate all at once."""
    _, names, rows = exported(example, "dopri5")
    _, result = simulated(models, build_dir, example, "dopri5")
    assert result.info["method"] == "dopri5" and rows.shape[0] == len(result.t)
    # the steps are the run's own, longer than the records' spacing: records are read
    # from a step's dense output after the step was taken
    assert result.info["steps"] < len(result.t) - 1
    assert_columns_equal(names, rows, result, 1e-12)


def test_dopri5_with_events_equals_simulate(exported, models, build_dir):
    """The solar array through both latches, located on dopri5's dense output."""
    folder, names, rows = exported("solar_array", "dopri5")
    _, result = simulated(models, build_dir, "solar_array", "dopri5")
    assert [e["name"] for e in result.events] == ["panel_latch", "root_latch"]
    assert_columns_equal(names, rows, result, 1e-12)
    logged = np.loadtxt(folder / "out_events.csv", delimiter=",", skiprows=1,
                        usecols=0, ndmin=1)
    assert np.max(np.abs(logged - [e["t"] for e in result.events])) <= 1e-12


def test_dopri5_stop_event_in_the_example_and_the_fmu(models, build_dir, tmp_path):
    """pendulum_limit with its log event made a stop, run by dopri5: the example's last
    row is the stop's, as simulate's; the FMU read every 1e-3 s (many records in each
    step) ends at the stop with fmi2Discard, every row equal to simulate's."""
    text = (EXAMPLES / "pendulum_limit.yaml").read_text()
    assert "do: log" in text and "method: rk4" in text
    model = tmp_path / "pendulum_stop.yaml"
    model.write_text(text.replace("do: log", "do: stop").replace("method: rk4",
                                                                  "method: dopri5")
                     .replace("name: pendulum_limit", "name: pendulum_stop"))
    folder = export_c(model, tmp_path / "stop_c", build_dir)
    run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
    assert run(["./pendulum_stop_selftest"], folder).strip() == "selftest passed"
    run(["./pendulum_stop_example", "out.csv"], folder)
    names, rows = read_csv(folder / "out.csv")
    solver = fccgen.load(model, build_dir, linear_solver="sparse")
    result = solver.simulate(reactions=False)
    assert result.events[-1]["action"] == "stop" and result.t[-1] < 3.0 - 1e-9
    assert rows.shape[0] == len(result.t)
    assert_columns_equal(names, rows, result, 1e-12)
    if fmpy is None:
        return
    from fccgen.export.fmu import export_fmu
    fine = fmpy.simulate_fmu(str(export_fmu(model, tmp_path / "stop.fmu", build_dir)),
                             stop_time=3.0, output_interval=1e-3)
    want = solver.simulate(reactions=False, output_dt=1e-3)
    assert want.info["steps"] * 10 < len(want.t)
    assert fine["time"][-1] == pytest.approx(result.t[-1], abs=1e-15)
    assert_fmu_equal(fine, want, 1e-10)


def test_no_heap_allocation_while_stepping(exported, tmp_path):
    for example, method in (("four_bar_driven", "baumgarte"),
                            ("four_bar_driven", "dopri5"), ("solar_array", "dopri5")):
        folder = exported(example, method)[0]
        exe = tmp_path / f"alloc_{example}_{method}"
        run([CC, "-std=c99", "-O2", f"-I{folder}", f"-DMODEL={example}",
             f"-DHEADER={example}.h", str(HERE / "c" / "export_alloc.c"),
             str(folder / f"lib{example}.a"), "-o", str(exe),
             "-Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,--wrap=free", "-lm"], tmp_path)
        lines = run([str(exe)], tmp_path).splitlines()
        assert int(lines[0].split()[1]) > 20
        words = lines[1].split()
        assert words[0] == "allocations" and int(words[1]) == 0, (method, lines)


fmpy = None
try:
    import fmpy
except ImportError:                                   # a test dependency
    pass


def fmu_rows(models, build_dir, tmp_path, example, method, **kw):
    from fccgen.export.fmu import export_fmu
    path = export_fmu(models(example, method), tmp_path / f"{example}.fmu", build_dir)
    return fmpy.simulate_fmu(str(path), **kw)


def assert_fmu_equal(rows, result, rtol):
    assert np.allclose(rows["time"], result.t, rtol=0, atol=1e-12)
    names = [n for n in rows.dtype.names[1:] if not n.startswith("events.")]
    assert names and set(names) <= set(result.names)
    for name in names:
        want = result[name]
        scale = max(float(np.max(np.abs(want))), 1e-300)
        assert np.max(np.abs(rows[name] - want)) <= rtol * scale, name


@pytest.mark.skipif(fmpy is None, reason="needs FMPy")
def test_baumgarte_fmu_equals_simulate(models, build_dir, tmp_path):
    rows = fmu_rows(models, build_dir, tmp_path, "four_bar_driven", "baumgarte",
                    stop_time=1.0, output_interval=0.01)
    _, result = simulated(models, build_dir, "four_bar_driven", "baumgarte")
    assert_fmu_equal(rows, result, 1e-10)


@pytest.mark.skipif(fmpy is None, reason="needs FMPy")
def test_dopri5_fmu_equals_simulate_at_any_communication_points(models, build_dir,
                                                               tmp_path):
    """The solar array through both latches: communication points every 0.004 s, which
    are not the model's records (output_dt = dt = 1e-3), equal simulate with
    output_dt 0.004: dopri5's records come from the dense output wherever they are."""
    rows = fmu_rows(models, build_dir, tmp_path, "solar_array", "dopri5", stop_time=3.0,
                    output_interval=0.004)
    _, result = simulated(models, build_dir, "solar_array", "dopri5", output_dt=0.004)
    assert len(result.events) == 2
    assert_fmu_equal(rows, result, 1e-10)


@pytest.mark.skipif(fmpy is None, reason="needs FMPy")
def test_dopri5_inputs_hold_over_the_run_as_in_simulate(models, build_dir, tmp_path,
                                                         capsys):
    """simulate refuses an input that changes over a dopri5 run (its steps cross the
    records); the FMU refuses a new value during the run with the reason, and takes a
    start value set before the run's start."""
    path = models("panel_input", "dopri5")
    solver = fccgen.load(path, build_dir, linear_solver="sparse")
    times, torque = np.array([0.0, 1.0, 2.0]), np.array([0.0, 0.05, -0.05])
    with pytest.raises(ValueError, match="changes over the run"):
        solver.simulate(inputs={"hinge_torque": (times, torque)}, reactions=False)
    from fccgen.export.fmu import export_fmu
    fmu = str(export_fmu(path, tmp_path / "panel_input.fmu", build_dir))
    signal = np.array(list(zip(times, torque)),
                      dtype=[("time", np.float64), ("hinge_torque", np.float64)])
    # FMPy's default logger prints the FMU's messages. (A logger= of our own would
    # stay in FMPy's native proxy after the call, freed: a later FMU's message in the
    # same process would then call freed memory.)
    capsys.readouterr()
    with pytest.raises(Exception):
        fmpy.simulate_fmu(fmu, stop_time=2.0, output_interval=0.01, input=signal)
    said = capsys.readouterr().out
    assert "holds its value over a dopri5 run" in said, said
    rows = fmpy.simulate_fmu(fmu, stop_time=2.0, output_interval=0.01,
                             start_values={"hinge_torque": 0.05})
    result = solver.simulate(inputs={"hinge_torque": 0.05}, reactions=False)
    assert_fmu_equal(rows, result, 1e-10)
