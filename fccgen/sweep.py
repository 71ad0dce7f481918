"""Many runs of one compiled model with different numbers (``fccgen sweep``,
docs/sweeps.md), on Dask: a local cluster by default, a running scheduler when given.

The model is compiled once, before anything is dispatched; every combination of the
``--set`` values (their Cartesian product, in the order given) is checked then, so a
bad key or value stops the sweep before it starts, and so are the ``--outputs``
(:mod:`fccgen.sweep_outputs`). Each task receives the compiled solver (in another
process: pickled as its plan and module folder, see :mod:`fccgen.runtime.params`) and
its numbers, makes a new solver with
:meth:`~fccgen.runtime.CompiledSolver.with_parameters` and runs the model's own
simulate settings (which ``simulate.t_end`` and the like may change). A run that fails
gives a row with status ``failed`` and the error's text; a run longer than the time
limit (``run_timeout`` seconds of wall time, checked whenever the integrator pauses,
about every 0.5 s) is stopped and gives a row with status ``timeout``; the others go on.

One row per run: ``run`` (its place in the sweep, from 1), the parameters, ``status``,
``error``, ``wall_time`` (seconds, the task's own), ``steps``, ``t_final``,
``energy_drift`` (max |E - E0|, losses of events added back), ``max_constraint_error``,
``model_hash`` (the numbers of the run), then the ``--outputs`` and
``final.P.x final.P.y final.P.z`` of each moving point.

Finished work is never lost (:mod:`fccgen.sweep_table`): rows go to a partial file as
they finish; Ctrl-C ends in :class:`SweepInterrupted` and a lost scheduler or cluster in
:class:`SweepStopped`, each saying how many rows were saved and where.
"""
from __future__ import annotations

import itertools
import logging
import os
import time
import warnings
from pathlib import Path

from .errors import FccgenError, HostError
from .progress import Reporter
from .sweep_outputs import Output, check_outputs, evaluate, parse_outputs
from .sweep_table import (PartialWriter, SweepTable, check_table_path, partial_path,
                          read_partial)

__all__ = ["SweepInterrupted", "SweepStopped", "SweepTable", "check_table_path",
           "combinations", "parse_sets", "require_dask", "run_one", "sweep"]

FIGURES = ("status", "error", "wall_time", "steps", "t_final", "energy_drift",
           "max_constraint_error", "model_hash")
# Sweeps of this process whose runs are to stop (Ctrl-C, a lost scheduler): the runs
# in threads of a local cluster read it whenever their integrator pauses.
_CANCELLED: set[str] = set()


