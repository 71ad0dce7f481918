"""The branch of every angle driver, checked on a run's results.

An angle driver's row sin(theta - f) holds at theta = f and at f + pi; the initial
assembly starts on f(0) (fccgen.mechanism.initial_positions), and a run cannot jump
half a turn between its steps. A run given its own start state (``q0``) can still
follow f + pi: the joint's angle column, computed from the bodies' frames, against
f(t) from the driver's expression is the independent signal, and a run where they
differ by more than a quarter turn warns.
"""
from __future__ import annotations

import math
import warnings

from ..errors import RunWarning


def check_driver_branches(plan, result) -> None:
    """Warn (``info["warnings"]``, RunWarning) when a driven joint's angle is more than
    a quarter turn from its driver's f(t) at some record."""
    lowering = getattr(plan.model, "mechanism", None)
    drivers = [d for d in (getattr(lowering, "drivers", None) or [])
               if d.quantity == "angle"]
    if not drivers or not len(result.t):
        return
    from ..expressions.time_jets import time_function
    for d in drivers:
        angle = result.columns.get(f"{d.joint}.angle")
        if angle is None:
            continue
        f = time_function(d.function)
        off = [k for k, t in enumerate(result.t)
               if math.cos(float(angle[k]) - f(float(t))[0]) < 0.0]
        if off:
            k = off[0]
            text = (f"driver {d.name!r}: the joint {d.joint} is at {float(angle[k]):.6g} rad "
                    f"at t = {float(result.t[k]):.6g}, but the driver prescribes "
                    f"{f(float(result.t[k]))[0]:.6g}: it follows the driver's other branch, "
                    f"f(t) + pi (a driver row sin(angle - f) holds on both); start the run "
                    f"from the model's initial state, which is assembled at f(0)")
            result.info.setdefault("warnings", []).append(text)
            warnings.warn(text, RunWarning, stacklevel=3)
