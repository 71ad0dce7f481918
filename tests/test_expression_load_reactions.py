"""Joint reactions of models whose force and torque loads are expressions (of t, of
joint quantities over turns, of named tables, of the model's inputs): the balance
takes each load's value as the run held it at the record (fccgen.numeric.record_loads,
fccgen.mechanism.reactions). Checked against the recorded motion (central differences
of the mass centre), closed forms of bodies held still, the same loads written as
constants and as a torsion spring, and the NumPy version."""
from __future__ import annotations

import numpy as np
import pytest

import fccgen
from fccgen.errors import ModelError
from fccgen.mechanism.reactions import reactions
from fccgen.numeric import record_loads

G, MASS, D, H = 9.81, 1.5, 0.5, 0.2        # gravity, kg, arm, offset along the axis
I_AXIS = 0.12                                # about the body's z (the hinge axis)


def vec(r, name, kind):
    return np.column_stack([r[f"{name}.{kind}{c}"] for c in "xyz"])


HINGE = "type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 0, 1]"


def model(tmp_path, loads: str, name: str = "expr_arm", joint: str = HINGE) -> str:
    """An arm on a revolute hinge at the origin, axis z (or on ``joint``), its mass
    centre D out along x and H along the axis; ``loads``: the YAML lines of its
    loads."""
    text = f"""name: {name}
gravity: [0, {-G}, 0]
bodies:
  arm: {{mass: {MASS}, center: [{D}, 0, {H}], inertia: [0.002, {I_AXIS}, {I_AXIS}],
        frame: {{x: [1, 0, 0], y: [0, 1, 0]}}}}
joints:
  - {{name: H, {joint}}}
loads:
{loads}
simulate: {{t_end: 2.0, dt: 1.0e-3, method: rk4}}
"""
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return str(path)


def fourth_order_acceleration(c, h):
    return (-c[4:] + 16 * c[3:-1] - 30 * c[2:-2] + 16 * c[1:-3] - c[:-4]) / (12 * h * h)


@pytest.mark.parametrize("numeric", [False, True], ids=["compiled", "numpy"])
def test_a_hinge_wound_over_turns_balances_the_recorded_motion(tmp_path, numeric):
    """A spring-like torque 20 (8 - H.angle) - 0.5 H.rate + 0.2 sin 3t swings the arm
    to 14 rad (over two turns) against gravity. The hinge's force on the arm equals
    m a_G - m g, a_G by fourth-order central differences of the recorded mass centre
    (independent of the balance's kinematics and of the load's evaluation): measured
    2.1e-4 N at dt = 1 ms (6.1e-5 N at 0.5 ms) against forces up to 1.5e3 N; 1e-3 N
    allowed. With the angle not counted over turns the load and the accelerations of
    the balance are those of the wrong branch (on the tape-spring example: 2.6 N off).
    The perpendicular torque about the hinge point closes the balance about G of the
    planar motion (z principal): T_xy = -((p - r_G) x F)_xy, with the same F. The
    NumPy version over 0.4 s (it is slow), by then at 13 rad."""
    path = model(tmp_path, '  - {type: torque, body: arm, value: [0, 0, '
                 '"20*(8.0 - H.angle) - 0.5*H.rate + 0.2*sin(3*t)"]}')
    h = 1e-3
    r = (fccgen.load_numeric(path).simulate(dt=h, t_end=0.4) if numeric else
         fccgen.load(path).simulate(dt=h))
    assert r.info["reactions"]["computed"] and r.info["reactions"]["unique"]
    assert r["H.angle"].max() > 4 * np.pi          # wound past several half turns
    c = vec(r, "arm", "c")
    want = MASS * (fourth_order_acceleration(c, h) - [0.0, -G, 0.0])
    F = vec(r, "H", "f")[2:-2]
    assert np.abs(F - want).max() < 1e-3
    assert np.abs(want).max() > 1e3
    T = vec(r, "H", "t")[2:-2]
    assert np.abs(T[:, 2]).max() == 0.0            # a revolute carries no axial torque
    moment = -np.cross(-c[2:-2], want)             # p = 0: (p - r_G) = -r_G
    assert np.abs(T[:, :2] - moment[:, :2]).max() < 1e-3 * max(D, H) * 2


