"""Many runs of one compiled model at once: ``solver.simulate_many(parameters, ...)``.

Each parameter set becomes its own instance, a solver of the same compiled module with
those numbers (:mod:`fccgen.runtime.params`): its own kernels' parameters, engine
(one C struct: docs/engine.md), event state and set-up. The set-up is the instance's
own (a number that moves the initial positions moves its consistent initial state and
its rank decision, fccgen.runtime.setup_reuse), so every instance gives bit for bit
the result of ``solver.with_parameters(set).simulate(...)`` with the same options.
What is a function of inputs a set leaves alone is shared by the instances, keyed by
the bytes of those inputs, so sharing never changes an answer: the rank decisions (by
the Jacobian, fccgen.runtime.setup_reuse), the sparse solve's view and its ordering
(runtime/sparse_setup.py, paths.kept_structure).

The instances run on ``threads`` worker threads. A run's per-step loop is compiled
code that holds no Python lock (the GIL), so the loops of different instances run at
the same time on different cores; the Python parts of a run (the new numbers' plan,
the set-up, the naming of the result's columns, reactions) take the GIL and run one at
a time. BLAS is single-threaded for the whole call (fccgen.threads), as for one run.

A run that fails (a singular position, a divergence, a value a rule of the model file
refuses) gives a :class:`RunFailure` in its place, with the reason and the rows it
recorded before it stopped; the other runs are kept. Ctrl-C stops every run at its
next pause and raises KeyboardInterrupt.
"""
from __future__ import annotations

import math
import os
import threading
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field

from ..errors import FccgenError
from ..progress import Reporter

# Options of simulate that name one start: each instance takes its own
NOT_SHARED = ("q0", "v0")


@dataclass
class RunFailure:
    """The entry of a run that failed: its place in the list, its numbers, why it
    stopped (the error's first line is ``error``, the whole text ``message``), the
    exception's class name, and the rows recorded before it stopped (a Result with
    ``info["partial"]``, or None)."""
    index: int
    params: dict
    error: str
    kind: str
    message: str = ""
    partial: object = None
    model_hash: str | None = None
    ok: bool = field(default=False, init=False)

    def __repr__(self) -> str:
        return f"RunFailure(run {self.index}, {self.kind}: {self.error})"


class Cancelled(FccgenError):
    """A run of simulate_many stopped because the call was interrupted."""


def parameter_sets(parameters) -> list[dict]:
    """The parameter sets as dicts of with_parameters keys: a list (or tuple) of
    mappings, or a pandas DataFrame whose columns are keys (a NaN cell leaves that
    number as the model has it)."""
    if hasattr(parameters, "to_dict") and hasattr(parameters, "columns"):
        rows = parameters.to_dict(orient="records")
        return [{str(k): v for k, v in row.items() if not _missing(v)} for row in rows]
    if isinstance(parameters, dict):
        raise TypeError("simulate_many takes a list of parameter sets (dicts) or a pandas "
                        "DataFrame, not one dict; for one set use with_parameters(...)"
                        ".simulate(...)")
    try:
        sets = list(parameters)
    except TypeError:
        raise TypeError(f"simulate_many takes a list of parameter sets (dicts) or a pandas "
                        f"DataFrame, not {type(parameters).__name__}") from None
    for k, item in enumerate(sets):
        if not hasattr(item, "items"):
            raise TypeError(f"parameter set {k} is a {type(item).__name__}, not a dict of "
                            f"with_parameters keys (e.g. {{'bodies.arm.mass': 2.0}})")
    return [dict(item) for item in sets]


def _missing(value) -> bool:
    try:
        return value is None or (isinstance(value, float) and math.isnan(value))
    except TypeError:
        return False


