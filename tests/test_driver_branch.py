"""A driver whose f(0) is far from the written angle starts on f(0), not on f - pi.

An angle driver's row sin(theta - f) holds on two branches; the first projection from
the written angle met the nearer one, so a driver with f(0) = 2.5 rad and the joint
written at 0 ran the whole simulation at f - pi (the audit: ``H.angle`` followed
f - pi). The assembly now continues from the written configuration to f(0), and a run
whose joint is on the other branch anyway (its own q0) warns.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.errors import RunWarning

# A 1 m, 1 kg arm about y driven at f = 2.5 + 2 t from its written angle 0 (it is
# assembled 143 degrees away, upside down). The motor holds it against gravity
# (theta'' = 0): its torque on the arm is -m g c cos(theta) (c = 0.5 m; a turn about
# +y takes the arm's +x towards -z, gravity's torque about +y is m g c cos theta).
DRIVEN = """
name: far_driver
gravity: [0, 0, -9.81]
bodies:
  arm: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-4, 0.08, 0.08]}
joints:
  - {name: H, type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 1, 0]}
drivers:
  - {name: motor, joint: H, angle: "2.5 + 2*t"}
simulate: {t_end: 1.0, dt: 1.0e-3, method: rk4}
"""


@pytest.fixture(scope="module")
def driven(build_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("driver") / "far_driver.yaml"
    path.write_text(DRIVEN)
    return path, fccgen.load(path, build_dir)


def test_a_far_driver_starts_on_its_angle(driven):
    """The angle follows f(t) (not f - pi) in the compiled and the NumPy version, to
    1e-9 rad (the projection's tolerance), and the motor's torque is the one that
    holds the arm at that angle, -m g c cos f(t), to 1e-6 N m (RK4's error in the
    recorded accelerations' solve, measured 1e-10)."""
    path, solver = driven
    with warnings.catch_warnings():
        warnings.simplefilter("error", RunWarning)
        result = solver.simulate(output_dt=0.1)
        numeric = fccgen.load_numeric(path).simulate(t_end=0.2, dt=1e-2, output_dt=0.1)
    f = 2.5 + 2.0 * result.t
    assert np.max(np.abs(result["H.angle"] - f)) < 1e-9
    assert np.max(np.abs(result["motor.torque"] + 9.81 * 0.5 * np.cos(f))) < 1e-6
    assert np.max(np.abs(numeric["H.angle"] - (2.5 + 2.0 * numeric.t))) < 1e-9


def test_a_run_on_the_other_branch_warns(driven):
    """Started by hand at the arm turned half a turn (the driver's row holds there
    too), the run follows f + pi, and says so with the time and both angles."""
    _, solver = driven
    init = solver.initial_state()
    q = init.q.copy()
    q[:3] *= -1.0                                    # the arm's far end through H
    q, _ = solver.project_positions(q)
    v = solver.project_velocities(q, init.v)
    with pytest.warns(RunWarning, match=r"driver 'motor': the joint H is at -0.64159.* "
                                        r"at t = 0, but the driver prescribes 2.5"):
        result = solver.simulate(t_end=0.1, output_dt=0.1, q0=q, v0=v)
    assert abs(result["H.angle"][0] - (2.5 - np.pi)) < 1e-9


def test_a_closed_loop_driven_from_far_keeps_its_assembly(build_dir, tmp_path):
    """The driven four-bar of the examples with its crank's driver started 2 rad past
    the written crank angle: assembled by continuation from the written configuration,
    the crank follows f(t) to 1e-9 rad and the loop stays closed."""
    text = (EXAMPLES / "four_bar_driven.yaml").read_text()
    assert 'angle: "10*t"' in text
    path = tmp_path / "four_bar_far.yaml"
    path.write_text(text.replace('angle: "10*t"', 'angle: "2.0 + 10*t"'))
    result = fccgen.load(path, build_dir).simulate(t_end=0.2, output_dt=0.05)
    assert np.max(np.abs(result["O.angle"] - (2.0 + 10.0 * result.t))) < 1e-9
    assert result.info["max_constraint_error"] < 1e-9
