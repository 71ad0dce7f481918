"""Drivers (rheonomic constraints, docs/joints.md "Drivers"): their kernels in both
versions, the driven four-bar's motor torque against minimal coordinates, a slider
driven along a prismatic joint, and the model file's rules."""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest
import sympy

import fccgen
from fccgen.derive import derive_class
from fccgen.errors import ModelError
from fccgen.model.load import load_model_text
from fccgen.numeric import element_kernel
from fccgen.plan.classes import ElementClass

from kernel_checks import assert_derived_matches_numeric, d1, random_case

F, T = False, True
FUNCTION = "0.3*sin(2*t) + 0.1*t**2 + 0.2"
CLASSES = [
    ElementClass("driver_angle", (), (F, F, F), frozenset(), FUNCTION),
    ElementClass("driver_angle", (), (T, T, F), frozenset(), FUNCTION),
    ElementClass("driver_position", (), (F, F, F), frozenset(), FUNCTION),
    ElementClass("driver_position", (), (T, T, F), frozenset(), "2*t"),
    ElementClass("driver_distance", (), (F, F), frozenset(), FUNCTION),
    ElementClass("driver_distance", (), (T, F), frozenset(), "1 + exp(-t)"),
    ElementClass("driver_coordinate", (), (F,), frozenset(), FUNCTION),
    ElementClass("driver_coordinate", (), (F,), frozenset({"ey"}), "t**3"),
]
IDS = [f"{c.kind}-{''.join('F' if f else 'm' for f in c.fixed)}" for c in CLASSES]


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_sympy_and_numpy_driver_kernels_agree(cls):
    """SymPy differentiation of g(q, t) against the hand-written chain rule of the
    numeric version, in doubles: 1e-12 of each kernel's largest entry (sums of a few
    terms of size 1)."""
    assert derive_class(cls).kernels["constraint_rate"] is not None
    assert_derived_matches_numeric(cls, rtol=1e-12)


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_driver_kernels_are_the_time_derivatives_of_g(cls):
    """Along q(t) = q + v t + a t^2/2 from time t0: dg/dt = B v + g_t and
    d2g/dt2 = B a + bias, by five-point differences in t (h = 1e-3: truncation
    ~h^4 g^(5) ~ 1e-11, rounding ~1e-16/h^2 ~ 1e-10 for the second derivative);
    checked at 1e-8."""
    q, v, p = random_case(cls, 5)
    a = np.random.default_rng(9).normal(size=cls.n_q)
    t0 = p[0]

    def g_at(s):
        ps = p.copy()
        ps[0] = t0 + s
        return element_kernel(cls, "constraints", q + v * s + a * s * s / 2, v, ps)

    B = element_kernel(cls, "constraint_jacobian", q, v, p).reshape(cls.n_g, cls.n_q)
    rate = element_kernel(cls, "constraint_rate", q, v, p)
    bias = element_kernel(cls, "constraint_bias", q, v, p)
    h = 1e-3
    first = d1(g_at, 0.0, 1.0, h)
    second = (-g_at(2 * h) + 16 * g_at(h) - 30 * g_at(0.0) + 16 * g_at(-h)
              - g_at(-2 * h)) / (12 * h * h)
    assert np.max(np.abs(first - (B @ v + rate))) <= 1e-8
    assert np.max(np.abs(second - (B @ a + bias))) <= 1e-8


# -- the driven four-bar (examples/four_bar_driven.yaml) ------------------------------

L1, L2, L3, L0 = 0.1, 0.35, 0.3, 0.4            # crank, coupler, rocker, ground
MASS = (0.2, 0.7, 0.6)
I_Z = (1.71666666666667e-4, 0.00716333333333333, 0.004515)   # about z, mass centres
G = 9.81
OMEGA, THETA0 = 10.0, math.pi / 3


