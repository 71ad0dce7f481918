"""Joint reactions and driver forces while events hold joints (fccgen.runs.held_rows):
after a lock the accelerations hold the locked rows and the locked joint's reaction
gains the held direction, against closed forms of bodies that the lock leaves at rest
or in rigid rotation, and the compiled runtime against the NumPy version (independent
kernels for the locked rows' gradients and biases)."""
from __future__ import annotations

import numpy as np
import pytest

import fccgen
from fccgen.api import plan_model
from fccgen.runs.held_rows import held_segments, joint_kinds
from test_joints import write

G = 9.81


def vec(r, joint, kind):
    return np.column_stack([r[f"{joint}.{kind}{c}"] for c in "xyz"])


def centre(r, body):
    return np.column_stack([r[f"{body}.c{c}"] for c in "xyz"])


def test_a_latched_panel_holds_the_motor_torque_and_nothing_else():
    """examples/panel_latch.yaml: a torque pair opens the panel about its hinge on a
    free-floating bus; the plastic latch leaves one rigid body at rest (zero momenta),
    so on the panel the hinge must cancel its own 0.5 N m about z and nothing else.
    Before, the reactions after the latch came from accelerations without the lock
    (|F| 0.33 N, tz -0.002 N m). 1e-10: the rounding of the balance at rest."""
    r = fccgen.load(fccgen.example_path("panel_latch")).simulate(output_dt=0.25)
    (latch,) = r.events
    after = r.t > latch["t"]
    assert after.sum() >= 8
    assert np.abs(vec(r, "H", "f")[after]).max() < 1e-10
    assert np.abs(vec(r, "H", "t")[after] - [0.0, 0.0, -0.5]).max() < 1e-10
    before = ~after                           # free hinge: no torque along its axis
    assert np.abs(r["H.tz"][before]).max() < 1e-2 * np.abs(r["H.fx"][before]).max()


DRIVEN_LATCH = """\
name: driven_latch
gravity: [0, -9.81, 0]
bodies:
  link1: {mass: 1.0, center: [0.5, 0, 0], inertia: [0.001, 0.08, 0.08]}
  link2: {mass: 2.0, center: [1.5, 0, 0], inertia: [0.002, 0.17, 0.17]}
joints:
  - {name: O, type: revolute, bodies: [ground, link1], at: [0, 0, 0], axis: [0, 0, 1]}
  - {name: A, type: revolute, bodies: [link1, link2], at: [1, 0, 0], axis: [0, 0, 1]}
drivers:
  - {name: motor, joint: O, angle: "2*t"}
events:
  - {name: latch, when: "A.angle <= -0.2", do: lock, joint: A}
simulate: {t_end: 0.3, dt: 1.0e-3, output_dt: 0.02}
"""


@pytest.fixture(scope="module")
def driven_latch(tmp_path_factory):
    """(compiled, NumPy) runs of DRIVEN_LATCH."""
    path = write(tmp_path_factory.mktemp("held"), DRIVEN_LATCH)
    return fccgen.load(path).simulate(), fccgen.load_numeric(path).simulate()


def test_a_driven_arm_latched_rigid_turns_on_its_motor_against_gravity(driven_latch):
    """A driven link (2 rad/s) carries a second link on a free hinge, which falls back
    and latches at -0.2 rad. After it the two turn as one rigid body at constant rate
    about O: the motor torque is minus gravity's moment, 9.81 sum m_i x_Gi, and the
    latched hinge carries link 2: F = m2 (a_G2 - g) with a_G2 = -w^2 r_G2 (centripetal),
    T = (r_G2 - A) x F about its point. 1e-9 of the values (about 20 to 35): the
    motion's own drift (RK4 at 1 ms with projection)."""
    for r in driven_latch:
        (latch,) = r.events
        after = r.t > latch["t"]
        assert after.sum() >= 10
        masses = {"link1": 1.0, "link2": 2.0}
        tau = G * sum(m * centre(r, b)[:, 0] for b, m in masses.items())
        assert np.abs(r["motor.torque"][after] - tau[after]).max() < 1e-9 * np.abs(tau).max()
        g2 = centre(r, "link2")
        force = 2.0 * (-4.0 * g2 + [0.0, G, 0.0])
        hinge = 2.0 * centre(r, "link1")         # A: link 1's far end, G1 its middle
        torque = np.cross(g2 - hinge, force)
        assert np.abs(vec(r, "A", "f")[after] - force[after]).max() < 1e-9 * 20
        assert np.abs(vec(r, "A", "t")[after] - torque[after]).max() < 1e-9 * 20
        assert r.info["reactions"]["unique"]


def test_compiled_and_numpy_reactions_agree_through_a_lock(driven_latch):
    """The two versions hold the latch with their own joint-quantity kernels; their
    runs differ by the event times' location (2e-13 s), so 1e-10 of the values."""
    compiled, numeric = driven_latch
    cols = [c for c in compiled.columns if c.startswith(("O.", "A.")) and
            c.split(".")[1] in ("fx", "fy", "fz", "tx", "ty", "tz")] + ["motor.torque"]
    for c in cols:
        scale = max(np.abs(compiled[c]).max(), 1.0)
        assert np.abs(compiled[c] - numeric[c]).max() < 1e-10 * scale, c


