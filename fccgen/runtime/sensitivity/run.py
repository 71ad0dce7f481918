"""A run with forward sensitivities: the checks, the set-up (fccgen.runtime.sensitivity.
parameters, the parameter-derivative module) and the sensitivities' columns.

The engine carries d(q, v)/dp through RK4's own stages and the linearised
projections (engine/fcc_sens.h); this module turns the records into
``d(<column>)/d(<key>)`` for the coordinate and speed columns and, by the chain rule
through the same output functions, for every other column of the state.
"""
from __future__ import annotations


from ...errors import ModelError
from .columns import column_name, column_sensitivities
from .parameters import directions


# The event actions whose jumps the engine carries the sensitivities through
# (engine/fcc_sens_events.c).
CARRIED = ("stop", "log", "lock", "unlock")
TIME_KEY = "d(time)/d({})"


def split_keys(keys) -> list[str]:
    """Parameter keys from a list or one comma-separated string (commas inside [k]
    never occur: a key's component is one index)."""
    if isinstance(keys, str):
        keys = keys.split(",")
    return [str(k).strip() for k in keys if str(k).strip()]


def check_request(solver, keys, method: str, project: bool) -> list[str]:
    """The keys as a list of strings, or ModelError / ValueError saying what cannot be
    done (and why) before anything runs."""
    model = solver.plan.model
    keys = split_keys(keys)
    if not keys:
        raise ValueError("sensitivities: name at least one parameter key "
                         "(e.g. bodies.arm.mass)")
    if len(set(keys)) != len(keys):
        raise ValueError(f"sensitivities: a key is named twice: {', '.join(keys)}")
    if method != "rk4":
        raise ValueError(f"sensitivities are integrated by the rk4 method (the model's "
                         f"or method='rk4'), not by {method}")
    if not project:
        raise ValueError("sensitivities need the projected rk4 (project=True)")
    for k, event in enumerate(model.events):
        if event.action not in CARRIED:
            raise ModelError(model.source, event.where.line, f"events[{k}] ({event.name})",
                             f"sensitivities are carried through {', '.join(CARRIED)} "
                             f"events, not through a {event.action} (the impact's and the "
                             "rest's jumps are not derived yet; joint limits are bounces)",
                             show_value=False)
    if solver.linear_solver == "sparse" and dense_reason(solver):
        raise ValueError(f"sensitivities of this model run on the dense path: "
                         f"{dense_reason(solver)}; load the solver with "
                         f"linear_solver='dense' or 'auto'")
    return keys


# The event actions whose sensitivities need the dense path (engine/fcc_sens_events.c:
# the locked rows' stage and projection terms are formed with the dense M and B).
DENSE_ACTIONS = ("lock", "unlock")


def dense_reason(solver) -> str | None:
    """Why a run with sensitivities of a solver on the sparse path takes the dense
    path instead, or None (it stays on the sparse path)."""
    actions = sorted({ev.action for ev in solver.plan.model.events} & set(DENSE_ACTIONS))
    if actions:
        return (f"the model's {' and '.join(actions)} events carry their sensitivities "
                "with the dense matrices M and B")
    return None


def on_sparse(solver) -> bool:
    """Whether a run of ``solver`` with sensitivities takes the sparse path (the
    solver's own path is the sparse one and nothing needs the dense matrices)."""
    return bool(solver.sparse) and dense_reason(solver) is None


def engine_for(solver):
    """The engine a run with sensitivities takes (on_sparse: the solver's own)."""
    return solver._engine if on_sparse(solver) else solver.dense_engine()


def setup(solver, keys, build_dir):
    """The engine's Sensitivities for ``keys`` (checked) of ``solver``."""
    from .._sens import Sensitivities
    from .build import load_dp
    dP, S0 = directions(solver, keys)
    module = load_dp(solver.plan, build_dir)
    return Sensitivities(engine_for(solver).asm, module, dP, S0)


def attach(solver, result, keys, sens) -> None:
    """Add the columns ``d(<column>)/d(<key>)`` of every column of the state and key
    (fccgen.runtime.sensitivity.columns) to ``result``; ``info["sensitivities"]``: the keys."""
    records = sens.records
    if "stopped_at" in result.info or records.shape[0] > len(result.t):
        records = records[:len(result.t)]      # a stop event: the records so far
    if records.shape[0] != len(result.t) or records.shape[2] != 2 * solver.plan.n_q:
        raise AssertionError("sensitivity records do not match the run's records")
    worst = 0.0
    for j, key in enumerate(keys):
        cols, err = column_sensitivities(solver, result, key, records[:, j, :],
                                         sens.dP[j])
        worst = max(worst, err)
        for col in list(result.columns):
            if col in cols:
                result.columns[column_name(col, key)] = cols[col]
                if col in result.hidden:
                    result.hidden.add(column_name(col, key))
    events = getattr(result, "events", None) or []
    if events:                     # each event row: d(time)/d(key), dt_e/dp (engine)
        rows = sens.event_records
        if rows is None or rows.shape[0] < len(events):
            raise AssertionError("sensitivity event records do not match the run's events")
        for i, row in enumerate(events):
            for j, key in enumerate(keys):
                row[TIME_KEY.format(key)] = float(rows[i, j])
    result.info["sensitivities"] = list(keys)
    result.info["sensitivity_path"] = "sparse" if on_sparse(solver) else "dense"
    if solver.sparse and not on_sparse(solver):
        result.info["sensitivity_path_note"] = (
            f"the run took the dense path although the model's own path is the sparse "
            f"one: {dense_reason(solver)}")
    result.info["sensitivity_column_error"] = worst
