"""Inverse dynamics along drivers (fccgen.analysis.inverse): the driven four-bar's
motor torque against minimal coordinates and against a forward run, the refusal of
models with freedoms left, and the command line."""
from __future__ import annotations

import numpy as np
import pytest

import fccgen
from conftest import EXAMPLES
from fccgen.analysis.inverse import output_times
from fccgen.cli import main
from fccgen.errors import ModelError, RunWarning
from fccgen.results.result import Result
from test_drivers import OMEGA, SLIDER, THETA0, minimal_torque
from test_joints import write

FOUR_BAR = EXAMPLES / "four_bar_driven.yaml"


@pytest.fixture(scope="module")
def inverse(compiled, build_dir):
    compiled("four_bar_driven")                  # built once for the session
    return fccgen.inverse_dynamics(FOUR_BAR, t_end=0.7, dt=0.01, build_dir=build_dir)


def test_four_bar_motor_torque_matches_minimal_coordinates(inverse):
    """The crank follows 10 t (positions from the Newton projection to 1e-11 at each
    row, no integration), so motor.torque from the multipliers matches
    tau = M'(theta) omega^2 / 2 + V'(theta) to 1e-8 N m (measured 1e-13; torques reach
    ~1 N m), and the crank hinge's axial reaction from the body balance holds the same
    torque."""
    r = inverse
    assert r.info["method"] == "inverse" and r.info["dof"] == 0
    assert len(r.t) == 71 and r.t[-1] == pytest.approx(0.7)
    assert np.max(np.abs(r["O.angle"] - OMEGA * r.t)) <= 1e-10
    tau = minimal_torque()(THETA0 + OMEGA * r.t)
    assert np.max(np.abs(tau)) > 0.5                   # not vacuous: the motor works
    assert np.max(np.abs(r["motor.torque"] - tau)) <= 1e-8
    assert np.max(np.abs(r["O.tz"] - tau)) <= 1e-8


def test_four_bar_inverse_equals_the_forward_run(inverse, compiled):
    """A forward RK4 run of the same model records the same states (a fully driven
    run's positions and speeds come from the projections, exact to rounding): motor
    torque and reactions agree to 1e-8 (N m, N)."""
    f = compiled("four_bar_driven").simulate(t_end=0.7, dt=1e-3, output_dt=0.01)
    assert np.max(np.abs(f.t - inverse.t)) <= 1e-12
    for name in ("motor.torque", "O.fx", "O.fy", "C.fx", "C.fy", "coupler.cx"):
        assert np.max(np.abs(f[name] - inverse[name])) <= 1e-8, name


def test_freedoms_left_are_refused(tmp_path):
    """The slider of tests/test_drivers.py without its driver keeps one freedom (its
    9 coordinates: two points and the axis)."""
    text = SLIDER.split("drivers:")[0] + "simulate: {t_end: 0.1}\n"
    rule = r"0 driver\(s\) rank B = 8 of 9 coordinates leaves 1 degree"
    with pytest.raises(ModelError, match=rule):
        fccgen.inverse_dynamics(write(tmp_path, text), numeric=True)


def test_driven_slider_force_is_mass_times_acceleration(tmp_path):
    """The slider pushed along x against gravity -9.81 x: x = 0.1 sin 2t, so the
    driver's force is m (x'' + 9.81) = 2 (-0.4 sin 2t + 9.81) (numeric version;
    1e-9 N: the projections are exact to rounding)."""
    r = fccgen.inverse_dynamics(write(tmp_path, SLIDER), t_end=0.5, dt=0.05, numeric=True)
    want = 2.0 * (-0.4 * np.sin(2 * r.t) + 9.81)
    assert np.max(np.abs(r["push.force"] - want)) <= 1e-9
    assert np.max(np.abs(r["S.fx"] - want)) <= 1e-9


