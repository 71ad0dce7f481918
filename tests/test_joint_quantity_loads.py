"""Forces and torques whose expressions read joint quantities (kinds force_q,
torque_q; docs/elements.md "Loads of joint quantities"): both kernel versions, the
equivalence with the spring-damper elements and the model file's rules."""
from __future__ import annotations

import numpy as np
import pytest

import fccgen
from fccgen import api
from fccgen.errors import ModelError
from fccgen.model.load import load_model_text
from fccgen.plan.classes import ElementClass

from kernel_checks import (assert_derived_matches_numeric, assert_force_jacobians_match,
                           random_case)

F, T = False, True
# body (ri, rj, u), then the joint families' triples (position: u, ra, rb; angle:
# A.ri, A.rj, B.ri, B.rj, u)
POSITION = ElementClass("force_q", (), (F, T, F, F, F, T), frozenset({"b2"}),
                        "S:position|-3*S.position - 0.2*S.speed;t*S.speed**2;1")
# max and min are written with abs for the derivation (fccgen.derive.joint_loads)
MINMAX = ElementClass("force_q", (), (F, T, F, F, F, T), frozenset(),
                      "S:position|max(S.position, 0.1*t, S.speed);min(S.speed, 1);1")
ANGLE = ElementClass("torque_q", (), (T, F, F, T, T, F, F, F), frozenset(),
                     "A:angle|0;-2*A.angle - 0.3*A.rate;sin(t)*A.rate**2")
BOTH = ElementClass("force_q", (), (F, F, F, F, F, F, T, F, F, T, T), frozenset(),
                    "S:position,C:angle|S.speed*t;exp(-S.position)*C.angle;C.rate")


@pytest.mark.parametrize("cls", [POSITION, MINMAX], ids=["position", "min-max"])
def test_sympy_and_numpy_kernels_agree(cls):
    """SymPy's kernels of a position-reading force against the NumPy version: 1e-12
    of each kernel's largest entry (rounding of sums of a few terms). The
    angle-reading classes are compared compiled against numeric in the runs below."""
    assert_derived_matches_numeric(cls, rtol=1e-12)


@pytest.mark.parametrize("cls", [POSITION, ANGLE, BOTH], ids=["position", "angle", "both"])
def test_numeric_jacobians_match_finite_differences(cls):
    """df/dq, df/dq' of the NumPy version against five-point differences (h = 1e-4:
    truncation ~h^4 f^(5) ~ 1e-14 times the local scale, rounding ~1e-16/h = 1e-12;
    checked at 1e-8 relative). Random q are off the rigid-body manifold, which the
    kernels do not need."""
    assert_force_jacobians_match(cls, *random_case(cls, 2), h=1e-4, rtol=1e-8)


# -- the same motion as the spring-damper elements -----------------------------------

def model(arm_load: str, slider_load: str) -> str:
    return f"""\
name: quantity_loads
gravity: [0, -9.81, 0]
bodies:
  arm: {{mass: 2.0, center: [0.4, 0, 0], inertia: [0.01, 0.05, 0.05]}}
  slider: {{mass: 1.5, center: [0, 1, 0], inertia: [0.01, 0.02, 0.03]}}
joints:
  - {{name: O, type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 0, 1]}}
  - {{name: S, type: prismatic, bodies: [ground, slider], at: [0, 1, 0], axis: [1, 0, 0]}}
loads:
  - {arm_load}
  - {slider_load}
initial:
  joints: {{O: {{rate: 2.0}}, S: {{speed: 0.5}}}}
simulate: {{t_end: 1.0, dt: 1.0e-3, output_dt: 0.01}}
"""


ELEMENTS = model("{type: torsion_spring, joint: O, stiffness: 3.0, damping: 0.2}",
                 "{type: linear_spring, joint: S, stiffness: 6.0, length: 0, damping: 0}")
EXPRESSIONS = model('{type: torque, body: arm, value: [0, 0, "-3*O.angle - 0.2*O.rate"]}',
                    '{type: force, body: slider, value: ["-6*S.position", 0, 0]}')


@pytest.fixture(scope="module")
def runs(tmp_path_factory, build_dir):
    out = {}
    for name, text in (("elements", ELEMENTS), ("expressions", EXPRESSIONS)):
        path = tmp_path_factory.mktemp(name) / f"{name}.yaml"
        path.write_text(text)
        out[name] = (fccgen.load(path, build_dir).simulate(),
                     fccgen.load_numeric(path).simulate(t_end=0.1), path)
    return out


