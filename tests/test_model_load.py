"""Valid model files load into the expected dataclasses, and the plan accepts them."""
import math
from pathlib import Path

import numpy as np
import pytest

from fccgen.model import (METHODS, AngularVelocity, BodyPoint, Distance, Force, Initial,
                          PointOnLine, SimulateDefaults, Spring, Torque, load_model,
                          load_model_text)
from fccgen.model.yamlnodes import parse_yaml
from fccgen.plan import make_plan

REPO = Path(__file__).resolve().parents[1]

# Every key of the model file (docs/design.md §2), short and long forms.
FULL = """\
name: rig
gravity: [0, 0, -9.81]
points:
  O: {at: [0, 0, 0], fixed: true}
  C: {at: [0, 0, 1], fixed: true}
  P: [0, 1, 0]
  Q: {at: [1, 1, 0], fixed: false}
  R: {at: [1, 2, 0]}
  on: [2, 2, 0]                   # a YAML 1.1 boolean word, used as a name
vectors:
  z: {along: [0, 0, 1], fixed: true}
  u: [0, 1, 0]
  w: [0, 0.6, 0.8000000004]       # |w| - 1 = 3.2e-10: within 1e-9, normalised
bodies:
  arm:
    points: [O, P]
    vector: z
    mass: 2.5
    center: &mid [0, 0.5, 0]
    inertia: [0.1, 0.2, 0.3]
  link:
    points: [P, Q]
    vector: u
    mass: 1.5e1
    inertia: [2, 3, 4, 0.1, 0.2, 0.3]
  bob:
    points: [Q, R]
    vector: w
    mass: 1
    inertia: [0, 0, 0]
  slider:
    points: [R, on]
    vector: u
    mass: 5E-1
    center: [0.5, 0, 0]
    inertia: [1, 1, 2.000000002]  # I3 - (I1 + I2) = 2e-9 <= 1e-9 * sum: accepted
constraints:
  - {type: point_on_line, point: on, line: [C, {body: arm, at: [0, 1, 0]}]}
  - {type: distance, points: [O, R], length: 2.0}
loads:
  - {type: force, body: arm, value: [0, 0, -1]}
  - {type: force, body: link, at: *mid, value: [1, 0, 0]}
  - {type: torque, body: link, value: [0, 0, 0.5]}
  - {type: spring, ends: [C, R], stiffness: 4530}
  - {type: spring, ends: [O, {body: bob, at: [0, 0.5, 0]}], stiffness: 10,
     length: 0.07785, damping: 0.2}
initial:
  points: {P: [0, 0, 1]}
  bodies:
    arm: {angular_velocity: [0, 150, -4.6], frame: body}
    link: {angular_velocity: [1, 0, 0]}
simulate: {t_end: 5E+1, dt: 1e-3, method: rk4, output_dt: 2.5e-2}
"""

MINIMAL = """\
name: pendulum
points:
  O: {at: [0, 0, 0], fixed: true}
  P: [1, 0, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
bodies:
  rod: {points: [O, P], vector: z, mass: 1, inertia: [0, 0, 0]}
"""

# The heavy top of docs/design.md §2 with numbers: a disk, so I2 = I1 + I3 exactly.
HEAVY_TOP = """\
name: heavy_top
gravity: [0, 0, -9.81]
points:
  O: {at: [0, 0, 0], fixed: true}
  P: [0, 1, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
  u: [1, 0, 0]
bodies:
  top:
    points: [O, P]
    vector: u
    mass: 15.0
    center: [1, 0, 0]
    inertia: [0.234375, 0.46875, 0.234375, 0, 0, 0]
initial:
  bodies: {top: {angular_velocity: [0, 150, -4.6], frame: body}}
simulate: {t_end: 2.0, dt: 1.0e-3, method: rk4}
"""


def line_of(fragment: str, text: str = FULL) -> int:
    """1-based line of the first line of ``text`` that starts with ``fragment``."""
    return next(k for k, line in enumerate(text.splitlines(), 1)
                if line.startswith(fragment))


@pytest.fixture(scope="module")
def full():
    return load_model_text(FULL, "rig.yaml")


