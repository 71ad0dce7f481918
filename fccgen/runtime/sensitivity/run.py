"""A run with forward sensitivities: the checks, the set-up (fccgen.runtime.sensitivity.
parameters, the parameter-derivative module) and the sensitivities' columns.

The engine carries d(q, v)/dp through the stages of RK4 or DOPRI5 (engine/fcc_sens.h,
fcc_sens_dopri5.h) and the linearised projections; this module turns the records into
``d(<column>)/d(<key>)`` for the coordinate and speed columns and, by the chain rule
through the same output functions, for every other column of the state.
"""
from __future__ import annotations


from ...errors import ModelError
from .columns import column_name, column_sensitivities
from .geometry import kind as geometry_kind
from .parameters import directions


# The event actions whose jumps the engine carries the sensitivities through
# (engine/fcc_sens_events.c).
# A bounce carries its rests (its row's lock) and releases (engine/fcc_sens.h).
CARRIED = ("stop", "log", "lock", "unlock", "bounce")
TIME_KEY = "d(time)/d({})"
# The methods that carry them (engine/fcc_rk4.c, fcc_dopri5.c).
METHODS = ("rk4", "dopri5")


def split_keys(keys) -> list[str]:
    """Parameter keys from a list or one comma-separated string (commas inside [k]
    never occur: a key's component is one index)."""
    if isinstance(keys, str):
        keys = keys.split(",")
    return [str(k).strip() for k in keys if str(k).strip()]


def check_request(solver, keys, method: str, project: bool,
                  error_control=None) -> list[str]:
    """The keys as a list of strings, or ModelError / ValueError saying what cannot be
    done (and why) before anything runs. error_control: the ``sensitivity_error``
    option (None: not given; dopri5 only)."""
    model = solver.plan.model
    keys = split_keys(keys)
    if not keys:
        raise ValueError("sensitivities: name at least one parameter key "
                         "(e.g. bodies.arm.mass)")
    if len(set(keys)) != len(keys):
        raise ValueError(f"sensitivities: a key is named twice: {', '.join(keys)}")
    if method not in METHODS:
        raise ValueError(f"sensitivities are integrated by the rk4 or dopri5 method (the "
                         f"model's, or method='rk4' or 'dopri5'), not by {method}")
    if error_control is not None and method != "dopri5":
        raise ValueError("sensitivity_error puts the sensitivities into dopri5's error "
                         f"control; {method} has none (its steps are dt)")
    if error_control is not None and not isinstance(error_control, bool):
        raise ValueError(f"sensitivity_error must be True or False, not {error_control!r}")
    if not project:
        raise ValueError(f"sensitivities need the projected {method} (project=True)")
    if method == "dopri5" and solver.linear_solver == "sparse":
        raise ValueError("dopri5 carries sensitivities on the dense path only; load the "
                         "model with linear_solver='auto' or 'dense', or use rk4 on the "
                         "sparse path")
    if solver.linear_solver == "sparse":
        moved = [key for key in keys if geometry_kind(key) is not None]
        if moved:
            # a geometry key can move coordinates the sparse path holds fixed (a planar
            # model's pinned out-of-plane coordinates), whose change its solves leave out
            raise ValueError(f"sensitivities to geometry ({', '.join(moved)}) run on the "
                             "dense path only; load the model with linear_solver='auto' "
                             "or 'dense'")
    for k, event in enumerate(model.events):
        if event.action not in CARRIED:
            raise ModelError(model.source, event.where.line, f"events[{k}] ({event.name})",
                             f"sensitivities are carried through {', '.join(CARRIED)} "
                             f"events, not through a {event.action}",
                             show_value=False)
        if event.action == "bounce" and solver.linear_solver == "sparse":
            # the impact's, rest's and release's jumps (engine/fcc_sens_events.c)
            # take the dense path's mass matrix and multipliers
            raise ModelError(model.source, event.where.line, f"events[{k}] ({event.name})",
                             "sensitivities are carried through a bounce (a joint "
                             "limit) on the dense path only; load the model with "
                             "linear_solver='auto' or 'dense'", show_value=False)
    return keys


def dense_reason(solver, keys, method: str) -> str | None:
    """Why a run with sensitivities of a solver whose own path is the sparse one
    takes the dense path instead (under linear_solver="auto"; "sparse" refuses these:
    check_request), or None (it stays on the sparse path)."""
    if method == "dopri5":
        return "dopri5 carries sensitivities on the dense path only"
    moved = [key for key in keys if geometry_kind(key) is not None]
    if moved:
        return (f"sensitivities to geometry ({', '.join(moved)}) can move coordinates "
                "the sparse path holds fixed")
    if any(ev.action == "bounce" for ev in solver.plan.model.events):
        return "the model's bounce events carry their sensitivities with the dense M"
    return None


def on_sparse(solver, keys, method: str) -> bool:
    """Whether a run of ``solver`` with sensitivities to ``keys`` by ``method`` takes
    the sparse path (the solver's own path is the sparse one and nothing needs the
    dense matrices)."""
    return bool(solver.sparse) and dense_reason(solver, keys, method) is None


def engine_for(solver, keys, method: str):
    """The engine a run with sensitivities takes (on_sparse: the solver's own)."""
    return solver._engine if on_sparse(solver, keys, method) else solver.dense_engine()


def setup(solver, keys, build_dir, engine):
    """The Sensitivities for ``keys`` (checked) of ``solver`` on ``engine`` (engine_for)."""
    from .._sens import Sensitivities
    from .build import load_dp
    dP, S0 = directions(solver, keys)
    module = load_dp(solver.plan, build_dir)
    return Sensitivities(engine.asm, module, dP, S0)


def error_scale(solver, keys) -> list[float]:
    """Each parameter's size for dopri5's error control of the sensitivities (the
    tolerance of d(state)/dp_j is atol / size: p_j dq/dp_j is measured like q):
    |value|, or 1 for a parameter that is 0."""
    from .parameters import current_value
    model = solver.plan.model
    return [abs(current_value(model, key)) or 1.0 for key in keys]


def attach(solver, result, keys, sens, method: str = "rk4") -> None:
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
    reason = dense_reason(solver, keys, method) if solver.sparse else None
    sparse = bool(solver.sparse) and reason is None          # on_sparse
    result.info["sensitivity_path"] = "sparse" if sparse else "dense"
    if reason is not None:
        result.info["sensitivity_path_note"] = (
            f"the run took the dense path although the model's own path is the sparse "
            f"one: {reason}")
    result.info["sensitivity_column_error"] = worst
