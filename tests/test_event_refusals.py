"""Event combinations that cannot do what they say are refused when the model file is
read, with file, line, item, rule and value (they used to run and exit 0):

* a bounce on an event function that reads speeds (docs/events.md refused it in
  words only): Newton's law needs the function's gradient in the positions;
* a lock, unlock or bounce on a joint a driver prescribes, and limits on such a joint:
  the driver kept turning a locked joint and the run warned with a wrong reason.
"""
from __future__ import annotations

import pytest

from fccgen.errors import ModelError
from fccgen.model.load import load_model_text

BASE = """\
name: hinge
gravity: [0, 0, -9.81]
bodies:
  arm: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-4, 0.08, 0.08]}
  ball: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-4, 0.08, 0.08]}
joints:
  - {name: A, type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 1, 0]%s}
  - {name: B, type: revolute, bodies: [arm, ball], at: [1, 0, 0], axis: [0, 1, 0]}
"""
DRIVER = "drivers:\n  - {name: motor, joint: A, angle: '2*t'}\n"


def load(events: str = "", limits: str = "", drivers: str = ""):
    return load_model_text(BASE % limits + drivers + (f"events:\n{events}" if events
                                                      else ""), "m.yaml")


@pytest.mark.parametrize("when", ["A.rate", "B.angle + 0.1*B.rate", "B.angle*A.rate"])
def test_a_bounce_on_a_function_of_speeds_is_refused(when):
    with pytest.raises(ModelError) as info:
        load(f"  - {{name: e, when: '{when}', direction: falling, do: bounce}}\n")
    err = info.value
    assert (err.file, err.line, err.item) == ("m.yaml", 10, "events[0].when")
    assert "reads speeds, but a bounce needs an event function of positions" in err.rule
    assert err.value == when


def test_speeds_still_log_and_stop_and_positions_still_bounce():
    m = load("  - {name: e1, when: 'A.rate', direction: falling, do: log}\n"
             "  - {name: e2, when: 'B.rate >= 3', do: stop}\n"
             "  - {name: e3, when: 'B.angle - t', direction: falling, do: bounce}\n")
    assert [e.action for e in m.events] == ["log", "stop", "bounce"]


@pytest.mark.parametrize("action", ["lock", "unlock", "bounce"])
def test_an_event_on_a_driven_joint_is_refused(action):
    with pytest.raises(ModelError) as info:
        load(f"  - {{name: e, when: 'A.angle >= 1', do: {action}, joint: A}}\n",
             drivers=DRIVER)
    err = info.value
    assert (err.file, err.line, err.item) == ("m.yaml", 12, "events[0].joint")
    assert err.rule.startswith("is driven by driver 'motor', which prescribes its motion")
    assert err.value == "A"


def test_limits_on_a_driven_joint_are_refused():
    with pytest.raises(ModelError) as info:
        load(limits=", limits: [-1, 1]", drivers=DRIVER)
    err = info.value
    assert (err.file, err.line, err.item) == ("m.yaml", 7, "joints.A.limits")
    assert "driven by driver 'motor'" in err.rule and err.value == [-1.0, 1.0]


def test_other_joints_of_a_driven_model_lock():
    m = load("  - {name: e, when: 'B.angle >= 1', do: lock, joint: B}\n"
             "  - {name: f, when: 'A.angle >= 1', do: log}\n", drivers=DRIVER)
    assert [e.joint for e in m.events] == ["B", None]
