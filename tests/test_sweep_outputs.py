"""``--outputs`` of a sweep (fccgen.sweep.outputs, docs/sweeps.md): the grammar, its
checks against the model before any run, and each value against a separate run of
the same numbers (the same compiled code in this process: equal to the last bit)."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from conftest import EXAMPLES
from fccgen.cli import main
from fccgen.sweep import sweep as run_sweep
from fccgen.sweep.outputs import Output, parse_outputs


def test_the_grammar():
    assert parse_outputs("motor.torque:max, latch:time,run:steps,P.x:final") == [
        Output("motor.torque", "max", "column"), Output("latch", "time", "event"),
        Output("run", "steps", "run"), Output("P.x", "final", "column")]
    assert parse_outputs(None) == [] and parse_outputs(["a.b:tmin"])[0].label == "a.b:tmin"


@pytest.mark.parametrize("text, words", [
    ("P.x", "expected NAME:STATISTIC"),
    ("P.x:", "expected NAME:STATISTIC"),
    (":max", "expected NAME:STATISTIC"),
    ("P.x:maximum", "unknown statistic 'maximum'; a column takes final, initial, max, "
                    "min, absmax, tmax, tmin; an event takes time, count, last"),
    ("P.x:max,P.x:max", "'P.x:max': is given twice"),
    ("", "expected NAME:STATISTIC"),
])
def test_bad_items_are_named(text, words):
    with pytest.raises(ValueError, match="--outputs") as caught:
        parse_outputs(text)
    assert words in str(caught.value)


def test_column_statistics_and_run_statistics(compiled):
    solver = compiled("double_pendulum")
    outputs = ("P2.x:final,P2.x:initial,P2.y:max,P2.y:min,P1.vx:absmax,P2.y:tmax,"
               "P2.y:tmin,run:steps,run:newton_iterations,run:max_constraint_error")
    masses = [0.5, 0.8]
    table = run_sweep(solver, {"bodies.rod2.mass": masses, "simulate.t_end": [0.3]},
                      workers=1, outputs=outputs)
    assert table.columns[-len(solver.plan.model.moving_points) * 3 - 10:][:10] == \
        outputs.split(",")
    for row, mass in zip(table.rows, masses):
        r = solver.with_parameters({"bodies.rod2.mass": mass}).simulate(t_end=0.3)
        y = r["P2.y"]
        assert row["P2.x:final"] == r["P2.x"][-1] and row["P2.x:initial"] == r["P2.x"][0]
        assert row["P2.y:max"] == y.max() and row["P2.y:min"] == y.min()
        assert row["P1.vx:absmax"] == np.abs(r["P1.vx"]).max()
        assert row["P2.y:tmax"] == r.t[np.argmax(y)] and row["P2.y:tmin"] == r.t[np.argmin(y)]
        assert row["run:steps"] == r.info["steps"] == 300
        assert row["run:newton_iterations"] == r.info["newton_iterations"]
        assert row["run:max_constraint_error"] == r.info["max_constraint_error"]


def test_event_times_and_counts(compiled):
    """The pendulum's log event `quarter` (A.angle >= 0.5) and its joint limit."""
    solver = compiled("pendulum_limit")
    base = solver.simulate(t_end=1.5)
    names = sorted({e["name"] for e in base.events})
    limit = next(n for n in names if n != "quarter")
    outputs = f"quarter:time,quarter:last,quarter:count,{limit}:count,A.angle:max"
    table = run_sweep(solver, {"bodies.arm.mass": [1.0, 2.0], "simulate.t_end": [1.5]},
                      workers=1, outputs=outputs)
    for row, mass in zip(table.rows, [1.0, 2.0]):
        r = solver.with_parameters({"bodies.arm.mass": mass}).simulate(t_end=1.5)
        quarter = [e["t"] for e in r.events if e["name"] == "quarter"]
        assert quarter and row["quarter:time"] == quarter[0]
        assert row["quarter:last"] == quarter[-1]
        assert row["quarter:count"] == len(quarter)
        assert row[f"{limit}:count"] == sum(e["name"] == limit for e in r.events) > 0
        assert row["A.angle:max"] == r["A.angle"].max()


def test_an_event_that_never_happens_leaves_its_time_empty(compiled, tmp_path):
    solver = compiled("pendulum_limit")
    out = tmp_path / "t.csv"
    run_sweep(solver, {"simulate.t_end": [0.01]}, workers=1, out=out,
              outputs="quarter:time,quarter:count")
    with open(out, newline="") as fh:
        (row,) = list(csv.DictReader(fh))
    assert row["quarter:time"] == "" and row["quarter:count"] == "0"


def test_a_driver_torque_maximum(compiled):
    """What issue 22 asks a designer to read: the motor torque's maximum."""
    solver = compiled("four_bar_driven")
    table = run_sweep(solver, {"simulate.t_end": [0.2]}, workers=1,
                      outputs="motor.torque:max,motor.torque:absmax")
    r = solver.simulate(t_end=0.2)
    (row,) = table.rows
    assert row["motor.torque:max"] == r["motor.torque"].max()
    assert row["motor.torque:absmax"] == np.abs(r["motor.torque"]).max() > 0


@pytest.mark.parametrize("outputs, words", [
    ("P2.z:max,P3.x:max", ["--outputs item 'P3.x:max': the model has no result column "
                           "'P3.x' (did you mean P2.x", "its columns: t, "]),
    ("latch:time", ["--outputs item 'latch:time': the model has no event 'latch'; its "
                    "events: none"]),
    ("run:step", ["--outputs item 'run:step': a run has no statistic 'step' (did you "
                  "mean steps", "its statistics: "]),
    ("P2.x:biggest", ["--outputs item 'P2.x:biggest': unknown statistic 'biggest'"]),
])
def test_cli_bad_outputs_stop_before_the_runs(build_dir, tmp_path, capsys, outputs, words):
    code = main(["sweep", str(EXAMPLES / "double_pendulum.yaml"), "--build-dir",
                 str(build_dir), "-q", "--set", "bodies.rod2.mass=1,2", "--outputs",
                 outputs, "--out", str(tmp_path / "t.csv")])
    out, err = capsys.readouterr()
    assert code == 1 and out == "" and err.count("\n") == 1
    assert err.startswith("fccgen: error: ")
    for w in words:
        assert w in err
    assert not list(tmp_path.iterdir())           # no table, no partial file


def test_a_column_with_values_the_run_could_not_give_has_no_time_of_its_extremes():
    """A column NaN from some record on (an angle whose turns the records lost, a
    driver force past a dropped event log) has no max, min or time of either: NaN,
    not the time of its first NaN, which numpy's argmax gives."""
    from fccgen.sweep.outputs import _column_stat
    t = np.array([0.0, 1.0, 2.0, 3.0])
    x = np.array([0.0, 5.0, np.nan, np.nan])
    for stat in ("max", "min", "tmax", "tmin"):
        assert np.isnan(_column_stat(t, x, stat)), stat
    assert _column_stat(t, x, "initial") == 0.0
