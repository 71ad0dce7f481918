"""Say which part of a model a solver failure comes from.

A singular reduced mass matrix (M not positive definite on the null space of B) is a
property of the model, not of the numbers the integrator happened to meet: some
motion allowed by the constraints carries no mass or inertia. The eigenvector of the
smallest eigenvalue of N^T M N (N a basis of the null space of B) is that motion; its
largest coordinates name the points and vectors that move without inertia, and the
bodies and constraints that use them are the items to look at.
"""
from __future__ import annotations

import numpy as np

from ..errors import SimulationError
from .massless import massless_motion


def explained(exc: SimulationError, solver, q, v=None, setting=None) -> SimulationError:
    """exc as a located SimulationError (fccgen.runs.locate): the model file, the line and
    the item it comes from, the solver's own sentence as the rule and, for a singular
    mass matrix, the motion without inertia named; attributes such as partial_result
    are kept. setting: (name, value, given) of the run's step setting."""
    from .locate import failure_state, locate
    if getattr(exc, "item", None) is not None:
        return exc
    text = str(exc)
    source = str(solver.plan.model.source)
    if text.startswith(f"{source}: "):
        text = text[len(source) + 2:]
    if "singular" in text:
        try:
            hint = massless_motion(solver.plan, solver.mass_matrix(q),
                                   solver.constraint_jacobian(q))
        except (SimulationError, ValueError, np.linalg.LinAlgError):
            hint = ""
        if hint:
            text += f"; {hint}"
    qs, vs, ts = failure_state(exc, q, v)
    where = locate(solver, text, qs, vs, ts, setting)
    out = SimulationError.located(source, where.line, where.item, text, where.value)
    out.__dict__.update({k: x for k, x in exc.__dict__.items()
                         if k not in ("file", "line", "item", "rule", "value")})
    return out
