"""rk4's second way of locating an event (simulate(event_location="interpolant"),
engine/fcc_rk4.c): the crossing found on the step's interpolant, the acceleration
evaluated at the step's end for it, and the state at the located time taken from the
interpolant and projected, as dopri5 takes it from its continuous extension. Its
point is a bounded cost: an event step takes the step, one evaluation and the rest of
the step, whatever the crossing. Checked against the default way (partial steps
re-integrated until the real integration's bracket closes to event_tol), which
locates the same crossings of the same motion."""
from __future__ import annotations

import numpy as np
import pytest

DT = 1e-3


def event_evaluations(result) -> int:
    """Acceleration evaluations beyond the plain steps' four each."""
    return result.info["rhs_evaluations"] - 4 * result.info["steps"]


@pytest.fixture(scope="module", params=["dense", "sparse"])
def solar(request, compiled, compiled_sparse):
    solver = (compiled if request.param == "dense" else compiled_sparse)("solar_array")
    steps = solver.simulate(t_end=2.2, dt=DT, method="rk4")
    on_ip = solver.simulate(t_end=2.2, dt=DT, method="rk4", event_location="interpolant")
    return steps, on_ip


def test_an_event_step_costs_one_evaluation_and_the_rest_of_the_step(solar):
    """Each latch: one evaluation at the step's end and a step of the rest: exactly 5
    evaluations beyond the plain steps' (the partial steps' way takes 12 to 28)."""
    steps, on_ip = solar
    assert [r["name"] for r in on_ip.events] == ["panel_latch", "root_latch"]
    assert event_evaluations(on_ip) == 5 * len(on_ip.events)
    assert event_evaluations(steps) > event_evaluations(on_ip)
    assert steps.info["event_location"] == "steps"
    assert on_ip.info["event_location"] == "interpolant"


def test_the_same_latches_at_the_same_times(solar):
    """The interpolant's positions are quintic in the step's ends with exact end
    accelerations (error O(dt^6)) and its velocities cubic (O(dt^4), the size of one
    rk4 step's error), so its crossing is the real integration's to about that error
    over the hinge's rate. Measured on both paths: the latch times 1.5e-13 s and
    1.2e-12 s apart (the second after a state that carries the first latch's
    difference), the records 2.6e-12 of each column's largest value; the bounds are
    the next power of ten above ten times those: 1e-11 s and 1e-10."""
    steps, on_ip = solar
    assert [(r["name"], r["action"]) for r in on_ip.events] == [
        (r["name"], r["action"]) for r in steps.events]
    t_s = np.array([r["t"] for r in steps.events])
    t_i = np.array([r["t"] for r in on_ip.events])
    assert np.max(np.abs(t_s - t_i)) < 1e-11
    for name, column in on_ip.columns.items():
        other = steps.columns[name]
        scale = max(1.0, float(np.max(np.abs(other))))
        assert np.max(np.abs(column - other)) <= 1e-10 * scale, name


def test_the_located_state_is_on_the_constraints(solar):
    """The interpolated state is projected like any step's end: the run's constraint
    error stays at the position tolerance's level."""
    steps, on_ip = solar
    assert on_ip.info["max_constraint_error"] <= max(
        10 * steps.info["max_constraint_error"], 1e-10)


def test_bounces_and_rest_of_the_limited_pendulum(compiled):
    """examples/pendulum_limit.yaml: 23 bounces, the closing ones several to a step,
    then a rest. The same events at times within 1e-8 s of the partial steps' (the
    closing bounces, 1e-9 s apart, amplify every difference, as in
    tests/test_event_locate.py; measured 1.5e-10 s), with fewer evaluations (measured
    125 beyond the plain steps' against 716). A resting bounce's release function
    needs the accelerations: it is still located by partial steps."""
    solver = compiled("pendulum_limit")
    steps = solver.simulate(t_end=1.5, dt=DT, method="rk4")
    on_ip = solver.simulate(t_end=1.5, dt=DT, method="rk4", event_location="interpolant")
    assert [(r["name"], r["action"]) for r in on_ip.events] == [
        (r["name"], r["action"]) for r in steps.events]
    assert sum(r["action"] == "bounce" for r in on_ip.events) == 23
    assert on_ip.events[-1]["action"] == "rest"
    t_s = np.array([r["t"] for r in steps.events])
    t_i = np.array([r["t"] for r in on_ip.events])
    assert np.max(np.abs(t_s - t_i)) < 1e-8
    assert event_evaluations(on_ip) < 0.25 * event_evaluations(steps)


def test_refused_values_and_combinations(compiled, numeric):
    solver = compiled("solar_array")
    with pytest.raises(ValueError, match="event_location must be one of steps, "
                                         "interpolant, not 'dense'"):
        solver.simulate(t_end=0.01, event_location="dense")
    with pytest.raises(ValueError, match="does not carry sensitivities"):
        solver.simulate(t_end=0.01, event_location="interpolant",
                        sensitivities=["loads[0].stiffness"])
    with pytest.raises(ValueError, match="locates events by partial steps only"):
        numeric("solar_array").simulate(t_end=0.01, event_location="interpolant")


def test_dopri5_reports_its_continuous_extension(compiled):
    """dopri5 always locates on its continuous extension; its info says so."""
    result = compiled("solar_array").simulate(t_end=2.2, method="dopri5")
    assert result.info["event_location"] == "interpolant"
