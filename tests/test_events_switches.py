"""Switches of the compiled events (fccgen/runtime/_events.pyx): the degrees of freedom
after a lock or unlock decided by rank, resting contacts that release when their
contact force would pull, and event modules shared by models that differ only in
numbers (with_parameters, initial angles)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import fccgen.api as api
from fccgen.errors import RunWarning

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _four_bar(events: str) -> str:
    """examples/four_bar_driven.yaml without its driver (1 DOF) and with ``events``."""
    text = (EXAMPLES / "four_bar_driven.yaml").read_text()
    text = text.replace("name: four_bar_driven", "name: four_bar_locks")
    text = text.replace('drivers:\n  - {name: motor, joint: O, angle: "10*t"}\n', "")
    assert "drivers" not in text
    return text.replace("t_end: 1.0", "t_end: 0.6") + "events:\n" + events


TWICE = """\
  - {name: lock_O, when: "t >= 0.1", do: lock, joint: O}
  - {name: lock_C, when: "t >= 0.2", do: lock, joint: C}
  - {name: free_O, when: "t >= 0.3", do: unlock, joint: O}
  - {name: free_C, when: "t >= 0.4", do: unlock, joint: C}
"""
ONCE = """\
  - {name: lock_O, when: "t >= 0.1", do: lock, joint: O}
  - {name: free_O, when: "t >= 0.4", do: unlock, joint: O}
