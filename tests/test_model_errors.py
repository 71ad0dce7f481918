"""Every rule of the model loader, provoked once: file, line, item, rule and value.

Each case edits a valid model (BASE) by text replacement. The line the error must name
carries the marker ``#<`` in the edited text, so the expected line is read from the
text itself instead of being counted by hand.
"""
import math
from pathlib import Path

import pytest

from fccgen.errors import ModelError, shown
from fccgen.model import load_model, load_model_text

SOURCE = "slider.yaml"
MARK = "#<"
HIDDEN = object()          # the rule shows no value (e.g. a missing key)

BASE = """\
name: slider
gravity: [0, 0, -9.81]
points:
  O: {at: [0, 0, 0], fixed: true}
  A: [1, 0, 0]
  B: [2, 0, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
  u: [0, 1, 0]
bodies:
  crank:
    points: [O, A]
    vector: z
    mass: 1.0
    center: [0.5, 0, 0]
    inertia: [0.01, 0.1, 0.1]
  rod:
    points: [A, B]
    vector: u
    mass: 2.0
    inertia: [0.02, 0.2, 0.2, 0, 0, 0]
constraints:
  - {type: point_on_line, point: B, line: [O, {body: crank, at: [2, 0, 0]}]}
  - {type: distance, points: [O, B], length: 2.0}
loads:
  - {type: force, body: rod, value: [0, 1, 0]}
  - {type: torque, body: crank, value: [0, 0, 1]}
  - {type: spring, ends: [O, {body: rod, at: [0.5, 0, 0]}], stiffness: 100, damping: 0.5}
initial:
  points: {A: [0, 1, 0]}
  bodies: {crank: {angular_velocity: [0, 0, 1], frame: global}}
simulate: {t_end: 2.0, dt: 1e-3, method: rk4, output_dt: 1e-2}
"""

POINT_ON_LINE = "  - {type: point_on_line, point: B, line: [O, {body: crank, at: [2, 0, 0]}]}"
DISTANCE = "  - {type: distance, points: [O, B], length: 2.0}"
FORCE = "  - {type: force, body: rod, value: [0, 1, 0]}"
TORQUE = "  - {type: torque, body: crank, value: [0, 0, 1]}"
SPRING = ("  - {type: spring, ends: [O, {body: rod, at: [0.5, 0, 0]}], stiffness: 100, "
          "damping: 0.5}")
INITIAL_BODIES = "  bodies: {crank: {angular_velocity: [0, 0, 1], frame: global}}"
SIMULATE = "simulate: {t_end: 2.0, dt: 1e-3, method: rk4, output_dt: 1e-2}"


def block(start: str, end: str) -> str:
    """The lines of BASE from the line starting with ``start`` up to ``end``."""
    return BASE[BASE.index(start):BASE.index(end)]


POINTS_BLOCK = block("points:\n", "vectors:")
BODIES_BLOCK = block("bodies:\n", "constraints:")
CONSTRAINTS_BLOCK = block("constraints:\n", "loads:")
TOP_KEYS = "name, points, bodies, gravity, vectors, constraints, loads, initial, simulate"


def sub(old, new):
    """One text edit of BASE."""
    return (old, new)


