"""Loads of the mechanism level (docs/elements.md): forces and torques given as
expressions of t, the torsion spring-damper by ``joint:`` and the linear
spring-damper along a prismatic joint; both kernel versions, closed-form dynamics
and the model file's rules."""
from __future__ import annotations

import math

import numpy as np
import pytest

import fccgen
from fccgen.errors import ModelError
from fccgen.model.load import load_model_text
from fccgen.plan.classes import ElementClass

from kernel_checks import (assert_derived_matches_numeric, assert_force_jacobians_match,
                           random_case)

F, T = False, True
CLASSES = [
    ElementClass("torque_t", (), (T, F, T), frozenset(), "0.5*sin(3*t);t**2;1"),
    ElementClass("force_t", (), (T, F, F), frozenset({"b2"}), "t;exp(-t);2"),
    ElementClass("linear_spring", (), (F, F, F), frozenset()),
    ElementClass("linear_spring", (), (T, T, F), frozenset({"L"})),
]
IDS = ["torque_t", "force_t", "linear_spring", "linear_spring-fixed"]


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_sympy_and_numpy_load_kernels_agree(cls):
    """SymPy's kernels against the NumPy version written by hand: 1e-12 of each
    kernel's largest entry (double rounding of sums of a few terms)."""
    assert_derived_matches_numeric(cls, rtol=1e-12)


@pytest.mark.parametrize("cls", CLASSES[2:], ids=IDS[2:])
def test_linear_spring_jacobians_match_finite_differences(cls):
    """df/dq, df/dq' of the NumPy version against five-point differences (h = 1e-3;
    f is quadratic in q and linear in q': exact up to rounding, checked at 1e-9)."""
    assert_force_jacobians_match(cls, *random_case(cls, 1), h=1e-3, rtol=1e-9)


# -- dynamics -------------------------------------------------------------------------

MODEL = """\
name: joint_loads
bodies:
  arm: {mass: 2.0, center: [0.4, 0, 0], inertia: [0.01, 0.05, 0.05]}
  slider: {mass: 1.5, center: [0, 1, 0], inertia: [0.01, 0.02, 0.03]}
  wheel: {mass: 1.0, center: [0, -1, 0], inertia: [0.02, 0.03, 0.04]}
joints:
  - {name: O, type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 0, 1]}
  - {name: S, type: prismatic, bodies: [ground, slider], at: [0, 1, 0], axis: [1, 0, 0]}
  - {name: W, type: revolute, bodies: [ground, wheel], at: [0, -1, 0], axis: [0, 0, 1]}
loads:
  - {type: torsion_spring, joint: O, stiffness: 3.0, angle: 0.5}
  - {type: linear_spring, joint: S, stiffness: 6.0, length: 0.2, damping: 0}
  - {type: torque, body: wheel, value: [0, 0, "0.5*sin(3*t)"]}
simulate: {t_end: 3.0, dt: 1.0e-3, output_dt: 0.01}
"""
I_ARM = 0.05 + 2.0 * 0.4 ** 2          # about the hinge (parallel axes)
I_WHEEL = 0.04                         # about its mass centre, on the axis


@pytest.fixture(scope="module")
def loaded(tmp_path_factory):
    path = tmp_path_factory.mktemp("joint_loads") / "joint_loads.yaml"
    path.write_text(MODEL)
    return path


def test_joint_springs_and_timed_torque_follow_closed_forms(loaded, build_dir):
    """From rest: the arm's angle 0.5 (1 - cos w t), w = sqrt(k/I), the slider's
    position 0.2 (1 - cos w t), w = sqrt(k/m), and the wheel under 0.5 sin 3t turns
    by (0.5 / 3I) (t - sin(3t) / 3). RK4 at 1 ms over 3 s: global error ~dt^4 w^5 t,
    well below 1e-9; checked at 1e-9 (rad, m). The period of the torsion spring is
    2 pi sqrt(I/k) by the same closed form. The springs' potentials are in the
    energy, which the timed torque changes by its work only: E(t) - E(0) = the wheel's
    kinetic energy (1e-9 J)."""
    r = fccgen.load(loaded, build_dir).simulate()
    w_arm, w_slide = math.sqrt(3.0 / I_ARM), math.sqrt(6.0 / 1.5)
    assert np.max(np.abs(r["O.angle"] - 0.5 * (1 - np.cos(w_arm * r.t)))) <= 1e-9
    assert np.max(np.abs(r["S.position"] - 0.2 * (1 - np.cos(w_slide * r.t)))) <= 1e-9
    wheel = 0.5 / (3 * I_WHEEL) * (r.t - np.sin(3 * r.t) / 3)
    assert np.max(np.abs(r["W.angle"] - wheel)) <= 1e-9
    wheel_energy = I_WHEEL * (0.5 / (3 * I_WHEEL) * (1 - np.cos(3 * r.t))) ** 2 / 2
    assert np.max(np.abs(r["energy"] - r["energy"][0] - wheel_energy)) <= 1e-9
    assert r["energy"][0] > 0.3                       # the springs start stretched


def test_joint_loads_numeric_and_compiled_agree(loaded, build_dir):
    """The same 0.2 s run in both versions: the same method on the same equations,
    agreement to rounding (1e-12 rad, m)."""
    cs, ns = fccgen.load(loaded, build_dir), fccgen.load_numeric(loaded)
    rc, rn = cs.simulate(t_end=0.2), ns.simulate(t_end=0.2)
    for col in ("O.angle", "S.position", "W.angle"):
        assert np.max(np.abs(rc[col] - rn[col])) <= 1e-12


# -- the model file's rules -----------------------------------------------------------

ERRORS = [
    ("unknown joint", ("joint: O, stiffness: 3.0", "joint: Q, stiffness: 3.0"),
     "loads[0].joint", "names no joint", "Q"),
    ("torsion on a slider", ("joint: O, stiffness: 3.0", "joint: S, stiffness: 3.0"),
     "loads[0].joint", "a torsion_spring acts on the freedom of a revolute", "S"),
    ("linear on a hinge", ("joint: S, stiffness: 6.0", "joint: O, stiffness: 6.0"),
     "loads[1].joint", "a linear_spring acts on the freedom of a prismatic", "O"),
    ("free angle", ("angle: 0.5", "angle: .inf"), "loads[0].angle", "must be a finite",
     float("inf")),
    ("negative stiffness", ("stiffness: 6.0", "stiffness: -6.0"), "loads[1].stiffness",
     "", -6.0),
    ("bad expression", ('"0.5*sin(3*t)"', '"__import__(3)"'), "loads[2].value[2]",
     "calls only", "__import__(3)"),
    ("joint quantity", ('"0.5*sin(3*t)"', '"O.position"'), "loads[2].value[2]",
     "O has no quantity 'position'", "O.position"),
    ("linear spring keys", ("length: 0.2", "angle: 0.2"), "loads[1].angle", "unknown key",
     None),
]


@pytest.mark.parametrize("edit, item, rule, value", [c[1:] for c in ERRORS],
                         ids=[c[0] for c in ERRORS])
def test_joint_load_errors(edit, item, rule, value):
    assert edit[0] in MODEL
    with pytest.raises(ModelError) as info:
        load_model_text(MODEL.replace(edit[0], edit[1]), "m.yaml")
    err = info.value
    assert err.item == item and rule in err.rule, str(err)
    assert err.line is not None and err.file == "m.yaml"
    if value is not None:
        assert err.value == value