def loop_closure():
    """(theta, A, B, C, mass centres) of the four-bar in its crank angle theta, as SymPy
    expressions: the crank tip A, the coupler-rocker joint B on the upper intersection
    of the circles about A (coupler L2) and C (rocker L3), the ground pivot C."""
    th = sympy.Symbol("theta", real=True)
    A = sympy.Matrix([L1 * sympy.cos(th), L1 * sympy.sin(th)])
    C = sympy.Matrix([L0, 0])
    d = C - A
    dist = sympy.sqrt(d.dot(d))
    a = (L2 ** 2 - L3 ** 2 + dist ** 2) / (2 * dist)
    h = sympy.sqrt(L2 ** 2 - a ** 2)
    e = d / dist
    B = A + a * e + h * sympy.Matrix([-e[1], e[0]])
    return th, A, B, C, (A / 2, (A + B) / 2, (B + C) / 2)


@functools.cache                 # SymPy takes seconds; other test modules reuse it
def minimal_torque():
    """tau(theta) = M'(theta) omega^2 / 2 + V'(theta) of the four-bar in its crank
    angle theta (minimal coordinates, written from the loop closure with SymPy: B on
    the upper intersection of the circles about A and C); returns a NumPy function."""
    th, A, B, C, centres = loop_closure()
    angles = (th, sympy.atan2(B[1] - A[1], B[0] - A[0]),
              sympy.atan2(B[1] - C[1], B[0] - C[0]))
    M = sum(m * (sympy.diff(c, th).dot(sympy.diff(c, th))) + i * sympy.diff(phi, th) ** 2
            for m, c, i, phi in zip(MASS, centres, I_Z, angles))
    V = sum(m * G * c[1] for m, c in zip(MASS, centres))
    tau = sympy.diff(M, th) * OMEGA ** 2 / 2 + sympy.diff(V, th)
    return sympy.lambdify(th, tau, "numpy")


@pytest.mark.parametrize("method", ["rk4", "dopri5"])
def test_four_bar_motor_torque_matches_minimal_coordinates(compiled, method):
    """The crank follows 10 t exactly (a driver fixes every freedom: positions come
    from the Newton projection to 1e-11, speeds from B v = -g_t), so the recorded
    states are exact to rounding and motor.torque (minimum-norm multipliers) must match
    the minimal-coordinate torque to 1e-8 N m (torques here reach ~1 N m; the solve
    loses a few digits to the 3 redundant rows of the planar loop)."""
    solver = compiled("four_bar_driven")
    r = solver.simulate(t_end=0.7, dt=1e-3, output_dt=0.01, method=method)
    assert np.max(np.abs(r["O.angle"] - OMEGA * r.t)) <= 1e-10
    tau = minimal_torque()(THETA0 + OMEGA * r.t)
    assert np.max(np.abs(tau)) > 0.5                   # not vacuous: the motor works
    assert np.max(np.abs(r["motor.torque"] - tau)) <= 1e-8


def test_four_bar_numeric_and_compiled_agree(compiled, numeric):
    """The two versions on the driven four-bar at t = 0.37 s: constraint rate, bias,
    accelerations (1e-12 / 1e-10 relative as in test_compiled_vs_numeric) and the
    motor torque of a short run."""
    cs, ns = compiled("four_bar_driven"), numeric("four_bar_driven")
    rc = cs.simulate(t_end=0.37, dt=1e-3, output_dt=0.37)
    q = np.array([rc[f"{n}.{c}"][-1] for n, _ in cs.plan.triples for c in "xyz"])
    v = np.array([rc[f"{n}.v{c}"][-1] for n, _ in cs.plan.triples for c in "xyz"])
    for s in (cs, ns):
        s.set_time(0.37)
    for name in ("constraint_rate", "constraints"):
        a, b = getattr(cs, name)(q), getattr(ns, name)(q)
        assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, np.max(np.abs(b)))
    a, b = cs.constraint_bias(q, v), ns.constraint_bias(q, v)
    assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b))
    a, b = cs.accelerations(q, v), ns.accelerations(q, v)
    assert np.max(np.abs(a - b)) <= 1e-10 * np.max(np.abs(b))
    rn = ns.simulate(t_end=0.05, dt=1e-3, output_dt=0.05)
    rc = cs.simulate(t_end=0.05, dt=1e-3, output_dt=0.05)
    assert np.max(np.abs(rn["motor.torque"] - rc["motor.torque"])) <= 1e-10


