"""The Dask side of a sweep (docs/sweeps.md): the client and local cluster, the
dispatch of the runs and the collection of their rows as they finish, and what a
failure of the cluster is called."""
from __future__ import annotations

import logging

from ..errors import FccgenError, HostError
from .run import run_batch

# Runs per Dask task at most: a task is one simulate_many call; its rows reach the
# table (and the partial file) when it ends
BATCH_MAX = 16

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
    """Submit the runs in batches (:func:`batch_size`), each task one simulate_many
    call (fccgen.sweep.run.run_batch), and take the rows as they finish (into
    ``rows`` and the partial file). A task that raised gives failed rows; a task the
    cluster lost (cancelled) stops the sweep."""
    from dask.distributed import as_completed
    todo = [k for k, row in enumerate(rows) if row is None]
    if not todo:
        return
    try:
        shared = client.scatter(solver, broadcast=True)
    except Exception as exc:       # noqa: BLE001 - whatever the worker's load raised
        raise NoSolver(cause(exc)) from None
    batches = [todo[i:i + size] for size in [batch_size(len(todo), _threads(client))]
               for i in range(0, len(todo), size)]
    futures = [client.submit(run_batch, shared, [runs[k] for k in batch], method, outputs,
                             run_timeout, sweep_id, pure=False) for batch in batches]
    index = {f.key: batch for f, batch in zip(futures, batches)}
    done = len(runs) - len(todo)
    for future in as_completed(futures):
        batch = index[future.key]
        if future.status == "finished":
            got = future.result()
        elif future.status == "error":
            exc = future.exception()
            got = [dict(runs[k], status="failed", error=f"the task ended in "
                        f"{type(exc).__name__}: "
                        f"{str(exc).splitlines()[0] if str(exc) else ''}") for k in batch]
        else:
            raise Lost(f"run {batch[0] + 1} was {future.status}")
        for k, row in zip(batch, got):
            done += 1
            row["run"] = k + 1
            rows[k] = row
            if writer is not None:
                writer.add(row)
            say(f"sweep: {done} of {len(runs)} runs done", done=done)


def batch_size(n_runs: int, threads: int) -> int:
    """Runs per task: about four tasks per thread of the cluster (so that the threads
    stay busy to the end), at most BATCH_MAX."""
    return max(1, min(BATCH_MAX, n_runs // (4 * max(threads, 1))))


def _threads(client) -> int:
    """The cluster's worker threads (1 if it does not say)."""
    try:
        return int(sum(client.nthreads().values())) or 1
    except Exception:              # noqa: BLE001 - a scheduler that does not answer
        return 1


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
