"""The Dask side of a sweep (docs/sweeps.md): the client and local cluster, the
dispatch of the runs and the collection of their rows as they finish, and what a
failure of the cluster is called."""
from __future__ import annotations

import logging

from ..errors import FccgenError, HostError
from .run import run_one

class Lost(FccgenError):
    """The cluster cancelled a run the sweep did not cancel: its scheduler is gone."""


class NoSolver(FccgenError):
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


def client_for(scheduler: str | None, workers: int, timeout: float):
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
    # ":0": the scheduler's HTTP server takes a free port (with None it still binds
    # :8787, and a busy 8787 stops the cluster from starting)
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=workers,
                                       processes=False, dashboard_address=":0")
    return distributed.Client(cluster), cluster


def dispatch(client, solver, runs, method, outputs, run_timeout, sweep_id, rows,
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
        raise NoSolver(cause(exc)) from None
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
            raise Lost(f"run {k + 1} was {future.status}")
        row["run"] = k + 1
        rows[k] = row
        if writer is not None:
            writer.add(row)
        say(f"sweep: {done} of {len(runs)} runs done", done=done)


def why_stopped(exc, where: str) -> str:
    """What stopped the dispatch, in words."""
    if isinstance(exc, Lost):
        return f"the Dask scheduler at {where} was lost ({exc})"
    if isinstance(exc, NoSolver):
        return (f"the workers of {where} could not load the compiled solver ({exc}); "
                f"every worker must see the build folder at the same path (a shared file "
                f"system) and run the same fccgen and Python (docs/sweeps.md)")
    return f"the Dask cluster at {where} failed ({type(exc).__name__}: {exc})"


def cause(exc) -> str:
    """The innermost error's text: Dask wraps what a worker raised."""
    args = getattr(exc, "args", ())
    inner = args[0] if len(args) == 1 and isinstance(args[0], BaseException) else None
    return cause(inner) if inner is not None else f"{type(exc).__name__}: {exc}"


def close(client, cluster) -> None:
    """Close the client and the local cluster; a lost scheduler makes closing fail
    or wait, which must not hide why the sweep stopped."""
    for thing in (client, cluster):
        if thing is None:
            continue
        try:
            thing.close(timeout=10) if thing is client else thing.close()
        except Exception:           # noqa: BLE001 - already going down
            pass