def test_an_arm_held_by_its_spring_has_the_static_reactions(tmp_path):
    """The torque k (a0 - H.angle) with k a0 = m g D holds the arm still at its start
    (H.angle = 0): the hinge carries the weight, F = (0, m g, 0), and the moment of the
    weight about the hinge point across the axis, T = (-H m g, 0, 0) (the axial part is
    the spring's). Rounding and the run's drift from rest only: 1e-9 allowed."""
    k = 30.0
    a0 = MASS * G * D / k
    path = model(tmp_path, f'  - {{type: torque, body: arm, value: [0, 0, '
                 f'"{k}*({a0!r} - H.angle)"]}}')
    r = fccgen.load(path).simulate(t_end=0.5)
    assert np.abs(r["H.angle"]).max() < 1e-9
    # held at rest: the energy check measures no drift against a kinetic energy of
    # rounding (4.9e-32 J: it warned of a 1609 % drift before)
    assert r.info["energy_check"]["at_rest"]
    F, T = vec(r, "H", "f"), vec(r, "H", "t")
    assert np.abs(F - [0.0, MASS * G, 0.0]).max() < 1e-9
    assert np.abs(T - [-H * MASS * G, 0.0, 0.0]).max() < 1e-9


# a weld to ground leaves no freedom: the run warns that nothing can move, and its
# projections take out the motion of rounding (all of a kinetic energy of 1e-30 J)
@pytest.mark.filterwarnings("ignore::fccgen.errors.RunWarning")
def test_a_welded_body_under_loads_of_time_has_the_closed_form_reactions(tmp_path):
    """A body welded to ground at the origin under a force of t at a body point (r_a:
    the body point's offset from the mass centre, body frame = global here) and a
    torque of t stays still; the weld carries all: F = -(m g + f(t)) and
    T = -(r_G x m g + r_a x f(t) + tau(t)) about the weld point. Closed form, 1e-9."""
    loads = ('  - {type: force, body: arm, at: [0.3, 0.1, 0], '
             'value: ["2*sin(3*t)", "1 + t", "-0.5*t*t"]}\n'
             '  - {type: torque, body: arm, value: ["cos(t)", "0.25", "-2*t"]}')
    path = model(tmp_path, loads, "welded", "type: weld, bodies: [ground, arm], "
                 "at: [0, 0, 0]")
    r = fccgen.load(path).simulate(t_end=1.0, dt=1e-2)
    t = r.t
    f = np.column_stack([2 * np.sin(3 * t), 1 + t, -0.5 * t * t])
    tau = np.column_stack([np.cos(t), np.full_like(t, 0.25), -2 * t])
    weight = np.array([0.0, -MASS * G, 0.0])
    r_g = np.array([D, 0.0, H])
    r_a = r_g + [0.3, 0.1, 0.0]
    assert np.abs(vec(r, "H", "f") - -(weight + f)).max() < 1e-9
    want_t = -(np.cross(r_g, weight) + np.cross(r_a, f) + tau)
    assert np.abs(vec(r, "H", "t") - want_t).max() < 1e-9
    assert np.abs(want_t).max() > 1.0


def test_a_constant_written_as_an_expression_gives_the_same_reactions(tmp_path):
    """The same force at a body point and torque, given as numbers and as
    expressions of t that equal them: the runs and the reactions agree to rounding
    (1e-10 N, N m, against forces of 30 N)."""
    const = ('  - {type: force, body: arm, at: [0.3, 0.1, 0], value: [0.5, 2.0, -1.0]}\n'
             '  - {type: torque, body: arm, value: [0.1, 0.2, 0.7]}')
    expr = ('  - {type: force, body: arm, at: [0.3, 0.1, 0], '
            'value: ["0.5 + 0*t", "2.0 + 0*t", "-1.0 + 0*t"]}\n'
            '  - {type: torque, body: arm, value: ["0.1 + 0*t", "0.2 + 0*t", '
            '"0.7 + 0*t"]}')
    a = fccgen.load(model(tmp_path, const, "const")).simulate(t_end=1.0)
    b = fccgen.load(model(tmp_path, expr, "expr")).simulate(t_end=1.0)
    assert b.info["reactions"]["computed"]
    for name in ("H.fx", "H.fy", "H.fz", "H.tx", "H.ty", "H.tz"):
        assert np.abs(a[name] - b[name]).max() < 1e-10, name
    assert np.abs(a["H.fx"]).max() > 1.0


