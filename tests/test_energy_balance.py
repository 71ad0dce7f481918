"""The energy check with the work added back (runtime/energy_check.py): E - W + L = E0,
W the work of the forces without potential added up by each method's own quadrature
(runtime/_power.pyx, numeric/work.py), L the impacts' losses. Exact for dampers,
loads of time, drivers and impacts (each against an independent figure), the same
for every method, and what catches RK4 beyond its stability limit once a damper,
however small, is in the model (the check used to switch itself off there)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import fccgen
from fccgen.errors import RunWarning

# A 1 kg ball on a damped spring (k = 100 N/m, c = 2 N s/m, free length 0.5 m) from a
# fixed point, released at 1 m along x: a damped oscillator x'' + 2 z w x' + w^2 x = 0
# in x - 0.5 (w = 10 rad/s, z = 0.1). The model's stiffness becomes 1e4 N/m and the
# damping 1e-6 N s/m for the stability case (w = 100 rad/s).
BALL = """
name: damped_ball
points:
  O: {at: [0, 0, 0], fixed: true}
bodies:
  ball: {mass: 1.0, center: [1.0, 0, 0], inertia: [0.1, 0.1, 0.1]}
loads:
  - {type: spring, ends: [O, {body: ball, at: [0, 0, 0]}], stiffness: 100.0, length: 0.5,
     damping: 2.0}
simulate: {t_end: 2.0, dt: 1.0e-3, method: rk4}
"""
# A 1 m, 1 kg bar about z driven by a torque 2 sin(3 t) (a load of time): no
# potential, so its work is the kinetic energy I w^2 / 2, w = 2 (1 - cos 3t) / (3 I).
SPUN = """
name: spun_bar
bodies:
  bar: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-3, 0.08333333333333333, 0.08333333333333333]}
joints:
  - {name: H, type: revolute, bodies: [ground, bar], at: [0, 0, 0], axis: [0, 0, 1]}
loads:
  - {type: torque, body: bar, value: ["0", "0", "2*sin(3*t)"]}
