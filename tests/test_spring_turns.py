"""Torsion springs and loads of joint angles past half a turn (issue: a spring whose
deflection came from atan2 reversed its torque half a turn from its free angle).

The kernels count turns: their angle is th + atan2(...) with th the joint angle of the
last accepted state, which the runtime copies from the event kernels' angle references
(compiled) or keeps per element (NumPy). Checked against independent references: a
single bar on a preloaded hinge spring under gravity in minimal coordinates
(theta'' I = -k (theta - theta_f) + m g c cos theta, SciPy's DOP853 at 1e-12), and the
closed form of a bar between two angle-linear torques swinging over more than a turn.
"""
from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import fccgen
from fccgen.errors import RunWarning

# A 1 m, 1 kg bar on a hinge about y in a vertical plane, its spring relaxed at 3.0 rad
# (preloaded: it pushes the bar up and over), thrown backwards at 5 rad/s: it swings
# back to -0.38 rad, 3.38 rad from the free angle, past half a turn.
BAR = """
name: turn_bar
gravity: [0, 0, -9.81]
bodies:
  bar: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-3, 0.08333333333333333, 0.08333333333333333]}
joints:
  - {name: H, type: revolute, bodies: [ground, bar], at: [0, 0, 0], axis: [0, 1, 0]}
loads:
  - {type: torsion_spring, joint: H, stiffness: 2.0, angle: 3.0}
initial:
  joints: {H: {rate: -5.0}}
simulate: {t_end: 2.0, dt: 1.0e-3, method: rk4}
"""
K, FREE, RATE0, MGC, INERTIA = 2.0, 3.0, -5.0, 9.81 * 0.5, 1.0 / 3.0

# The same bar without gravity between a spring relaxed at 4.5 rad (beyond pi) and a
# load torque -(theta - 1) written as an expression of H.angle about z: theta'' I =
# -(3 theta - 10), so theta = 10/3 (1 - cos w t), w^2 = 3 / I, swinging from 0 to
# 6.67 rad, more than a turn.
OVER = """
name: turn_over
bodies:
  bar: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-3, 0.08333333333333333, 0.08333333333333333]}
joints:
  - {name: H, type: revolute, bodies: [ground, bar], at: [0, 0, 0], axis: [0, 0, 1]}
loads:
  - {type: torsion_spring, joint: H, stiffness: 2.0, angle: 4.5}
  - {type: torque, body: bar, value: ["0", "0", "-(H.angle - 1.0)"]}
simulate: {t_end: 2.0, dt: 1.0e-3, method: rk4}
"""


