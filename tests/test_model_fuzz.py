"""Fuzzing the model loader, ``fccgen check`` and a short simulation with mutated
examples (hypothesis, derandomized: the same cases on every run).

Each case takes an example of examples/ and applies one to three mutations: a number
set to an extreme (0, -1, 1e308, nan, inf, 1e-300, 5e-324, 10**400, ...) or to any
float, a value replaced by text, a list, a mapping or null, a key dropped, renamed or
written twice, a value nested deeply, two values made one (a YAML alias), a value made
an alias bomb, a tab put in, an integer of 6,000 digits, the file cut short.

Oracles:

* load + check (FCCGEN_FUZZ_EXAMPLES cases, 2,000 by default): the model fails with an
  exception of fccgen.errors whose text is shorter than 10 kB and names the file, or
  it passes and check's report holds no nan or infinity;
* load + compiled simulate (FCCGEN_FUZZ_RUNS cases, 60 by default): numbers only,
  nonzero to nonzero, so that the model keeps its structure and its compiled module
  (element classes are keyed by structure: no compile per case); the run fails with an
  exception of fccgen.errors shorter than 10 kB, or all its results are finite.

* the mechanism sections, load + check with generation (FCCGEN_FUZZ_SECTIONS cases,
  100 by default): models with joints, drivers (expressions, rates, a table), loads of
  expressions and joint quantities, torsion and linear springs, events and limits,
  under the mutations above and text mutations of their expressions, names and paths
  (an odd token put in, a random expression, another name, a path out of the
  folder). The same oracle, and a ModelError must name an item, no error quotes a
  table's text; a model that passes has had its kernels derived, printed and
  rendered (check's generation), so it is one simulate can build.

FCCGEN_FUZZ_REPORT=FILE appends each test's counts to FILE.

The long version: ``FCCGEN_FUZZ_EXAMPLES=100000 FCCGEN_FUZZ_RUNS=2000
FCCGEN_FUZZ_SECTIONS=20000 pytest -q tests/test_model_fuzz.py`` (hours on one core;
docs/reliability.md has the counts of a run); FCCGEN_FUZZ_SEED=N draws other cases
(seeded by N instead of derandomized).
"""
from __future__ import annotations

import copy
import math
import os
import re
from collections import Counter
from pathlib import Path

import numpy as np
import yaml
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st

import fccgen
from fccgen.diagnostics.check import check_model
from fccgen.errors import FccgenError, ModelError

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
# a02_n_four_bar is left out: a check of it takes 0.7 s, and its items are of the kinds
# four_bar has.
CHECK_EXAMPLES = ("a01_pendulum", "double_pendulum", "four_bar", "free_body",
                  "spherical_pendulum", "deployable")
RUN_EXAMPLES = ("double_pendulum", "four_bar")      # compiled by other tests as well
N_CHECK = int(os.environ.get("FCCGEN_FUZZ_EXAMPLES", "2000"))
N_RUN = int(os.environ.get("FCCGEN_FUZZ_RUNS", "60"))
N_SECTIONS = int(os.environ.get("FCCGEN_FUZZ_SECTIONS", "100"))
# A file that each fuzz test appends its counts to (for the long runs' records).
REPORT = os.environ.get("FCCGEN_FUZZ_REPORT")


def record(test: str, n: int, outcomes: Counter) -> None:
    if REPORT:
        with open(REPORT, "a", encoding="utf-8") as f:
            f.write(f"{test}: {n} cases, {dict(sorted(outcomes.items()))}\n")
SEED = os.environ.get("FCCGEN_FUZZ_SEED")
MAX_MESSAGE = 10_000


def fuzz_settings(n: int):
    """Settings of a fuzz test of n cases: derandomized, or seeded by FCCGEN_FUZZ_SEED."""
    config = settings(max_examples=n, derandomize=SEED is None, database=None,
                      deadline=None, suppress_health_check=list(HealthCheck))
    if SEED is None:
        return config
    return lambda test: seed(int(SEED))(config(test))

EXTREMES = [0, 0.0, -1, 1, 1e308, -1e308, math.nan, math.inf, -math.inf, 1e-300, -1e-300,
            5e-324, 1e12, -1e12, 1.000001e12, 1e-30, 9e-31, 2 ** 64, 10 ** 400]
NOT_NUMBERS = ["text", "", None, True, [], {}, [1, 2, 3], {"a": 1}, "O", "__init__",
               "x" * 300, "1e999", ".nan"]
KEYS = ["at", "mass", "points", "type", "length", "x", "__init__", "name", "fixed",
        "along", "dt", "value", "ends", "bodies", "inertia"]
