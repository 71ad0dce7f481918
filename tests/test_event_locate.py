"""The cost of locating an event with rk4 (engine/fcc_event_locate.c, fcc_rk4.c): the
trials (re-integrated partial steps, four acceleration evaluations each) are placed by
the step's Hermite interpolant, so the bracket closes in two of them; the located
times are the Illinois search's to the location tolerance, on the solar array's two
latches, on both solve paths, and on a pendulum's bounces, several to a step."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from fccgen.runtime import _rk4
from fccgen.runtime import solver as solver_module

EVENT_TOL = 1e-12          # simulate's default location tolerance (seconds)


def run(solver, monkeypatch, interpolant: bool, t_end: float = 2.2):
    """A run with rk4 (dt 1e-3; the solar array through both latches by 2.2 s), its
    trials placed by the interpolant or by the Illinois iteration alone (the search
    it replaces)."""
    monkeypatch.setattr(solver_module, "simulate_rk4",
                        functools.partial(_rk4.simulate_rk4, interpolant=interpolant))
    return solver.simulate(t_end=t_end, dt=1e-3, method="rk4")


@pytest.fixture(scope="module", params=["dense", "sparse"])
def runs(request, compiled, compiled_sparse):
    solver = (compiled if request.param == "dense" else compiled_sparse)("solar_array")
    with pytest.MonkeyPatch.context() as mp:
        guided = run(solver, mp, True)
        illinois = run(solver, mp, False)
    return guided, illinois


def event_evaluations(result) -> int:
    """The acceleration evaluations beyond the plain steps' four each: the event
    steps' extra cost (trials, the state at the located time, the rest of the
    step)."""
    return result.info["rhs_evaluations"] - 4 * result.info["steps"]


def test_event_steps_take_fewer_evaluations(runs):
    """Per latch the guided search takes at most three partial steps and the rest of
    the step (16 evaluations; measured two, 12), the Illinois search five or more and
    the rest (measured 26 to 32): the guided one takes fewer on each path."""
    guided, illinois = runs
    assert [r["name"] for r in guided.events] == ["panel_latch", "root_latch"]
    assert 0 < event_evaluations(guided) <= 16 * len(guided.events)
    assert event_evaluations(guided) < event_evaluations(illinois)


def test_located_times_are_the_illinois_ones(runs):
    """Both searches stop with the bracket's end past the crossing of the same real
    integration, within EVENT_TOL of it: the first latch's times differ by less than
    EVENT_TOL. The second latch follows a state that differs by that first difference
    times the hinge rates (up to 8 rad/s) held in the lock: 2 EVENT_TOL (measured
    2.5e-13 and 3.7e-13 s). The records agree to 1e-9 (measured 2e-11: the located
    times' difference times the rates and the latch's velocity jump)."""
    guided, illinois = runs
    assert [(r["name"], r["action"]) for r in guided.events] == [
        (r["name"], r["action"]) for r in illinois.events]
    t_g = np.array([r["t"] for r in guided.events])
    t_i = np.array([r["t"] for r in illinois.events])
    assert abs(t_g[0] - t_i[0]) < EVENT_TOL
    assert np.all(np.abs(t_g - t_i) < 2 * EVENT_TOL)
    for name, column in guided.columns.items():
        other = illinois.columns[name]
        scale = max(1.0, float(np.max(np.abs(other))))
        assert np.max(np.abs(column - other)) <= 1e-9 * scale, name


def test_bounces_continued_in_one_step(compiled, monkeypatch):
    """The limited pendulum (examples/pendulum_limit.yaml): 23 bounces, the closing
    ones several to a step, each located from the instant of the one before (a start
    that counts as before the crossing on the interpolant as in the real bracket),
    then a rest. The same events as the Illinois search, at times within 1e-8 s (the
    closing bounces, 1e-9 s apart, amplify the 1e-12 s location tolerance, as between
    the compiled and the NumPy runs, tests/test_numeric_events.py; measured 9e-12 s),
    with fewer evaluations (measured 716 beyond the plain steps' against 1848)."""
    solver = compiled("pendulum_limit")
    guided = run(solver, monkeypatch, True, t_end=1.5)
    illinois = run(solver, monkeypatch, False, t_end=1.5)
    assert [(r["name"], r["action"]) for r in guided.events] == [
        (r["name"], r["action"]) for r in illinois.events]
    assert sum(r["action"] == "bounce" for r in guided.events) == 23
    assert guided.events[-1]["action"] == "rest"
    t_g = np.array([r["t"] for r in guided.events])
    t_i = np.array([r["t"] for r in illinois.events])
    assert np.max(np.abs(t_g - t_i)) < 1e-8
    assert event_evaluations(guided) < 0.5 * event_evaluations(illinois)

