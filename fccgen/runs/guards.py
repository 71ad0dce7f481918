"""Guards that every integration method shares (docs/reliability.md, "Runs that blow
up" and "Runs without projection"): the bounds past which a run has diverged, and the
check of a run's constraint error when nothing projected the state back.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import RunWarning

# A run without projection whose scaled constraint residual max_k |g_k| / ||B_k||
# exceeds this fraction of the model's size (its largest body length) has left the
# mechanism: its positions are no longer the mechanism's, however smooth.
DRIFT_OF_SIZE = 1e-3


def divergence_bounds(q0, v0, t_end: float, dt: float | None) -> tuple[float, float]:
    """(q_bound, v_bound) of a run: 1e6 times the size the state can reach by moving at
    its initial speed, q_ref + |v0| t_end, and 1e6 times the speed that crosses the
    model's size in one step dt, |v0| + q_ref / dt (q_ref = max |q0|, or 1; adaptive
    methods, dt None, have no step to measure speeds by: no speed bound). An unstable
    explicit step grows the state by a constant factor per step, so it passes these
    within tens of steps, while no accurate run comes near them."""
    q0, v0 = np.asarray(q0, float), np.asarray(v0, float)
    q_ref = float(np.max(np.abs(q0))) if q0.size else 1.0
    q_ref = q_ref if q_ref > 0.0 else 1.0
    v_ref = float(np.max(np.abs(v0))) if v0.size else 0.0
    return (1e6 * (q_ref + v_ref * t_end),
            np.inf if dt is None else 1e6 * (v_ref + q_ref / dt))


def check_constraint_drift(solver, result, project: bool) -> None:
    """For a run without projection: ``info["constraint_drift"]`` (the largest scaled
    residual over the records, at the record of the largest max |g|, and when), and a
    warning when it exceeds DRIFT_OF_SIZE of the model's size."""
    if project or not len(result.t):
        return
    plan = solver.plan
    k = int(np.argmax(np.asarray(result["constraint_error"], float)))
    q = np.array([result.columns[f"{name}.{c}"][k] for name, _ in plan.triples
                  for c in "xyz"])
    if hasattr(solver, "set_time"):
        solver.set_time(float(result.t[k]))
    g, B = solver.constraints(q), solver.constraint_jacobian(q)
    norms = np.sqrt(np.einsum("ij,ij->i", B, B)) if B.size else np.ones(0)
    scaled = float(np.max(np.abs(g) / np.where(norms > 0, norms, 1.0), initial=0.0))
    size = float(solver.length_scale)
    result.info["constraint_drift"] = {"scaled_residual": scaled, "t": float(result.t[k]),
                                       "size": size}
    if not scaled <= DRIFT_OF_SIZE * size:
        text = (f"without projection the run left the constraints: the scaled residual "
                f"max |g_k| / ||B_k|| reached {scaled:.3g} at t = {float(result.t[k]):.6g}, "
                f"{scaled / size:.3g} of the model's size {size:.3g} (more than "
                f"{DRIFT_OF_SIZE:g}): from there the positions are not the mechanism's; "
                f"run with projection (rk4 or dopri5 without --no-project) or a smaller "
                f"--dt / --rtol")
        result.info.setdefault("warnings", []).append(text)
        warnings.warn(text, RunWarning, stacklevel=3)
