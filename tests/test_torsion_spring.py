"""The torsion spring-damper (kind torsion_spring, docs/elements.md): NumPy against
SymPy kernels and finite differences, the model file's rules, and the dynamics of a
body hinged to ground against the closed-form oscillator."""
from __future__ import annotations

import math

import numpy as np
import pytest

import fccgen
from fccgen.api import plan_model
from fccgen.errors import ModelError
from fccgen.numeric import element_kernel
from fccgen.plan.classes import ElementClass
from fccgen.runtime import CompiledSolver

from states import random_state
from kernel_checks import assert_derived_matches_numeric, d1, gradient, random_case

F, T = False, True
KIND = "torsion_spring"
# fixed patterns of (A.ri, A.rj, B.ri, B.rj, u)
CLASSES = [
    ElementClass(KIND, (), (F, F, F, F, F), frozenset()),
    ElementClass(KIND, (), (F, F, F, F, F), frozenset({"lA", "lB", "sin0"})),
    ElementClass(KIND, (), (T, T, F, F, T), frozenset()),
    ElementClass(KIND, (), (T, T, T, F, T), frozenset({"c"})),
    ElementClass(KIND, (), (T, F, F, T, F), frozenset({"lB", "cos0"})),
]
IDS = ["".join("F" if f else "m" for f in c.fixed) + "-" + "-".join(sorted(c.zeros))
       for c in CLASSES]


def numeric(name, cls, q, v, p):
    return element_kernel(cls, name, q, v, p)


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_numeric_force_jacobians_match_finite_differences(cls):
    """Five-point differences at h = 2e-4: on random (off-manifold) states atan2(S, C)
    has large high derivatives, truncation ~h^4 f^(5) stays below 1e-9 of the largest
    entry, rounding ~1e-16 |f| / h ~ 1e-12; checked at 1e-8."""
    for seed in range(3):
        q, v, p = random_case(cls, seed)
        n = cls.n_q
        jq = numeric("force_jacobian_q", cls, q, v, p).reshape(n, n)
        jv = numeric("force_jacobian_v", cls, q, v, p).reshape(n, n)
        fq = np.array([d1(lambda x: numeric("applied_forces", cls, x, v, p), q, e, 2e-4)
                       for e in np.eye(n)]).T
        fv = np.array([d1(lambda x: numeric("applied_forces", cls, q, x, p), v, e, 2e-4)
                       for e in np.eye(n)]).T
        scale = max(1.0, np.max(np.abs(fq)), np.max(np.abs(fv)))
        assert np.max(np.abs(jq - fq)) <= 1e-8 * scale
        assert np.max(np.abs(jv - fv)) <= 1e-8 * scale
        assert np.max(np.abs(jq)) > 1e-3             # not vacuous


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_force_is_minus_gradient_of_energy_plus_damping(cls):
    """f = -dV/dq - c phi' dphi/dq: with c = 0 the force is the energy's gradient
    (five-point differences, 1e-8 of the force); the damping part does negative work
    f_c . q' = -c phi'^2 <= 0."""
    q, v, p = random_case(cls, 4)
    undamped = p.copy()
    if "c" not in cls.zeros:
        undamped[cls.param_names.index("c")] = 0.0
    f = numeric("applied_forces", cls, q, v, undamped)
    dV = gradient(lambda x: np.array([numeric("energy", cls, x, v, undamped)[1]]), q)[0]
    assert np.max(np.abs(f + dV)) <= 1e-8 * max(1.0, np.max(np.abs(f)))
    if "c" not in cls.zeros:
        work = (numeric("applied_forces", cls, q, v, p) - f) @ v
        assert work < 0


@pytest.mark.parametrize("cls", CLASSES[2:4], ids=IDS[2:4])
def test_sympy_and_numpy_kernels_agree(cls):
    """(Classes that derive in seconds; the compiled module of every kind is also
    checked by test_printing and the compiled hinge model below.) Two derivations (SymPy differentiation, NumPy vector algebra) of the same
    functions, in doubles: 1e-12 of each kernel's largest entry."""
    assert_derived_matches_numeric(cls, seeds=range(2), numeric=numeric, rtol=1e-12)


# -- models ---------------------------------------------------------------------------