# -- a slider, a winch and a driven point: one model, one build -----------------------

SLIDER = """\
name: driven_slider
gravity: [-9.81, 0, 0]
bodies:
  slider: {mass: 2.0, center: [0.5, 0, 0], inertia: [0.01, 0.02, 0.03]}
joints:
  - {name: S, type: prismatic, bodies: [ground, slider], at: [0.5, 0, 0],
     axis: [1, 0, 0]}
drivers:
  - {name: push, joint: S, position: "0.1*sin(2*t)"}
simulate: {t_end: 1.0, dt: 1.0e-3, output_dt: 0.01}
"""
# Without gravity: the slider of SLIDER; a bob hanging from (5, 0, 0) on a distance
# joint whose length a winch drives (a vertical prismatic joint keeps it below); a bar
# given by points, hinged at O about z, its end P driven along y.
DRIVEN = """\
name: driven_three
points:
  O: {at: [10, 0, 0], fixed: true}
  P: [11, 0, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
bodies:
  slider: {mass: 2.0, center: [0.5, 0, 0], inertia: [0.01, 0.02, 0.03]}
  bob: {mass: 2.0, center: [5, -1, 0], inertia: [0.01, 0.02, 0.03]}
  arm: {points: [O, P], vector: z, mass: 2.0, center: [0.5, 0, 0],
        inertia: [0.01, 0.1, 0.1]}
joints:
  - {name: S, type: prismatic, bodies: [ground, slider], at: [0.5, 0, 0],
     axis: [1, 0, 0]}
  - {name: D, type: distance, bodies: [ground, bob], at: [[5, 0, 0], [5, -1, 0]]}
  - {name: V, type: prismatic, bodies: [ground, bob], at: [5, -1, 0], axis: [0, 1, 0]}
drivers:
  - {name: push, joint: S, position: "0.1*sin(2*t)"}
  - {name: winch, joint: D, distance: "1 + 0.1*sin(2*t)"}
  - {name: lift, point: P, direction: [0, 1, 0], value: "0.5*sin(t)"}
simulate: {t_end: 1.0, dt: 1.0e-3, output_dt: 0.01}
"""


def test_position_distance_and_coordinate_drivers(tmp_path, build_dir):
    """Every motion prescribed in full, so the forces are exact to rounding (1e-9 N on
    forces up to ~1 N, positions 1e-10):
    - push: x = 0.1 sin 2t along the prismatic joint, force m x'' = -0.8 sin 2t;
    - winch: the distance s = 1 + 0.1 sin 2t replaces the joint's own length row; the
      force along it (positive apart) is m s'' = -0.8 sin 2t;
    - lift: the bar's end at y = 0.5 sin t, theta = asin(0.5 sin t); the force along y
      at P balances I_O theta'' = x_P F, I_O = I_yy + m (l/2)^2 = 0.6."""
    path = tmp_path / "driven_three.yaml"
    path.write_text(DRIVEN)
    r = fccgen.load(path, build_dir).simulate()
    assert np.max(np.abs(r["S.position"] - 0.1 * np.sin(2 * r.t))) <= 1e-10
    assert np.max(np.abs(r["S.speed"] - 0.2 * np.cos(2 * r.t))) <= 1e-10
    assert np.max(np.abs(r["push.force"] + 0.8 * np.sin(2 * r.t))) <= 1e-9
    assert np.max(np.abs(-r["V.position"] - 0.1 * np.sin(2 * r.t))) <= 1e-10
    assert np.max(np.abs(r["winch.force"] + 0.8 * np.sin(2 * r.t))) <= 1e-9
    assert np.max(np.abs(r["P.y"] - 0.5 * np.sin(r.t))) <= 1e-10
    t = sympy.Symbol("t")
    theta = sympy.asin(sympy.sin(t) / 2)
    force = sympy.lambdify(t, 0.6 * theta.diff(t, 2) / sympy.cos(theta), "numpy")(r.t)
    assert np.max(np.abs(force)) > 0.1
    assert np.max(np.abs(r["lift.force"] - force)) <= 1e-9


