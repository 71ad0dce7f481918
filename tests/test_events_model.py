"""Reading ``events:`` and joint ``limits:`` (fccgen.model.events): what is kept, and
every rule broken named with file, line, item, rule and value."""
from __future__ import annotations

import pytest
import sympy

from fccgen.errors import ModelError
from fccgen.model.load import load_model_text

BASE = """\
name: hinge
gravity: [0, 0, -9.81]
points:
  Q: {at: [0, 0, 1], fixed: true}
bodies:
  arm: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-4, 0.08, 0.08]}
  ball: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-4, 0.08, 0.08]}
joints:
  - {name: A, type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 1, 0]%s}
  - {name: B, type: spherical, bodies: [arm, ball], at: [1, 0, 0]}
"""


def load(events: str = "", limits: str = ""):
    text = BASE % limits + (f"events:\n{events}" if events else "")
    return load_model_text(text, "m.yaml")


def test_events_and_limits_are_read():
    m = load("  - {name: e1, when: 'A.angle >= 3.14159', do: lock, joint: A}\n"
             "  - {name: e2, when: 'Q.z - t', direction: either, do: log}\n"
             "  - {name: e3, when: 'A.rate < 0', direction: rising, do: stop}\n",
             ", limits: [-1, 2], restitution: 0.25")
    by = {e.name: e for e in m.events}
    assert list(by) == ["A_lower", "A_upper", "e1", "e2", "e3"]
    a = sympy.Symbol("A.angle", real=True)
    assert by["A_lower"].function == a + 1.0 and by["A_lower"].direction == "falling"
    assert by["A_upper"].function == a - 2.0 and by["A_upper"].restitution == 0.25
    assert by["A_upper"].action == "bounce" and by["A_upper"].joint == "A"
    assert by["e1"].direction == "rising" and by["e1"].joint == "A"
    assert by["e2"].direction == "either" and by["e2"].where.line == 13
    assert by["e3"].direction == "rising"          # the key overrides the operator


@pytest.mark.parametrize("events, limits, line, item, rule, value", [
    ("  - {name: e, when: 'C.angle >= 1', do: log}\n", "", 12, "events[0].when",
     "unknown name", "C.angle >= 1"),
    ("  - {name: e, when: 'B.angle >= 1', do: log}\n", "", 12, "events[0].when",
     "unknown name", "B.angle >= 1"),
    ("  - {name: e, when: 'A.angle >= 1', do: lock, joint: B}\n", "", 12,
     "events[0].joint", "names a spherical joint, which has no angle or slide to lock",
     "B"),
    ("  - {name: e, when: 'A.angle >= 1', do: lock}\n", "", 12, "events[0].joint",
     "missing required key", None),
    ("  - {name: e, when: 'A.angle >= 1', do: bounce, joint: A, restitution: 1.5}\n", "",
     12, "events[0].restitution", "must be a restitution from 0 to 1", "1.5"),
    ("  - {name: e, when: 'A.angle >= 1', do: bounce, restitution: -0.1}\n", "",
     12, "events[0].restitution", "must be a restitution from 0 to 1", "-0.1"),
    ("  - {name: e, when: 'A.angle >= 1', do: explode}\n", "", 12, "events[0].do",
     "unknown action", "explode"),
    ("  - {name: e, when: 'A.angle', direction: up, do: log}\n", "", 12,
     "events[0].direction", "unknown direction", "up"),
    ("  - {name: e, when: 'A.angle >= 1', do: log, joint: A}\n", "", 12,
     "events[0].joint", "applies only to lock, unlock and bounce", "A"),
    ("  - {name: e, when: 'A.angle == 1', do: log}\n", "", 12, "events[0].when",
     "compares with >=", "A.angle == 1"),
    ("  - {name: e, when: 'A.angle >= 1', do: log}\n"
     "  - {name: e, when: 'A.angle >= 2', do: log}\n", "", 13, "events[1].name",
     "is the name of another event", "e"),
    ("", ", limits: [1, 2]", 9, "joints[0].limits", "lower <= 0 <= upper", "[1, 2]"),
    ("", ", limits: [-1, 2], restitution: 2", 9, "joints[0].restitution",
     "must be a restitution from 0 to 1", "2"),
    ("", ", restitution: 0.5", 9, "joints[0].restitution",
     "applies only to a joint with limits", "0.5"),
])
def test_bad_events_name_file_line_item_rule_value(events, limits, line, item, rule,
                                                     value):
    with pytest.raises(ModelError) as info:
        load(events, limits)
    err = info.value
    assert (err.file, err.line, err.item) == ("m.yaml", line, item), str(err)
    assert rule in err.rule, str(err)
    if value is not None:
        assert value in str(err.value), str(err)
