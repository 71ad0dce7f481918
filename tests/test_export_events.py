"""Events and turn-counting springs in the exports (docs/export.md, "Events"): the
event kernels and their settings travel in the project and the exported engine runs
them as fccgen simulate does.

* examples/solar_array.yaml (two lock events), pendulum_limit (a log event) and
  tape_spring_hinge (no event, a spring whose angle counts turns): the project builds
  under -std=c99 -Wall -Wextra -pedantic -Werror, its example's CSV equals fccgen
  simulate on the sparse path to 1e-12 of each column's largest magnitude (the same C
  engine, events located by the same Illinois iterations, only the compiler's flags
  differ; measured 2e-16), and its selftest passes;
* no heap allocation from the solar array's start to its end (3000 steps, both
  latches): the events' work is allocated at create;
* FMPy runs the FMU of examples/solar_array_input.yaml (the solar array with a bus
  torque input) over 2.5 s, through both latches: with the input at its start value
  it equals fccgen simulate of solar_array.yaml; with a panel mass set through
  start_values it equals with_parameters; with the input driven from a table it
  equals simulate(inputs=...) with the table. To 1e-10 of each column's magnitude,
  except constraint_error: max |g| after the projection is rounding (1e-12 of the
  model's size), whose digits differ once a parameter is set as base + slope (x - x0)
  instead of from the model file; it is compared to 1e-11 absolute (below the
  position tolerance, 1e-11 here);
* the FMU's event outputs (events.count and the latest event's row, events.last.*)
  at each communication point equal simulate's event log up to that time: through
  both latches (times to 1e-10 s), with a panel mass set, and for 127 ticks of a log
  event, past the C log's 64 rows and with 3 or 4 events per communication step;
  through FMI calls they read only as their own types and cannot be set;
* a stop event (pendulum_limit's log event made a stop) ends the C example and the
  FMU (fmi2Discard, fmi2LastSuccessfulTime) where simulate's run ends;
* the example's event log (FILE_events.csv, read through NAME_event_row) equals
  simulate's event table, row by row; past the log's 64 rows the example says how
  many events it did not keep.
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import EXAMPLES

import fccgen
from fccgen.export import export_c

CC = shutil.which("cc") or shutil.which("gcc")
MAKE = shutil.which("make")
STRICT = "-std=c99 -Wall -Wextra -pedantic -Werror -O2"
HERE = Path(__file__).resolve().parent
LATCHED = 2.5          # s: past both latches (1.25 s and 2.06 s)

pytestmark = pytest.mark.skipif(CC is None or MAKE is None
                                or not sys.platform.startswith("linux"),
                                reason="needs a C compiler, make and GNU ld (Linux)")


def run(cmd, cwd):
    done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    assert done.returncode == 0, f"{cmd}: {done.stdout}\n{done.stderr}"
    return done.stdout


@pytest.fixture(scope="session")
def project(build_dir, tmp_path_factory):
    root = tmp_path_factory.mktemp("export_events")
    cache = {}

    def get(name):
        if name not in cache:
            folder = export_c(EXAMPLES / f"{name}.yaml", root / name, build_dir)
            run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
            cache[name] = folder
        return cache[name]
    return get


@pytest.mark.parametrize("name", ["solar_array", "pendulum_limit", "tape_spring_hinge"])
def test_the_example_runs_the_events_as_simulate(name, project, compiled_sparse):
    folder = project(name)
    run([f"./{name}_example", "out.csv"], folder)
    names = (folder / "out.csv").read_text().splitlines()[0].split(",")
    rows = np.loadtxt(folder / "out.csv", delimiter=",", skiprows=1, ndmin=2)
    result = compiled_sparse(name).simulate(reactions=False)
    assert rows.shape == (len(result.t), len(names))
    for k, column in enumerate(names):
        want = result.t if column == "t" else result[column]
        scale = max(float(np.max(np.abs(want))), 1e-300)
        assert np.max(np.abs(rows[:, k] - want)) <= 1e-12 * scale, column
    if name == "solar_array":          # both latches happened in the run compared
        assert [e["name"] for e in result.events] == ["panel_latch", "root_latch"]
    if name == "tape_spring_hinge":    # no event functions: no event log
        assert not (folder / "out_events.csv").exists()
    else:
        assert_event_rows(folder / "out_events.csv", result.events)
    assert run([f"./{name}_selftest"], folder).strip() == "selftest passed"


def assert_event_rows(path, events):
    """The example's event CSV holds simulate's event table: the same keys as
    columns, the same names, actions and dof, the times to 1e-12 relative and the
    numbers to 1e-12 of each column's largest magnitude (the same engine: measured
    equal); constraint_error, rounding after the projection, to 1e-11 absolute (below
    the position tolerance)."""
    from fccgen.events.table import COLUMNS
    lines = path.read_text().splitlines()
    assert tuple(lines[0].split(",")) == COLUMNS
    rows = [dict(zip(COLUMNS, line.split(","))) for line in lines[1:]]
    assert len(rows) == len(events) and events
    for column in COLUMNS:
        got = [r[column] for r in rows]
        want = [e[column] for e in events]
        if column in ("name", "action"):
            assert got == want, column
        elif column == "dof":
            assert [int(x) for x in got] == want
        else:
            got, want = np.array(got, float), np.array(want, float)
            if column == "t":
                assert np.all(np.abs(got - want) <= 1e-12 * np.abs(want)), column
            elif column == "constraint_error":
                assert np.all(np.abs(got - want) <= 1e-11), column
            else:
                scale = max(float(np.max(np.abs(want))), 1e-300)
                assert np.all(np.abs(got - want) <= 1e-12 * scale), column


def test_an_event_log_past_its_capacity_says_how_many_it_dropped(build_dir, tmp_path):
    """A log event that fires 127 times (sin(200 t) crosses zero every pi/200 s over
    2 s) on the panel of examples/panel_input.yaml: the exported log keeps its first
    64 rows, equal to simulate's first 64, and the example says on stderr how many it
    did not keep (63); the FMU's event outputs count all 127 and show the last."""
    text = (EXAMPLES / "panel_input.yaml").read_text().replace(
        "simulate:", "events:\n  - {name: tick, when: \"sin(200*t)\", do: log}\nsimulate:")
    model = tmp_path / "panel_input.yaml"
    model.write_text(text)
    folder = export_c(model, tmp_path / "ticks", build_dir)
    run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
    done = subprocess.run(["./panel_input_example", "ticks.csv"], cwd=folder,
                          capture_output=True, text=True)
    result = fccgen.load(model, build_dir, linear_solver="sparse").simulate(
        reactions=False)
    assert done.returncode == 0 and len(result.events) == 127
    assert "63 events past the log's 64 rows are not in ticks_events.csv" in done.stderr
    assert_event_rows(folder / "ticks_events.csv", result.events[:64])
    # the FMU's event outputs go on past the 64 rows: every event counted, the latest
    # one's row at each communication point; 0.05 s holds 3 or 4 ticks (pi/200 s
    # apart), so the count steps by 3 or 4 and the outputs show the latest of them
    fmpy = pytest.importorskip("fmpy")
    from fccgen.export.fmu import export_fmu
    fmu = export_fmu(model, tmp_path / "ticks.fmu", build_dir)
    rows = fmpy.simulate_fmu(str(fmu), stop_time=2.0, output_interval=0.05)
    assert set(np.diff(rows["events.count"])) == {3, 4}
    assert_event_outputs(rows, result.events, fmu)


