"""Say which part of a model a solver failure comes from: the failure as a located
error (file, line, item; fccgen.runs.locate), and for a singular reduced mass matrix
the motion that carries no mass or inertia (fccgen.runs.massless)."""
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
