"""Many runs of one compiled model with different numbers (``fccgen sweep``,
docs/sweeps.md, docs/design.md §5), on Dask: a local cluster by default, a running
scheduler when given.

The model is compiled once, before anything is dispatched; every combination of the
``--set`` values (their Cartesian product, in the order given) is checked then, so a
bad key or value stops the sweep before it starts, and so are the ``--outputs``
(:mod:`fccgen.sweep.outputs`). Each task receives the compiled solver (in another
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
``final.P.x final.P.y final.P.z`` of each moving point the user named (and, with
joints, ``final.B.cx final.B.cy final.B.cz`` of each body: fccgen.sweep.run.final_columns).

Finished work is never lost (:mod:`fccgen.sweep.table`): rows go to a partial file as
they finish; Ctrl-C ends in :class:`SweepInterrupted` and a lost scheduler or cluster in
:class:`SweepStopped`, each saying how many rows were saved and where.
"""
from __future__ import annotations

import itertools
import os
import time
import warnings
from pathlib import Path

from ..errors import FccgenError, HostError
from ..progress import Reporter
from .cluster import (client_for, close, dispatch, quiet_dask, require_dask,
                            why_stopped)
from .outputs import check_outputs, parse_outputs
from .run import CANCELLED, RunTimedOut, final_columns, run_one
from .table import (PartialWriter, SweepTable, check_table_path, partial_path,
                          read_partial)

__all__ = ["RunTimedOut", "SweepInterrupted", "SweepStopped", "SweepTable",
           "check_table_path", "combinations", "parse_sets", "quiet_dask", "require_dask",
           "run_one", "sweep"]

FIGURES = ("status", "error", "wall_time", "steps", "t_final", "energy_drift",
           "max_constraint_error", "model_hash")
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


def _check_outputs(solver, runs, outputs, method) -> None:
    """The outputs' names against a short run of the first combination: the columns
    a result of the model has, its events and the statistics a run of the method
    reports (sweep_outputs.check_outputs)."""
    from ..settings import methods as registry
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
    from ..settings import methods as registry
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
    :mod:`fccgen.sweep.outputs`); ``run_timeout``: seconds of wall time a run may take
    (None: no limit); ``out``: the table file (.csv or .parquet), its rows written to
    the partial file beside it as they finish; ``resume``: keep the rows of that file,
    left by a sweep that stopped, and run only the others (see :func:`_resumed`).
    ``progress``: called with a :class:`~fccgen.progress.ProgressEvent` (stage
    "sweep", done of total runs) as the runs end."""
    from ..results.provenance import provenance
    runs = combinations(sets)
    outputs = parse_outputs(outputs) if not isinstance(outputs, list) else outputs
    if out is not None:
        out = check_table_path(out, resume=resume)
    if method is not None:
        from ..settings.methods import get as method_named
        from ..runtime.solver import METHODS
        method_named(method, METHODS)
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be at least 1 (got {workers})")
    if run_timeout is not None and not run_timeout > 0:
        raise ValueError(f"--run-timeout must be a positive number of seconds "
                         f"(got {run_timeout!r})")
    from ..settings.limits import refuse
    refuse(solver.plan.model, method)
    for params in runs:                       # bad keys and values stop it here
        solver.with_parameters(params)
    if outputs:
        _check_outputs(solver, runs, outputs, method)
    keys = list(sets)
    finals = [label for label, _ in final_columns(solver.plan)]
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
    client, cluster = client_for(scheduler, workers, connect_timeout)   # then the file
    try:
        writer = (PartialWriter(partial_path(out), columns, append=resuming)
                  if out is not None else None)
    except BaseException:
        close(client, cluster)
        raise
    where = scheduler or f"a local cluster of {workers} thread(s)"
    sweep_id = f"{os.getpid()}-{id(client)}-{time.monotonic_ns()}"
    try:
        say(f"sweep: {len(runs)} runs on {where}"
            + (f", {_done(rows)} kept from {kept}" if _done(rows) else ""), done=_done(rows))
        dispatch(client, solver, runs, method, outputs, run_timeout, sweep_id, rows,
                  writer, say, where)
    except KeyboardInterrupt:
        CANCELLED.add(sweep_id)
        raise SweepInterrupted(_stopped_text("interrupted (Ctrl-C)", rows, writer, out),
                               _done(rows), writer and writer.path,
                               [r for r in rows if r]) from None
    except Exception as exc:       # whatever ends the dispatch: scheduler, cluster, comm
        CANCELLED.add(sweep_id)
        why = why_stopped(exc, where)
        raise SweepStopped(_stopped_text(why, rows, writer, out), _done(rows),
                           writer and writer.path, [r for r in rows if r]) from None
    finally:
        if writer is not None:
            writer.close()
        close(client, cluster)
        CANCELLED.discard(sweep_id)
    info["where"] = where
    table = SweepTable(keys, rows, time.perf_counter() - start, where, columns, info)
    if out is not None:
        table.save(out)
        writer.remove()
    return table


def _resumed(solver, runs, path, columns) -> list[dict | None]:
    """The rows of the partial file ``path`` in the places of their runs (None where
    a run is still to do). A row is kept when its run number, its swept values and
    its ``model_hash`` are those of this sweep's run (ValueError otherwise: another
    sweep's or another model's rows); rows of runs stopped by the time limit run
    again."""
    from ..results.provenance import model_hash
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