def default_threads() -> int:
    """The cores this process may use."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:                   # not on Linux
        return os.cpu_count() or 1


def simulate_many(solver, parameters, *, threads=None, progress=None, run_progress=None,
                  **options) -> list:
    """One result per parameter set, in order (see the module docstring).

    parameters: a list of dicts of with_parameters keys, or a pandas DataFrame whose
    columns are such keys; threads: worker threads (None: the cores; 1: one after the
    other in this thread); progress: called with a ProgressEvent (stage "simulate_many",
    done of total runs) as runs end; run_progress: called with a run's index when it
    starts, returns that run's progress callback (or None), e.g. to stop it past a
    time limit (it raises from there); options: those of ``simulate`` (t_end, dt, method, output_dt, reactions, ...),
    the same for every run. An entry is a :class:`~fccgen.results.Result`, or a
    :class:`RunFailure` for a run that failed."""
    for name in NOT_SHARED:
        if name in options:
            raise TypeError(f"simulate_many does not take {name}=: each run starts from "
                            f"the initial state of its own numbers")
    sets = parameter_sets(parameters)
    if threads is None:
        threads = default_threads()
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"threads must be a whole number of at least 1 (got {threads!r})")
    _check_keys(solver, sets)
    out: list = [None] * len(sets)
    if not sets:
        return out
    say = Reporter(progress, "simulate_many", total=len(sets))
    stop = threading.Event()

    def run(k):
        out[k] = _run_one(solver, k, sets[k], options, run_progress, stop)
        return k
    from ..threads import single_threaded_blas
    with single_threaded_blas():        # held for every worker: none restores it early
        if threads == 1:
            for done, k in enumerate(range(len(sets)), 1):
                run(k)
                say(f"simulate_many: {done} of {len(sets)} runs done", done=done)
            return out
        pool = ThreadPoolExecutor(max_workers=min(threads, len(sets)),
                                  thread_name_prefix="fccgen-run")
        pending = {pool.submit(run, k) for k in range(len(sets))}
        done = 0
        try:
            while pending:
                finished, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
                for future in finished:
                    future.result()      # _run_one catches what a run raises
                    done += 1
                    say(f"simulate_many: {done} of {len(sets)} runs done", done=done)
        except BaseException:
            stop.set()                   # each run stops at its next pause
            for future in pending:
                future.cancel()
            raise
        finally:
            pool.shutdown(wait=True)
    return out


def _check_keys(solver, sets: list[dict]) -> None:
    """A key that names nothing settable stops the call before any run (ModelError
    naming the set); a value a rule refuses fails only its own run."""
    from .params import check_key
    seen = set()
    for k, params in enumerate(sets):
        for key in params:
            if key in seen:
                continue
            try:
                check_key(solver.plan.model, key)
            except FccgenError as exc:
                exc.args = (f"parameter set {k}: {exc.args[0] if exc.args else exc}",
                            *exc.args[1:])
                raise
            seen.add(key)


def _run_one(solver, k: int, params: dict, options: dict, run_progress, stop) -> object:
    """Run k: a Result, or a RunFailure saying why it has none."""
    from ..errors import SimulationError
    progress = run_progress(k) if run_progress is not None else None

    def checked(event):
        if stop.is_set():
            raise Cancelled("simulate_many was interrupted")
        if progress is not None:
            progress(event)
    instance = None
    try:
        if stop.is_set():
            raise Cancelled("simulate_many was interrupted")
        instance = solver.with_parameters(params)
        return instance.simulate(progress=checked, **options)
    # Warning: a run warning the caller's filters turn into an error fails its run
    except (FccgenError, SimulationError, ArithmeticError, ValueError, Warning) as exc:
        text = str(exc) or type(exc).__name__
        model_hash = None
        if instance is not None:
            from ..results.provenance import model_hash as hash_of
            model_hash = hash_of(instance.plan)
        return RunFailure(index=k, params=dict(params), error=text.splitlines()[0],
                          kind=type(exc).__name__, message=text,
                          partial=getattr(exc, "partial_result", None),
                          model_hash=model_hash)
