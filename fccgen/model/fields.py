"""Typed reading of line-aware YAML nodes: every rule broken becomes a ModelError.

:class:`Reader` holds the source name and turns a node into the value a model field
needs (a number, a vector of 3 numbers, a name, a mapping with known keys, ...), or
raises :class:`ModelError` naming the file, the line, the item, the rule and the value.
"""
from __future__ import annotations

import math
import re

import numpy as np

from ..errors import ModelError
from .yamlnodes import YMap, YNode, YScalar, YSeq, shown

IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
IDENTIFIER_RULE = "must be a name matching [A-Za-z_][A-Za-z0-9_]*"

# Every number of a model is at most MAX_MAGNITUDE in size, and every quantity that must
# be positive (a mass, a distance, a time) at least MIN_POSITIVE. Why these: the kernels
# are polynomials of low degree (at most ~6: m l^2 w^2, k (l - l0)^2, ...) in the
# model's numbers, with at most a few divisions by masses and lengths, so no
# intermediate exceeds (1e12)^6 (1e30)^2 = 1e132, far below the 1.8e308 where doubles
# overflow, and squares of accelerations (F/m <= 1e42) stay finite too. 24 decades
# between the two leave room for any consistent units (SI, mm-g-s, t-mm-s: a 1 um
# gear's inertia in kg m^2 is ~1e-25).
MAX_MAGNITUDE = 1e12
MIN_POSITIVE = 1e-30
# Lists of names in messages (e.g. "points are: ...") show at most this many.
LISTED_NAMES = 20


def child(item: str, key) -> str:
    """Item path of a mapping key (``bodies.arm``) or a sequence index (``line[1]``)."""
    return f"{item}[{key}]" if isinstance(key, int) else f"{item}.{key}" if item else key


def listing(names) -> str:
    names = list(names)
    if len(names) > LISTED_NAMES:
        return ", ".join(names[:LISTED_NAMES]) + f", ... ({len(names)} in all)"
    return ", ".join(names) if names else "(none)"


class Reader:
    """Reads typed values out of nodes, raising ModelError against ``source``."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, line: int | None, item: str, rule: str, value=None, *,
             show_value: bool = True) -> ModelError:
        """The error to raise (returned so that callers write ``raise r.fail(...)``)."""
        return ModelError(self.source, line, item, rule, value, show_value=show_value)

    def bad(self, node: YNode, item: str, rule: str) -> ModelError:
        """The error for ``node`` breaking ``rule``, showing the value seen."""
        return self.fail(node.line, item, rule, shown(node))

    # -- containers ----------------------------------------------------------------
    def mapping(self, node: YNode, item: str, required=(), optional=()) -> YMap:
        """A mapping whose keys are all in ``required`` or ``optional``, with every
        required key present."""
        if not isinstance(node, YMap):
            raise self.bad(node, item, "must be a mapping")
        allowed = (*required, *optional)
        for key, line in node.key_lines.items():
            if key not in allowed:
                raise self.fail(line, child(item, key),
                                f"unknown key; expected one of: {listing(allowed)}", key)
        for key in required:
            if key not in node.entries:
                raise self.fail(node.line, child(item, key), "missing required key",
                                show_value=False)
        return node

    def sequence(self, node: YNode, item: str, length: int | None = None) -> YSeq:
        if not isinstance(node, YSeq):
            raise self.bad(node, item, "must be a list" if length is None
                           else f"must be a list of {length} items")
        if length is not None and len(node.items) != length:
            raise self.bad(node, item, f"must be a list of {length} items, "
                                       f"not {len(node.items)}")
        return node

    def entries(self, node: YNode, item: str):
        """(key, key line, value node, item path) of every entry of a mapping."""
        node = self.mapping_any(node, item)
        for key, value in node.entries.items():
            yield key, node.key_lines[key], value, child(item, key)

    def mapping_any(self, node: YNode, item: str) -> YMap:
        if not isinstance(node, YMap):
            raise self.bad(node, item, "must be a mapping")
        return node

    # -- scalars ---------------------------------------------------------------------
    def number(self, node: YNode, item: str) -> float:
        """A finite int or float (not a bool) of magnitude at most MAX_MAGNITUDE, as
        float."""
        value = node.value if isinstance(node, YScalar) else None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.bad(node, item, "must be a number")
        try:
            x = float(value)
        except OverflowError:
            x = math.inf
        if not math.isfinite(x):
            raise self.bad(node, item, "must be a finite number")
        if abs(x) > MAX_MAGNITUDE:
            raise self.bad(node, item, f"must be at most {MAX_MAGNITUDE:g} in magnitude "
                                       "(fccgen's limit on every number of a model)")
        return x

    def positive(self, node: YNode, item: str) -> float:
        """A number in [MIN_POSITIVE, MAX_MAGNITUDE]."""
        x = self.number(node, item)
        if not x > 0:
            raise self.bad(node, item, "must be a positive number")
        if x < MIN_POSITIVE:
            raise self.bad(node, item, f"must be at least {MIN_POSITIVE:g} (fccgen's "
                                       "limit on a positive quantity of a model)")
        return x

    def nonnegative(self, node: YNode, item: str) -> float:
        x = self.number(node, item)
        if not x >= 0:
            raise self.bad(node, item, "must be a number >= 0")
        return x

    def numbers(self, node: YNode, item: str, lengths=(3,)) -> np.ndarray:
        """A list of numbers whose length is one of ``lengths``."""
        want = " or ".join(str(n) for n in lengths)
        if not isinstance(node, YSeq) or len(node.items) not in lengths:
            raise self.bad(node, item, f"must be a list of {want} numbers")
        return np.array([self.number(n, child(item, k)) for k, n in enumerate(node.items)],
                        dtype=float)

    def vec3(self, node: YNode, item: str) -> np.ndarray:
        return self.numbers(node, item, (3,))

    def boolean(self, node: YNode, item: str) -> bool:
        if not (isinstance(node, YScalar) and isinstance(node.value, bool)):
            raise self.bad(node, item, "must be true or false")
        return node.value

    def text(self, node: YNode, item: str) -> str:
        """A scalar as written (so that a name such as ``on`` or ``null`` stays a name)."""
        if not isinstance(node, YScalar):
            raise self.bad(node, item, "must be a name")
        return node.text

    def identifier(self, node: YNode, item: str) -> str:
        name = self.text(node, item)
        if not IDENTIFIER.fullmatch(name):
            raise self.fail(node.line, item, IDENTIFIER_RULE, name)
        return name

    def choice(self, node: YNode, item: str, choices, what: str = "value") -> str:
        word = self.text(node, item)
        if word not in choices:
            raise self.fail(node.line, item,
                            f"unknown {what}; expected one of: {listing(choices)}", word)
        return word

    def name_in(self, node: YNode, item: str, names, what: str, plural: str) -> str:
        """A name that must be a key of ``names`` (e.g. the model's points)."""
        name = self.text(node, item)
        if name not in names:
            raise self.fail(node.line, item,
                            f"names no {what}; {plural} are: {listing(names)}", name)
        return name
