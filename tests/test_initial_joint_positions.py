"""Initial joint angles and slide positions (``initial: joints: {A: {angle: a}}``,
``{S: {position: x}}``): the mechanism is assembled at them, the loops closed with the
smallest change elsewhere; values it cannot take are an error."""
from __future__ import annotations

import numpy as np
import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.errors import ModelError
from test_joints import write
from test_reactions import FOUR_BAR, pendulum

RATE = "joints: {O: {rate: 2.0}}"


def four_bar(tmp_path, joints: str, name="fa"):
    text = FOUR_BAR.replace(RATE, joints).replace("name: rx_four_bar", f"name: {name}")
    return write(tmp_path, text, f"{name}.yaml")


def loop_closure(theta: float) -> np.ndarray:
    """The coupler-rocker pin B of the four-bar (ground pins O = 0, C = (1, 0); crank
    0.5 m starting at atan2(0.4, 0.3); coupler |AB| and rocker |CB| as written) with
    the crank turned by theta: B on both circles, on the branch of the written
    configuration (left of A -> C)."""
    phi = np.arctan2(0.4, 0.3) + theta
    a_pin = 0.5 * np.array([np.cos(phi), np.sin(phi)])
    coupler, rocker = np.hypot(0.9, 0.4), np.hypot(0.2, 0.8)
    d_vec = np.array([1.0, 0.0]) - a_pin
    d = np.linalg.norm(d_vec)
    along = (coupler ** 2 - rocker ** 2 + d ** 2) / (2 * d)
    e = d_vec / d
    return a_pin + along * e + np.sqrt(coupler ** 2 - along ** 2) * np.array([-e[1], e[0]])


@pytest.mark.parametrize("theta", [0.9, -2.5, 4.0])
def test_four_bar_assembled_at_a_crank_angle_matches_the_loop_closure(tmp_path, theta):
    """B against the closed form to 1e-12 m (Newton to rounding; measured 1e-16), the
    crank angle column starts at theta, and the crank rate given with it is kept."""
    solver = fccgen.load_numeric(four_bar(tmp_path, f"joints: {{O: {{angle: {theta}, "
                                                    "rate: 2.0}}"))
    init = solver.initial_state()
    r = solver.simulate(t_end=0.002, dt=1e-3, q0=init.q, v0=init.v)
    b = np.array([r["B.x"][0], r["B.y"][0]])
    assert np.abs(b - loop_closure(theta)).max() < 1e-12
    assert r["O.angle"][0] == pytest.approx(theta, abs=1e-12)
    assert r["O.rate"][0] == pytest.approx(2.0, abs=1e-12)
    assert np.abs(solver.constraints(init.q)).max() < 1e-12


def test_a_hinge_turned_by_more_than_a_turn(tmp_path):
    """A hinged body turned by 7 rad about y: its mass centre is the written one turned
    by 7 rad (to 1e-12 m), and the angle column starts at 7, not at 7 - 2 pi."""
    text = pendulum() + "initial:\n  joints: {A: {angle: 7.0}}\n"
    solver = fccgen.load_numeric(write(tmp_path, text))
    r = solver.simulate(t_end=0.001, dt=1e-3)
    written = fccgen.load_numeric(write(tmp_path, pendulum(), "w.yaml")).simulate(
        t_end=0.001, dt=1e-3)
    c0 = np.array([written[f"bar.c{k}"][0] for k in "xyz"])
    c, s = np.cos(7.0), np.sin(7.0)
    turned = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ c0
    assert np.abs(np.array([r[f"bar.c{k}"][0] for k in "xyz"]) - turned).max() < 1e-12
    assert r["A.angle"][0] == pytest.approx(7.0, abs=1e-12)


def test_slider_crank_assembled_at_a_slide_position(tmp_path):
    """The spatial slider-crank with its slider moved 0.05 m: S.position starts there,
    every constraint holds (1e-12) and the crank has turned to close the loop."""
    text = (EXAMPLES / "rsup.yaml").read_text().replace(
        "  joints: {A: {rate: 6.0}}",
        "  joints: {S: {position: 0.05}}")
    solver = fccgen.load_numeric(write(tmp_path, text, "rsup_at.yaml"))
    init = solver.initial_state()
    r = solver.simulate(t_end=0.001, dt=1e-3, q0=init.q, v0=init.v)
    assert r["S.position"][0] == pytest.approx(0.05, abs=1e-12)
    assert np.abs(solver.constraints(init.q)).max() < 1e-12
    assert abs(r["A.angle"][0]) > 0.05


@pytest.mark.parametrize("joints, why", [
    ("{C: {angle: 2.5}}", "C.angle = "),                      # beyond the rocker's swing
    ("{O: {angle: 0.5}, C: {angle: 0.5}}", "O.angle = "),     # two on one freedom
])
def test_joint_values_the_mechanism_cannot_take_are_an_error(tmp_path, joints, why):
    path = four_bar(tmp_path, f"joints: {joints}", name="fa_bad")
    with pytest.raises(ModelError, match=r"fa_bad\.yaml:\d+: initial\.joints: the "
                                         r"mechanism cannot be assembled at these joint "
                                         rf"values.*it assembles up to {why}"):
        fccgen.load_numeric(path).initial_state()


@pytest.mark.parametrize("initial, item, rule", [
    ("{S: {angle: 0.1}}", "initial.joints.S.angle",
     "a prismatic joint has no angle; angle is for revolute and cylindrical joints"),
    ("{A: {position: 0.1}}", "initial.joints.A.position", "a revolute joint has no position"),
    ("{A: {angle: 0.1, position: 0.2}}", "initial.joints.A", "must give exactly one of angle"),
    ("{A: {angle: wide}}", "initial.joints.A.angle", "must be a number"),
])
def test_bad_initial_joint_positions(tmp_path, initial, item, rule):
    text = (EXAMPLES / "rsup.yaml").read_text().replace(
        "  joints: {A: {rate: 6.0}}", f"  joints: {initial}")
    with pytest.raises(ModelError) as info:
        fccgen.load_numeric(write(tmp_path, text, "rsup_bad.yaml"))
    assert "rsup_bad.yaml:" in str(info.value) and f"{item}: {rule}" in str(info.value)


def test_a_far_angle_is_reached_the_short_way(tmp_path):
    """1e6 rad is 10 million steps of 0.1 rad the long way round (the walk once went
    on without bound); whole turns give the same configuration, so the walk takes the
    short way: the mass centre is the written one turned by 1e6 rad, to 1e-9 m (the
    double 1e6 reduced by whole turns keeps ~1e-10 rad)."""
    text = pendulum() + "initial:\n  joints: {A: {angle: 1.0e6}}\n"
    r = fccgen.load_numeric(write(tmp_path, text)).simulate(t_end=0.001, dt=1e-3)
    written = fccgen.load_numeric(write(tmp_path, pendulum(), "w.yaml")).simulate(
        t_end=0.001, dt=1e-3)
    c0 = np.array([written[f"bar.c{k}"][0] for k in "xyz"])
    c, s = np.cos(1.0e6), np.sin(1.0e6)
    turned = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ c0
    assert np.abs(np.array([r[f"bar.c{k}"][0] for k in "xyz"]) - turned).max() < 1e-9