HINGE = """\
name: torsion_hinge
points:
  O: {{at: [0, 0, 0], fixed: true}}
  G: {{at: [1, 0, 0], fixed: true}}
  P: [0.6, 0.8, 0]
vectors:
  z: {{along: [0, 0, 1], fixed: true}}
bodies:
  ground: {{points: [O, G], vector: z, mass: 1.0, inertia: [1, 1, 1]}}
  arm: {{points: [O, P], vector: z, mass: 2.0, center: [0.4, 0, 0],
         inertia: [0.01, 0.05, 0.05]}}
loads:
  - {{type: torsion_spring, bodies: [ground, arm], axis: z, stiffness: {k},
      angle: {angle}, damping: {c}}}
simulate: {{t_end: 6.0, dt: 1.0e-3, method: rk4}}
"""
# the arm turns about z through O; z is its body axis e2 (beta = 0), so its inertia
# about the hinge is I_yy + m c^2 (parallel axes)
I_HINGE = 0.05 + 2.0 * 0.4 ** 2
K, ANGLE = 3.0, 0.5


def write(tmp_path, name, text):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


def arm_angle(result) -> np.ndarray:
    """theta of the arm about z from the initial configuration, from P's coordinates."""
    return np.unwrap(np.arctan2(result["P.y"], result["P.x"])) - math.atan2(0.8, 0.6)


def crossings(t, y):
    """Times where y changes sign, by linear interpolation between samples."""
    k = np.flatnonzero(np.sign(y[:-1]) * np.sign(y[1:]) < 0)
    return t[k] - y[k] * (t[k + 1] - t[k]) / (y[k + 1] - y[k])


def peaks(t, y):
    """(times, |values|) of the extrema of y by a parabola through three samples."""
    a = np.abs(y)
    k = np.flatnonzero((a[1:-1] > a[:-2]) & (a[1:-1] >= a[2:])) + 1
    y0, y1, y2 = y[k - 1], y[k], y[k + 1]
    shift = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)
    dt = t[1] - t[0]
    return t[k] + shift * dt, np.abs(y1 - 0.25 * (y0 - y2) * shift)


@pytest.fixture(scope="module")
def hinge_runs(tmp_path_factory):
    """Damped and undamped runs of the hinge model, compiled once: the undamped solver
    is the damped plan with c = 0 in the same module (numbers are runtime parameters;
    a model file with damping 0 would fold c away into another class)."""
    folder = tmp_path_factory.mktemp("torsion")
    path = write(folder, "hinge", HINGE.format(k=K, angle=ANGLE, c=0.1))
    damped = fccgen.load(path, folder / "generated")
    plan = plan_model(path)
    spring = next(el for el in plan.elements if el.cls.kind == KIND)
    spring.params[spring.cls.param_names.index("c")] = 0.0
    undamped = CompiledSolver(plan, damped.module)
    return {0.0: (undamped, undamped.simulate()), 0.1: (damped, damped.simulate())}


def test_undamped_hinge_oscillates_with_the_closed_form_period(hinge_runs):
    """V = k (theta - theta0)^2 / 2 exactly, so theta - theta0 = -theta0 cos(w t) with
    w = sqrt(k / I) at any amplitude. RK4 at w dt = 3e-3 has a phase error ~(w dt)^4,
    and linear interpolation of the crossings ~dt^2 w / 8: 1e-6 of the period is loose."""
    _, result = hinge_runs[0.0]
    phi = arm_angle(result) - ANGLE
    times = crossings(result.t, phi)
    assert len(times) >= 4
    period = 2 * np.mean(np.diff(times))
    want = 2 * math.pi * math.sqrt(I_HINGE / K)
    assert period == pytest.approx(want, rel=1e-6)
    # right-handed about z: the spring turns the arm from 0 towards +angle and beyond
    theta = arm_angle(result)
    assert np.max(theta) == pytest.approx(2 * ANGLE, rel=1e-6)
    assert np.min(theta) == pytest.approx(0.0, abs=1e-6)


def test_undamped_hinge_conserves_energy(hinge_runs):
    """RK4 with projection at w dt = 3e-3: energy drift ~1e-12 per period, checked
    against 1e-9 of the initial potential k theta0^2 / 2."""
    _, result = hinge_runs[0.0]
    e = result["energy"]
    assert e[0] == pytest.approx(K * ANGLE ** 2 / 2, rel=1e-12)
    assert np.max(np.abs(e - e[0])) <= 1e-9 * e[0]


def test_damped_hinge_decays_at_c_over_2i(hinge_runs):
    """I phi'' + c phi' + k phi = 0: phi = e^(-z t)(...) with z = c / (2 I) and damped
    period 2 pi / sqrt(k/I - z^2). Peaks by parabolic interpolation (error ~(w dt)^3)
    over three periods: 1e-4 relative on both."""
    _, result = hinge_runs[0.1]
    phi = arm_angle(result) - ANGLE
    zeta = 0.1 / (2 * I_HINGE)
    wd = math.sqrt(K / I_HINGE - zeta ** 2)
    times = crossings(result.t, phi)
    assert 2 * np.mean(np.diff(times)) == pytest.approx(2 * math.pi / wd, rel=1e-6)
    tp, ap = peaks(result.t, phi)
    assert len(tp) >= 4
    slope = np.polyfit(tp, np.log(ap), 1)[0]
    assert -slope == pytest.approx(zeta, rel=1e-4)
    assert np.all(np.diff(result["energy"]) <= 1e-12)     # the damper only takes energy