def slider(events: str) -> str:
    """A block on a frictionless rail at 30 degrees (tests/test_reactions.py)."""
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    axis, normal = np.array([c, 0, -s]), np.array([s, 0, c])
    centre_ = 0.1 * axis + 0.05 * normal
    return ("name: held_slider\ngravity: [0, 0, -9.81]\nbodies:\n"
            f"  block: {{mass: 3.0, center: {centre_.tolist()}, inertia: [0.01, 0.02, 0.03],"
            f"\n          frame: {{x: {axis.tolist()}, y: [0, 1, 0]}}}}\n"
            "joints:\n  - {name: S, type: prismatic, bodies: [ground, block], "
            f"at: [0, 0, 0], axis: {axis.tolist()}}}\n" + events)


def test_a_slider_locked_then_unlocked_on_its_rail(tmp_path):
    """The block slides, locks at 1 cm (a plastic stop: at rest, the rail holds all of
    its weight, F = (0, 0, m g), and the moment (r_G - p) x F), and slides on from rest
    after the unlock at 0.3 s (the rail's normal force m g cos 30 deg alone again).
    1e-9: rounding and the RK4 drift, as in tests/test_reactions.py."""
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    normal = np.array([s, 0, c])
    text = slider("events:\n"
                  "  - {name: stop, when: \"S.position >= 0.01\", do: lock, joint: S}\n"
                  "  - {name: go, when: \"t >= 0.3\", do: unlock, joint: S}\n")
    r = fccgen.load(write(tmp_path, text)).simulate(t_end=0.5, dt=1e-3, output_dt=0.01)
    lock, unlock = r.events
    assert (lock["action"], unlock["action"]) == ("lock", "unlock")
    p = np.column_stack([r[f"S_b.{k}"] for k in "xyz"])
    arm = centre(r, "block") - p
    held = (r.t > lock["t"]) & (r.t < unlock["t"])
    sliding = (r.t < lock["t"]) | (r.t > unlock["t"])
    weight = np.tile([0.0, 0.0, 3.0 * G], (len(r.t), 1))
    normal_force = np.tile(3.0 * G * c * normal, (len(r.t), 1))
    assert held.sum() >= 20 and sliding.sum() >= 20
    assert np.abs(vec(r, "S", "f")[held] - weight[held]).max() < 1e-9
    assert np.abs(vec(r, "S", "t")[held] - np.cross(arm, weight)[held]).max() < 1e-9
    assert np.abs(vec(r, "S", "f")[sliding] - normal_force[sliding]).max() < 1e-9
    assert np.abs(vec(r, "S", "t")[sliding]
                  - np.cross(arm, normal_force)[sliding]).max() < 1e-9


def test_held_segments_follow_the_event_table(tmp_path):
    """Locks and rests hold their joint's quantities from their event on (a record at
    the event's time shows the state after it), unlocks and releases let them go,
    bounces and logs hold nothing; a cylindrical joint holds its angle and slide."""
    text = slider("events:\n"
                  "  - {name: stop, when: \"S.position >= 0.01\", do: lock, joint: S}\n"
                  "  - {name: go, when: \"t >= 0.3\", do: unlock, joint: S}\n")
    model = plan_model(write(tmp_path, text)).model
    t = np.arange(10.0)
    rows = [{"t": 2.5, "name": "stop", "action": "lock"},
            {"t": 4.0, "name": "go", "action": "unlock"},
            {"t": 5.0, "name": "stop", "action": "rest"},
            {"t": 6.5, "name": "stop", "action": "bounce"},
            {"t": 7.0, "name": "stop", "action": "release"}]
    got = [(s.start, s.stop, sorted(s.keys)) for s in held_segments(model, t, rows)]
    held = [("S", "position")]
    assert got == [(0, 3, []), (3, 4, held), (4, 5, []), (5, 7, held), (7, 10, [])]
    assert [joint_kinds(k) for k in ("revolute", "prismatic", "cylindrical")] == [
        ("angle",), ("position",), ("angle", "position")]


def test_a_full_event_log_leaves_the_unknown_records_without_forces(tmp_path):
    """A run whose event log dropped events (its rows full) does not know what its
    locks held after the last logged event: its reactions and driver forces are NaN
    from there on, with a warning each, never computed as if nothing were held; the
    records before keep theirs."""
    from fccgen.errors import RunWarning
    from fccgen.mechanism.driver_forces import add_driver_columns
    from fccgen.mechanism.reactions import add_reactions
    from fccgen.runs.held_rows import of_run
    solver = fccgen.load(write(tmp_path, DRIVEN_LATCH))
    full = solver.simulate()
    result = solver.simulate(reactions=False)
    (latch,) = result.events
    rows = solver._held_quantities(solver._event_set(1e-12, 1e-6))
    held = of_run(solver, result, rows, dropped=1)
    known = int(np.searchsorted(result.t, latch["t"]))
    assert held.known == known and 0 < known < len(result.t)
    with pytest.warns(RunWarning, match="driver forces are NaN"):
        add_driver_columns(solver, result, held)
    with pytest.warns(RunWarning, match="joint reactions are NaN .* event log is full"):
        add_reactions(solver, result, held)
    for c in ("motor.torque", "A.tz", "O.fx"):
        assert np.array_equal(result[c][:known], full[c][:known]), c
        assert np.isnan(result[c][known:]).all(), c
    assert result.info["reactions"]["unknown_from"] == result.t[known]