def test_output_times_land_on_t_end():
    assert np.allclose(output_times(1.0, 0.25), [0, 0.25, 0.5, 0.75, 1.0])
    assert np.allclose(output_times(0.5, 0.2), [0, 0.2, 0.4, 0.5])
    with pytest.raises(ValueError, match="positive"):
        output_times(1.0, 0.0)


def test_command_line(tmp_path, build_dir, compiled, capsys):
    compiled("four_bar_driven")
    out = tmp_path / "inverse.npz"
    assert main(["inverse", str(FOUR_BAR), "--t-end", "0.1", "--dt", "0.05", "--out",
                 str(out), "--build-dir", str(build_dir), "-q"]) == 0
    text = capsys.readouterr().out
    assert "inverse dynamics, 3 rows" in text and "motor.torque: max" in text
    r = Result.load(out)
    assert len(r.t) == 3 and "O.tz" in r.names and "motor.torque" in r.names
    assert main(["inverse", str(EXAMPLES / "double_pendulum.yaml"), "--numeric",
                 "-q"]) == 2
    assert "degree(s) of freedom" in capsys.readouterr().err


def test_kinematic_rows_satisfy_the_constraints(inverse, compiled):
    """Every row of the run: g = 0, B q' = -g_t and B q'' + bias = 0 (the second time
    derivative of g along the motion) to 1e-10 (units of g per s^k; the projections
    stop at 1e-11 of a length, the acceleration solve is exact to rounding)."""
    solver = compiled("four_bar_driven")
    names = [name for name, _ in solver.plan.triples]
    q = np.column_stack([inverse[f"{n}.{c}"] for n in names for c in "xyz"])
    v = np.column_stack([inverse[f"{n}.v{c}"] for n in names for c in "xyz"])
    for t, qk, vk in zip(inverse.t, q, v):
        solver.set_time(float(t))
        B = solver.constraint_jacobian(qk)
        a = solver.accelerations(qk, vk)
        assert np.max(np.abs(solver.constraints(qk))) <= 1e-10
        assert np.max(np.abs(B @ vk + solver.constraint_rate(qk))) <= 1e-10
        assert np.max(np.abs(B @ a + solver.constraint_bias(qk, vk))) <= 1e-10
    assert np.max(np.abs(v)) > 0.5                     # not vacuous: it moves


def test_progress_reaches_the_end(compiled, monkeypatch):
    """With REPORT_EVERY = 0 every row reports; the last event is t_end (100%)."""
    import fccgen.analysis.inverse as inv
    monkeypatch.setattr(inv, "REPORT_EVERY", 0.0)
    events = []
    inv.solve_inverse(compiled("four_bar_driven"), t_end=0.05, dt=0.01,
                      progress=events.append)
    assert [e.stage for e in events] == ["inverse"] * len(events) and len(events) >= 6
    assert events[-1].done == pytest.approx(0.05) and "(100%)" in str(events[-1])


def test_numeric_and_compiled_inverse_agree(inverse, numeric):
    """The NumPy version's inverse dynamics of the four-bar over its first 0.1 s: the
    same rows to rounding (1e-10 N m, N)."""
    from fccgen.analysis.inverse import solve_inverse
    r = solve_inverse(numeric("four_bar_driven"), t_end=0.1, dt=0.01)
    assert len(r.t) == 11
    for name in ("motor.torque", "O.tz", "C.fx", "C.fy"):
        assert np.max(np.abs(r[name] - inverse[name][:11])) <= 1e-10, name


def test_a_motor_winding_a_spring_past_half_a_turn(tmp_path):
    """The motor of tests/test_driven_reactions.py (3 rad/s against a 2 N m/rad
    torsion spring, no gravity) driven to 9 rad: it holds k theta at every row, and so
    does the hinge. Before, the inverse run's driver forces read the spring at its
    planned reference, theta - 2 pi past pi: -3.57 N m at 4.5 rad instead of 9.
    1e-9 N m: the rows' kinematic projection and the least-squares multipliers."""
    from test_driven_reactions import WOUND
    r = fccgen.inverse_dynamics(write(tmp_path, WOUND))
    assert r["H.angle"][-1] == pytest.approx(9.0)
    assert np.abs(r["motor.torque"] - 2.0 * r["H.angle"]).max() < 1e-9
    assert np.abs(r["H.tz"] - 2.0 * r["H.angle"]).max() < 1e-9


