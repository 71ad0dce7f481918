"""Events on the sparse path (engine/fcc_events.c, fcc_event_actions.c): the same runs
as the dense path, through locks, unlocks and bounces, with the rows that enter the
solves decided by the pivots of their Schur complement instead of an SVD.

Tolerances. Both paths take the same RK4 steps, locate events on the same functions
to event_tol (1e-12 s) and apply the same impacts; they differ by the solves'
rounding (the dense null-space solve against the augmented-Lagrangian refinement,
which stops at 1e-15 of |x|), amplified by the motion. Hence 1e-9 of each column's
largest value (or of 1) on the states, and 1e-10 s on the event times: measured
1e-13 (the solar array's columns through both latches), 1.6e-11 (the 3-unit boom's
node speeds after its latch's shock), 1e-13 s and below on every event time.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import fccgen.api as api
from conftest import EXAMPLES, example_module
from fccgen.errors import RunWarning
from fccgen.runtime import CompiledSolver
from fccgen.runtime._sparse import SparseEngine
from test_events_switches import ONCE, TWICE, _four_bar


def pair(solver):
    """(dense, sparse) solvers of one compiled model and its events."""
    return tuple(CompiledSolver(solver.plan, solver.module, linear_solver=path,
                                events_module=solver.events_module)
                 for path in ("dense", "sparse"))


def runs(solver, t_end):
    dense, sparse = pair(solver)
    assert isinstance(sparse._engine, SparseEngine)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunWarning)
        # reactions off: post-processing of the recorded states, the same on both paths
        return [s.simulate(t_end=t_end, dt=1e-3, method="rk4", reactions=False)
                for s in (dense, sparse)]


def assert_same(rd, rs, names):
    assert [e["name"] for e in rd.events] == [e["name"] for e in rs.events] == names
    for a, b in zip(rd.events, rs.events):
        assert abs(a["t"] - b["t"]) <= 1e-10, a["name"]
        assert (a["dof"], a["action"]) == (b["dof"], b["action"]), a["name"]
    np.testing.assert_array_equal(rd.t, rs.t)
    for column in rd.columns:
        x, y = rd[column], rs[column]
        if column == "constraint_error":      # a residual: rounding of the state's size
            assert np.max(y) <= 1e-9
            continue
        assert np.max(np.abs(x - y)) <= 1e-9 * max(1.0, np.max(np.abs(x))), column


def test_solar_array_through_both_latches(compiled):
    """The solar array to 2.2 s: its panel hinge latches at 1.25 s, its root at
    2.06 s (8 -> 7 -> 6 DOF)."""
    rd, rs = runs(compiled("solar_array"), 2.2)
    assert_same(rd, rs, ["panel_latch", "root_latch"])
    assert [e["dof"] for e in rs.events] == [7, 6]


def test_latched_scissor_boom(build_dir, tmp_path):
    """The scissor boom of 3 units (45 coordinates), latched at 0.37 s: 1 -> 0 DOF,
    a plastic impact that takes all its kinetic energy."""
    path = tmp_path / "boom3.yaml"
    path.write_text(example_module("make_scissor_boom").model_text(3))
    rd, rs = runs(api.load(path, build_dir), 1.0)
    assert_same(rd, rs, ["latch"])
    assert rs.events[0]["dof"] == 0 and rs.events[0]["kinetic_energy_after"] < 1e-12


def test_pendulum_bouncing_on_its_limit(compiled):
    """examples/pendulum_limit.yaml for 1 s: a log event, then two bounces on the
    upper stop (restitution 0.5)."""
    rd, rs = runs(compiled("pendulum_limit"), 1.0)
    assert_same(rd, rs, ["quarter", "A_upper", "A_upper"])
    assert [e["action"] for e in rs.events] == ["log", "bounce", "bounce"]


@pytest.mark.parametrize("events, dofs", [(ONCE, [0, 1]), (TWICE, [0, 0, 0, 1])])
def test_locks_then_unlocks(build_dir, tmp_path, events, dofs):
    """The four-bar (1 DOF) locked at its crank, then unlocked; and locked at both
    hinges before unlocking both, where the second lock is redundant: the sparse
    path's pivot test finds it so (its pivot is rounding, 3e-17 of the row's scale),
    as the dense path's SVD does, and warns once."""
    path = tmp_path / "four_bar_locks.yaml"
    path.write_text(_four_bar(events))
    rd, rs = runs(api.load(path, build_dir), 0.6)
    assert [e["dof"] for e in rs.events] == dofs
    assert_same(rd, rs, [e["name"] for e in rd.events])
    if len(dofs) == 4:
        for r in (rd, rs):
            assert sum("'lock_C'" in w and "adds no constraint" in w
                       for w in r.info["warnings"]) == 1