class SweepStopped(HostError):
    """The sweep could not go on (the scheduler or cluster was lost); ``saved`` rows
    are in ``partial_path`` (``rows``: the finished rows)."""

    def __init__(self, message: str, saved: int = 0, partial_path=None, rows=()):
        super().__init__(message)
        self.saved, self.partial_path, self.rows = saved, partial_path, list(rows)


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep; the message says how many rows were saved and where
    (``rows``: the finished rows, also when no file was given)."""

    def __init__(self, message: str, saved: int = 0, partial_path=None, rows=()):
        super().__init__(message)
        self.saved, self.partial_path, self.rows = saved, partial_path, list(rows)


class RunTimedOut(FccgenError):
    """A run of the sweep reached its time limit."""


class _Cancelled(FccgenError):
    """A run of a sweep that has been stopped."""


class _Lost(FccgenError):
    """The cluster cancelled a run the sweep did not cancel: its scheduler is gone."""


class _NoSolver(FccgenError):
    """The workers could not receive the compiled solver (its module folder, read by
    path on each worker, is not there)."""


def quiet_dask() -> None:
    """Leave Dask's own log records below CRITICAL out from now on (the command line:
    a lost scheduler makes the client log tracebacks while it tries to reconnect, also
    after the sweep has ended, and the sweep's error paragraph already says what
    happened). Dask's configuration sets levels on its loggers one by one as it is
    imported, so it is imported first (a HostError when it is not installed)."""
    require_dask()
    names = [n for n in logging.Logger.manager.loggerDict
             if n == "distributed" or n.startswith("distributed.")]
    for name in {"distributed", "distributed.client", *names}:
        logging.getLogger(name).setLevel(logging.CRITICAL)


def require_dask():
    """dask.distributed, or a HostError saying how to install it (sweeps check this
    before anything is built)."""
    try:
        import dask.distributed
    except ImportError:
        raise HostError("fccgen sweep needs Dask, which is not installed. To fix it, "
                        "pip install 'fccgen[sweep]' (dask[distributed])") from None
    return dask.distributed


def parse_sets(items) -> dict[str, list[float]]:
    """``["KEY=V1,V2", ...]`` -> ``{KEY: [V1, V2]}`` (ValueError naming a bad item)."""
    sets: dict[str, list[float]] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        try:
            if not sep or not key:
                raise ValueError
            values = [float(v) for v in text.split(",")]
        except ValueError:
            raise ValueError(f"--set {item!r}: expected KEY=V1,V2,... with numbers, e.g. "
                             "bodies.arm.mass=1,2,3") from None
        if key in sets:
            raise ValueError(f"--set {key} is given twice")
        sets[key] = values
    if not sets:
        raise ValueError("a sweep needs at least one --set KEY=V1,V2,...")
    return sets


def combinations(sets: dict[str, list[float]]) -> list[dict[str, float]]:
    """Every combination of the values, the first key varying slowest."""
    keys = list(sets)
    return [dict(zip(keys, values)) for values in itertools.product(*sets.values())]


def _watch(limit: float | None, sweep_id: str | None):
    """The progress callback of a run: stops it past its time limit or when its sweep
    has been stopped (raised from the integrator's pause, so the run ends there)."""
    end = None if limit is None else time.monotonic() + limit

    def check(event):
        if sweep_id is not None and sweep_id in _CANCELLED:
            raise _Cancelled("the sweep was stopped")
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
        result = run.simulate(method=method, progress=_watch(run_timeout, sweep_id))
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


def _client(scheduler: str | None, workers: int, timeout: float):
    """A Dask client: of the running scheduler at ``scheduler``, else of a new local
    cluster of threads in this process (the compiled loops release the GIL)."""
    distributed = require_dask()
    if scheduler:
        try:
            return distributed.Client(scheduler, timeout=timeout), None
        except OSError as exc:
            raise HostError(f"no Dask scheduler answers at {scheduler} ({exc}). To fix "
                            "it, start one (dask scheduler) or leave --scheduler out for "
                            "a local cluster") from None
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=workers,
                                       processes=False, dashboard_address=None)
    return distributed.Client(cluster), cluster


def _check_outputs(solver, runs, outputs, method) -> None:
    """The outputs' names against a short run of the first combination: the columns
    a result of the model has, its events and the statistics a run of the method
    reports (sweep_outputs.check_outputs)."""
    from . import methods as registry
    model = solver.plan.model
    first = solver.with_parameters(runs[0])
    d = first.plan.model.simulate
    m = registry.get(d.method if method is None else method)
    sched = registry.schedule(m, d, None, None, None, registry.options_for(m, None, None, {}))
    t_probe = min(sched.output_dt, sched.t_end)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = first.simulate(method=method, t_end=t_probe, output_dt=t_probe)
    except (FccgenError, ArithmeticError, ValueError) as exc:
        raise ValueError(f"{model.source}: --outputs cannot be checked: a run of the "
                         f"first combination to t = {t_probe:g} failed: "
                         f"{str(exc).splitlines()[0]}") from None
    check_outputs(outputs, result.names, [e.name for e in model.events], result.info,
                  model.source)


def _settings(solver, method) -> dict:
    """The method and its settings, as the model's simulate section gives them."""
    from . import methods as registry
    d = solver.plan.model.simulate
    m = registry.get(d.method if method is None else method)
    opts = registry.options_for(m, None, None, {})
    sched = registry.schedule(m, d, None, None, None, opts)
    return {"method": m.name, "kind": m.kind, "dt": sched.dt, "output_dt": sched.output_dt,
            "t_end": sched.t_end, "project": m.projects, "options": opts}


