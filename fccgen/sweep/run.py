"""What one run of a sweep does, on a Dask worker (docs/sweeps.md): a new solver with
the run's numbers, the model's simulate settings, a row of figures; the run's time
limit and the stop of its sweep are read whenever its integrator pauses."""
from __future__ import annotations

import time

from ..errors import FccgenError
from .outputs import Output, evaluate

# Sweeps of this process whose runs are to stop (Ctrl-C, a lost scheduler): the runs
# in threads of a local cluster read it whenever their integrator pauses.
CANCELLED: set[str] = set()


class RunTimedOut(FccgenError):
    """A run of the sweep reached its time limit."""


class Cancelled(FccgenError):
    """A run of a sweep that has been stopped."""


def watch(limit: float | None, sweep_id: str | None):
    """The progress callback of a run: stops it past its time limit or when its sweep
    has been stopped (raised from the integrator's pause, so the run ends there)."""
    end = None if limit is None else time.monotonic() + limit

    def check(event):
        if sweep_id is not None and sweep_id in CANCELLED:
            raise Cancelled("the sweep was stopped")
        if end is not None and time.monotonic() > end:
            raise RunTimedOut(f"stopped by the run time limit of {limit:g} s (wall time) "
                              f"at t = {event.t:.6g} of {event.total:.6g}")
    return check


def run_one(solver, params: dict, method=None, outputs: list[Output] = (),
            run_timeout: float | None = None, sweep_id: str | None = None) -> dict:
    """One run of the sweep: its row of summary figures (:func:`run_batch` of one)."""
    return run_batch(solver, [params], method, outputs, run_timeout, sweep_id)[0]


def run_batch(solver, batch: list[dict], method=None, outputs: list[Output] = (),
              run_timeout: float | None = None, sweep_id: str | None = None) -> list[dict]:
    """The runs of one Dask task: ``solver.simulate_many`` of the batch's numbers, one
    after the other in the task's thread (the cluster's threads run tasks side by
    side), one row of summary figures per run, in order. A row's wall_time is its
    run's, set-up included."""
    starts: list[float] = []

    def run_watch(k):
        starts.append(time.perf_counter())
        return watch(run_timeout, sweep_id)
    entries = solver.simulate_many(batch, threads=1, run_progress=run_watch,
                                   method=method)
    starts.append(time.perf_counter())
    rows = []
    for k, (params, entry) in enumerate(zip(batch, entries)):
        row = dict(params)
        wall = starts[k + 1] - starts[k]
        if not entry.ok:
            if entry.model_hash is not None:
                row["model_hash"] = entry.model_hash
            status = "timeout" if entry.kind == RunTimedOut.__name__ else "failed"
            row.update(status=status, error=entry.message if status == "timeout"
                       else entry.error, wall_time=wall)
            rows.append(row)
            continue
        result, info = entry, entry.info
        row["model_hash"] = info["model"]["hash"]
        row.update(status="ok", error="", wall_time=wall,
                   steps=info.get("steps"), t_final=float(result.t[-1]),
                   energy_drift=info.get("energy_drift"),
                   max_constraint_error=info.get("max_constraint_error"))
        row.update(evaluate(list(outputs), result))
        for label, column in final_columns(solver.plan):
            row[label] = float(result[column][-1])
        rows.append(row)
    return rows


def final_columns(plan) -> list[tuple[str, str]]:
    """(table label, result column) of the final positions a sweep row carries: each
    moving point the user named (``final.P.x``), and for a model with joints each
    body's mass centre (``final.arm.cx``); the points and vectors the lowering made
    stay out, as they do of ``result.names``."""
    mechanism = plan.model.mechanism
    made = set(mechanism.internal()) if mechanism is not None else set()
    out = [(f"final.{p.name}.{c}", f"{p.name}.{c}") for p in plan.model.moving_points
           if p.name not in made for c in "xyz"]
    if mechanism is not None:
        out += [(f"final.{b}.{c}", f"{b}.{c}") for b, _ in plan.bodies
                for c in ("cx", "cy", "cz")]
    return out
