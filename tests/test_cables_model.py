"""The ``cables:`` section (docs/model-file.md "cables", docs/flexible.md): what a
member is lowered to, the errors of bad members, point forces, the nodes named as
points elsewhere, what ``fccgen check`` says, the stability limits it reads, the
curves the animation draws, and the strain and curvature columns."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fccgen.analysis import statics
from fccgen.analysis.cables import member_frequency, stable_step, step_advice
from fccgen.api import plan_model
from fccgen.diagnostics.check import check_model
from fccgen.errors import ModelError
from fccgen.mechanism import lower
from fccgen.mechanism.cable_outputs import cable_values
from fccgen.model import load_model_text
from fccgen.plan import make_plan
from fccgen.viz.cables import cable_lines

BASE = """
name: m
points:
  O: {at: [0, 0, 0], fixed: true}
  P: {at: [2, 0, 0], fixed: true}
cables:
  rope:
"""
MEMBER = {"from": "O", "to": "[1, 0, 0]", "elements": "4", "EA": "100.0", "EI": "1.0",
          "mass_per_length": "0.5"}


def text(extra: str = "", **member) -> str:
    fields = {**MEMBER, **member}
    lines = [f"    {k}: {v}" for k, v in fields.items() if v is not None]
    return BASE + "\n".join(lines) + "\n" + extra


def plan_of(source: str):
    return make_plan(lower(load_model_text(source, "m.yaml")))


def test_nodes_are_points_and_slopes_are_their_own_triples():
    plan = plan_of(text())
    names = [n for n, _ in plan.triples]
    assert names[:4] == ["rope.n1", "rope.n2", "rope.n3", "rope.tip"]   # n0 is O
    assert [k for n, k in plan.triples if n.endswith(".slope")] == ["slope"] * 5
    assert plan.n_q == 3 * (4 + 5) and plan.n_g == 0        # a pinned rope: no rows
    kinds = sorted(c.describe() for c in plan.classes)
    assert kinds == ["cable; fixed none; zeros c,gx,gy,gz,qx,qy,qz",
                     "cable; fixed r1; zeros c,gx,gy,gz,qx,qy,qz"]
    assert "rope.n2.slope.vz" in plan.columns() and "rope.tip.curvature" in plan.columns()


def test_both_ends_on_points_and_members_sharing_a_point():
    """Both ends pinned at named (fixed) points; a second member from the same point
    has its own slope there (slopes are named after their member)."""
    plan = plan_of(text(to="P", elements="1") + "  rope2: {from: O, to: [0, 1, 0], elements: 2, EA: 1, "
                                  "EI: 1, mass_per_length: 1}\n")
    assert plan.model.cables["rope"].nodes[-1] == "P"
    slopes = [n for n, k in plan.triples if k == "slope"]
    assert "rope.n0.slope" in slopes and "rope2.n0.slope" in slopes
    assert any(c.fixed == (True, False, True, False) for c in plan.classes)   # one element


def test_clamps_on_ground_and_on_a_moving_body():
    """A clamp on ground: two fixed normals and two linear rows; on a moving body: the
    node and two normals attached to it (3 rows each) and the two clamp rows."""
    ground = plan_of(text(**{"from": "{body: ground, at: [0, 0, 0], clamp: true}"}))
    assert ground.n_g == 2
    assert ground.model.points["rope.n0"].fixed
    body = plan_of("""
name: m
bodies:
  hub: {mass: 1, center: [0, 0, 0], inertia: [1, 1, 1]}
joints:
  - {name: J, type: revolute, bodies: [ground, hub], at: [0, 0, 0], axis: [0, 0, 1]}
cables:
  rope: {from: {body: hub, at: [0.5, 0, 0], clamp: true}, to: [1.5, 0, 0], elements: 2,
         EA: 100, EI: 1, mass_per_length: 0.5}
""")
    labels = [el.label for el in body.elements if el.label.startswith("cable rope:")]
    assert len(labels) == 1 + 2 + 2          # node, two normals, two clamp rows
    assert sum(el.cls.n_g for el in body.elements if el.label in labels) == 3 + 6 + 2


@pytest.mark.parametrize("member, item, rule", [
    ({"elements": "0"}, "cables.rope.elements", "must be a whole number in [1, 1000]"),
    ({"elements": "2.5"}, "cables.rope.elements", "must be a whole number"),
    ({"EA": "-1"}, "cables.rope.EA", "must be a positive number"),
    ({"damping": "-0.1"}, "cables.rope.damping", "must be a number >= 0"),
    ({"to": "[0, 0, 0]"}, "cables.rope.to", "is at the same place as the from end"),
    ({"to": "O"}, "cables.rope.to", "must be another point than the from end"),
    ({"to": "Q"}, "cables.rope.to", "names no point"),
    ({"to": "{body: arm, at: [1, 0, 0]}"}, "cables.rope.to.body", "names no body"),
    ({"to": "{at: [1, 0, 0]}"}, "cables.rope.to.body", "missing required key"),
    ({"to": "{body: ground, at: [1, 0, 0], clamp: 1}"}, "cables.rope.to.clamp",
     "must be true or false"),
    ({"to": "7"}, "cables.rope.to", "must be a point name"),
    ({"twist": "1"}, "cables.rope.twist", "unknown key"),
    ({"EI": None}, "cables.rope.EI", "missing required key"),
])
def test_bad_members_are_refused(member, item, rule):
    with pytest.raises(ModelError) as err:
        load_model_text(text(**member), "m.yaml")
    assert err.value.item == item and rule in err.value.rule


def test_a_cable_name_is_unique():
    with pytest.raises(ModelError, match="name already used by the point"):
        load_model_text(BASE.replace("rope:", "O:") + "    from: P\n    to: [1, 0, 0]\n"
                        "    elements: 1\n    EA: 1\n    EI: 1\n    mass_per_length: 1\n")


@pytest.mark.parametrize("load, rule", [
    ("{type: force, point: O, value: [0, 1, 0]}", "is a fixed point"),
    ("{type: force, point: nowhere, value: [0, 1, 0]}", "names no point"),
    ('{type: force, point: rope.tip, value: ["J.angle", 0, 0]}', "J.angle"),
])
def test_bad_point_forces_are_refused(load, rule):
    with pytest.raises(ModelError) as err:
        load_model_text(text("loads:\n  - " + load + "\n"), "m.yaml")
    assert rule in str(err.value)


def test_nodes_are_named_as_points_by_loads_springs_and_events():
    model = load_model_text(text("""loads:
  - {type: force, point: rope.tip, value: [0, -1, 0]}
  - {type: force, point: rope.n2, value: ["0", "sin(t)", "0"]}
  - {type: spring, ends: [rope.tip, P], stiffness: 3}