def test_an_expression_torque_of_the_joint_angle_over_turns(tmp_path):
    """The same motor against the spring written as a torque of the joint angle,
    -2 H.angle about z on the arm: the rows give the load its angle over turns, so the
    motor holds 2 theta to 9 rad, as with the spring (1e-9 N m, as above). Before,
    the inverse run left the reactions of such a load out."""
    from test_driven_reactions import WOUND
    text = WOUND.replace(
        "  - {type: torsion_spring, joint: H, stiffness: 2.0, angle: 0.0, damping: 0.0}",
        '  - {type: torque, body: arm, value: ["0", "0", "-2.0*H.angle"]}')
    assert text != WOUND
    r = fccgen.inverse_dynamics(write(tmp_path, text))
    assert r.info["reactions"]["computed"]
    assert np.abs(r["motor.torque"] - 2.0 * r["H.angle"]).max() < 1e-9
    assert np.abs(r["H.tz"] - 2.0 * r["H.angle"]).max() < 1e-9


def test_the_energy_of_a_spring_wound_past_half_a_turn(tmp_path):
    """The wound motor's rows store the spring's k theta^2 / 2 of the angle over
    turns, plus the arm's kinetic energy (I = 0.1 + 1 * 0.5^2 about the hinge, at
    3 rad/s), as `simulate` records it. Before, the inverse run read the spring at its
    planned reference: 4.75 J at 4.5 rad instead of 21.8. 1e-9 J: the rows' projection
    to the solver's tolerance."""
    from test_driven_reactions import WOUND
    r = fccgen.inverse_dynamics(write(tmp_path, WOUND))
    theta = r["H.angle"]
    assert theta[-1] == pytest.approx(9.0)
    assert np.abs(r["energy"] - (0.5 * 0.35 * 9.0 + theta ** 2)).max() < 1e-9
    assert r.info["energy_drift"] == pytest.approx(81.0)


def test_rows_too_far_apart_to_count_turns_leave_the_energy_nan(tmp_path):
    """A motor speeding up as t^3, read once a second: from 1 s to 2 s the angle moves
    7 rad while the rates' trapezoid says 7.5 and their advance 3, so the turn of the
    row at 2 s cannot be counted. The energy and the motor torque are NaN from there,
    each with a warning that says so, and kept before it: at 0 and 1 s the arm's
    kinetic energy (I = 0.35 kg m^2 at 3 t^2 rad/s) plus the spring's t^6 (1e-9 J,
    as above)."""
    from test_driven_reactions import WOUND
    text = WOUND.replace('angle: "3*t"', 'angle: "t**3"')
    assert text != WOUND
    with pytest.warns(RunWarning) as caught:
        r = fccgen.inverse_dynamics(write(tmp_path, text), t_end=3.0, dt=1.0)
    said = [str(w.message) for w in caught]
    assert any(w.startswith("the energy is NaN from t = 2 s on") for w in said), said
    assert any(w.startswith("the driver forces are NaN from t = 2 s on") for w in said)
    assert any("energy is NaN" in w for w in r.info["warnings"])
    t = r.t[:2]
    closed = 0.5 * 0.35 * (3 * t ** 2) ** 2 + t ** 6
    assert np.abs(r["energy"][:2] - closed).max() < 1e-9
    assert np.isnan(r["energy"][2:]).all()
    assert np.isfinite(r["motor.torque"][:2]).all()
    assert np.isnan(r["motor.torque"][2:]).all()
