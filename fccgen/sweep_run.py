"""What one run of a sweep does, on a Dask worker (docs/sweeps.md): a new solver with
the run's numbers, the model's simulate settings, a row of figures; the run's time
limit and the stop of its sweep are read whenever its integrator pauses."""
from __future__ import annotations

import time

from .errors import FccgenError
from .sweep_outputs import Output, evaluate

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
    from .provenance import model_hash
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
    for p in solver.plan.model.moving_points:
        for c in "xyz":
            row[f"final.{p.name}.{c}"] = float(result[f"{p.name}.{c}"][-1])
    return row
