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
    """One run of the sweep (executed by a Dask worker): a row of summary figures."""
    from ..results.provenance import model_hash
    start = time.perf_counter()
    row = dict(params)
    try:
        run = solver.with_parameters(params)
        row["model_hash"] = model_hash(run.plan)
        result = run.simulate(method=method, progress=watch(run_timeout, sweep_id))
    except RunTimedOut as exc:
        row.update(status="timeout", error=str(exc), wall_time=time.perf_counter() - start)
        return row
    except (FccgenError, ArithmeticError, ValueError) as exc:
        row.update(status="failed", error=str(exc).splitlines()[0],
                   wall_time=time.perf_counter() - start)
        return row
    info = result.info
    row.update(status="ok", error="", wall_time=time.perf_counter() - start,
               steps=info.get("steps"), t_final=float(result.t[-1]),
               energy_drift=info.get("energy_drift"),
               max_constraint_error=info.get("max_constraint_error"))
    row.update(evaluate(list(outputs), result))
    for label, column in final_columns(solver.plan):
        row[label] = float(result[column][-1])
    return row


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