def test_no_heap_allocation_while_the_solar_array_latches(project, tmp_path):
    folder = project("solar_array")
    exe = tmp_path / "alloc"
    run([CC, "-std=c99", "-O2", f"-I{folder}", "-DMODEL=solar_array",
         "-DHEADER=solar_array.h", str(HERE / "c" / "export_alloc.c"),
         str(folder / "libsolar_array.a"), "-o", str(exe),
         "-Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,--wrap=free", "-lm"], tmp_path)
    lines = run([str(exe)], tmp_path).splitlines()
    assert int(lines[0].split()[1]) > 20          # the set-up's, events' work included
    words = lines[1].split()
    assert words[0] == "allocations" and int(words[1]) == 0 and int(words[3]) == 3000


@pytest.fixture(scope="session")
def fmu(build_dir, tmp_path_factory):
    from fccgen.export.fmu import export_fmu
    return export_fmu(EXAMPLES / "solar_array_input.yaml",
                      tmp_path_factory.mktemp("fmu_events") / "solar_array_input.fmu",
                      build_dir)


def assert_equal_runs(rows, result):
    assert np.array_equal(rows["time"], result.t)
    for name in rows.dtype.names[1:]:
        if name.startswith("events."):
            continue                  # the event outputs: assert_event_outputs
        want = result[name]
        if name == "constraint_error":
            assert np.max(np.abs(rows[name] - want)) <= 1e-11
            continue
        scale = max(float(np.max(np.abs(want))), 1e-300)
        assert np.max(np.abs(rows[name] - want)) <= 1e-10 * scale, name