events:
  - {name: low, when: "rope.tip.y <= -0.5", do: stop}
"""), "m.yaml")
    plan = make_plan(lower(model))
    kinds = [el.cls.kind for el in plan.elements if el.label.startswith("loads")]
    assert kinds == ["point_force", "point_force_t", "spring"]
    assert model.events[0].name == "low"


def test_check_reports_members_and_their_step(tmp_path):
    """``fccgen check``: the member's line and the step advice of its method; the
    limit it gives is the largest stable RK4 step for the element modes."""
    path = tmp_path / "m.yaml"
    path.write_text(text("simulate: {t_end: 1, dt: 0.01, method: rk4}\n",
                         **{"from": "{body: ground, at: [0, 0, 0], clamp: true}"}))
    report = check_model(path).text()
    assert ("cable rope: 4 elements of 0.25, nodes rope.n0 ... rope.tip; 27 coordinates, "
            "2 constraint rows (ends: from clamped on ground; to free)") in report
    assert "rk4 at dt = 0.01 is UNSTABLE for the members: use dt <=" in report
    freq = member_frequency(plan_model(path).model.cables["rope"])
    assert freq.kind == "bending"             # sqrt(8400) sqrt(EI/rhoA)/L^2 > axial
    assert freq.omega * 0.25 ** 2 / math.sqrt(1 / 0.5) == pytest.approx(math.sqrt(8400),
                                                                         1e-9)
    assert "ali3p is implicit" in step_advice(freq, "ali3p", 0.01)


def test_stability_limits_are_the_methods_intervals():
    """RK4 on the imaginary axis to 2 sqrt 2 and on the real axis to 2.785; a damped
    mode's real pole limits the step more than its frequency."""
    assert stable_step([1j], "rk4") == pytest.approx(2 * math.sqrt(2), 1e-9)
    assert stable_step([-1.0], "rk4") == pytest.approx(2.785293563, 1e-8)
    w, c = 100.0, 0.1                      # c w = 10: overdamped, pole near -c w^2
    poles = np.roots([1.0, c * w * w, w * w])
    assert stable_step(poles, "rk4") < 2.8 / w / 5


def test_element_bound_is_above_the_highest_mode(compiled):
    """Irons's bound: the cantilever's highest natural frequency (8 elements) is at
    most its element bound, and not far below it (within a factor of 2)."""
    from fccgen.analysis import linearize, modes
    s = compiled("cantilever")
    f = modes(linearize(s, statics(s).q)).frequency_hz
    bound = member_frequency(s.plan.model.cables["beam"]).hz
    assert 0.5 * bound < f[-1] <= bound


def test_curvature_columns_and_curves_at_the_bent_cantilever(compiled):
    """Under the example's small tip load P the curvature at node x is |P| (L - x)/EI
    (the cubic elements hold it exactly but for the large-deflection correction,
    1e-6 here; 1e-4 of the root's value is allowed); the strain is zero to 1e-6; the
    animation's curve passes through every node."""
    s = compiled("cantilever")
    eq = statics(s)
    plan = s.plan
    cols = {f"{n}.{c}": np.array([eq.q[3 * k + j]]) for k, (n, _) in enumerate(plan.triples)
            for j, c in enumerate("xyz")}
    values = cable_values(plan, cols, 1)
    cable = plan.model.cables["beam"]
    P, EI, L = 0.15, 20.0, 1.0
    for k in range(cable.elements + 1):
        name = f"beam.n{k}" if k < cable.elements else "beam.tip"
        x = k * L / cable.elements
        assert values[f"{name}.curvature"][0] == pytest.approx(P * (L - x) / EI,
                                                               abs=1e-4 * P * L / EI)
        assert abs(values[f"{name}.strain"][0]) <= 1e-6

    class Result:                          # the few fields cable_lines reads
        t = np.zeros(1)
        columns = cols
    x, y, _ = cable_lines(plan.model, Result, 0)
    tip = plan.index["beam.tip"]
    assert (x[-2], y[-2]) == pytest.approx((eq.q[3 * tip], eq.q[3 * tip + 1]), abs=1e-15)
    assert y[0] == 0.0 and x.count(None) == 1