POINT = """\
name: driven_point
points:
  O: {at: [0, 0, 0], fixed: true}
  P: [1, 0, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
bodies:
  arm: {points: [O, P], vector: z, mass: 2.0, center: [0.5, 0, 0],
        inertia: [0.01, 0.1, 0.1]}
drivers:
  - {name: lift, point: P, direction: [0, 1, 0], value: "0.5*sin(t)"}
"""


# -- the model file's rules -----------------------------------------------------------

GOOD = SLIDER.replace("type: prismatic", "type: cylindrical")
ERRORS = [
    ("unknown joint", ("joint: S,", "joint: Q,"), "drivers[0].joint", "names no joint",
     "Q"),
    ("no such freedom", ("type: cylindrical", "type: revolute"), "drivers[0].position",
     "without that freedom", "S"),
    ("angle of a prismatic", ("type: cylindrical", "type: prismatic"), None, "angle", None),
    ("bad expression", ('"0.1*sin(2*t)"', '"__import__(1)"'), "drivers[0].position",
     "calls only", "__import__(1)"),
    ("unknown name", ('"0.1*sin(2*t)"', '"0.1*sin(2*s)"'), "drivers[0].position",
     "unknown name 's'", "0.1*sin(2*s)"),
    ("attribute", ('"0.1*sin(2*t)"', '"t.real"'), "drivers[0].position",
     "unknown name 't.real'", "t.real"),
    ("two quantities", ('position: "0.1*sin(2*t)"', 'position: "t", angle: "t"'),
     "drivers[0]", "needs exactly one of", "angle, position"),
    ("no closed-form integral", ('position: "0.1*sin(2*t)"', 'speed: "sin(t)/t"'),
     "drivers[0].speed", "no integral from 0 to t in closed form", "sin(t)/t"),
    ("rate of a prismatic", ("type: cylindrical", "type: prismatic"), None, "rate", None),
    ("distance of a slider", ("type: cylindrical", "type: prismatic"), None, "distance",
     None),
    ("no quantity", (', position: "0.1*sin(2*t)"', ""), "drivers[0]",
     "needs exactly one of", None),
    ("name clash", ("name: push,", "name: slider,"), "drivers[0].name",
     "name already used by the body", "slider"),
    ("driven twice", ('position: "0.1*sin(2*t)"}', 'position: "0.1*sin(2*t)"}\n'
                      '  - {name: pull, joint: S, position: "t"}'), "drivers",
     "twice", "pull"),
]


POINT_ERRORS = [
    ("fixed point", ("point: P,", "point: O,"), "drivers[0].point", "is a fixed point",
     "O"),
    ("unknown point", ("point: P,", "point: Q,"), "drivers[0].point",
     "names no moving point", "Q"),
    ("zero direction", ("direction: [0, 1, 0]", "direction: [0, 0, 0]"),
     "drivers[0].direction", "its length is zero", None),
    ("bad value", ('"0.5*sin(t)"', '"0.5*sin(t"'), "drivers[0].value",
     "is not an expression", "0.5*sin(t"),
]


@pytest.mark.parametrize("edit, item, rule, value", [c[1:] for c in POINT_ERRORS],
                         ids=[c[0] for c in POINT_ERRORS])
def test_coordinate_driver_errors(edit, item, rule, value):
    assert edit[0] in POINT
    with pytest.raises(ModelError) as info:
        load_model_text(POINT.replace(edit[0], edit[1]), "m.yaml")
    err = info.value
    assert err.item == item and rule in err.rule, str(err)
    assert err.line is not None and err.file == "m.yaml"
    if value is not None:
        assert err.value == value


@pytest.mark.parametrize("edit, item, rule, value", [c[1:] for c in ERRORS],
                         ids=[c[0] for c in ERRORS])
