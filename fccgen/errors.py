"""Errors that fccgen raises for bad input and failed builds or simulations."""
from __future__ import annotations


class FccgenError(Exception):
    """Base class of every error fccgen raises on purpose."""


class ModelError(FccgenError, ValueError):
    """A model file breaks a rule.

    The message is one sentence: where (file and line), the item, the rule broken and
    the value seen, e.g. ``pendulum.yaml:12: bodies.arm.mass: must be a positive
    number (got -1.0)``.
    """

    def __init__(self, file: str, line: int | None, item: str, rule: str, value=None,
                 *, show_value: bool = True):
        self.file = file
        self.line = line
        self.item = item
        self.rule = rule
        self.value = value
        where = f"{file}:{line}" if line is not None else f"{file}"
        text = f"{where}: {item}: {rule}"
        if show_value:
            text += f" (got {value!r})"
        super().__init__(text)


class BuildError(FccgenError, RuntimeError):
    """Generating or compiling a model's kernels failed; the message holds the
    compiler's own output."""


class SimulationError(FccgenError, RuntimeError):
    """A simulation cannot go on (singular mass matrix on the constraint manifold,
    failed assembly, non-finite state)."""


class RunWarning(UserWarning):
    """A run finished but something in it needs the user's attention (a change of the
    degrees of freedom, a start near a singular position, a model that cannot move).
    The same texts are in ``result.info["warnings"]``."""