def test_compiled_and_numeric_hinge_agree(hinge_runs, tmp_path):
    """Kernels of the compiled model against the NumPy version on random consistent
    states (1e-12 of each quantity's size, as in test_compiled_vs_numeric)."""
    solver, _ = hinge_runs[0.1]
    ns = fccgen.load_numeric(write(tmp_path, "hinge", HINGE.format(k=K, angle=ANGLE,
                                                                   c=0.1)))
    rng = np.random.default_rng(3)
    for _ in range(4):
        q, v = random_state(ns, rng, spread=0.3)
        for name in ("applied_forces", "force_jacobian_q", "force_jacobian_v"):
            want = getattr(ns, name)(q, v)
            got = getattr(solver, name)(q, v)
            assert np.max(np.abs(got - want)) <= 1e-12 * max(1.0, np.max(np.abs(want)))
        assert solver.energy(q, v) == pytest.approx(ns.energy(q, v), rel=1e-12)


FREE_PAIR = """\
name: free_pair
points:
  A0: [0, 0, 0]
  H: [1, 0, 0]
  B1: [1.5, 0.8, 0.1]
vectors:
  z: [0, 0, 1]
bodies:
  a: {points: [A0, H], vector: z, mass: 1.0, center: [0.5, 0, 0], inertia: [0.01, 0.1, 0.1]}
  b: {points: [H, B1], vector: z, mass: 0.7, center: [0.3, 0.1, 0],
      inertia: [0.02, 0.05, 0.06]}
loads:
  - {type: torsion_spring, bodies: [a, b], axis: z, stiffness: 2.0, angle: 0.4}
initial:
  bodies: {a: {angular_velocity: [0.4, -0.3, 0.5]}, b: {angular_velocity: [0.4, -0.3, -0.5]}}
simulate: {t_end: 0.4, dt: 2.0e-3, method: rk4}
"""


def test_free_pair_conserves_energy_with_a_moving_axis(tmp_path):
    """Two free bodies hinged about a tumbling shared axis (the class with every triple
    moving), NumPy version: RK4 with projection keeps energy to 1e-8 of its size."""
    solver = fccgen.load_numeric(write(tmp_path, "free_pair", FREE_PAIR))
    result = solver.simulate()
    e = result["energy"]
    assert np.ptp(result["z.x"]) > 0.05                    # the axis does move
    assert np.max(np.abs(e - e[0])) <= 1e-8 * abs(e[0])


# -- model file rules ------------------------------------------------------------------

def load_error(tmp_path, spring: str) -> str:
    text = HINGE.format(k=K, angle=ANGLE, c=0).split("loads:")[0]
    text = text.replace("vectors:\n  z: {along: [0, 0, 1], fixed: true}",
                        "vectors:\n  z: {along: [0, 0, 1], fixed: true}\n  x: [1, 0, 0]")
    text += "  third: {points: [O, P], vector: x, mass: 1.0, inertia: [1, 1, 1]}\n"
    text += f"loads:\n  - {spring}\n"
    with pytest.raises(ModelError) as info:
        plan_model(write(tmp_path, "bad", text))
    return str(info.value)


@pytest.mark.parametrize("spring, rule", [
    ("{type: torsion_spring, bodies: [arm, third], axis: z, stiffness: 1}",
     "loads[0].axis: must be the vector of both bodies (the hinge axis they share); "
     "body third has vector x (got 'z')"),
    ("{type: torsion_spring, bodies: [arm, arm], axis: z, stiffness: 1}",
     "loads[0].bodies: must name two different bodies"),
    ("{type: torsion_spring, bodies: [arm, nobody], axis: z, stiffness: 1}",
     "loads[0].bodies[1]: names no body"),
    ("{type: torsion_spring, bodies: [ground, arm], axis: z, stiffness: -1}",
     "loads[0].stiffness: must be a number >= 0"),
    ("{type: torsion_spring, bodies: [ground, arm], axis: z, stiffness: 1, angle: .inf}",
     "loads[0].angle: must be a finite number"),
    ("{type: torsion_spring, bodies: [ground, arm], stiffness: 1}",
     "loads[0].axis: missing required key"),
    ("{type: torsion_spring, bodies: [ground, arm], axis: z, stiffness: 1, length: 1}",
     "loads[0].length: unknown key"),
])
def test_model_rules(tmp_path, spring, rule):
    message = load_error(tmp_path, spring)
    assert "bad.yaml:" in message and rule in message, message