# (id, edits, item, rule fragment, value seen)
CASES = [
    # top level
    ("unknown top key", [sub("name: slider", "name: slider\ncolour: red #<")],
     "colour", f"unknown key; expected one of: {TOP_KEYS}", "colour"),
    ("missing name", [sub("name: slider\ngravity: [0, 0, -9.81]",
                          "gravity: [0, 0, -9.81] #<")],
     "name", "missing required key", HIDDEN),
    ("name pattern", [sub("name: slider", "name: 2slider #<")],
     "name", "must be a name matching [A-Za-z_][A-Za-z0-9_]*", "2slider"),
    ("name too long", [sub("name: slider", "name: " + "s" * 65 + " #<")],
     "name", "must be at most 64 characters long", "s" * 65),
    ("name keyword", [sub("name: slider", "name: class #<")],
     "name", "must not be a Python keyword", "class"),
    ("name not scalar", [sub("name: slider", "name: [slider] #<")],
     "name", "must be a name", ["slider"]),
    ("gravity length", [sub("gravity: [0, 0, -9.81]", "gravity: [0, -9.81] #<")],
     "gravity", "must be a list of 3 numbers", [0, -9.81]),
    ("gravity entry", [sub("gravity: [0, 0, -9.81]", "gravity: [0, 0, g] #<")],
     "gravity[2]", "must be a number", "g"),
    ("gravity bool", [sub("gravity: [0, 0, -9.81]", "gravity: [0, 0, true] #<")],
     "gravity[2]", "must be a number", True),
    ("gravity not finite", [sub("gravity: [0, 0, -9.81]", "gravity: [0, 0, .inf] #<")],
     "gravity[2]", "must be a finite number", math.inf),
    # points and vectors
    ("point name pattern", [sub("  B: [2, 0, 0]", "  B: [2, 0, 0]\n  2C: [3, 0, 0] #<")],
     "points.2C", "must be a name matching", "2C"),
    ("duplicate yaml key", [sub("  B: [2, 0, 0]", "  B: [2, 0, 0]\n  B: [5, 0, 0] #<")],
     "points.B", "duplicate key (first given on line 6)", "B"),
    ("vector named like a point", [sub("  u: [0, 1, 0]", "  u: [0, 1, 0]\n  A: {along: [0, 0, 1], fixed: true} #<")],
     "vectors.A", "name already used by the point on line 5", "A"),
    ("body named like a vector", [sub("  rod:", "  u: #<")],
     "bodies.u", "name already used by the vector on line 9", "u"),
    ("point long form unknown key",
     [sub("  O: {at: [0, 0, 0], fixed: true}", "  O: {at: [0, 0, 0], fixed: true, mass: 1} #<")],
     "points.O.mass", "unknown key; expected one of: at, fixed", "mass"),
    ("point long form missing at", [sub("  O: {at: [0, 0, 0], fixed: true}", "  O: {fixed: true} #<")],
     "points.O.at", "missing required key", HIDDEN),
    ("fixed not bool", [sub("  O: {at: [0, 0, 0], fixed: true}", "  O: {at: [0, 0, 0], fixed: 1} #<")],
     "points.O.fixed", "must be true or false", 1),
    ("point short form length", [sub("  A: [1, 0, 0]", "  A: [1, 0] #<")],
     "points.A", "must be a list of 3 numbers", [1, 0]),
    ("points not a mapping", [sub(POINTS_BLOCK, "points: [O, A, B] #<\n")],
     "points", "must be a mapping", ["O", "A", "B"]),
    ("vector not unit", [sub("  u: [0, 1, 0]", "  u: [0, 1.1, 0] #<")],
     "vectors.u", "must be a unit vector (|v| = 1 within 1e-09)", [0, 1.1, 0]),
    ("vector just off unit", [sub("  u: [0, 1, 0]", "  u: [0, 1.000000002, 0] #<")],
     "vectors.u", "must be a unit vector", [0, 1.000000002, 0]),
    ("vector long form unknown key",
     [sub("  z: {along: [0, 0, 1], fixed: true}", "  z: {at: [0, 0, 1], fixed: true} #<")],
     "vectors.z.at", "unknown key; expected one of: along, fixed", "at"),
    # bodies
    ("bodies empty", [sub(BODIES_BLOCK, "bodies: {} #<\n")],
     "bodies", "must name at least one body", {}),
    ("body unknown key", [sub("    mass: 1.0", "    mass: 1.0\n    colour: red #<")],
     "bodies.crank.colour", "unknown key; expected one of: points, vector, mass, inertia, center",
     "colour"),
    ("body missing mass", [sub("    points: [O, A]", "    points: [O, A] #<"),
                           sub("    mass: 1.0\n", "")],
     "bodies.crank.mass", "missing required key", HIDDEN),
    ("body three points", [sub("    points: [O, A]", "    points: [O, A, B] #<")],
     "bodies.crank.points", "must be a list of 2 items, not 3", ["O", "A", "B"]),
    ("body unknown point", [sub("    points: [O, A]", "    points: [O, Q] #<")],
     "bodies.crank.points[1]", "names no point; points are: O, A, B", "Q"),
    ("body same point twice", [sub("    points: [O, A]", "    points: [A, A] #<")],
     "bodies.crank.points", "must be two different points", ["A", "A"]),
    ("body unknown vector", [sub("    vector: z", "    vector: w #<")],
     "bodies.crank.vector", "names no vector; vectors are: z, u", "w"),
    ("mass negative", [sub("    mass: 1.0", "    mass: -1.0 #<")],
     "bodies.crank.mass", "must be a positive number", -1.0),
    ("mass zero", [sub("    mass: 1.0", "    mass: 0 #<")],
     "bodies.crank.mass", "must be a positive number", 0),
    ("mass text", [sub("    mass: 1.0", "    mass: heavy #<")],
     "bodies.crank.mass", "must be a number", "heavy"),
    ("mass overflows", [sub("    mass: 1.0", "    mass: 1" + "0" * 400 + " #<")],
     "bodies.crank.mass", "must be a finite number", 10 ** 400),
    ("center length", [sub("    center: [0.5, 0, 0]", "    center: [0.5, 0] #<")],
     "bodies.crank.center", "must be a list of 3 numbers", [0.5, 0]),
    ("inertia length", [sub("    inertia: [0.01, 0.1, 0.1]", "    inertia: [0.01, 0.1, 0.1, 0] #<")],
     "bodies.crank.inertia", "must be a list of 3 or 6 numbers", [0.01, 0.1, 0.1, 0]),
    ("inertia negative", [sub("    inertia: [0.01, 0.1, 0.1]", "    inertia: [0.01, -0.1, 0.1] #<")],
     "bodies.crank.inertia", "must be positive definite (or all zero for a point mass); "
     "its principal moments are -0.1, 0.01, 0.1", [0.01, -0.1, 0.1]),
    ("inertia indefinite tensor",
     [sub("    inertia: [0.02, 0.2, 0.2, 0, 0, 0]", "    inertia: [1, 1, 1, 2, 0, 0] #<")],
     "bodies.rod.inertia", "its principal moments are -1, 1, 3", [1, 1, 1, 2, 0, 0]),
    ("inertia semidefinite", [sub("    inertia: [0.01, 0.1, 0.1]", "    inertia: [0, 0.1, 0.1] #<")],
     "bodies.crank.inertia", "must be positive definite", [0, 0.1, 0.1]),
    ("inertia triangle", [sub("    inertia: [0.01, 0.1, 0.1]", "    inertia: [0.01, 0.1, 0.2] #<")],
     "bodies.crank.inertia", "principal moments 0.01, 0.1, 0.2 break the triangle inequality",
     [0.01, 0.1, 0.2]),
    # I3 - (I1 + I2) = 1e-8 > 1e-9 * (I1 + I2 + I3): outside the tolerance
    ("inertia triangle just broken",
     [sub("    inertia: [0.01, 0.1, 0.1]", "    inertia: [1, 1, 2.00000001] #<")],
     "bodies.crank.inertia", "break the triangle inequality", [1, 1, 2.00000001]),
    ("body points coincide", [sub("  B: [2, 0, 0]", "  B: [1, 0, 0]"),
                              sub("    points: [A, B]", "    points: [A, B] #<")],
     "bodies.rod.points", "points A and B are at the same place [1, 0, 0]", ["A", "B"]),
    ("vector parallel", [sub("  u: [0, 1, 0]", "  u: [1, 0, 0]"),
                         sub("    vector: u", "    vector: u #<")],
     "bodies.rod.vector", "vector u is parallel to the line from A to B (angle 0 degrees)", "u"),
    ("vector antiparallel", [sub("  u: [0, 1, 0]", "  u: [-1, 0, 0]"),
                             sub("    vector: u", "    vector: u #<")],
     "bodies.rod.vector", "(angle 180 degrees)", "u"),
    # sin(angle) = 1e-4 < 1e-3: too parallel; |u| - 1 = 5e-9 - 5e-9 passes the unit rule
    ("vector nearly parallel", [sub("  u: [0, 1, 0]", "  u: [0.999999995, 1e-4, 0]"),
                                sub("    vector: u", "    vector: u #<")],
     "bodies.rod.vector", "(angle 0.00573 degrees); a body needs sin(angle) >= 0.001", "u"),
    ("moving point in no body", [sub("  B: [2, 0, 0]", "  B: [2, 0, 0]\n  C: [3, 0, 0] #<")],
     "points.C", "moving point belongs to no body, so it has no mass", "C"),
    ("moving vector in no body", [sub("  u: [0, 1, 0]", "  u: [0, 1, 0]\n  w: [1, 0, 0] #<")],
     "vectors.w", "moving vector belongs to no body, so it has no mass", "w"),
    # constraints
    ("constraints not a list", [sub(CONSTRAINTS_BLOCK, "constraints: 3 #<\n")],
     "constraints", "must be a list", 3),
    ("constraint missing type", [sub(DISTANCE, "  - {points: [O, B], length: 2.0} #<")],
     "constraints[1].type", "missing required key", HIDDEN),
    ("constraint unknown type", [sub(DISTANCE, DISTANCE.replace("distance", "gap") + " #<")],
     "constraints[1].type", "unknown type; expected one of: point_on_line, distance", "gap"),
    ("constraint unknown key", [sub(DISTANCE, DISTANCE.replace("}", ", stiff: 1} #<"))],
     "constraints[1].stiff", "unknown key; expected one of: type, points, length", "stiff"),
    ("constraint missing length", [sub(DISTANCE, "  - {type: distance, points: [O, B]} #<")],
     "constraints[1].length", "missing required key", HIDDEN),
    ("line end unknown point", [sub(POINT_ON_LINE, "  - {type: point_on_line, point: B, line: [O, Q]} #<")],
     "constraints[0].line[1]", "names no point; points are: O, A, B", "Q"),
    ("line end unknown body", [sub(POINT_ON_LINE, POINT_ON_LINE.replace("crank", "shaft") + " #<")],
     "constraints[0].line[1].body", "names no body; bodies are: crank, rod", "shaft"),
    ("body point unknown key", [sub(POINT_ON_LINE, POINT_ON_LINE.replace("at:", "pos:") + " #<")],
     "constraints[0].line[1].pos", "unknown key; expected one of: body, at", "pos"),
    ("body point missing at",
     [sub(POINT_ON_LINE, "  - {type: point_on_line, point: B, line: [O, {body: crank}]} #<")],
     "constraints[0].line[1].at", "missing required key", HIDDEN),
    ("line of one point", [sub(POINT_ON_LINE, "  - {type: point_on_line, point: B, line: [O, O]} #<")],
     "constraints[0].line", "must name different points", ["O", "O"]),
    ("point on its own line", [sub(POINT_ON_LINE, "  - {type: point_on_line, point: O, line: [O, A]} #<")],
     "constraints[0].point", "must not be an end of its own line", "O"),
    ("distance length zero", [sub(DISTANCE, DISTANCE.replace("2.0", "0") + " #<")],
     "constraints[1].length", "must be a positive number", 0),
    ("distance one point", [sub(DISTANCE, "  - {type: distance, points: [O], length: 2.0} #<")],
     "constraints[1].points", "must be a list of 2 items, not 1", ["O"]),
    # loads
    ("load unknown type", [sub(FORCE, FORCE.replace("force", "push") + " #<")],
     "loads[0].type", "unknown type; expected one of: force, torque, spring", "push"),
    ("force unknown body", [sub(FORCE, FORCE.replace("rod", "shaft") + " #<")],
     "loads[0].body", "names no body; bodies are: crank, rod", "shaft"),
    ("force at length", [sub(FORCE, FORCE.replace("}", ", at: [0.1, 0]} #<"))],
     "loads[0].at", "must be a list of 3 numbers", [0.1, 0]),
    ("force missing value", [sub(FORCE, "  - {type: force, body: rod} #<")],
     "loads[0].value", "missing required key", HIDDEN),
    ("torque has no point", [sub(TORQUE, TORQUE.replace("}", ", at: [0, 0, 0]} #<"))],
     "loads[1].at", "unknown key; expected one of: type, body, value", "at"),
    ("spring stiffness negative", [sub(SPRING, SPRING.replace("100", "-100") + " #<")],
     "loads[2].stiffness", "must be a number >= 0", -100),
    ("spring damping negative", [sub(SPRING, SPRING.replace("damping: 0.5", "damping: -0.5") + " #<")],
     "loads[2].damping", "must be a number >= 0", -0.5),
    ("spring length negative", [sub(SPRING, SPRING.replace("damping: 0.5", "damping: 0.5, length: -1") + " #<")],
     "loads[2].length", "must be a number >= 0", -1),
    ("spring missing stiffness", [sub(SPRING, "  - {type: spring, ends: [O, B]} #<")],
     "loads[2].stiffness", "missing required key", HIDDEN),
    ("spring same ends", [sub(SPRING, "  - {type: spring, ends: [B, B], stiffness: 1} #<")],
     "loads[2].ends", "must name different points", ["B", "B"]),
    # initial
    ("initial unknown key", [sub("  points: {A: [0, 1, 0]}", "  points: {A: [0, 1, 0]}\n  speeds: {} #<")],
     "initial.speeds", "unknown key; expected one of: points, bodies", "speeds"),
    ("initial unknown point", [sub("  points: {A: [0, 1, 0]}", "  points: {Q: [0, 1, 0]} #<")],
     "initial.points.Q", "names no point; points are: O, A, B", "Q"),
    ("initial fixed point", [sub("  points: {A: [0, 1, 0]}", "  points: {O: [0, 1, 0]} #<")],
     "initial.points.O", "is a fixed point; only moving points can be given a velocity", "O"),
    ("initial velocity length", [sub("  points: {A: [0, 1, 0]}", "  points: {A: [0, 1]} #<")],
     "initial.points.A", "must be a list of 3 numbers", [0, 1]),
    ("initial unknown body", [sub(INITIAL_BODIES, INITIAL_BODIES.replace("crank", "shaft") + " #<")],
     "initial.bodies.shaft", "names no body; bodies are: crank, rod", "shaft"),
    ("initial frame", [sub(INITIAL_BODIES, INITIAL_BODIES.replace("global", "world") + " #<")],
     "initial.bodies.crank.frame", "unknown frame; expected one of: global, body", "world"),
    ("initial missing angular velocity", [sub(INITIAL_BODIES, "  bodies: {crank: {frame: body}} #<")],
     "initial.bodies.crank.angular_velocity", "missing required key", HIDDEN),
    # simulate
    ("simulate unknown key", [sub(SIMULATE, "simulate: {t_start: 0} #<")],
     "simulate.t_start", "unknown key; expected one of: t_end, dt, method, output_dt",
     "t_start"),
    ("t_end zero", [sub(SIMULATE, "simulate: {t_end: 0} #<")],
     "simulate.t_end", "must be a positive number", 0),
    ("dt negative", [sub(SIMULATE, "simulate: {dt: -1e-3} #<")],
     "simulate.dt", "must be a positive number", -1e-3),
    ("dt above t_end", [sub(SIMULATE, "simulate: {t_end: 1.0, dt: 2.0} #<")],
     "simulate.dt", "must be at most t_end (1)", 2.0),
    ("t_end below default dt", [sub(SIMULATE, "simulate: {t_end: 1e-4} #<")],
     "simulate.t_end", "must be at least dt (0.001, the default)", 1e-4),
    ("method unknown", [sub(SIMULATE, "simulate: {method: euler} #<")],
     "simulate.method", "unknown method; expected one of: rk4", "euler"),
    ("output_dt zero", [sub(SIMULATE, "simulate: {output_dt: 0} #<")],
     "simulate.output_dt", "must be a positive number", 0),
    ("output_dt below dt", [sub(SIMULATE, "simulate: {dt: 1e-3, output_dt: 5E-4} #<")],
     "simulate.output_dt", "must be at least dt (0.001)", 5e-4),
    # YAML itself
    ("yaml syntax", [sub("  B: [2, 0, 0]", "  B: [2, 0, 0]] #<")],
     "YAML", "is not valid YAML: expected <block end>, but found ']'", "B: [2, 0, 0]] #<"),
    ("yaml tab", [sub("  B: [2, 0, 0]", "\tB: [2, 0, 0] #<")],
     "YAML", "is not valid YAML: found character '\\t' that cannot start any token",
     "B: [2, 0, 0] #<"),
    ("yaml python tag", [sub("    mass: 1.0", "    mass: !!python/object/apply:os.getcwd [] #<")],
     "bodies.crank.mass", "has an unsupported YAML tag",
     "tag:yaml.org,2002:python/object/apply:os.getcwd"),
    ("yaml python scalar tag", [sub("    mass: 1.0", "    mass: !!python/name:os.getcwd '' #<")],
     "bodies.crank.mass", "has an unsupported YAML tag",
     "tag:yaml.org,2002:python/name:os.getcwd"),
    ("yaml custom tag", [sub("  rod:", "  rod: !body #<")],
     "bodies.rod", "has an unsupported YAML tag", "!body"),
    ("yaml bad explicit int", [sub("    mass: 1.0", "    mass: !!int heavy #<")],
     "bodies.crank.mass", "cannot be read as tag:yaml.org,2002:int", "heavy"),
    ("yaml bad explicit bool", [sub("    center: [0.5, 0, 0]", "    center: [0.5, 0, !!bool maybe] #<")],
     "bodies.crank.center[2]", "cannot be read as tag:yaml.org,2002:bool", "maybe"),
    ("yaml recursive alias", [sub("gravity: [0, 0, -9.81]", "gravity: &g [0, 0, *g] #<")],
     "gravity[2]", "is a recursive alias", HIDDEN),
    ("yaml merge key", [sub("  rod:", "  rod:\n    <<: {mass: 2.0} #<")],
     "bodies.rod.<<", "unknown key", "<<"),
    ("yaml complex key", [sub("name: slider", "name: slider\n? [a, b] #<\n: 1")],
     "YAML", "has a key that is not a plain name", "? [a, b] #<"),
]