def sweep(solver, sets: dict[str, list[float]], *, scheduler=None, method=None,
          workers=None, progress=None, connect_timeout=10.0, outputs=None,
          run_timeout: float | None = None, out=None, resume: bool = False) -> SweepTable:
    """Run every combination of ``sets`` with a compiled ``solver``; see the module
    docstring. ``workers``: threads of the local cluster (default: the cores, at most
    4); ``connect_timeout``: seconds to wait for the scheduler; ``outputs``: what the
    table carries besides its figures (``"motor.torque:max,latch:time"``, see
    :mod:`fccgen.sweep_outputs`); ``run_timeout``: seconds of wall time a run may take
    (None: no limit); ``out``: the table file (.csv or .parquet), its rows written to
    the partial file beside it as they finish; ``resume``: keep the rows of that file,
    left by a sweep that stopped, and run only the others (see :func:`_resumed`).
    ``progress``: called with a :class:`~fccgen.progress.ProgressEvent` (stage
    "sweep", done of total runs) as the runs end."""
    from .provenance import provenance
    runs = combinations(sets)
    outputs = parse_outputs(outputs) if not isinstance(outputs, list) else outputs
    if out is not None:
        out = check_table_path(out, resume=resume)
    if method is not None:
        from .methods import get as method_named
        from .runtime.solver import METHODS
        method_named(method, METHODS)
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be at least 1 (got {workers})")
    if run_timeout is not None and not run_timeout > 0:
        raise ValueError(f"--run-timeout must be a positive number of seconds "
                         f"(got {run_timeout!r})")
    from .method_limits import refuse
    refuse(solver.plan.model, method)
    for params in runs:                       # bad keys and values stop it here
        solver.with_parameters(params)
    if outputs:
        _check_outputs(solver, runs, outputs, method)
    keys = list(sets)
    finals = [f"final.{p.name}.{c}" for p in solver.plan.model.moving_points for c in "xyz"]
    columns = ["run", *keys, *FIGURES, *(o.label for o in outputs), *finals]
    info = provenance(solver.plan, solver.settings())
    info.update(_settings(solver, method), sets=sets, outputs=[o.label for o in outputs],
                run_timeout=run_timeout)
    workers = workers or min(os.cpu_count() or 1, 4)
    start = time.perf_counter()
    rows: list[dict | None] = [None] * len(runs)
    kept = partial_path(out) if resume and out is not None else None
    if kept is not None and kept.exists():          # before the cluster starts
        rows = _resumed(solver, runs, kept, columns)
        info["resumed_rows"] = _done(rows)
    resuming = kept is not None and kept.exists()
    say = Reporter(progress, "sweep", total=len(runs))
    client, cluster = _client(scheduler, workers, connect_timeout)   # then the file
    try:
        writer = (PartialWriter(partial_path(out), columns, append=resuming)
                  if out is not None else None)
    except BaseException:
        _close(client, cluster)
        raise
    where = scheduler or f"a local cluster of {workers} thread(s)"
    sweep_id = f"{os.getpid()}-{id(client)}-{time.monotonic_ns()}"
    try:
        say(f"sweep: {len(runs)} runs on {where}"
            + (f", {_done(rows)} kept from {kept}" if _done(rows) else ""), done=_done(rows))
        _dispatch(client, solver, runs, method, outputs, run_timeout, sweep_id, rows,
                  writer, say, where)
    except KeyboardInterrupt:
        _CANCELLED.add(sweep_id)
        raise SweepInterrupted(_stopped_text("interrupted (Ctrl-C)", rows, writer, out),
                               _done(rows), writer and writer.path,
                               [r for r in rows if r]) from None
    except Exception as exc:       # whatever ends the dispatch: scheduler, cluster, comm
        _CANCELLED.add(sweep_id)
        why = _why(exc, where)
        raise SweepStopped(_stopped_text(why, rows, writer, out), _done(rows),
                           writer and writer.path, [r for r in rows if r]) from None
    finally:
        if writer is not None:
            writer.close()
        _close(client, cluster)
        _CANCELLED.discard(sweep_id)
    info["where"] = where
    table = SweepTable(keys, rows, time.perf_counter() - start, where, columns, info)
    if out is not None:
        table.save(out)
        writer.remove()
    return table