def test_names_and_source(full):
    assert full.name == "rig" and full.source == "rig.yaml"
    assert list(full.points) == ["O", "C", "P", "Q", "R", "on"]
    assert list(full.vectors) == ["z", "u", "w"]
    assert list(full.bodies) == ["arm", "link", "bob", "slider"]
    assert [p.name for p in full.moving_points] == ["P", "Q", "R", "on"]
    assert [v.name for v in full.moving_vectors] == ["u", "w"]


def test_points_short_and_long_forms(full):
    p = full.points
    assert [p[n].fixed for n in p] == [True, True, False, False, False, False]
    np.testing.assert_array_equal(p["Q"].at, [1, 1, 0])
    np.testing.assert_array_equal(p["on"].at, [2, 2, 0])
    assert p["P"].at.dtype == float and p["P"].at.shape == (3,)
    assert (p["O"].where.file, p["O"].where.line) == ("rig.yaml", line_of("  O:"))
    assert p["on"].where.line == line_of("  on:")


def test_vectors_normalised(full):
    w = full.vectors["w"].along
    raw = np.array([0, 0.6, 0.8000000004])
    # normalising divides by the norm once: the result is a unit vector to rounding
    assert abs(np.linalg.norm(w) - 1.0) < 4e-16
    np.testing.assert_array_equal(w, raw / np.linalg.norm(raw))
    assert full.vectors["z"].fixed and not full.vectors["u"].fixed


def test_bodies(full):
    arm, link, bob, slider = full.bodies.values()
    assert (arm.i, arm.j, arm.u, arm.mass) == ("O", "P", "z", 2.5)
    assert link.mass == 15.0 and slider.mass == 0.5
    np.testing.assert_array_equal(arm.center, [0, 0.5, 0])
    np.testing.assert_array_equal(link.center, [0, 0, 0])          # default
    np.testing.assert_array_equal(arm.inertia, np.diag([0.1, 0.2, 0.3]))
    np.testing.assert_array_equal(link.inertia, [[2, 0.1, 0.2], [0.1, 3, 0.3],
                                                 [0.2, 0.3, 4]])
    np.testing.assert_array_equal(bob.inertia, np.zeros((3, 3)))   # a point mass
    assert arm.where.line == line_of("  arm:")


def test_constraints(full):
    pol, dist = full.constraints
    assert isinstance(pol, PointOnLine) and pol.type == "point_on_line"
    assert pol.point == "on"
    assert pol.line == ("C", BodyPoint("arm", (0.0, 1.0, 0.0)))
    assert isinstance(dist, Distance) and dist.points == ("O", "R") and dist.length == 2.0
    assert pol.where.line == line_of("  - {type: point_on_line")
    assert dist.where.line == line_of("  - {type: distance")


def test_loads(full):
    f0, f1, torque, s0, s1 = full.loads
    assert isinstance(f0, Force) and f0.at is None and f0.body == "arm"
    np.testing.assert_array_equal(f0.value, [0, 0, -1])
    assert f1.at == (0.0, 0.5, 0.0)                                # through the alias
    assert isinstance(torque, Torque) and torque.body == "link"
    np.testing.assert_array_equal(torque.value, [0, 0, 0.5])
    assert isinstance(s0, Spring) and s0.ends == ("C", "R")
    assert (s0.stiffness, s0.length, s0.damping) == (4530.0, None, 0.0)
    assert s1.ends == ("O", BodyPoint("bob", (0.0, 0.5, 0.0)))
    assert (s1.stiffness, s1.length, s1.damping) == (10.0, 0.07785, 0.2)
    assert s1.where.line == line_of("  - {type: spring, ends: [O")


