"""Errors that fccgen raises for bad input and failed builds or simulations."""
from __future__ import annotations


class FccgenError(Exception):
    """Base class of every error fccgen raises on purpose."""


# Longest text of a value, an item path and a rule in a message: a message stays below
# a few kB whatever the file holds (a megabyte-long scalar, a key of any length).
SHOWN_VALUE_CHARS = 200
SHOWN_ITEM_CHARS = 300
SHOWN_RULE_CHARS = 1000


def clip(text: str, limit: int) -> str:
    """``text`` cut to ``limit`` characters, saying how long it was."""
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text)} characters)"


def shown(value) -> str:
    """repr of a value as a message shows it, at most SHOWN_VALUE_CHARS long."""
    try:
        text = repr(value)
    except ValueError:      # an int too long for str() (sys.set_int_max_str_digits)
        text = _long_int_repr(value)
    return clip(text, SHOWN_VALUE_CHARS)


def _long_int_repr(value) -> str:
    """repr that writes an integer too long for str() as its number of digits."""
    if isinstance(value, int):
        try:
            return repr(value)
        except ValueError:
            digits = int(value.bit_length() * 0.30102999566) + 1   # log10(2)
            return f"<an integer of about {digits} digits>"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k!r}: {_long_int_repr(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_long_int_repr(v) for v in value) + "]"
    return repr(value)


class ModelError(FccgenError, ValueError):
    """A model file breaks a rule.

    The message is one sentence: where (file and line), the item, the rule broken and
    the value seen, e.g. ``pendulum.yaml:12: bodies.arm.mass: must be a positive
    number (got -1.0)``. The value, item and rule are shown cut to SHOWN_*_CHARS (the
    attributes keep them whole).
    """

    def __init__(self, file: str, line: int | None, item: str, rule: str, value=None,
                 *, show_value: bool = True):
        self.file = file
        self.line = line
        self.item = item
        self.rule = rule
        self.value = value
        where = f"{file}:{line}" if line is not None else f"{file}"
        text = f"{where}: {clip(item, SHOWN_ITEM_CHARS)}: {clip(rule, SHOWN_RULE_CHARS)}"
        if show_value:
            text += f" (got {shown(value)})"
        super().__init__(text)


class BuildError(FccgenError, RuntimeError):
    """Generating or compiling a model's kernels failed; the message holds the
    compiler's own output."""


class SimulationError(FccgenError, RuntimeError):
    """A simulation cannot go on (singular mass matrix on the constraint manifold,
    failed assembly, non-finite state)."""