def fmu_run(fmu, **kw):
    fmpy = pytest.importorskip("fmpy")
    return fmpy.simulate_fmu(str(fmu), stop_time=LATCHED, output_interval=0.01, **kw)


def test_the_fmu_latches_as_simulate(fmu, compiled_sparse):
    result = compiled_sparse("solar_array").simulate(t_end=LATCHED, output_dt=0.01,
                                                     reactions=False)
    assert [e["name"] for e in result.events] == ["panel_latch", "root_latch"]
    assert_equal_runs(fmu_run(fmu), result)


def test_a_panel_mass_from_start_values_equals_with_parameters(fmu, compiled_sparse):
    values = {"bodies.panel2.mass": 12.0}
    solver = compiled_sparse("solar_array").with_parameters(values)
    result = solver.simulate(t_end=LATCHED, output_dt=0.01, reactions=False)
    assert len(result.events) == 2 and result.events[0]["t"] > 1.3   # later latches
    rows = fmu_run(fmu, start_values=values)
    assert_equal_runs(rows, result)
    assert_event_outputs(rows, result.events, fmu)


def enumerations(fmu):
    """{EventName, EventAction: {value: item}} from the FMU's modelDescription.xml."""
    fmpy = pytest.importorskip("fmpy")
    types = fmpy.read_model_description(str(fmu)).typeDefinitions
    return {t.name: {int(i.value): i.name for i in t.items} for t in types}


def assert_event_outputs(rows, events, fmu):
    """The FMU's event outputs at each communication point are simulate's event log
    up to that time: events.count counts the events at or before it, and the
    events.last.* outputs hold the latest one's row (name and action through the
    Enumeration items of modelDescription.xml); before the first event the count and
    every field are 0 and name and action the item "(none)". Times to 1e-10 s and the
    numbers to 1e-10 of each key's largest magnitude (the issue's FMU tolerance; the
    same engine and steps give equal values), constraint_error to 1e-11 absolute (as
    assert_equal_runs: rounding after the projection)."""
    items = enumerations(fmu)
    t_events = np.array([e["t"] for e in events])
    count = rows["events.count"]
    assert count[-1] == len(events)
    for r, t in enumerate(rows["time"]):
        n = int(np.sum(t_events <= t + 1e-12))
        assert count[r] == n, t
        if n == 0:
            assert items["EventName"][rows["events.last.name"][r]] == "(none)"
            assert items["EventAction"][rows["events.last.action"][r]] == "(none)"
            assert all(rows[f"events.last.{k}"][r] == 0 for k in
                       ("time", "impulse", "kinetic_energy_before", "dof"))
            continue
        want = events[n - 1]
        assert items["EventName"][rows["events.last.name"][r]] == want["name"]
        assert items["EventAction"][rows["events.last.action"][r]] == want["action"]
        assert rows["events.last.dof"][r] == want["dof"]
        assert abs(rows["events.last.time"][r] - want["t"]) <= 1e-10
        assert abs(rows["events.last.constraint_error"][r]
                   - want["constraint_error"]) <= 1e-11
        for key in ("impulse", "kinetic_energy_before", "kinetic_energy_after",
                    "speed_before"):
            scale = max(max(abs(e[key]) for e in events), 1e-300)
            assert abs(rows[f"events.last.{key}"][r] - want[key]) <= 1e-10 * scale, key


def test_the_fmus_event_outputs_are_simulates_event_log(fmu, compiled_sparse):
    """Both latches, seen by the importer: the count steps 0, 1, 2 at the first
    communication points at or past 1.25 s and 2.06 s; FMPy's validation (the standard's
    schema: the Enumeration types, discrete Integer outputs) reports no problem."""
    fmpy = pytest.importorskip("fmpy")
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(fmu)) == []
    result = compiled_sparse("solar_array").simulate(t_end=LATCHED, output_dt=0.01,
                                                     reactions=False)
    rows = fmu_run(fmu)
    assert sorted(set(rows["events.count"])) == [0, 1, 2]
    assert_event_outputs(rows, result.events, fmu)


