"""Joint reactions of driven models (fccgen.mechanism.reactions): a driver's torque
(force) joins its joint's reaction, joint springs and point drivers act on their
bodies. Checked against the drivers' own columns (minimum-norm multipliers, an
independent computation) and, on the driven four-bar, against the total momentum rate
from minimal coordinates."""
from __future__ import annotations

import numpy as np
import pytest
import sympy

import fccgen
from fccgen.errors import ModelError
from fccgen.mechanism.reactions import reactions
from test_drivers import G, MASS, OMEGA, THETA0, loop_closure
from test_joints import write


def centre_accelerations():
    """(crank, coupler, rocker) mass-centre accelerations as NumPy functions of the
    crank angle theta at the constant rate OMEGA: a = OMEGA^2 d2c/dtheta2, with the
    centres from the loop closure (B on the upper intersection of the circles about
    A and C), the geometry of tests/test_drivers.minimal_torque."""
    th, _, _, _, centres = loop_closure()
    return [sympy.lambdify(th, list(sympy.diff(c, th, 2) * OMEGA ** 2), "numpy")
            for c in centres]


def test_driven_four_bar_reactions(compiled):
    """examples/four_bar_driven.yaml: the ground joints O and C carry the whole
    mechanism, so F_O + F_C = sum m a_G - sum m g with a_G from minimal coordinates; the
    crank hinge O holds the motor, so O.tz equals motor.torque (from the multipliers).
    The states of a fully driven run are exact to rounding (the Newton projection to
    1e-11 of a length), so both hold to 1e-8 (N, N m; forces here reach ~20 N)."""
    r = compiled("four_bar_driven").simulate(t_end=0.3, dt=1e-3, output_dt=0.01)
    info = r.info["reactions"]
    assert info["computed"] and info["residual"] < 1e-9, info
    theta = THETA0 + OMEGA * r.t
    total = np.zeros((len(r.t), 3))
    for m, acc in zip(MASS, centre_accelerations()):
        ax, ay = acc(theta)
        total += m * np.column_stack([ax, ay + G, 0 * theta])      # m (a_G - g)
    ground = sum(np.column_stack([r[f"{j}.f{c}"] for c in "xyz"]) for j in "OC")
    assert np.max(np.abs(total)) > 5.0                  # not vacuous: the links move
    assert np.max(np.abs(ground - total)) <= 1e-8
    assert np.max(np.abs(r["motor.torque"])) > 0.5
    assert np.max(np.abs(r["O.tz"] - r["motor.torque"])) <= 1e-8


DRIVEN_SPRINGS = """\
name: rx_driven
gravity: [0, -9.81, 0]
points:
  O: [10, 0, 0]
  P: [11, 0, 0]
vectors:
  z: [0, 0, 1]
bodies:
  slider: {mass: 2.0, center: [0.5, 0, 0], inertia: [0.01, 0.02, 0.03]}
  arm: {points: [O, P], vector: z, mass: 2.0, center: [0.5, 0.1, 0],
        inertia: [0.01, 0.1, 0.1]}
  bar: {mass: 1.5, center: [0.3, 2, 0], inertia: [0.01, 0.05, 0.05]}
joints:
  - {name: S, type: prismatic, bodies: [ground, slider], at: [0.5, 0, 0], axis: [1, 0, 0]}
  - {name: H, type: revolute, bodies: [ground, arm], at: [10, 0, 0], axis: [0, 0, 1]}
  - {name: R, type: revolute, bodies: [ground, bar], at: [0, 2, 0], axis: [0, 0, 1]}
loads:
  - {type: linear_spring, joint: S, stiffness: 40, damping: 0.5, length: 0.05}
  - {type: torsion_spring, joint: R, stiffness: 3, damping: 0.2, angle: 0.3}
  - {type: torsion_spring, joint: H, stiffness: 2, damping: 0.1}
drivers:
  - {name: push, joint: S, position: "0.1*sin(2*t)"}
  - {name: motor, joint: R, angle: "0.5*sin(3*t)"}
  - {name: lift, point: P, direction: [0, 1, 0], value: "0.5*sin(t)"}
"""


def test_joint_springs_and_all_driver_kinds_in_the_balance(tmp_path):
    """A slider driven along a prismatic joint against a joint linear spring, a bar
    driven about a hinge against a joint torsion spring, an arm hinged to ground with a
    joint torsion spring and its tip driven along y (a point driver): every load and
    driver placed, the balance closes (residual at rounding, 1e-10) with a unique
    solution, and the driven joints' axial components equal the drivers' columns
    (computed from the multipliers) to 1e-9 (forces of a few N). Every body is driven,
    so the states come from the projections and do not depend on the step."""
    r = fccgen.load_numeric(write(tmp_path, DRIVEN_SPRINGS)).simulate(
        t_end=0.3, dt=1e-2, output_dt=0.05)
    info = r.info["reactions"]
    assert info["computed"] and info["unique"] and info["residual"] < 1e-10, info
    assert np.max(np.abs(r["push.force"])) > 1.0 and np.max(np.abs(r["motor.torque"])) > 1.0
    assert np.max(np.abs(r["S.fx"] - r["push.force"])) <= 1e-9
    assert np.max(np.abs(r["R.tz"] - r["motor.torque"])) <= 1e-9