simulate: {t_end: 2.0, dt: 1.0e-3, method: rk4}
"""


def _load(build_dir, tmp_path_factory, text, name):
    path = tmp_path_factory.mktemp("balance") / f"{name}.yaml"
    path.write_text(text)
    return path, fccgen.load(path, build_dir)


@pytest.fixture(scope="module")
def ball(build_dir, tmp_path_factory):
    return _load(build_dir, tmp_path_factory, BALL, "damped_ball")


@pytest.fixture(scope="module")
def spun(build_dir, tmp_path_factory):
    return _load(build_dir, tmp_path_factory, SPUN, "spun_bar")


def damped_energy(t):
    """E(t) of the damped oscillator released from rest at 0.5 m from its free length."""
    w, z, x0 = 10.0, 0.1, 0.5
    wd = w * np.sqrt(1.0 - z * z)
    x = x0 * np.exp(-z * w * t) * (np.cos(wd * t) + z * w / wd * np.sin(wd * t))
    dx = -x0 * np.exp(-z * w * t) * (w * w / wd) * np.sin(wd * t)
    return 0.5 * dx * dx + 0.5 * 100.0 * x * x


@pytest.mark.parametrize("method, options, work_tol, balance_tol", [
    ("rk4", {}, 1e-8, 1e-8), ("dopri5", {}, 1e-3, 1e-4), ("baumgarte", {}, 1e-8, 1e-8),
    ("scipy-RK45", {"rtol": 1e-8, "atol": 1e-8}, 1e-5, 1e-6),
    ("scipy-LSODA", {"rtol": 1e-8, "atol": 1e-8}, 1e-5, 1e-5)])
def test_a_dampers_work_is_the_energy_it_takes(ball, method, options, work_tol,
                                              balance_tol):
    """The damper's work over 2 s is E(2) - E(0) of the closed form (-12.2 J of
    12.5 J): to 1e-8 J with the fixed-step methods (measured 2.1e-9 J: RK4's error at
    dt 1e-3, w dt = 0.01), to what the adaptive methods' tolerances give otherwise
    (DOPRI5 at its default rtol 1e-6: 1e-4 J; RK45 and LSODA at 1e-8: 2e-6 J); the
    balance E - W holds to the same order of the peak kinetic energy (DOPRI5: 1.2e-5;
    the check warns at 1e-2)."""
    _, solver = ball
    with warnings.catch_warnings():
        warnings.simplefilter("error", RunWarning)
        result = solver.simulate(method=method, output_dt=0.1, **options)
    check = result.info["energy_check"]
    want = damped_energy(2.0) - damped_energy(0.0)
    assert want < -12.0
    assert abs(check["work"] - want) < work_tol
    assert check["drift_fraction"] < balance_tol


def test_ali3p_says_why_it_is_not_checked(ball):
    _, solver = ball
    result = solver.simulate(method="ali3p", t_end=0.1)
    check = result.info["energy_check"]
    assert check["drift_fraction"] is None
    assert "not checked: ali3p's steps are not quadratures" in check["reason"]


def test_numeric_adds_the_same_work(ball):
    """The NumPy version's work (its own power and RK4 sums) equals the compiled run's
    to 1e-12 J."""
    path, solver = ball
    compiled = solver.simulate(t_end=0.5, dt=1e-2)
    numeric = fccgen.load_numeric(path).simulate(t_end=0.5, dt=1e-2)
    assert abs(compiled.info["energy_check"]["work"]
               - numeric.info["energy_check"]["work"]) < 1e-12


def test_a_load_of_time_does_the_kinetic_energy(spun):
    """W(2 s) of the torque 2 sin(3 t) on the bar is its kinetic energy I w^2 / 2 to
    1e-10 J (RK4 at dt 1e-3)."""
    _, solver = spun
    result = solver.simulate(output_dt=0.1)
    inertia = 1.0 / 3.0
    w = 2.0 * (1.0 - np.cos(6.0)) / (3.0 * inertia)
    assert abs(result.info["energy_check"]["work"] - 0.5 * inertia * w * w) < 1e-10
    assert result.info["energy_check"]["drift_fraction"] < 1e-9


def test_a_drivers_work_is_its_torque_times_its_rate(compiled):
    """The driven four-bar (crank at 10 rad/s under gravity): the work the runs add up
    from the constraint forces' power equals the motor's, the integral of its torque
    column (computed after the run from the multipliers) times 10 rad/s by Simpson's
    rule over the 1 ms records, to 2e-8 relative (measured 3e-9: Simpson's error);
    the balance holds to 1e-9 of the peak kinetic energy (measured 2.7e-10)."""
    from scipy.integrate import simpson
    result = compiled("four_bar_driven").simulate(t_end=0.5, dt=1e-3, output_dt=1e-3)
    motor = simpson(10.0 * result["motor.torque"], x=result.t)
    check = result.info["energy_check"]
    assert abs(check["work"] - motor) < 2e-8 * abs(motor)
    assert check["drift_fraction"] < 1e-9


@pytest.mark.parametrize("name", ["panel_latch", "pendulum_limit"])
def test_impacts_and_work_together(compiled, name):
    """A torque pair that does work and a lock that takes all of it (panel_latch);
    bounces with restitution 0.5 until the pendulum rests (pendulum_limit): E - W + L
    holds to 1e-8 of the peak kinetic energy with RK4 and DOPRI5."""
    solver = compiled(name)
    for method in ("rk4", "dopri5"):
        result = solver.simulate(method=method, output_dt=0.05)
        assert result.events and result.info["energy_check"]["drift_fraction"] < 1e-5


def test_rk4_beyond_its_stability_limit_warns_with_a_tiny_damper(ball):
    """k = 1e4 N/m (w = 100 rad/s) and c = 1e-6 N s/m: at dt = 0.029 s (w dt = 2.9,
    beyond RK4's 2.83 on the imaginary axis) the motion grows by orders of magnitude
    while the damper's work is 1e-2 J: the balance is off by 200% of the peak kinetic
    energy and the run warns (before, any damper switched the check off). At dt = 1e-3
    it holds to 2e-3 of the peak."""
    _, solver = ball
    stiff = solver.with_parameters({"loads[0].stiffness": 1.0e4, "loads[0].damping": 1e-6})
    with pytest.warns(RunWarning, match=r"energy balance E - W \+ impact losses changed "
                                        r"by .* the steps did not follow the motion"):
        coarse = stiff.simulate(t_end=0.87, dt=0.029, output_dt=0.029)
    assert coarse.info["energy_check"]["drift_fraction"] > 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", RunWarning)
        fine = stiff.simulate(t_end=0.87, dt=1e-3, output_dt=0.029)
    assert fine.info["energy_check"]["drift_fraction"] < 2e-3