# Keys whose nonzero numbers change no element class (no zero folded, nothing moved).
RUN_KEYS = {"mass", "inertia", "stiffness", "damping", "value", "gravity", "t_end", "dt",
            "output_dt", "angular_velocity"}
RUN_VALUES = [-1.0, 1e12, -1e12, 1e-30, 1e-300, 1e308, math.nan, math.inf, 1e6, 1e-6,
              7.5, -3.0]

_DATA: dict[str, dict] = {}
# libyaml's emitter when PyYAML has it: writing the cases is then ~10x cheaper than
# reading them (fccgen reads with PyYAML's Python parser, for its line numbers).
DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def example(name: str):
    """A fresh copy of the plain data of examples/<name>.yaml."""
    if name not in _DATA:
        _DATA[name] = yaml.safe_load((EXAMPLES / f"{name}.yaml").read_text())
    return copy.deepcopy(_DATA[name])


def dump(data) -> str:
    return yaml.dump(data, Dumper=DUMPER, sort_keys=False, default_flow_style=None,
                     width=200)


def paths(node, prefix=()):
    """Every (path, value) below ``node``; a path is a tuple of keys and indices."""
    items = node.items() if isinstance(node, dict) else (
        enumerate(node) if isinstance(node, list) else ())
    for key, value in items:
        yield prefix + (key,), value
        yield from paths(value, prefix + (key,))


def parent(data, path):
    for key in path[:-1]:
        data = data[key]
    return data


def is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def bomb(levels: int):
    """Nested lists where each level repeats the one below 9 times: 9**levels
    strings once expanded, a few lines of YAML with anchors."""
    node = ["lol"] * 9
    for _ in range(levels - 1):
        node = [node] * 9
    return node


def mutate(data, draw) -> bool:
    """One mutation of the plain data ``data`` (in place), drawn with ``draw``; False
    when it made the data a graph (shared or bomb: walking it again could expand it
    or never end), so that it must be the last."""
    all_paths = list(paths(data))
    kind = draw(st.sampled_from(["number", "float", "value", "drop", "rename", "nest",
                                 "share", "bomb"]))
    numbers = [p for p, v in all_paths if is_number(v)]
    if kind in ("number", "float") and numbers:
        path = draw(st.sampled_from(numbers))
        value = (draw(st.sampled_from(EXTREMES)) if kind == "number" else
                 draw(st.floats(allow_nan=True, allow_infinity=True)))
        parent(data, path)[path[-1]] = value
        return True
    path = draw(st.sampled_from([p for p, _ in all_paths]))
    holder, key = parent(data, path), path[-1]
    if kind == "drop":
        del holder[key]
    elif kind == "rename" and isinstance(holder, dict):
        holder[draw(st.sampled_from(KEYS))] = holder.pop(key)
    elif kind == "nest":
        value = holder[key]
        for _ in range(draw(st.sampled_from([2, 10, 45, 60]))):
            value = [value]
        holder[key] = value
    elif kind == "share":           # may make a cycle: a recursive alias
        other = draw(st.sampled_from([p for p, _ in all_paths]))
        holder[key] = parent(data, other)[other[-1]]
        return False
    elif kind == "bomb":
        holder[key] = bomb(draw(st.integers(2, 9)))
        return False
    else:
        holder[key] = copy.deepcopy(draw(st.sampled_from(NOT_NUMBERS)))
    return True


def text_mutation(text: str, draw) -> str:
    """A mutation of the YAML text itself."""
    lines = text.splitlines(keepends=True)
    kind = draw(st.sampled_from(["duplicate", "cut", "tab", "deep", "alias", "hex"]))
    k = draw(st.integers(0, max(len(lines) - 1, 0)))
    if kind == "duplicate" and lines:
        return "".join(lines[:k + 1] + lines[k:])
    if kind == "cut":
        return text[:draw(st.integers(0, len(text)))]
    if kind == "tab":
        return "".join(lines[:k] + ["\t"] + lines[k:])
    if kind == "alias":
        return text + "extra: *undefined_anchor\n"
    if kind == "hex":               # an integer too long for str(): no limit in base 16
        numbers = list(re.finditer(r"(?<![\w.])\d+(?![\w.])", text))
        if numbers:
            m = numbers[draw(st.integers(0, len(numbers) - 1))]
            return text[:m.start()] + "0x" + "f" * 5000 + text[m.end():]
    depth = draw(st.sampled_from([49, 51, 600, 5000]))
    return "deep: " + "[" * depth + "]" * depth + "\n" + text