def _dispatch(client, solver, runs, method, outputs, run_timeout, sweep_id, rows,
              writer, say, where) -> None:
    """Submit every run and take the rows as they finish (into ``rows`` and the
    partial file). A task that raised gives a failed row; a task the cluster lost
    (cancelled) stops the sweep."""
    from dask.distributed import as_completed
    todo = [k for k, row in enumerate(rows) if row is None]
    if not todo:
        return
    try:
        shared = client.scatter(solver, broadcast=True)
    except Exception as exc:       # noqa: BLE001 - whatever the worker's load raised
        raise _NoSolver(_cause(exc)) from None
    futures = [client.submit(run_one, shared, runs[k], method, outputs, run_timeout,
                             sweep_id, pure=False) for k in todo]
    index = {f.key: k for f, k in zip(futures, todo)}
    for done, future in enumerate(as_completed(futures), len(runs) - len(todo) + 1):
        k = index[future.key]
        if future.status == "finished":
            row = future.result()
        elif future.status == "error":
            exc = future.exception()
            row = dict(runs[k], status="failed", error=f"the task ended in "
                       f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}")
        else:
            raise _Lost(f"run {k + 1} was {future.status}")
        row["run"] = k + 1
        rows[k] = row
        if writer is not None:
            writer.add(row)
        say(f"sweep: {done} of {len(runs)} runs done", done=done)


def _resumed(solver, runs, path, columns) -> list[dict | None]:
    """The rows of the partial file ``path`` in the places of their runs (None where
    a run is still to do). A row is kept when its run number, its swept values and
    its ``model_hash`` are those of this sweep's run (ValueError otherwise: another
    sweep's or another model's rows); rows of runs stopped by the time limit run
    again."""
    from .provenance import model_hash
    rows: list[dict | None] = [None] * len(runs)
    for k, row in read_partial(path, columns).items():
        params = runs[k - 1] if 1 <= k <= len(runs) else None
        if params is None or any(row.get(key) != value for key, value in params.items()):
            raise ValueError(f"{path}: its row of run {k} is not a run of this sweep "
                             f"(another --set?): move the file elsewhere or delete it")
        if "model_hash" in row and row["model_hash"] != model_hash(
                solver.with_parameters(params).plan):
            raise ValueError(f"{path}: its row of run {k} was computed with other numbers "
                             f"(the model file changed?): move the file elsewhere or "
                             f"delete it")
        if row.get("status") != "timeout":
            rows[k - 1] = row
    return rows


def _why(exc, where: str) -> str:
    """What stopped the dispatch, in words."""
    if isinstance(exc, _Lost):
        return f"the Dask scheduler at {where} was lost ({exc})"
    if isinstance(exc, _NoSolver):
        return (f"the workers of {where} could not load the compiled solver ({exc}); "
                f"every worker must see the build folder at the same path (a shared file "
                f"system) and run the same fccgen and Python (docs/sweeps.md)")
    return f"the Dask cluster at {where} failed ({type(exc).__name__}: {exc})"


def _cause(exc) -> str:
    """The innermost error's text: Dask wraps what a worker raised."""
    args = getattr(exc, "args", ())
    inner = args[0] if len(args) == 1 and isinstance(args[0], BaseException) else None
    return _cause(inner) if inner is not None else f"{type(exc).__name__}: {exc}"


def _done(rows) -> int:
    return sum(r is not None for r in rows)


def _stopped_text(why: str, rows, writer, out) -> str:
    """One paragraph: why the sweep stopped, how many rows were saved and where."""
    done, total = _done(rows), len(rows)
    text = f"sweep stopped after {done} of {total} runs: {why}. "
    if writer is None:
        return text + ("No table file was given, so the finished rows are not saved; "
                       "give out= (--out) to keep rows as they finish.")
    if done == 0:
        writer.remove()                      # only its header: nothing to keep
        return text + "No run had finished, so nothing was written."
    return text + (f"The {done} finished row{'s are' if done != 1 else ' is'} saved in "
                   f"{writer.path} (CSV, in the order the runs ended; column run gives "
                   f"each row's place in the sweep); {Path(out).name} was not written. "
                   f"Run the same sweep with --resume to keep them and run the rest.")


def _close(client, cluster) -> None:
    """Close the client and the local cluster; a lost scheduler makes closing fail
    or wait, which must not hide why the sweep stopped."""
    for thing in (client, cluster):
        if thing is None:
            continue
        try:
            thing.close(timeout=10) if thing is client else thing.close()
        except Exception:           # noqa: BLE001 - already going down
            pass

