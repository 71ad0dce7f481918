"""solver.simulate_many (fccgen.runtime.many): each run equals its single run bit for
bit, on any number of threads; a failed run is reported in its place and the others
kept. Short runs of the smallest models; nothing here is timed."""
from __future__ import annotations

import numpy as np
import pytest

from fccgen.errors import ModelError
from fccgen.runtime.many import RunFailure
from fccgen.runtime import setup_reuse

T_END = 0.6           # the limited pendulum meets its stop before t = 0.45 s in each set


def _same(a, b) -> bool:
    """Every column and the event log of two results are identical."""
    return (a.names == b.names and all(np.array_equal(a[c], b[c]) for c in a.names)
            and [(e["name"], e["t"]) for e in a.events]
            == [(e["name"], e["t"]) for e in b.events])


@pytest.fixture(scope="module")
def limited(compiled):
    return compiled("pendulum_limit")


# masses and a hinge moved along the arm's axis (the stop's events stay), and a
# length of the arm's mass centre that moves the initial state's speeds and energy
SETS = [{"bodies.arm.mass": 1.0}, {"bodies.arm.mass": 2.5},
        {"bodies.arm.center[0]": 0.8, "bodies.arm.mass": 0.7},
        {"gravity[2]": -20.0}]


def test_each_run_equals_its_single_run_with_events(limited):
    runs = limited.simulate_many(SETS, t_end=T_END, threads=2)
    assert len(runs) == len(SETS)
    for params, run in zip(SETS, runs):
        single = limited.with_parameters(params).simulate(t_end=T_END)
        assert _same(run, single), params
        assert len(run.events) >= 1            # the stop was met: events ran
    # the numbers did reach the runs: the stop is met at other times
    assert len({float(run.events[0]["t"]) for run in runs}) == len(SETS)


def test_one_and_two_threads_give_identical_results(limited):
    one = limited.simulate_many(SETS, t_end=T_END, threads=1)
    two = limited.simulate_many(SETS, t_end=T_END, threads=2)
    assert all(_same(a, b) for a, b in zip(one, two))


def test_a_failed_run_is_reported_and_the_others_kept(limited):
    sets = [{"bodies.arm.mass": 1.5},
            {"simulate.dt": 0.5},                 # diverges (the engine's bound)
            {"bodies.arm.mass": -1.0},            # a value the model file refuses
            {"bodies.arm.mass": 2.0}]
    runs = limited.simulate_many(sets, t_end=1.0, threads=2)
    assert isinstance(runs[1], RunFailure) and isinstance(runs[2], RunFailure)
    assert runs[1].kind == "SimulationError" and "diverged" in runs[1].error
    assert runs[1].index == 1 and runs[1].params == sets[1]
    assert runs[1].partial is not None and runs[1].partial.info["partial"]
    assert runs[2].kind == "ModelError" and "positive" in runs[2].error
    for k in (0, 3):
        assert _same(runs[k], limited.with_parameters(sets[k]).simulate(t_end=1.0))


def test_geometry_that_moves_the_initial_state(compiled):
    """A moved point moves the initial state (and the lengths that follow from it):
    each run does its own set-up at its own start, as its single run does (the rank
    decisions kept for the process are dropped first: they are keyed by the Jacobian,
    which the moved point changes)."""
    setup_reuse.forget()
    solver = compiled("four_bar")
    sets = [{}, {"points.B.at[1]": 0.30}]
    runs = solver.simulate_many(sets, t_end=0.05, threads=2)
    singles = [solver.with_parameters(p).simulate(t_end=0.05) for p in sets]
    assert all(_same(a, b) for a, b in zip(runs, singles))
    assert runs[0]["B.y"][0] != runs[1]["B.y"][0]
    assert not any(run.info["setup"]["rank_decision"]["reused"] for run in runs)


def test_a_data_frame_of_sets(limited):
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame({"bodies.arm.mass": [1.0, 2.0], "gravity[2]": [-9.81, np.nan]})
    runs = limited.simulate_many(frame, t_end=0.05, threads=1)
    assert _same(runs[0], limited.with_parameters(
        {"bodies.arm.mass": 1.0, "gravity[2]": -9.81}).simulate(t_end=0.05))
    # a NaN cell leaves the model's own number
    assert _same(runs[1], limited.with_parameters(
        {"bodies.arm.mass": 2.0}).simulate(t_end=0.05))


def test_bad_calls_are_refused_before_any_run(limited):
    with pytest.raises(ModelError, match=r"parameter set 1: .*bodies\.nothing\.mass"):
        limited.simulate_many([{"bodies.arm.mass": 1.0}, {"bodies.nothing.mass": 1.0}])
    with pytest.raises(TypeError, match="not one dict"):
        limited.simulate_many({"bodies.arm.mass": 1.0})
    with pytest.raises(TypeError, match="q0="):
        limited.simulate_many([{}], q0=limited.plan.q0)
    with pytest.raises(ValueError, match="threads"):
        limited.simulate_many([{}], threads=0)
    assert limited.simulate_many([]) == []


def test_progress_counts_the_runs(limited):
    events = []
    limited.simulate_many([{}, {"bodies.arm.mass": 2.0}], t_end=0.01, threads=2,
                          progress=events.append)
    assert [e.done for e in events] == [1, 2]
    assert all(e.stage == "simulate_many" and e.total == 2 for e in events)