"""


@pytest.fixture(scope="module")
def four_bars(build_dir, tmp_path_factory):
    folder = tmp_path_factory.mktemp("switches")
    out = {}
    for name, events in (("twice", TWICE), ("once", ONCE)):
        path = folder / f"four_bar_{name}.yaml"
        path.write_text(_four_bar(events))
        out[name] = api.load(path, build_dir)
    return out


def test_a_second_latch_on_a_one_dof_mechanism_is_redundant(four_bars):
    """The four-bar (1 DOF) locked at its crank hinge O, then at its rocker hinge C:
    the first lock leaves 0 DOF, the second adds no constraint (its row follows from
    the loop and O's row): DOF 1 -> 0 -> 0 with a RunWarning naming it. Unlocking O
    leaves C holding (its row is used now: still 0 DOF, no singular solve); unlocking
    C frees the crank again (1 DOF). While locked nothing moves; after the release
    the motion equals that of a run locked once (O from 0.1 to 0.4 s): both start
    from rest at the same configuration, held to the projection's 1e-12 by different
    rows, so they agree to 1e-10 rad over the remaining 0.2 s (measured: equal, and
    7e-34 rad/s in the rates)."""
    with pytest.warns(RunWarning, match="'lock_C'.*adds no constraint.*stay 0"):
        twice = four_bars["twice"].simulate(method="rk4", dt=1e-3)
    assert [(r["name"], r["dof"]) for r in twice.events] == [
        ("lock_O", 0), ("lock_C", 0), ("free_O", 0), ("free_C", 1)]
    assert twice.info["dof"] == twice.info["final_dof"] == 1        # ends free
    assert sum("adds no constraint" in w for w in twice.info["warnings"]) == 1
    assert twice.events[0]["kinetic_energy_after"] <= 1e-20
    held = (twice.t > 0.1) & (twice.t <= 0.4)
    for j in "OC":
        assert np.max(np.abs(twice[f"{j}.rate"][held])) <= 1e-12
        assert np.ptp(twice[f"{j}.angle"][held]) <= 1e-12
    once = four_bars["once"].simulate(method="rk4", dt=1e-3)
    assert [(r["name"], r["dof"]) for r in once.events] == [("lock_O", 0), ("free_O", 1)]
    np.testing.assert_array_equal(twice.t, once.t)
    for name in ("O.angle", "C.angle", "A.angle"):
        assert np.max(np.abs(twice[name] - once[name])) <= 1e-10, name
        assert np.max(np.abs(twice[name.replace("angle", "rate")]
                             - once[name.replace("angle", "rate")])) <= 1e-9, name
    assert abs(twice["O.angle"][-1] - twice["O.angle"][held][0]) > 1e-3   # moves again


# -- resting contacts that release ---------------------------------------------------
G = 9.81
THETA = 1.0                                   # the example's upper limit (rad)


@pytest.fixture(scope="module")
def pulled(build_dir, tmp_path_factory):
    """examples/pendulum_limit.yaml with restitution 0.2 (it rests on its upper limit
    within 0.8 s) and a torque -t N m about +y on the arm, lifting it (its event
    module is the example's: restitution is a runtime number)."""
    text = (EXAMPLES / "pendulum_limit.yaml").read_text()
    assert "restitution: 0.5" in text
    text = text.replace("restitution: 0.5", "restitution: 0.2")
    text += 'loads:\n  - {type: torque, body: arm, value: [0, "-t", 0]}\n'
    path = tmp_path_factory.mktemp("release") / "pendulum_pulled.yaml"
    path.write_text(text)
    return api.load(path, build_dir)


@pytest.mark.parametrize("method, opts", [("rk4", dict(dt=1e-3)),
                                          ("dopri5", dict(rtol=1e-10, atol=1e-10))])
def test_a_resting_contact_releases_when_the_load_pulls_it_off(pulled, method, opts):
    """Gravity holds the arm (m = 1, centre 0.5 from the hinge) on its upper limit
    theta = 1 with the torque m g 0.5 cos(theta) = 2.650 N m; the load's torque -t
    (about +y, lifting the arm) exceeds it at T = 0.5 g cos(1) s. At rest v = 0, so the
    row's multiplier is the static balance, linear in t: it turns tensile at T, and
    the release is located there like any event. Its error: the location tolerance
    (1e-12 s) plus the balance's own, the lever arm held to the position tolerance
    (constraint error up to 3e-12 m on 0.5 m, times T): about 3e-11 s; checked at
    1e-10 s (measured -2.8e-12 s with rk4, -1.8e-11 s with dopri5). After it the arm
    leaves the limit (no new bounce) and the DOF is 1 again."""
    result = pulled.simulate(method=method, t_end=3.0, **opts)
    actions = [r["action"] for r in result.events]
    assert actions[-2:] == ["rest", "release"] and "release" not in actions[:-1]
    assert actions[0] == "log"                              # the example's 'quarter' 
    rest, release = result.events[-2:]
    assert rest["t"] < 1.0 and release["name"] == rest["name"] == "A_upper"
    assert (rest["dof"], release["dof"]) == (0, 1)
    assert abs(release["t"] - 0.5 * G * math.cos(THETA)) <= 1e-10
    assert release["impulse"] == 0.0
    held = (result.t > rest["t"]) & (result.t <= release["t"])
    assert np.max(np.abs(result["A.angle"][held] - THETA)) <= 1e-11
    after = result.t > release["t"] + 0.05
    assert np.all(np.diff(result["A.angle"][result.t > release["t"]]) < 0)
    assert np.all(result["A.angle"][after] < THETA - 1e-6)


def test_a_resting_contact_stays_while_the_load_is_too_weak(pulled):
    """Up to t = 2.6 s the torque t stays below gravity's 2.650 N m (it reaches 98% of
    it, from 28% when the arm comes to rest): no release, the arm rests on its limit to
    the end (held to 1e-11 rad)."""
    result = pulled.simulate(method="rk4", t_end=2.6, dt=1e-3)
    assert result.events[-1]["action"] == "rest" and result.events[-1]["t"] < 0.8
    assert all(r["action"] != "release" for r in result.events)
    after = result.t > result.events[-1]["t"]
    assert np.max(np.abs(result["A.angle"][after] - THETA)) <= 1e-11


# -- one event module for every initial configuration ---------------------------------
def _pendulum_at(phi: float) -> str:
    """examples/pendulum_limit.yaml with the arm starting phi below the horizontal
    (turned about the hinge axis +y): its angle is 0 there, the limits relative to it."""
    text = (EXAMPLES / "pendulum_limit.yaml").read_text()
    c, s = math.cos(phi), math.sin(phi)
    old = "center: [0.5, 0, 0],"
    assert old in text
    return text.replace(old, f"center: [{0.5 * c!r}, 0, {-0.5 * s!r}], "
                             f"frame: {{x: [{c!r}, 0, {-s!r}], y: [0, 1, 0]}},")


def test_initial_angles_share_one_event_module(build_dir, tmp_path, monkeypatch):
    """Two pendulums that start at different angles: the numbers of the initial
    configuration are runtime parameters of the event kernels, so the second load
    compiles nothing (its event module is the first one's, from the cache). Started
    there (the example's point arm_center moved by with_parameters) its angle still
    reads 0 at the start and follows the arm: the angle from the arm's centre,
    atan2(-z, x) - phi, to 1e-12 rad (rounding of the atan2 of both)."""
    import fccgen.build.companion as companion
    import fccgen.events.build as events_build
    compiles = []
    real = companion.compile_sources
    monkeypatch.setattr(companion, "compile_sources",
                        lambda *a, **k: compiles.append(a[2]) or real(*a, **k))
    built = []
    for phi in (0.0, 0.3):
        path = tmp_path / f"pendulum_{phi}.yaml"
        path.write_text(_pendulum_at(phi))
        built.append(events_build.build_events(api.plan_model(path), tmp_path / "gen"))
    assert compiles == ["pendulum_limit_events"]
    assert (built[0].cache_hit, built[1].cache_hit) == (False, True)
    assert built[0].directory == built[1].directory
    solver = api.load(EXAMPLES / "pendulum_limit.yaml", build_dir).with_parameters(
        {"points.arm_center.at": [0.5 * math.cos(0.3), 0.0, -0.5 * math.sin(0.3)]})
    result = solver.simulate(t_end=0.3, dt=1e-3, method="rk4")
    geometric = np.arctan2(-result["arm_center.z"], result["arm_center.x"]) - 0.3
    assert result["A.angle"][0] == 0.0
    assert np.max(np.abs(result["A.angle"] - geometric)) <= 1e-12
    assert result.events[0]["name"] == "quarter"


def test_with_parameters_keeps_the_events(build_dir, tmp_path):
    """with_parameters binds the same event module to the new numbers: the example
    pendulum with the arm's mass doubled and its centre (the lowered model's point
    arm_center) moved 0.3 rad down runs the events of a model file written with those
    numbers, row for row: the same kernels and numbers, so equal to 1e-12 (rounding
    of the pose's sine and cosine at most)."""
    phi = 0.3
    moved = tmp_path / "pendulum_moved.yaml"
    moved.write_text(_pendulum_at(phi).replace("mass: 1.0", "mass: 2.0"))
    direct = api.load(moved, build_dir)
    base = api.load(EXAMPLES / "pendulum_limit.yaml", build_dir)
    solver = base.with_parameters({"bodies.arm.mass": 2.0, "points.arm_center.at":
                                   [0.5 * math.cos(phi), 0.0, -0.5 * math.sin(phi)]})
    assert solver.events_module is base.events_module
    a = solver.simulate(t_end=1.0, dt=1e-3, method="rk4").events
    b = direct.simulate(t_end=1.0, dt=1e-3, method="rk4").events
    assert len(a) == len(b) >= 3
    for x, y in zip(a, b):
        assert (x["name"], x["action"], x["dof"]) == (y["name"], y["action"], y["dof"])
        for key in ("t", "impulse", "kinetic_energy_before", "kinetic_energy_after"):
            assert abs(x[key] - y[key]) <= 1e-12 * max(1.0, abs(y[key])), key


def test_switch_notes_become_warnings():
    """The runtime's note bits (log columns 9, 10) give one text each: a redundant
    lock, and a rank after a switch decided in the uncertain band with its singular
    value; rows without notes give none."""
    from fccgen.events.table import event_rows, switch_warnings
    from fccgen.runtime._events import ACTIONS, LOG_COLUMNS, NOTES
    assert LOG_COLUMNS[9:] == ("note", "sigma")
    log = np.zeros((3, len(LOG_COLUMNS)))
    log[:, 0] = [0.1, 0.2, 0.3]
    log[:, 2] = ACTIONS.index("lock")
    log[1, 9], log[2, 9], log[2, 10] = NOTES["redundant"], NOTES["uncertain"], 3e-8
    rows = event_rows(["latch"], ACTIONS, log)
    texts = switch_warnings(rows, log, NOTES)
    assert len(texts) == 2
    assert "t = 0.2" in texts[0] and "adds no" in texts[0]
    assert "t = 0.3" in texts[1] and "3e-08" in texts[1] and "uncertain" in texts[1]