def test_a_bus_torque_driven_from_fmpy_equals_simulate_inputs(fmu, compiled_sparse):
    times = np.array([0.0, 0.5, 1.0, 1.6, LATCHED])
    torque = np.array([0.0, 0.8, -0.5, 0.3, 0.0])
    signal = np.array(list(zip(times, torque)),
                      dtype=[("time", np.float64), ("bus_torque", np.float64)])
    solver = compiled_sparse("solar_array_input")
    result = solver.simulate(t_end=LATCHED, output_dt=0.01, reactions=False,
                             inputs={"bus_torque": (times, torque)})
    assert len(result.events) == 2
    assert_equal_runs(fmu_run(fmu, input=signal), result)
    plain = solver.simulate(t_end=LATCHED, output_dt=0.01, reactions=False)
    assert np.max(np.abs(plain["bus.wz"] - result["bus.wz"])) > 1e-3   # the torque acted


def test_the_event_outputs_are_typed_and_read_only(fmu, compiled_sparse):
    """Through FMI calls: events.count reads as an Integer (0 before the first latch,
    1 after a doStep past it, with the latch's time as a Real), not as a Real; the
    Real events.last.time not as an Integer; setting an event output is refused."""
    fmpy = pytest.importorskip("fmpy")
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave
    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="ev")
    slave.instantiate()
    try:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        assert slave.getInteger([vr["events.count"]]) == [0]
        slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=1.3)
        latch = compiled_sparse("solar_array").simulate(t_end=1.3, reactions=False).events
        assert slave.getInteger([vr["events.count"], vr["events.last.dof"]]) == [
            1, latch[0]["dof"]]
        assert abs(slave.getReal([vr["events.last.time"]])[0] - latch[0]["t"]) <= 1e-10
        for call, ref in ((slave.getReal, "events.count"),
                          (slave.getInteger, "events.last.time")):
            with pytest.raises(FMICallException):
                call([vr[ref]])
        with pytest.raises(FMICallException):
            slave.setInteger([vr["events.count"]], [3])
        slave.terminate()
    finally:
        slave.freeInstance()


def test_a_stop_event_ends_the_exported_run_where_simulate_ends(build_dir, tmp_path):
    """pendulum_limit with its log event made a stop: the example's last row is the
    stop's time and state, as simulate's last record; step_to returns 1 from then on."""
    text = (EXAMPLES / "pendulum_limit.yaml").read_text()
    assert "do: log" in text
    model = tmp_path / "pendulum_stop.yaml"
    model.write_text(text.replace("do: log", "do: stop")
                     .replace("name: pendulum_limit", "name: pendulum_stop"))
    folder = export_c(model, tmp_path / "stop_c", build_dir)
    run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
    run(["./pendulum_stop_example", "out.csv"], folder)
    assert run(["./pendulum_stop_selftest"], folder).strip() == "selftest passed"
    rows = np.loadtxt(folder / "out.csv", delimiter=",", skiprows=1, ndmin=2)
    result = fccgen.load(model, build_dir, linear_solver="sparse").simulate(reactions=False)
    assert result.t[-1] < 3.0 - 1e-9 and result.events[-1]["action"] == "stop"
    assert rows.shape[0] == len(result.t) and rows[-1, 0] == pytest.approx(result.t[-1],
                                                                           abs=1e-15)
    scale = np.maximum(np.max(np.abs(rows), axis=0), 1e-300)
    want = np.column_stack([result.t] + [result[n] for n in
                                         (folder / "out.csv").read_text().split("\n")[0]
                                         .split(",")[1:]])
    assert np.all(np.abs(rows - want) <= 1e-12 * scale)
    # the FMU: doStep returns fmi2Discard, FMPy reads fmi2LastSuccessfulTime and ends
    fmpy = pytest.importorskip("fmpy")
    from fccgen.export.fmu import export_fmu
    fmu_rows = fmpy.simulate_fmu(str(export_fmu(model, tmp_path / "stop.fmu", build_dir)),
                                 stop_time=3.0, output_interval=0.01)
    assert fmu_rows["time"][-1] == pytest.approx(result.t[-1], abs=1e-15)
    assert fmu_rows["A.angle"][-1] == pytest.approx(result["A.angle"][-1], rel=1e-12)