def test_initial_and_simulate(full):
    np.testing.assert_array_equal(full.initial.point_velocities["P"], [0, 0, 1])
    arm = full.initial.body_angular_velocities["arm"]
    link = full.initial.body_angular_velocities["link"]
    assert isinstance(arm, AngularVelocity) and arm.frame == "body"
    np.testing.assert_array_equal(arm.value, [0, 150, -4.6])
    assert link.frame == "global"                                  # default
    assert full.simulate == SimulateDefaults(t_end=50.0, dt=1e-3, method="rk4",
                                             output_dt=0.025)
    np.testing.assert_array_equal(full.gravity, [0, 0, -9.81])
    keys = ["name", "gravity", "points", "vectors", "bodies", "constraints", "loads",
            "initial", "simulate"]
    assert {k: w.line for k, w in full.where.items()} == {k: line_of(k) for k in keys}


def test_plan_of_full_model(full):
    plan = make_plan(full)
    assert plan.triples == [("P", "point"), ("Q", "point"), ("R", "point"),
                            ("on", "point"), ("u", "vector"), ("w", "vector")]
    assert plan.n_q == 18
    # 4 bodies x 2 rigid rows + 2 unit vectors + point_on_line 3 + distance 1
    assert plan.n_g == 4 * 2 + 2 + 3 + 1
    assert len(plan.elements) == 4 + 2 + 2 + 5
    np.testing.assert_array_equal(plan.q0[:3], [0, 1, 0])
    spring = plan.elements[[e.label for e in plan.elements].index("loads[3]")]
    free = spring.params[list(spring.cls.param_names).index("L0")]
    # omitted free length = initial distance |R - C| = |[1, 2, -1]|; one sqrt's rounding
    assert abs(free - math.sqrt(6)) < 1e-15
    assert "on.vx" in plan.columns() and "slider.wz" in plan.columns()


def test_defaults():
    model = load_model_text(MINIMAL)
    assert model.source == "<string>"
    np.testing.assert_array_equal(model.gravity, [0, 0, 0])
    assert model.constraints == [] and model.loads == []
    assert model.initial == Initial()
    assert model.simulate == SimulateDefaults(t_end=1.0, dt=1e-3, method="rk4",
                                              output_dt=None)
    np.testing.assert_array_equal(model.bodies["rod"].center, [0, 0, 0])
    assert make_plan(model).n_q == 3


def test_heavy_top_of_the_design_page():
    model = load_model_text(HEAVY_TOP, "heavy_top.yaml")
    top = model.bodies["top"]
    np.testing.assert_array_equal(np.diag(top.inertia), [0.234375, 0.46875, 0.234375])
    plan = make_plan(model)
    assert plan.n_q == 6 and plan.n_g == 3          # body: 2 rows; unit vector: 1 row
    assert model.simulate.dt == 1e-3


def test_nearly_parallel_vector_allowed():
    """sin(angle) = 2e-3 is above the 1e-3 limit, so the body is accepted."""
    model = load_model_text(MINIMAL.replace("along: [0, 0, 1]", "along: [0.999998, 2e-3, 0]"))
    assert model.vectors["z"].along[1] == pytest.approx(2e-3, rel=1e-9)  # normalised only


def test_load_from_file(tmp_path):
    path = tmp_path / "pendulum.yaml"
    path.write_text(MINIMAL)
    assert load_model(path).source == str(path)
    assert load_model(str(path)).name == "pendulum"


@pytest.mark.parametrize("text, value", [
    ("1e-3", 1e-3), ("5E+2", 500.0), ("-2.5e1", -25.0), (".5e1", 5.0), ("1.0e3", 1000.0),
    ("+1e0", 1.0), ("1.5", 1.5), ("1.0e-3", 1e-3), ("12", 12), ("-7", -7),
    ("e5", "e5"), ("1e", "1e"), ("1e-3x", "1e-3x"), ("'1e-3'", "1e-3"),
])
def test_yaml_12_floats(text, value):
    node = parse_yaml(f"x: {text}\n", "f.yaml").entries["x"]
    assert node.value == value and type(node.value) is type(value)


def test_methods_is_data():
    import fccgen.settings.methods
    assert tuple(METHODS) == tuple(fccgen.settings.methods.names())
    assert "rk4" in METHODS


def test_import_does_not_load_sympy(tmp_path):
    from conftest import run_python
    code = "import fccgen.model, sys; assert 'sympy' not in sys.modules"
    run_python(code, tmp_path)
