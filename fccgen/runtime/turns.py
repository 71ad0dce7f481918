"""Warnings where a kernel's angle may have left its atan2 branch (docs/elements.md,
"Angles over turns"): torsion springs, loads of joint angles and events count a joint
angle's turns from step to step through references that the runs re-base after every
accepted step (fccgen.events.references)."""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import RunWarning

# Methods whose loops re-base the angle references after every accepted step (ali3p's
# does not: a spring's angle is then exact within half a turn of its free angle).
REBASING = ("rk4", "dopri5", "baumgarte", *(f"scipy-{m}" for m in
                                           ("RK45", "DOP853", "Radau", "BDF", "LSODA")))


def turn_check(result, plan, module, events, turn) -> None:
    """Warn when a kernel's angle may have left its atan2 branch (docs/elements.md,
    "Angles over turns"): with re-basing (``turn``: the run's largest, and its angle),
    a step that turned a joint by more than TURN_WARN (a quarter turn) between two
    re-basings; without (``turn`` None: ali3p), a recorded angle, counted over the
    records, beyond half a turn from its planned reference (a spring's free angle)."""
    names = [n for n in module.QUANTITY_NAMES if n.endswith(".angle")]
    text = None
    if turn is not None:
        turn, j = turn
        if turn > TURN_WARN and j >= 0:
            text = (f"the angle {names[j]} turned {turn:.3g} rad within one step: angles "
                    f"(torsion springs, loads of joint angles, events) are counted over "
                    f"turns from step to step and need less than half a turn per step; "
                    f"rerun with a smaller --dt (or tighter --rtol) and compare")
    elif len(result.t):
        from ..events.references import reference_slots
        params = np.concatenate([el.params for el in plan.elements])
        kept = [(name, params[slot]) for slot, name in reference_slots(plan)]
        q = _coordinates(plan, result)
        events.reset(q[0])
        for k, qk in enumerate(q):
            events.refresh(qk)
            r = events.quantity_kernels(qk, np.zeros_like(qk))[0]
            angle = dict(zip(module.QUANTITY_NAMES, r))
            far = [(n, angle[f"{n}.angle"], th) for n, th in kept
                   if abs(angle[f"{n}.angle"] - th) >= np.pi]
            if far:
                n, a, th = far[0]
                text = (f"{n}.angle = {a:.6g} rad at t = {result.t[k]:.6g}: "
                        f"{result.info.get('method')} measures the angles of torsion "
                        f"springs and loads of joint angles within half a turn of {th:.6g} "
                        f"rad (the free angle; 0 for loads), so from there the torque has "
                        f"the wrong sign; use rk4 or dopri5, which count turns")
                break
        events.restore()
    if text:
        result.info.setdefault("warnings", []).append(text)
        warnings.warn(text, RunWarning, stacklevel=4)


TURN_WARN = 0.5 * np.pi


def _coordinates(plan, result) -> np.ndarray:
    """q at every record, from the result's coordinate columns."""
    return np.column_stack([result.columns[f"{name}.{c}"] for name, _ in plan.triples
                            for c in "xyz"])
