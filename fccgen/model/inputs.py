"""The model file's ``inputs:`` section (docs/model-file.md, "Inputs").

``inputs: {base_torque: 0.0}`` declares named scalars with a start value. A load's
expressions and event functions read them as they read ``t``; the runtime holds each at a value set from
outside between steps (``simulate(inputs=...)``, the exported C API's
``<name>_set_input``, an FMU's input variables), so changing one needs no rebuild.

Names are identifiers that name nothing else of the model: not a point, vector, body,
joint, driver, cable or event, not ``t``, ``pi`` or a function of the expression
grammar, not a Python keyword (the grammar's parser reads expressions as Python), not
a result column without a dot (``energy``, ``constraint_error``: an FMU's variables
have unique names) and not a top-level section of the model file (the first word of
the ``with_parameters`` keys, such as ``gravity``).
"""
from __future__ import annotations

import ast
import keyword

from .fields import IDENTIFIER, IDENTIFIER_RULE, Reader
from .yamlnodes import YNode

MAX_INPUTS = 256
# names that mean something else where an input name would stand
OTHER_MEANINGS = {"t": "the time", "energy": "a result column",
                  "constraint_error": "a result column", "work": "a result column"}
# where an input cannot be read, and why (the reader of each place raises it)
NOT_IN_DRIVERS = ("reads the input {name}; a driver prescribes a motion, and an input "
                  "is held between steps and set from outside, so each change would make "
                  "the driven position (or, for rate:, its integral) jump: drive the "
                  "joint through a load of the input instead (a torque or force), or "
                  "write the motion in t")
NOT_IN_POINT_FORCES = ("reads the input {name}; a force on a cable node is a function "
                       "of t only: inputs enter the loads on bodies (force, torque)")


def reserved_meaning(name: str, top_keys) -> str | None:
    """What ``name`` means already, if an input may not take it."""
    from ..expressions.grammar import CONSTANTS, FUNCTIONS
    if name in OTHER_MEANINGS:
        return OTHER_MEANINGS[name]
    if name in FUNCTIONS:
        return "a function of the expression grammar"
    if name in CONSTANTS:
        return "a constant of the expression grammar"
    if keyword.iskeyword(name) or keyword.issoftkeyword(name):
        return "a Python keyword (expressions are parsed as Python syntax)"
    if name in top_keys:
        return "a section of the model file (and the first word of its parameter keys)"
    return None


def read_inputs(reader: Reader, node: YNode, claim, top_keys) -> dict[str, float]:
    """name -> start value of the ``inputs:`` mapping; ``claim(name, kind, line, item)``
    reserves each name against the model's other names."""
    out: dict[str, float] = {}
    for name, line, value, item in reader.entries(node, "inputs"):
        if not IDENTIFIER.fullmatch(name):
            raise reader.fail(line, item, IDENTIFIER_RULE, name)
        meaning = reserved_meaning(name, top_keys)
        if meaning:
            raise reader.fail(line, item, f"is {meaning}; an input needs a name of its "
                              "own", name)
        claim(name, "input", line, item)
        out[name] = reader.number(value, item)
        if len(out) > MAX_INPUTS:
            raise reader.fail(line, "inputs", f"holds more than {MAX_INPUTS} inputs",
                              len(out))
    return out


def refuse_inputs(reader: Reader, expr, inputs, line, item: str, text, rule: str) -> None:
    """Raise ``rule`` (with the input's name) when ``expr`` reads one of ``inputs``."""
    used = sorted(s.name for s in expr.free_symbols if s.name in inputs)
    if used:
        raise reader.fail(line, item, rule.format(name=used[0]), text)


def names_read(text: str, candidates) -> tuple[str, ...]:
    """The names of ``candidates`` (the model's inputs) that the checked expression
    text ``text`` reads, sorted; "ex;ex;ex" (a load's components) and
    "header|ex;ex;ex" (a load of joint quantities) are read part by part. The text is
    parsed only (it was checked by the expression grammar when the model was loaded),
    never evaluated; no SymPy (planning a cached model imports none)."""
    wanted = set(candidates)
    if not wanted or not text or text.startswith("table:"):
        return ()
    found = set()
    for part in text.split("|", 1)[-1].split(";"):
        for node in ast.walk(ast.parse(part.strip(), mode="eval")):
            if isinstance(node, ast.Name) and node.id in wanted:
                found.add(node.id)
    return tuple(sorted(found))
