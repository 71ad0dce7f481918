"""How near the motion comes to a singular position of its constraints, read from the
pilot's positions, and the warning it gives.

At a singular position (A02's chain lying flat, a linkage at a dead point) the
constraint Jacobian B loses rank, and the motion that leaves it picks one of several
branches. Which one a run picks need not follow its step: A02's runs at steps that
step doubling calls converged take other branches than runs at finer steps, 1e-4 m
apart (docs/accuracy.md). No global estimate made of runs sees that, so the run says
so. The runtime's own signal (factorisations that dropped rows) exists on the dense
path only; this one holds on every path: the smallest kept singular value of B (rows
scaled as the rank rule scales them, fccgen.rank) relative to the largest, at the
output positions of the pilot's finest rung. Near a singular position it falls
toward zero; along a motion far from one it stays within a small factor of its start.
"""
from __future__ import annotations

import numpy as np

from .. import rank as rank_rule

# The motion came near a singular position when the smallest kept scaled singular
# value fell below this share of its value at the start. Measured: A02 falls from
# 0.031 to 8.9e-4 (0.029 of it) on the pilot's outputs of its first 2 s, Andrews'
# mechanism stays within 0.4 % of its start, the solar array and the double pendulum
# do not move it at all.
APPROACH = 0.1
# Beyond this many coordinates a dense SVD per sampled position costs more than the
# run; such models are not checked here (docs/accuracy.md).
MAX_COORDINATES = 500


def approach(solver, result) -> dict | None:
    """start, smallest (sigma_r / sigma_1 at the first output and its smallest value
    over the outputs) and the time of the smallest, for a run's recorded positions;
    None when the model has no constraint rows or is too large to check."""
    plan = solver.plan
    columns = [f"{name}.{c}" for name, _ in plan.triples for c in "xyz"]
    rank = int(result.info.get("rank") or 0)
    if (rank <= 0 or len(columns) != solver.n_q or solver.n_q > MAX_COORDINATES
            or not all(c in result.columns for c in columns)):
        return None
    q = np.column_stack([np.asarray(result[c], float) for c in columns])
    kept = []
    for row in q:
        sigma = rank_rule.scaled_singular_values(solver.constraint_jacobian(row),
                                                 solver.row_groups)
        kept.append(sigma[rank - 1] / sigma[0] if sigma.size >= rank and sigma[0] > 0
                    else np.nan)
    kept = np.asarray(kept)
    if not np.all(np.isfinite(kept)):
        return None
    k = int(np.argmin(kept))
    return dict(start=float(kept[0]), smallest=float(kept[k]),
                time=float(np.asarray(result.t)[k]))


def approach_warning(found: dict | None, estimate: float) -> list[str]:
    """The warning when the pilot's motion came near a singular position."""
    if found is None or not found["smallest"] < APPROACH * found["start"]:
        return []
    return [f"the motion comes near singular positions of the constraints (the smallest "
            f"kept singular value of the constraint Jacobian, rows scaled, falls from "
            f"{found['start']:.2g} at the start to {found['smallest']:.2g} at t = "
            f"{found['time']:.6g} in the pilot): there the motion can take another "
            "branch, and runs at different steps need not take the same one, which "
            f"no estimate from two runs sees; the error estimate {estimate:.2g} is not "
            "a promise; compare runs at several settings (method=, dt= or rtol=)"]
