"""Many runs of one compiled model with different numbers (docs/design.md §5,
``fccgen sweep``), on Dask: a local cluster by default, a running scheduler when given.

The model is compiled once, before anything is dispatched; every combination of the
``--set`` values (their Cartesian product, in the order given) is checked then, so a
bad key or value stops the sweep before it starts. Each task receives the compiled
solver (in another process: pickled as its plan and module folder, see
:mod:`fccgen.runtime.params`) and its numbers, makes a new solver with
:meth:`~fccgen.runtime.CompiledSolver.with_parameters` and runs the model's own
simulate settings (which ``simulate.t_end`` and the like may change). A run that fails
gives a row with status ``failed`` and the error's text; the others go on.

One row per run: the parameters, ``status``, ``error``, ``wall_time`` (seconds, the
task's own), ``steps``, ``t_final``, ``energy_drift`` (max |E - E0|),
``max_constraint_error`` and ``final.P.x final.P.y final.P.z`` of each moving point.
"""
from __future__ import annotations

import csv
import itertools
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from .errors import FccgenError, HostError
from .progress import Reporter

FIGURES = ("status", "error", "wall_time", "steps", "t_final", "energy_drift",
           "max_constraint_error")


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


def run_one(solver, params: dict, method=None) -> dict:
    """One run of the sweep (executed by a Dask worker): a row of summary figures."""
    start = time.perf_counter()
    row = dict(params)
    try:
        result = solver.with_parameters(params).simulate(method=method)
    except (FccgenError, ArithmeticError, ValueError) as exc:
        row.update(status="failed", error=str(exc).splitlines()[0],
                   wall_time=time.perf_counter() - start)
        return row
    info = result.info
    row.update(status="ok", error="", wall_time=time.perf_counter() - start,
               steps=info.get("steps"), t_final=float(result.t[-1]),
               energy_drift=info.get("energy_drift"),
               max_constraint_error=info.get("max_constraint_error"))
    for p in solver.plan.model.moving_points:
        for c in "xyz":
            row[f"final.{p.name}.{c}"] = float(result[f"{p.name}.{c}"][-1])
    return row


@dataclass
class SweepTable:
    """The rows of a sweep, in the order of :func:`combinations`."""
    keys: list[str]
    rows: list[dict]
    wall_time: float
    where: str                              # the cluster that ran it
    columns: list[str] = field(default_factory=list)

    @property
    def failed(self) -> int:
        return sum(r["status"] != "ok" for r in self.rows)

    def save(self, path) -> Path:
        """Write the table as CSV (header first, numbers in their shortest exact form)
        or Parquet (``.parquet``: one typed column per name, through pyarrow, the
        optional extra ``parquet``), atomically."""
        path = check_table_path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            if path.suffix.lower() == ".parquet":
                _write_parquet(tmp, self.columns, self.rows)
            else:
                with open(tmp, "w", newline="", encoding="utf-8") as fh:
                    w = csv.writer(fh)
                    w.writerow(self.columns)
                    for row in self.rows:
                        w.writerow([_cell(row.get(c)) for c in self.columns])
            os.replace(tmp, path)
        finally:
            if tmp.exists():
                tmp.unlink()
        return path


def _pyarrow():
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        raise ValueError("a .parquet sweep table needs pyarrow: pip install "
                         "'fccgen[parquet]' (or write .csv)") from None
    return pyarrow


def _write_parquet(path: Path, columns: list[str], rows: list[dict]) -> None:
    pa = _pyarrow()
    data = {}
    for c in columns:
        values = [row.get(c) for row in rows]
        if any(isinstance(x, float) for x in values) and all(
                x is None or isinstance(x, (int, float)) for x in values):
            values = [None if x is None else float(x) for x in values]   # one type
        data[c] = values
    pa.parquet.write_table(pa.Table.from_pydict(data), str(path))


def _cell(value) -> str:
    if value is None:
        return ""
    return repr(value) if isinstance(value, float) else str(value)   # floats round-trip


def check_table_path(path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in (".csv", ".parquet"):
        raise ValueError(f"{path}: a sweep table is written as .csv or .parquet (got "
                         f"{path.suffix or 'no suffix'!r})")
    if path.suffix.lower() == ".parquet":
        _pyarrow()                        # missing: say so before any run
    if path.is_dir():
        raise ValueError(f"{path} is a folder; give a file name, e.g. {path / 'sweep.csv'}")
    return path


def _client(scheduler: str | None, workers: int, timeout: float):
    """A Dask client: of the running scheduler at ``scheduler``, else of a new local
    cluster of threads in this process (the compiled loops release the GIL)."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise HostError("fccgen sweep needs Dask: pip install 'fccgen[sweep]' "
                        "(dask[distributed])") from None
    if scheduler:
        try:
            return Client(scheduler, timeout=timeout), None
        except OSError as exc:
            raise HostError(f"no Dask scheduler answers at {scheduler} ({exc}). To fix "
                            "it, start one (dask scheduler) or leave --scheduler out for "
                            "a local cluster") from None
    cluster = LocalCluster(n_workers=1, threads_per_worker=workers, processes=False,
                           dashboard_address=None)
    return Client(cluster), cluster


def sweep(solver, sets: dict[str, list[float]], *, scheduler=None, method=None,
          workers=None, progress=None, connect_timeout=10.0) -> SweepTable:
    """Run every combination of ``sets`` with a compiled ``solver``; see the module
    docstring. ``workers``: threads of the local cluster (default: the cores, at most
    4); ``connect_timeout``: seconds to wait for the scheduler. ``progress``: called
    with a :class:`~fccgen.progress.ProgressEvent` (stage "sweep", done of total runs)
    as the runs end."""
    runs = combinations(sets)
    say = Reporter(progress, "sweep", total=len(runs))
    for params in runs:                       # bad keys and values stop it here
        solver.with_parameters(params)
    if method is not None:
        from .methods import get as method_named
        from .runtime.solver import METHODS
        method_named(method, METHODS)
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be at least 1 (got {workers})")
    workers = workers or min(os.cpu_count() or 1, 4)
    start = time.perf_counter()
    client, cluster = _client(scheduler, workers, connect_timeout)
    try:
        from dask.distributed import as_completed
        where = scheduler or f"a local cluster of {workers} thread(s)"
        say(f"sweep: {len(runs)} runs on {where}", done=0)
        shared = client.scatter(solver, broadcast=True)
        futures = [client.submit(run_one, shared, params, method, pure=False)
                   for params in runs]
        for done, _ in enumerate(as_completed(futures), 1):
            say(f"sweep: {done} of {len(runs)} runs done", done=done)
        rows = client.gather(futures)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    keys = list(sets)
    finals = [f"final.{p.name}.{c}" for p in solver.plan.model.moving_points for c in "xyz"]
    return SweepTable(keys, rows, time.perf_counter() - start, where,
                      [*keys, *FIGURES, *finals])