def test_expression_loads_move_as_the_spring_elements(runs):
    """A torque -k O.angle - c O.rate on a hinged arm (gravity in the hinge plane, so
    the arm swings about a moving equilibrium) and a force -k S.position on a slider
    give the trajectories of the torsion_spring and linear_spring elements: the same
    generalized forces written another way (other rounding, and so other iterates of
    the projections, which stop at their tolerance rather than at rounding): the
    same trajectory to 1e-10 rad, m over 1 s; rates and speeds to 1e-9 (measured
    2e-10 rad/s: they carry the velocity projection's stopping error)."""
    a, b = runs["elements"][0], runs["expressions"][0]
    for col, tol in (("O.angle", 1e-10), ("O.rate", 1e-9), ("S.position", 1e-10),
                     ("S.speed", 1e-9)):
        assert np.max(np.abs(a[col] - b[col])) <= tol, col
    assert np.ptp(a["O.angle"]) > 0.3 and np.ptp(a["S.position"]) > 0.1   # it moves


def test_expression_loads_give_the_spring_elements_reactions(runs):
    """The reaction balance takes each expression load's value as the run held it
    (tests/test_expression_load_reactions.py): the expression model's joint reactions
    are the spring elements' to 1e-8 N, N m (its trajectory differs by 1e-10; measured
    8e-10 N against 40 N)."""
    expr, elem = runs["expressions"][0], runs["elements"][0]
    assert expr.info["reactions"]["computed"] and expr.info["reactions"]["unique"]
    for joint in "OS":
        for c in ("fx", "fy", "fz", "tx", "ty", "tz"):
            name = f"{joint}.{c}"
            assert np.max(np.abs(expr[name] - elem[name])) <= 1e-8, name
    assert np.max(np.abs(elem["O.fy"])) > 10.0


def test_expression_loads_compiled_and_numeric_agree(runs):
    """0.1 s of the expression model in both versions: the same method on the same
    equations, agreement to rounding (1e-12 rad, m)."""
    rc, rn, _ = runs["expressions"]
    for col in ("O.angle", "S.position"):
        n = len(rn[col])
        assert np.max(np.abs(rc[col][:n] - rn[col])) <= 1e-12, col


def test_expression_loads_have_the_spring_elements_tangents(runs, build_dir):
    """Modes about the static equilibrium use df/dq and df/dq' (the compiled
    Jacobians): the expression model's frequencies and damping ratios are the spring
    elements' to 1e-9 relative (the equilibrium is solved to its tolerance, ~1e-12)."""
    (a, _), (b, _) = (api.modes(runs[n][2], build_dir=build_dir)
                      for n in ("elements", "expressions"))
    assert np.allclose(a.frequency_hz, b.frequency_hz, rtol=1e-9, atol=0)
    assert np.allclose(a.damping_ratio, b.damping_ratio, rtol=1e-9, atol=1e-12)
    assert np.max(a.damping_ratio) > 0.01                 # the dampers are felt


# -- the model file's rules -----------------------------------------------------------

ERRORS = [
    ("unknown joint", ("-3*O.angle", "-3*Q.angle"), "loads[0].value[2]",
     "unknown name 'Q.angle'", "-3*Q.angle - 0.2*O.rate"),
    ("quantity the joint lacks", ("-3*O.angle", "-3*O.position"), "loads[0].value[2]",
     "O has no quantity 'position' (it has O.angle, O.rate)",
     "-3*O.position - 0.2*O.rate"),
    ("slider angle", ("-6*S.position", "-6*S.angle"), "loads[1].value[0]",
     "S has no quantity 'angle'", "-6*S.angle"),
    ("attribute call", ("-6*S.position", "S.position.real"), "loads[1].value[0]",
     "attribute access is only Joint.quantity", "S.position.real"),
]


@pytest.mark.parametrize("edit, item, rule, value", [c[1:] for c in ERRORS],
                         ids=[c[0] for c in ERRORS])
def test_quantity_load_errors(edit, item, rule, value):
    assert edit[0] in EXPRESSIONS
    with pytest.raises(ModelError) as info:
        load_model_text(EXPRESSIONS.replace(edit[0], edit[1]), "m.yaml")
    err = info.value
    assert err.item == item and rule in err.rule, str(err)
    assert err.line is not None and err.file == "m.yaml"
    assert err.value == value