@pytest.fixture(scope="module")
def bar(build_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("turns") / "turn_bar.yaml"
    path.write_text(BAR)
    return path, fccgen.load(path, build_dir)


@pytest.fixture(scope="module")
def over(build_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("turns") / "turn_over.yaml"
    path.write_text(OVER)
    return path, fccgen.load(path, build_dir)


def bar_reference(t):
    """theta(t) of the bar in minimal coordinates (its own equation, SciPy)."""
    def rhs(_, y):
        return [y[1], (-K * (y[0] - FREE) + MGC * np.cos(y[0])) / INERTIA]
    sol = solve_ivp(rhs, (0.0, t[-1]), [0.0, RATE0], method="DOP853", t_eval=t,
                    rtol=1e-12, atol=1e-12)
    return sol.y[0]


@pytest.mark.parametrize("method, tol", [("rk4", 1e-7), ("dopri5", 1e-5)])
def test_a_preloaded_spring_swung_back_past_half_a_turn(bar, method, tol):
    """The bar swings back to -0.38 rad, 3.38 rad from the spring's free angle. Before,
    the spring's torque reversed there and the bar ended 8 rad off; now the angle
    follows the minimal-coordinate reference to 2e-10 rad (RK4, dt 1e-3: its own
    error; tol 1e-7) and 6e-6 rad (DOPRI5 at its default rtol 1e-6; tol 1e-5), and the
    energy holds (the potential k phi^2 / 2 is the unwrapped one)."""
    _, solver = bar
    with warnings.catch_warnings():
        warnings.simplefilter("error", RunWarning)
        result = solver.simulate(output_dt=0.05, method=method)
    angle = result["H.angle"]
    assert angle.min() < FREE - np.pi - 0.2            # it did go past half a turn
    assert np.max(np.abs(angle - bar_reference(result.t))) < tol
    assert result.info["energy_check"]["drift_fraction"] < 1e-3


def test_numeric_counts_turns_as_the_compiled_run(bar):
    """The NumPy version keeps its own references (per element, from its own angle):
    the same RK4 steps as the compiled run to 1e-11 rad."""
    path, solver = bar
    compiled = solver.simulate(t_end=1.0, dt=1e-2, method="rk4")
    numeric = fccgen.load_numeric(path).simulate(t_end=1.0, dt=1e-2, method="rk4")
    assert compiled["H.angle"].min() < FREE - np.pi
    assert np.max(np.abs(compiled["H.angle"] - numeric["H.angle"])) < 1e-11


def test_free_angles_and_load_angles_beyond_a_turn(over):
    """A spring relaxed at 4.5 rad (refused before: free angles had to lie within
    (-pi, pi)) and a load reading H.angle take the bar over 6.67 rad: the closed form
    to 1e-8 rad (RK4, dt 1e-3, w = 3 rad/s: its error is 1e-10), with SciPy's DOP853
    and with the NumPy version."""
    path, solver = over
    result = solver.simulate(output_dt=0.05)
    w = np.sqrt(3.0 / INERTIA)
    exact = 10.0 / 3.0 * (1.0 - np.cos(w * result.t))
    assert result["H.angle"].max() > 2 * np.pi
    assert np.max(np.abs(result["H.angle"] - exact)) < 1e-8
    # SciPy's DOP853 re-bases after each of its steps too (from the start's angle 0,
    # 4.5 rad from the spring's free angle): to 1e-7 at rtol = atol = 1e-10
    scipy = solver.simulate(method="scipy-DOP853", rtol=1e-10, atol=1e-10, output_dt=0.05)
    assert np.max(np.abs(scipy["H.angle"] - exact)) < 1e-7
    numeric = fccgen.load_numeric(path).simulate(t_end=1.0, dt=1e-2, method="rk4")
    assert np.max(np.abs(numeric["H.angle"] - 10.0 / 3.0 * (
        1.0 - np.cos(w * numeric.t)))) < 1e-5                    # RK4 at dt 1e-2


def test_kernels_called_alone_measure_from_the_free_angle(over):
    """Outside a run the reference is the spring's free angle (the deflection within
    half a turn of it) and the load's 0; a run leaves them so."""
    _, solver = over
    solver.simulate(t_end=0.5)
    el = next(e for e in solver.plan.elements if e.cls.kind == "torsion_spring")
    names = el.cls.param_names
    th = el.params[names.index("th")]
    assert th == 4.5
    init = solver.initial_state()
    f = solver.applied_forces(init.q, init.v)
    numeric = fccgen.load_numeric(over[0])
    assert np.max(np.abs(f - numeric.applied_forces(init.q, init.v))) < 1e-12


def test_ali3p_which_does_not_count_turns_warns(bar):
    """ali3p measures the spring's angle within half a turn of its free angle: past it
    the run warns, with the angle and the time, and names the methods that count.
    Its reactions, which count the turns along the records, then disagree with the
    run's spring: they warn that they do not balance the bodies."""
    _, solver = bar
    with pytest.warns(RunWarning) as caught:
        solver.simulate(t_end=1.0, dt=1e-3, method="ali3p")
    said = [str(w.message) for w in caught]
    assert any(re.search(r"H.angle = .* within half a turn of 3 rad", w) for w in said)
    assert any("joint reactions leave an imbalance" in w for w in said), said


def test_a_step_that_turns_a_joint_too_far_warns(bar):
    """Counting turns needs less than half a turn per step: of two RK4 steps of 0.25 s
    the second turns the bar 2.1 rad, more than the quarter turn a run accepts without
    a word (without projection, which would stop such a step for its constraint
    error; the run also reports its constraint drift and its energy)."""
    _, solver = bar
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", RunWarning)
        solver.simulate(t_end=0.5, dt=0.25, output_dt=0.25, method="rk4", project=False)
    said = [str(w.message) for w in seen]
    assert any(re.search(r"H.angle turned 2.1\d rad within one step", m) for m in said)
