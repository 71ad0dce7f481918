"""The generalized force of every driver (result columns ``D.torque``, ``D.force``),
computed after a run from the recorded states.

At a recorded state (t, q, q') the engine's accelerations q'' satisfy
M q'' + B^T lambda = f - h, so the multipliers solve

    B^T lambda = f - h - M q''

(least squares, minimum norm: with redundant rows lambda is not unique, but the
component of a driver row is, since no dependency among the rows involves it). A
driver row is g = sin(theta - f) (angle) or s - f (position), whose derivative along
the driven joint coordinate is 1 on the constraint (theta = f), so the torque (force)
the driver applies on the joint's second body about (along) the axis is the
generalized force of that row on the joint coordinate: -lambda_row. A distance
driver's row d.d - f^2 has the derivative 2 s = 2 f along the distance s, so its force
(positive: pushing the bodies apart) is -2 f(t) lambda_row.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import RunWarning
from .lowering import driver_column, driver_label

# Singular values of B^T below this fraction of the largest count as zero in the
# minimum-norm solve: the rank tolerance of the solvers (fccgen.rank).
RCOND = 1e-10
# Records whose turns are counted at once (fccgen.numeric.record_loads).
CHUNK = 1024


def driver_rows(plan) -> dict[str, tuple[int, object]]:
    """{result column: (constraint row, dg/ds as a function of t)} of the plan's
    drivers (s the driven joint quantity)."""
    lowering = getattr(plan.model, "mechanism", None)
    drivers = getattr(lowering, "drivers", None) or []
    if not drivers:
        return {}
    start, rows = 0, {}
    by_label = {}
    for el in plan.elements:
        by_label[el.label] = start
        start += el.cls.n_g
    from ..expressions.time_jets import time_function     # numeric imports this module
    for d in drivers:
        slope = (lambda t: 1.0) if d.quantity != "distance" else (
            lambda t, f=time_function(d.function): 2.0 * f(t)[0])
        rows[driver_column(d)] = (by_label[driver_label(d)], slope)
    return rows


def multipliers(solver, t: float, q: np.ndarray, v: np.ndarray, held=None,
                keys=frozenset()) -> np.ndarray:
    """The minimum-norm multipliers lambda of B's rows at (t, q, q') (module
    docstring). held, keys: the rows that the run's events hold at this record
    (fccgen.runs.held_rows): the accelerations hold them, and their multipliers join
    the least-squares solve (a driver's row is no combination of a lock's: a driven
    joint takes no lock, fccgen.model.events)."""
    solver.set_time(t)
    B = solver.constraint_jacobian(q)
    if keys:
        a, G = held.solve(q, v, keys)
        B = np.vstack([B, G])
    else:
        a = solver.accelerations(q, v)
    rhs = solver.applied_forces(q, v) - solver.h_vector(q, v) - solver.mass_matrix(q) @ a
    return np.linalg.lstsq(B.T, rhs, rcond=RCOND)[0]


def record_chunks(n: int, size: int, held):
    """(slice of records, held rows) of the first n records, in chunks of at most
    ``size`` records in order, each within one segment of constant held rows
    (fccgen.runs.held_rows; held None: none held)."""
    for start, stop, keys in held.segments if held is not None else [(0, n, frozenset())]:
        stop = min(stop, n)
        for first in range(start, stop, size):
            yield slice(first, min(stop, first + size)), keys


def add_driver_columns(solver, result, held=None, loads=None) -> None:
    """Append the drivers' generalized forces to ``result`` (in place); held: the
    rows the run's events held (:func:`multipliers`); loads: what the run held at
    each record (fccgen.numeric.record_loads.RecordLoads: its inputs and the angle
    references of the kernels that count turns, so that a spring wound past half a
    turn pulls as it did in the run; None: the planned parameters)."""
    rows = driver_rows(solver.plan)
    if not rows or len(result.t) == 0:
        return
    plan = solver.plan
    q = np.column_stack([result.columns[f"{name}.{c}"] for name, _ in plan.triples
                         for c in "xyz"])
    v = np.column_stack([result.columns[f"{name}.v{c}"] for name, _ in plan.triples
                         for c in "xyz"])
    values = {col: np.full(len(result.t), np.nan) for col in rows}
    known = len(result.t) if held is None else held.known
    reason = held.unknown_reason(result.t) if known < len(result.t) else ""
    parts = record_chunks(known, CHUNK, held)
    records = (((k, keys) for part, keys in parts for k in range(part.start, part.stop))
               if loads is None else loads.placed(result.t, q, v, parts))
    try:
        for k, keys in records:    # with loads: the parameters held at the record's
            t = float(result.t[k])
            lam = multipliers(solver, t, q[k], v[k], held, keys)
            for col, (row, slope) in rows.items():
                values[col][k] = -slope(t) * lam[row]
    finally:
        if loads is not None:
            loads.restore()
    if loads is not None and loads.lost is not None:    # turns the records cannot count
        known, reason = loads.lost
    result.columns.update(values)
    if known < len(result.t):
        text = f"the driver forces are NaN from t = {result.t[known]:.9g} s on: {reason}"
        result.info.setdefault("warnings", []).append(text)
        warnings.warn(text, RunWarning, stacklevel=3)