def test_an_export_that_locates_on_the_interpolant(build_dir, tmp_path, compiled_sparse):
    """fccgen export --event-location interpolant: the project's runs locate events on
    the step's interpolant by default, its example's CSV equals simulate(
    event_location="interpolant") to 1e-12 (the same engine and steps), its selftest
    replays that run, and NAME_set_event_location("steps") gives back simulate's
    default run (the example's own run is the default; the harness sets the other)."""
    from fccgen.export.cli import run_export
    args = type("Args", (), dict(model=EXAMPLES / "solar_array.yaml", c_dir=None,
                                 fmu=None, build_dir=build_dir, sensitivities=False,
                                 event_location="interpolant"))
    args.c_dir = tmp_path / "on_ip"
    assert run_export(args, None) == 0
    folder = args.c_dir
    run([MAKE, "-s", f"CC={CC}", f"CFLAGS={STRICT}"], folder)
    run(["./solar_array_example", "out.csv"], folder)
    names = (folder / "out.csv").read_text().splitlines()[0].split(",")
    rows = np.loadtxt(folder / "out.csv", delimiter=",", skiprows=1, ndmin=2)
    result = compiled_sparse("solar_array").simulate(reactions=False,
                                                     event_location="interpolant")
    assert [e["name"] for e in result.events] == ["panel_latch", "root_latch"]
    for k, column in enumerate(names):
        want = result.t if column == "t" else result[column]
        scale = max(float(np.max(np.abs(want))), 1e-300)
        assert np.max(np.abs(rows[:, k] - want)) <= 1e-12 * scale, column
    assert_event_rows(folder / "out_events.csv", result.events)
    assert run(["./solar_array_selftest"], folder).strip() == "selftest passed"
    # the API switches back to partial steps: the default run, simulate's
    harness = tmp_path / "steps.c"
    harness.write_text(
        '#include <stdio.h>\n#include "solar_array.h"\n'
        "int main(void)\n{\n"
        "    solar_array_sim *sim = solar_array_create();\n"
        "    int k = solar_array_output_index(\"P.z\");\n"
        "    if (sim == NULL || k < 0\n"
        "        || solar_array_set_event_location(sim, \"nearest\") == 0\n"
        "        || solar_array_set_event_location(sim, \"steps\") != 0\n"
        "        || solar_array_start(sim, 2.5) != 0 || solar_array_step_to(sim, 2.5) != 0)\n"
        "        return 1;\n"
        "    printf(\"%a\\n\", solar_array_output(sim, k));\n"
        "    solar_array_destroy(sim);\n"
        "    return 0;\n}\n")
    exe = tmp_path / "steps"
    run([CC, "-std=c99", "-O2", f"-I{folder}", str(harness),
         str(folder / "libsolar_array.a"), "-o", str(exe), "-lm"], tmp_path)
    got = float.fromhex(run([str(exe)], tmp_path).strip())
    want = compiled_sparse("solar_array").simulate(t_end=2.5, reactions=False)
    other = compiled_sparse("solar_array").simulate(t_end=2.5, reactions=False,
                                                    event_location="interpolant")
    # the two ways end 7.6e-13 apart in P.z (of its 0.24); the C engine and the
    # Python build differ by rounding (2e-16 relative): 1e-14 tells them apart
    scale = float(np.max(np.abs(want["P.z"])))
    assert abs(got - want["P.z"][-1]) <= 1e-14 * scale
    assert abs(got - other["P.z"][-1]) > 1e-13 * scale


def test_interpolant_location_with_sensitivities_is_refused(build_dir, tmp_path):
    from fccgen.export.c_project import ExportError
    from fccgen.export.cli import run_export
    args = type("Args", (), dict(model=EXAMPLES / "solar_array.yaml",
                                 c_dir=tmp_path / "x", fmu=None, build_dir=build_dir,
                                 sensitivities=True, event_location="interpolant"))
    with pytest.raises(ExportError, match="does not carry sensitivities"):
        run_export(args, None)
    assert not (tmp_path / "x").exists()