def edited(edits) -> str:
    text = BASE
    for old, new in edits:
        assert text.count(old) == 1, f"edit target not once in the model: {old!r}"
        text = text.replace(old, new, 1)
    return text


def marked_line(text: str) -> int:
    lines = [k for k, line in enumerate(text.splitlines(), 1) if MARK in line]
    assert len(lines) == 1, "a case marks exactly one line"
    return lines[0]


def expect_error(text: str, source: str = SOURCE) -> ModelError:
    with pytest.raises(ModelError) as info:
        load_model_text(text, source)
    return info.value


def check(err: ModelError, line, item, rule, value, source=SOURCE):
    message = str(err)
    assert (err.file, err.line, err.item) == (source, line, item), message
    assert rule in err.rule, message
    assert message.startswith(f"{source}:{line}: {item}: " if line else f"{source}: {item}: ")
    if value is HIDDEN:
        assert "(got" not in message
    else:
        assert err.value == value, message
        assert message.endswith(f"(got {shown(value)})"), message


def test_base_model_is_valid():
    model = load_model_text(BASE, SOURCE)
    assert model.name == "slider" and len(model.loads) == 3


@pytest.mark.parametrize("edits, item, rule, value",
                         [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_rule(edits, item, rule, value):
    text = edited(edits)
    check(expect_error(text), marked_line(text), item, rule, value)


def test_cases_ids_unique():
    assert len({c[0] for c in CASES}) == len(CASES)


WHOLE_FILES = [
    ("empty", "", None, "model file", "is empty; it needs the keys name, points, bodies",
     HIDDEN),
    ("comments only", "# nothing\n", None, "model file", "is empty", HIDDEN),
    ("a list", "- a\n- b\n", 1, "model file",
     "must be a mapping with the keys name, points, bodies", ["a", "b"]),
    ("two documents", "name: a\n---\nname: b\n", 2, "YAML",
     "is not valid YAML: but found another document", "---"),
    ("bad character", "name: a\x07\n", 1, "YAML",
     "is not valid YAML: unacceptable character #x0007", "name: a\x07"),
]


@pytest.mark.parametrize("text, line, item, rule, value", [c[1:] for c in WHOLE_FILES],
                         ids=[c[0] for c in WHOLE_FILES])
def test_whole_file(text, line, item, rule, value):
    check(expect_error(text), line, item, rule, value)


def test_file_not_found(tmp_path: Path):
    path = tmp_path / "missing.yaml"
    with pytest.raises(ModelError) as info:
        load_model(path)
    check(info.value, None, "model file", "cannot be read (No such file or directory)",
          HIDDEN, source=str(path))


def test_file_not_utf8(tmp_path: Path):
    path = tmp_path / "latin1.yaml"
    path.write_bytes("name: caf\u00e9\n".encode("latin-1"))
    with pytest.raises(ModelError) as info:
        load_model(path)
    check(info.value, None, "model file", "is not UTF-8 text", HIDDEN, source=str(path))


def test_error_from_file_names_the_path(tmp_path: Path):
    """Errors from a file give the path as the caller wrote it."""
    path = tmp_path / "bad.yaml"
    text = edited([sub("    mass: 1.0", "    mass: -2 #<")])
    path.write_text(text)
    with pytest.raises(ModelError) as info:
        load_model(str(path))
    check(info.value, marked_line(text), "bodies.crank.mass", "must be a positive number",
          -2, source=str(path))


def test_error_is_a_value_error():
    """Callers that only know ValueError still catch bad models."""
    with pytest.raises(ValueError):
        load_model_text(edited([sub("    mass: 1.0", "    mass: -1")]))