def test_springs_left_out_break_the_balance(tmp_path):
    """Not a tautology: with the joint springs' loads removed from the balance the
    driven joints' reactions no longer match the drivers' columns."""
    import fccgen.mechanism.reactions as rx
    solver = fccgen.load_numeric(write(tmp_path, DRIVEN_SPRINGS))
    result = solver.simulate(t_end=0.1, dt=1e-2, output_dt=0.05, reactions=False)
    cols, _ = reactions(solver, result)
    keep = rx._linear
    try:
        rx._linear = lambda *args: None
        wrong, _ = reactions(solver, result)
    finally:
        rx._linear = keep
    assert np.max(np.abs(cols["S.fx"] - result["push.force"])) <= 1e-9
    assert np.max(np.abs(wrong["S.fx"] - result["push.force"])) > 0.1


def test_point_driver_on_a_shared_point_refuses_reactions(tmp_path):
    """A point driver on the ball joint between two moving bodies acts on both: its
    force cannot be given to one body, and the run says why it has no reactions."""
    text = ("name: rx_point\nbodies:\n"
            "  a: {mass: 1, center: [0.5, 0, 0], inertia: [0.01, 0.02, 0.03]}\n"
            "  b: {mass: 1, center: [1.5, 0, 0], inertia: [0.01, 0.02, 0.03]}\n"
            "joints:\n"
            "  - {name: A, type: spherical, bodies: [ground, a], at: [0, 0, 0]}\n"
            "  - {name: K, type: spherical, bodies: [a, b], at: [1, 0, 0]}\n"
            "drivers:\n"
            "  - {name: lift, point: K, direction: [0, 1, 0], value: '0.1*t'}\n")
    solver = fccgen.load_numeric(write(tmp_path, text))
    r = solver.simulate(t_end=0.01, dt=1e-3, output_dt=0.01)
    assert not r.info["reactions"]["computed"]
    assert "shared by a and b" in r.info["reactions"]["reason"]
    with pytest.raises(ModelError, match="driver lift"):
        reactions(solver, r)


WINCH = """\
name: rx_winch
gravity: [0, -9.81, 0]
bodies:
  bob: {mass: 2.0, center: [5, -1, 0], inertia: [0.01, 0.02, 0.03]}
joints:
  - {name: D, type: distance, bodies: [ground, bob], at: [[5, 0, 0], [5, -1, 0]]}
  - {name: V, type: prismatic, bodies: [ground, bob], at: [5, -1, 0], axis: [0, 1, 0]}
drivers:
  - {name: winch, joint: D, distance: "1 + 0.1*sin(2*t)"}
"""


def test_distance_driver_force_is_the_joint_reaction_along_the_line(tmp_path):
    """A bob hung from a winch (a driven distance joint) inside a vertical guide: the
    distance joint's reaction on the bob, along r_b - r_a (down), equals winch.force
    (positive pushing apart), and both equal -m (g + y'') with y = -(1 + 0.1 sin 2t)
    (the guide carries no vertical force): 1e-9 N."""
    r = fccgen.load_numeric(write(tmp_path, WINCH)).simulate(
        t_end=0.3, dt=1e-2, output_dt=0.05)
    assert r.info["reactions"]["computed"], r.info["reactions"]
    along = -r["D.fy"]                                  # the line points down (-y)
    want = -2.0 * (9.81 + 0.4 * np.sin(2 * r.t))
    assert np.max(np.abs(r["winch.force"] - want)) <= 1e-9
    assert np.max(np.abs(along - r["winch.force"])) <= 1e-9


WOUND = """\
name: wound_driver
bodies:
  arm: {mass: 1.0, center: [0.5, 0, 0], inertia: [0.001, 0.1, 0.1]}
joints:
  - {name: H, type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 0, 1]}
drivers:
  - {name: motor, joint: H, angle: "3*t"}
loads:
  - {type: torsion_spring, joint: H, stiffness: 2.0, angle: 0.0, damping: 0.0}
simulate: {t_end: 3.0, dt: 1.0e-3, output_dt: 0.25}
"""


@pytest.mark.parametrize("numeric", [False, True])
def test_a_motor_winding_a_spring_past_half_a_turn_holds_it(numeric, tmp_path):
    """A motor turns a hinge at a constant 3 rad/s against its torsion spring (2 N m
    per rad, relaxed at 0) to 9 rad: no gravity, no angular acceleration, so the motor
    holds the spring, k theta, and so does the hinge's reaction along its axis.
    Before, the driver forces took the springs' planned angle references: past pi the
    spring read theta - 2 pi and the motor torque came out -3.57 N m at 4.5 rad, not
    9 (the reactions counted the turns). 1e-10 N m: rounding of the balance."""
    path = write(tmp_path, WOUND)
    solver = fccgen.load_numeric(path) if numeric else fccgen.load(path)
    r = solver.simulate(t_end=1.5 if numeric else 3.0)     # NumPy: 4.5 rad, past pi
    assert r["H.angle"][-1] > 4.0
    spring = 2.0 * r["H.angle"]
    assert np.abs(r["motor.torque"] - spring).max() < 1e-10
    assert np.abs(r["H.tz"] - spring).max() < 1e-10