def test_a_load_of_the_angle_gives_the_torsion_springs_reactions(tmp_path):
    """-k (H.angle - a0) - c H.rate is the torque of a torsion spring (k, free angle
    a0, damping c) on H. On the records of the spring's run, wound over two turns, the
    reactions with the load (its value from the kernels at the run's turn references,
    the accelerations with them) are the spring's (its torque from the balance's own
    unwrapping of the records, fccgen.mechanism.reactions._torsion): 1e-9 of their
    size (rounding)."""
    spring = ('  - {type: torsion_spring, joint: H, stiffness: 20.0, angle: 8.0, '
              'damping: 0.5}')
    load = ('  - {type: torque, body: arm, value: [0, 0, '
            '"-20*(H.angle - 8.0) - 0.5*H.rate"]}')
    a = fccgen.load(model(tmp_path, spring, "spring")).simulate()
    assert a["H.angle"].max() > 2 * np.pi
    solver = fccgen.load(model(tmp_path, load, "load"))
    cols, info = reactions(solver, a, loads=record_loads.of_run(
        solver.plan, solver._asm.put_params, None, None))
    assert info["unique"]
    for kind in "ft":
        want = vec(a, "H", kind)
        got = np.column_stack([cols[f"H.{kind}{c}"] for c in "xyz"])
        assert np.abs(got - want).max() < 1e-9 * np.abs(want).max(), kind


def test_tape_spring_table_compiled_and_numpy_reactions_agree():
    """examples/tape_spring_table.yaml (a named table of the hinge angle and the
    rate): the compiled solver's reactions and the NumPy version's over 0.1 s (the
    NumPy version is slow) agree to 1e-9 of their size (the two runs differ by
    rounding: measured below 1e-12 N)."""
    path = "examples/tape_spring_table.yaml"
    a = fccgen.load(path).simulate(t_end=0.1)
    b = fccgen.load_numeric(path).simulate(t_end=0.1)
    assert a.info["reactions"]["computed"] and b.info["reactions"]["computed"]
    for kind in "ft":                  # its torques are 0 (planar, z principal)
        want = vec(a, "H", kind)
        assert np.abs(vec(b, "H", kind) - want).max() <= 1e-9 * np.abs(want).max(), kind
    assert np.abs(a["H.fx"]).max() > 0.1


J_PANEL = 0.1666667 + 2.0 * 0.5 ** 2            # examples/panel_input.yaml, about z


def panel_force(r, torque):
    """The hinge force on the panel of examples/panel_input.yaml (no gravity, a
    revolute about z at the origin): m (alpha z x r_G - w^2 r_G), alpha = T / J with
    the torque T the run held at each record, w the recorded rate."""
    c = vec(r, "panel", "c")
    alpha = torque / J_PANEL
    w = r["hinge.rate"]
    return 2.0 * (np.cross([0.0, 0.0, 1.0], c) * alpha[:, None] - (w * w)[:, None] * c)


@pytest.mark.parametrize("numeric", [False, True])
def test_an_input_driven_load_gets_the_held_inputs_reactions(numeric):
    """examples/panel_input.yaml with its hinge torque given as a function of t: held
    from each output time to the next, so at a record the torque sampled at its time.
    The hinge force is m a_G of the rigid rotation (closed form from the recorded
    angle and rate): 1e-9 N against 0.1 N; with the sample of the record before it
    would be off by m r dT/J = 2e-4 N. The start value alone (no inputs given) gives
    its own closed form too."""
    path = "examples/panel_input.yaml"
    solver = (fccgen.load_numeric if numeric else fccgen.load)(path)
    t_end = 0.3 if numeric else 2.0

    def given(t):
        return 0.02 * (1.0 + 5.0 * t)
    r = solver.simulate(t_end=t_end, inputs={"hinge_torque": given})
    assert r.info["reactions"]["computed"]
    torque = np.array([given(t) for t in r.t])
    F = vec(r, "hinge", "f")
    want = panel_force(r, torque)
    assert np.abs(F - want).max() < 1e-9
    assert np.abs(want).max() > 0.01
    assert np.abs(vec(r, "hinge", "t")).max() < 1e-9      # z principal, plane motion
    r0 = solver.simulate(t_end=t_end)
    want0 = panel_force(r0, np.full(len(r0.t), 0.02))
    assert np.abs(vec(r0, "hinge", "f") - want0).max() < 1e-9


def test_reactions_called_without_the_runs_loads_are_refused():
    """reactions(solver, result) alone cannot know what an expression load held at
    the records (its inputs, its turns): refused, naming the load."""
    solver = fccgen.load("examples/panel_input.yaml")
    r = solver.simulate(t_end=0.1, reactions=False)
    with pytest.raises(ModelError, match=r"loads\[0\].*input hinge_torque.*only the run"):
        reactions(solver, r)