@st.composite
def mutated_text(draw, names=CHECK_EXAMPLES):
    name = draw(st.sampled_from(names))
    data = example(name)
    for _ in range(draw(st.integers(1, 3))):
        if not isinstance(data, dict) or not data or not mutate(data, draw):
            break
    text = dump(data)
    if draw(st.integers(0, 4)) == 0:
        text = text_mutation(text, draw)
    return text


def clean_error(exc: FccgenError, path: Path, names_file: bool = True):
    text = str(exc)
    assert len(text) < MAX_MESSAGE, text[:500]
    if names_file:
        assert str(path) in text, text


NON_FINITE = re.compile(r"\b(nan|inf|infinity)\b", re.IGNORECASE)


def test_fuzz_load_and_check(tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz") / "model.yaml"
    outcomes = Counter()

    @fuzz_settings(N_CHECK)
    @given(mutated_text())
    def case(text):
        path.write_text(text)
        try:
            report = check_model(path, generate=False)
        except FccgenError as exc:
            clean_error(exc, path)
            outcomes["error"] += 1
            return
        assert not NON_FINITE.search(report.text()), report.text()
        outcomes["passed"] += 1

    case()
    record("load and check", N_CHECK, outcomes)
    # The mutations reach both sides: most cases break a rule, some still pass.
    assert outcomes["error"] >= N_CHECK // 2 and outcomes["passed"] >= N_CHECK // 50, \
        outcomes


@st.composite
def number_mutation(draw):
    """An example with one to three of its nonzero numbers under RUN_KEYS changed to
    another nonzero number."""
    name = draw(st.sampled_from(RUN_EXAMPLES))
    data = example(name)
    for _ in range(draw(st.integers(1, 3))):
        targets = [p for p, v in paths(data) if is_number(v) and v != 0
                   and any(k in RUN_KEYS for k in p if isinstance(k, str))]
        path = draw(st.sampled_from(targets))
        value = draw(st.one_of(st.sampled_from(RUN_VALUES),
                               st.floats(allow_nan=True, allow_infinity=True)
                               .filter(lambda x: x != 0)))
        parent(data, path)[path[-1]] = value
    return name, dump(data)


def test_fuzz_simulate(build_dir, compiled, tmp_path_factory):
    for name in RUN_EXAMPLES:            # built (or found cached) once, before timing
        compiled(name)
    folder = tmp_path_factory.mktemp("fuzz_run")
    outcomes = Counter()

    @fuzz_settings(N_RUN)
    @given(number_mutation())
    def case(mutation):
        name, text = mutation
        path = folder / f"{name}.yaml"
        path.write_text(text)
        try:
            solver = fccgen.load(path, build_dir)
            d = solver.plan.model.simulate
            result = solver.simulate(t_end=min(d.t_end, 20 * d.dt))
        except FccgenError as exc:
            clean_error(exc, path, names_file=isinstance(exc, ModelError))
            outcomes["error"] += 1
            return
        assert np.all(np.isfinite(result.table())), name
        outcomes["passed"] += 1

    case()
    record("compiled simulate", N_RUN, outcomes)
    assert outcomes["error"] >= 1 and outcomes["passed"] >= 1, outcomes


# -- the mechanism sections: joints, drivers, loads of expressions, springs, events,
# limits, tables -------------------------------------------------------------------
SECTION_MODELS = {
    "pendulum_limit": None, "panel_latch": None, "four_bar_driven": None,
    "sections": """\
name: sections
gravity: [0, 0, -9.81]
bodies:
  a: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-3, 0.08, 0.08]}
  b: {mass: 0.5, center: [1.5, 0, 0], inertia: [1.0e-3, 0.04, 0.04]}
  c: {mass: 0.2, center: [1.5, 0, -0.5], inertia: [1.0e-3, 0.01, 0.01]}
joints:
  - {name: A, type: revolute, bodies: [ground, a], at: [0, 0, 0], axis: [0, 1, 0],
     limits: [-1.0, 1.5], restitution: 0.3}
  - {name: B, type: cylindrical, bodies: [a, b], at: [1, 0, 0], axis: [1, 0, 0]}
  - {name: S, type: prismatic, bodies: [b, c], at: [1.5, 0, 0], axis: [0, 0, 1]}
drivers:
  - {name: spin, joint: B, angle: {table: motion.csv}}
  - {name: push, joint: S, speed: "0.1*cos(2*t)"}
loads:
  - {type: torque, body: a, value: [0, "0.2*sin(3*t) - 0.05*A.rate + 0.1*A.angle", 0]}
  - {type: force, body: b, value: ["0.5*B.position - 0.1*B.speed", 0, "-t"]}
  - {type: torsion_spring, joint: A, stiffness: 2.0, angle: 0.2, damping: 0.01}
  - {type: linear_spring, joint: B, stiffness: 10.0, length: 0.0, damping: 0.1}
initial:
  joints: {A: {angle: 0.1}}
events:
  - {name: reach, when: "A.angle >= 1.2", do: log}
  - {name: low, when: "S.position + 0.5", direction: falling, do: stop}
  - {name: late, when: "t >= 0.5*S.position + 2", do: stop}
simulate: {t_end: 0.05, dt: 1.0e-3, method: rk4}
""",
}
TABLE = "t, angle\n0, 0\n0.5, 0.2\n1, 0.3\n"
ODD_PIECES = ["#", " # */ x /*", "'", '"', "\\", "\n", "\r", "\0", "/*", "*/", "//",
              "??/", "{{ x }}", "[", ":", ";", "%", "\u00e9", "\u2028", "__class__",
              "1e308", "1/0", "sqrt(-1)", "10**400", "A.angle.x", "lambda: 0"]
EXPRESSIONS = ["t", "sin(t)", "1/t", "sqrt(t)", "log(t)", "abs(t)", "min(t, 1)",
               "A.angle", "1/A.angle", "abs(A.rate)", "A.rate**2", "B.position",
               "S.speed", "exp(1000*t)", "t**0.5", "atan2(t, 0)", "max(A.angle, 0)",
               "0", "1e12*t", "(4294967296**2 + 1)*t", "B.angle", "pi", "A.rate*A.angle"]
PATHS = ["motion.csv", "../motion.csv", "/etc/passwd", "missing.csv", "a" * 300,
         "motion.csv/x", ".", "huge.csv", "bad.csv"]


def section_model(name: str):
    text = SECTION_MODELS[name]
    if text is None:
        return example(name)
    return yaml.safe_load(text)


def text_mutation_of_strings(data, draw) -> None:
    """One mutation of a string of the model: an odd piece put in, a random
    expression, a name, or a table path."""
    strings = [p for p, v in paths(data) if isinstance(v, str)]
    if not strings:
        return
    path = draw(st.sampled_from(strings))
    holder, key = parent(data, path), path[-1]
    kind = draw(st.sampled_from(["odd", "expression", "name", "path"]))
    value = holder[key]
    if kind == "odd":
        k = draw(st.integers(0, len(value)))
        holder[key] = value[:k] + draw(st.sampled_from(ODD_PIECES)) + value[k:]
    elif kind == "expression":
        a, b = draw(st.sampled_from(EXPRESSIONS)), draw(st.sampled_from(EXPRESSIONS))
        holder[key] = draw(st.sampled_from([a, f"{a} + {b}", f"{a}*{b}", f"{a} >= {b}"]))
    elif kind == "name":
        holder[key] = draw(st.sampled_from(["A", "B", "S", "a", "ground", "motion",
                                            "X" * 70, "t", "A_lower"]))
    else:
        holder[key] = draw(st.sampled_from(PATHS))


@st.composite
def mutated_section(draw):
    name = draw(st.sampled_from(sorted(SECTION_MODELS)))
    data = section_model(name)
    for _ in range(draw(st.integers(1, 3))):
        if not isinstance(data, dict) or not data:
            break
        if draw(st.booleans()):
            text_mutation_of_strings(data, draw)
        elif not mutate(data, draw):
            break
    return dump(data)


def test_fuzz_sections_load_and_check(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz_sections") / "model"
    folder.mkdir()
    (folder / "motion.csv").write_text(TABLE)
    (folder / "huge.csv").write_text("t, a\n0, 0\n1, " + "9" * 200_000 + "\n")
    (folder / "bad.csv").write_text("t, a\n0, 0\nSECRET, 1\n")
    path = folder / "model.yaml"
    outcomes = Counter()

    @fuzz_settings(N_SECTIONS)
    @given(mutated_section())
    def case(text):
        path.write_text(text)
        try:
            report = check_model(path)
        except FccgenError as exc:
            clean_error(exc, path)
            assert "SECRET" not in str(exc)
            if isinstance(exc, ModelError):
                assert exc.item, str(exc)
            outcomes["error"] += 1
            outcomes[type(exc).__name__] += 1
            return
        assert not NON_FINITE.search(report.text()), report.text()
        assert "derived, printed to C and rendered" in report.text()
        outcomes["passed"] += 1

    case()
    record("sections load, check and generate", N_SECTIONS, outcomes)
    assert outcomes["error"] >= N_SECTIONS // 2 and outcomes["passed"] >= N_SECTIONS // 50, \
        outcomes