def test_driver_errors(edit, item, rule, value):
    assert edit[0] in GOOD
    text = GOOD.replace(edit[0], edit[1])
    if item is None:                 # a position driver on a prismatic joint is fine,
        key = rule                   # its angle (rate) is not
        text = text.replace("position:", f"{key}:")
        item, rule, value = f"drivers[0].{key}", "a prismatic joint without that", "S"
    with pytest.raises(ModelError) as info:
        load_model_text(text, "m.yaml")
    err = info.value
    assert err.item == item and rule in err.rule, str(err)
    assert err.line is not None and err.file == "m.yaml"
    if value is not None:
        assert err.value == value


@pytest.mark.parametrize("text", [
    "0.3*sin(2*t) + 0.1*t**2 + atan2(t, 2) + sqrt(1 + t)/exp(t) + max(t, 1)",
    "tan(t/3) - cos(t)**3 + log(2 + t)*min(-t, 0.5) + abs(t - 0.3) + pi*t**-1",
    "(1 + t)**(0.5*t) + 2**t - 10*t"])
def test_time_jets_match_sympy(text):
    """The numeric version's f, f', f'' (forward-mode jets, no SymPy) against SymPy's
    derivatives of the same text, at a few times: 1e-12 relative (a few roundings)."""
    from fccgen.expressions.grammar import parse_expression
    from fccgen.expressions.time_jets import time_function
    t = sympy.Symbol("t", real=True)
    f = parse_expression(text, {"t": t}, source="-", line=None, item="-")
    for time in (0.4, 1.3, 2.2):
        want = [float(f.diff(t, k).subs(t, time)) for k in range(3)]
        got = time_function(text)(time)
        assert np.allclose(got, want, rtol=1e-12, atol=1e-12), (got, want)


@pytest.mark.parametrize("rate, key", [("10", "rate"), ("0.2*cos(2*t) + 0.3*t", "speed"),
                                       ("exp(-t)*sin(3*t)", "speed")])
def test_rate_drivers_integrate_in_closed_form(rate, key):
    """rate: / speed: give f = integral of the rate from 0 (SymPy, decimals made exact
    rationals first): f(0) = 0 and f' = the rate, to rounding (1e-12)."""
    from fccgen.expressions.grammar import parse_expression
    text = GOOD.replace('position: "0.1*sin(2*t)"', f'{key}: "{rate}"')
    if key == "rate":
        text = text.replace("type: cylindrical", "type: revolute")
    driver = load_model_text(text, "m.yaml").drivers[0]
    assert driver.quantity == ("angle" if key == "rate" else "position")
    t = sympy.Symbol("t", real=True)
    f = parse_expression(driver.function, {"t": t}, source="-", line=None, item="-")
    r = parse_expression(rate, {"t": t}, source="-", line=None, item="-")
    assert abs(float(f.subs(t, 0))) <= 1e-12
    for time in (0.3, 1.7):
        assert abs(float((f.diff(t) - r).subs(t, time))) <= 1e-12


def test_initial_joint_speeds_with_a_driver(tmp_path):
    """initial: joints: with a driver: the speeds keep B v = -dg/dt. The crank rate
    the motor prescribes (10 rad/s) is consistent and kept to 1e-9; another rate of the
    same freedom (the rocker's) that disagrees is refused, naming the item."""
    from conftest import EXAMPLES as EXAMPLE_DIR
    text = (EXAMPLE_DIR / "four_bar_driven.yaml").read_text()
    good = tmp_path / "good.yaml"
    good.write_text(text + "initial:\n  joints: {O: {rate: 10}}\n")
    solver = fccgen.load_numeric(good)
    init = solver.initial_state()
    assert init.velocity_residual <= 1e-9
    crank = solver.body_outputs(init.q, init.v)[0, 5]       # crank.wz
    assert abs(crank - 10.0) <= 1e-9
    bad = tmp_path / "bad.yaml"
    bad.write_text(text + "initial:\n  joints: {C: {rate: 30}}\n")
    with pytest.raises(ModelError, match="initial.joints: these joint speeds cannot all "
                                         "hold"):
        fccgen.load_numeric(bad).initial_state()