def test_records_too_far_apart_to_count_turns_leave_no_reactions(tmp_path):
    """A stiff spring-like torque swings the arm through 16 rad every 0.3 s; recorded
    every 0.1 s the turns between records cannot be told from the records (the
    branch nearest the rate's advance and the trapezoid of the rates disagree): no
    reaction columns, the reason and a warning, never a guessed branch; the joint
    angle column is NaN from the same record on, with its own warning. Recorded every
    step, the same run has them."""
    path = model(tmp_path, '  - {type: torque, body: arm, value: [0, 0, '
                 '"200*(8.0 - H.angle)"]}')
    solver = fccgen.load(path)
    with pytest.warns(fccgen.errors.RunWarning) as caught:
        r = solver.simulate(t_end=1.0, output_dt=0.1)
    said = [str(w.message) for w in caught]
    assert any("too far to count its turns" in w for w in said), said
    lost = r.info["angle_turns_lost"]["H.angle"]
    assert any(w.startswith(f"H.angle is NaN from t = {lost:.9g} s on") for w in said)
    k = int(np.searchsorted(r.t, lost))
    assert np.isfinite(r["H.angle"][:k]).all() and np.isnan(r["H.angle"][k:]).all()
    assert not r.info["reactions"]["computed"]
    assert "record more often" in r.info["reactions"]["reason"]
    assert "H.fx" not in r.columns
    assert solver.simulate(t_end=1.0).info["reactions"]["computed"]


def test_a_static_equilibrium_on_a_load_of_the_angle_has_its_reactions(tmp_path):
    """fccgen statics of the arm whose torque k (a0 - H.angle) is not its weight's
    moment at the start: at the equilibrium angle theta (k (a0 - theta) = m g D cos
    theta, checked here) the hinge carries the weight, F = (0, m g, 0), and across the
    axis the weight's moment about the hinge point, T = (-H m g, 0, 0); along the axis
    the load's value balances the weight's moment, which a revolute cannot carry, so
    the balance's residual is at rounding only with the load's value right. 1e-8
    (the equilibrium is solved to about 1e-10)."""
    k, a0 = 30.0, 0.6
    path = model(tmp_path, f'  - {{type: torque, body: arm, value: [0, 0, '
                 f'"{k}*({a0} - H.angle)"]}}', "static_arm")
    for numeric in (False, True):
        eq, r = fccgen.api.equilibrium(path, numeric=numeric)
        theta = float(r["H.angle"][0])
        assert abs(k * (a0 - theta) - MASS * G * D * np.cos(theta)) < 1e-8
        assert abs(theta) > 0.1                            # away from the start
        assert r.info["reactions"]["computed"] and r.info["reactions"]["residual"] < 1e-8
        assert np.abs(vec(r, "H", "f") - [0.0, MASS * G, 0.0]).max() < 1e-8
        assert np.abs(vec(r, "H", "t") - [-H * MASS * G, 0.0, 0.0]).max() < 1e-8


def test_the_records_angles_are_the_kernels_angles_over_turns(tmp_path):
    """The angles RecordLoads measures for a chunk of records at once are those of
    the kernels' own measure record by record (joint_loads._angle, reference 0) up to
    whole turns, to rounding (1e-12 rad), and they are the run's H.angle column
    (measured 3e-14 rad at 14 rad; 1e-12 allowed); they pass two turns without a
    jump."""
    from fccgen.numeric.joint_loads import _angle
    from fccgen.numeric.kinematics import Local
    path = model(tmp_path, '  - {type: torque, body: arm, value: [0, 0, '
                 '"20*(8.0 - H.angle) - 0.5*H.rate"]}')
    solver = fccgen.load(path)
    r = solver.simulate(reactions=False)
    plan = solver.plan
    names = [name for name, _ in plan.triples]
    q = np.column_stack([r[f"{t}.{c}"] for t in names for c in "xyz"])
    v = np.column_stack([r[f"{t}.v{c}"] for t in names for c in "xyz"])
    loads = record_loads.RecordLoads(plan, lambda slots, values: None)
    loads.chunk(r.t, q, v)
    (e, prefix), = loads.sources
    el = plan.elements[e]
    params = np.array(el.params, float)
    k = el.cls.param_names.index(prefix + "th")
    params[k:k + 3] = 0.0, 1.0, 0.0
    idx = el.q_index()
    for row in range(0, len(r.t), 97):
        angle = _angle(Local(el.cls, q[row, idx], v[row, idx], params), prefix)[0]
        turns = (loads.angles[0, row] - angle) / (2 * np.pi)
        assert abs(turns - round(turns)) < 1e-12 / (2 * np.pi)
    assert np.abs(loads.angles[0] - r["H.angle"]).max() < 1e-12
    assert np.abs(np.diff(loads.angles[0])).max() < 0.5 and loads.angles.max() > 4 * np.pi
