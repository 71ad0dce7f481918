"""The sensitivities of a run's columns: ``d(<column>)/d(<key>)`` at every record.

The coordinate and speed columns (``P.x``, ``P.vx``, ``u.x`` ...) are the integrated
sensitivities themselves. Every other column that is a function of the state and the
model's numbers (mass centres, angular velocities, energy, joint angles and rates,
strains and curvatures) is differentiated by the chain rule through the same output
functions that made the column: along the direction (s_q, s_v, dP) at each record, by
central differences of step h and h/2 combined by Richardson's rule (error O(h^4),
about 1e-12 relative with the steps below; the two estimates' difference is kept in
``result.info["sensitivity_column_error"]``). Columns of the constraint forces
(reactions, driver forces) and ``constraint_error`` have none.
"""
from __future__ import annotations

import copy
import dataclasses

import numpy as np

from ...numeric.record_loads import RecordLoads, energies
from ...results.result import _with_joint_columns, result_from_arrays

NO_SENSITIVITY = ("constraint_error",)
# The direction's step: this fraction of the model's length (positions), of the
# largest speed (speeds) and of the parameter.
REL_STEP = 1e-3


def column_name(column: str, key: str) -> str:
    return f"d({column})/d({key})"


def _shifted_solver(solver, dP_j: np.ndarray, eps: float):
    """A solver of the same module whose element parameters are P + eps dP_j."""
    from ..params import solver_options
    plan = copy.copy(solver.plan)
    start, elements = 0, []
    for el in plan.elements:
        k = len(el.params)
        elements.append(dataclasses.replace(el, params=el.params + eps * dP_j[start:start + k]))
        start += k
    plan.elements = elements
    return type(solver)(plan, solver.module, **solver_options(solver))


def _columns(solver, t, q, v, impacts) -> dict[str, np.ndarray]:
    """The columns of the records (t, q, v); impacts: the run's event times. The
    energy is taken with the angle references counted over turns along the records,
    as the run had them (a spring wound past half a turn: its angle over turns)."""
    body = []
    for tk, qk, vk in zip(t, q, v):
        solver.set_time(float(tk))
        body.append(solver.body_outputs(qk, vk))
    loads = RecordLoads(solver.plan, solver.put_params)
    loads.impacts = impacts
    energy, _, _ = energies(solver, t, q, v, loads)   # NaN where turns are not counted
    plan = solver.plan
    body = np.array(body).reshape(len(t), len(plan.bodies), 6)
    r = result_from_arrays(plan, t, q, v, body, np.array(energy), np.zeros(len(t)))
    r.events = [{"t": float(x)} for x in impacts]      # the angles' turns across them
    return _with_joint_columns(plan, r, warn=False).columns


def column_sensitivities(solver, result, key: str, S: np.ndarray, dP_j: np.ndarray):
    """({column: d(column)/d(key)} over the columns of the state, and the largest
    Richardson difference relative to the column's scale)."""
    plan, n = solver.plan, solver.plan.n_q
    names = [f"{name}.{c}" for name, _ in plan.triples for c in "xyz"]
    q = np.column_stack([result.columns[x] for x in names])
    v = np.column_stack([result.columns[f"{name}.v{c}"] for name, _ in plan.triples
                         for c in "xyz"])
    sq, sv = S[:, :n], S[:, n:]
    L = solver.length_scale
    h = REL_STEP * min(L / max(np.max(np.abs(sq)), 1e-300),
                       max(np.max(np.abs(v)), L) / max(np.max(np.abs(sv)), 1e-300),
                       1.0 / max(np.max(np.abs(dP_j)), 1e-300) * max(
                           np.max(np.abs(np.concatenate([el.params for el in plan.elements]))),
                           1.0))

    impacts = np.array(sorted(e["t"] for e in result.events), float)

    def at(eps):
        return _columns(_shifted_solver(solver, dP_j, eps), result.t, q + eps * sq,
                        v + eps * sv, impacts)

    plus, minus, plus2, minus2 = at(h), at(-h), at(h / 2), at(-h / 2)
    out, worst = {}, 0.0
    for col in plus:
        if col in NO_SENSITIVITY or col not in result.columns:
            continue
        d1 = (plus[col] - minus[col]) / (2 * h)
        d2 = (plus2[col] - minus2[col]) / h
        out[col] = (4 * d2 - d1) / 3
        if np.isnan(out[col]).all():
            continue
        scale = max(np.nanmax(np.abs(out[col])), 1e-300)
        worst = max(worst, float(np.nanmax(np.abs(d2 - d1)) / scale))
    for k, name in enumerate(names):                     # the integrated ones, exact
        out[name] = np.array(sq[:, k])
    for k, (name, _) in enumerate(plan.triples):
        for c in range(3):
            out[f"{name}.v{'xyz'[c]}"] = np.array(sv[:, 3 * k + c])
    return out, worst
