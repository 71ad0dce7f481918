"""``fccgen bench --accuracy``: the work-precision trade of every integration method.

Every method of :mod:`fccgen.settings.methods` runs over a ladder of settings (steps ``dt`` for
fixed-step methods, tolerances ``rtol`` for adaptive ones), with and without projection
where the method offers it, in the compiled version and, at the coarsest rungs only (it
is slow), in the numeric one. Each run's error is measured against a reference: a
published solution when one is given (:func:`published_reference`), otherwise a
converged run of the compiled RK4 at a step finer than the ladder's, checked against the
same run at twice that step (:func:`converged_reference`). The rows go to a CSV table,
a PNG plot (error against CPU time, one curve per method) and a text summary naming the
fastest method at each accuracy level.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, fields

import numpy as np

from ..settings import methods as registry
from ..errors import FccgenError
from ..progress import Reporter, restaged

TIME_MATCH = 1e-9        # output times and reference times must agree to this (s)


# -- references -------------------------------------------------------------------------

@dataclass
class Reference:
    """What the runs are measured against: times, and for each compared point its
    coordinate columns and their reference values. The error of a run is the largest
    Euclidean distance, over the reference times and the points, from the reference."""
    kind: str                               # "published" or "converged"
    description: str
    t: np.ndarray
    points: dict[str, dict[str, np.ndarray]]  # label -> {result column: values}

    @property
    def output_dt(self) -> float:
        return float(self.t[1] - self.t[0]) if len(self.t) > 1 else float(self.t[0])

    @property
    def t_end(self) -> float:
        return float(self.t[-1])

    def until(self, t_end: float) -> "Reference":
        """The same reference cut at ``t_end``."""
        keep = self.t <= t_end + TIME_MATCH
        return Reference(self.kind, f"{self.description}, up to t = {t_end:g}",
                         self.t[keep], {p: {c: v[keep] for c, v in cols.items()}
                                        for p, cols in self.points.items()})

    def error(self, result) -> tuple[float, float]:
        """(largest distance, time at which it occurs) of ``result`` from the reference;
        ValueError when the result's output times do not hold the reference times."""
        t = np.asarray(result.t)
        idx = np.searchsorted(t, self.t - TIME_MATCH)
        if np.any(idx >= len(t)) or np.any(np.abs(t[np.minimum(idx, len(t) - 1)] - self.t)
                                           > TIME_MATCH):
            raise ValueError(f"the run's output times (from {t[0]:g} to {t[-1]:g}, "
                             f"{len(t)} values) do not hold the reference times")
        dist = np.zeros(len(self.t))
        for cols in self.points.values():
            sq = sum((np.asarray(result[c])[idx] - ref) ** 2 for c, ref in cols.items())
            dist = np.maximum(dist, np.sqrt(sq))
        k = int(np.argmax(np.where(np.isfinite(dist), dist, np.inf)))
        return float(dist[k]), float(self.t[k])


def published_reference(path, point: str, columns, description: str,
                        delimiter=None) -> Reference:
    """A published time history of one point: a text table (``#`` comments, one header
    line) whose first column is time and whose next ``len(columns)`` columns are the
    point's coordinates, compared with the result columns ``columns`` (e.g. B0.x, B0.y)."""
    data = np.loadtxt(path, delimiter=delimiter, skiprows=_header_rows(path), ndmin=2)
    cols = {c: data[:, 1 + k] for k, c in enumerate(columns)}
    return Reference("published", description, data[:, 0], {point: cols})


def reference_from_table(path, point: str) -> Reference:
    """A published table (comma- or space-separated, ``#`` comments, one header line)
    of time and the coordinates of ``point``: 2 columns (x, y) or 3 (x, y, z)."""
    skip = _header_rows(path)
    with open(path) as fh:
        first = [line for k, line in enumerate(fh) if k == skip][0]
    delimiter = "," if "," in first else None
    n = len(first.split(delimiter)) - 1
    if n not in (2, 3):
        raise ValueError(f"{path}: a reference table holds time and 2 or 3 coordinates "
                         f"of one point (found {n} columns after time)")
    cols = [f"{point}.{c}" for c in "xyz"[:n]]
    return published_reference(path, point, cols, f"published table {path}, point {point} "
                               f"({', '.join(cols)})", delimiter)


def _header_rows(path) -> int:
    """Comment lines plus the one header line at the top of a reference table."""
    with open(path) as fh:
        n = 0
        for line in fh:
            n += 1
            if not line.lstrip().startswith("#"):
                return n
    return n


def compared_triples(plan) -> tuple[str, list[str]]:
    """("point", every moving point) or, in a model without any, ("vector", ...)."""
    kind = "point" if any(k == "point" for _, k in plan.triples) else "vector"
    return kind, [name for name, k in plan.triples if k == kind]


def converged_reference(solver, t_end: float, output_dt: float, dt: float,
                        progress=None) -> Reference:
    """The compiled RK4 with projection at ``dt`` (finer than any rung), checked against
    the same run at ``2 dt``: RK4's error falls 16-fold when the step halves, so the
    difference of the two runs over 15 estimates the reference's own error. progress:
    the two runs' events, as stages "reference dt=..." and "reference dt=2..."."""
    fine = solver.simulate(t_end=t_end, dt=dt, output_dt=output_dt, method="rk4",
                           progress=restaged(progress, f"reference dt={dt:g}"))
    coarse = solver.simulate(t_end=t_end, dt=2 * dt, output_dt=output_dt, method="rk4",
                             progress=restaged(progress, f"reference dt={2 * dt:g}"))
    kind, names = compared_triples(solver.plan)
    points = {n: {f"{n}.{c}": np.asarray(fine[f"{n}.{c}"]) for c in "xyz"} for n in names}
    ref = Reference("converged", "", np.asarray(fine.t), points)
    own, _ = ref.error(coarse)
    ref.description = (f"a converged run, the compiled rk4 with projection at dt = {dt:g} "
                       f"(it differs from the run at dt = {2 * dt:g} by {own:.2g}, so its "
                       f"own error is about {own / 15:.2g}); error = largest distance of "
                       f"any moving {kind} from it")
    return ref


# -- the ladder ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Variant:
    """One curve of the plot: a method, with or without projection, in one version."""
    method: str
    project: bool
    version: str = "compiled"           # or "numeric"

    @property
    def label(self) -> str:
        proj = "" if self.project else ", no projection"
        return f"{self.method} ({self.version}{proj})"


def default_variants(method_names=None, with_unprojected=True) -> list[Variant]:
    """Every registered method (or those named) in the compiled version: with projection
    where the method offers it, and without (to show what projection costs and buys)."""
    out = []
    for name in (registry.names() if method_names is None else method_names):
        m = registry.get(name)
        if m.projects:
            out.append(Variant(name, True))
        if not m.projects or with_unprojected:
            out.append(Variant(name, False))
    return out


@dataclass
class Row:
    """One run: the setting, its error against the reference and its cost."""
    model: str
    method: str
    version: str
    project: bool
    setting: str                 # "dt" or "rtol"
    value: float
    status: str = "ok"           # ok | failed | unsupported (by this version)
    error: float = math.nan      # m: largest position error over the reference times
    error_time: float = math.nan
    cpu_time: float = math.nan   # s of process CPU time for the whole run
    wall_time: float = math.nan
    steps: float = math.nan
    rhs_evaluations: float = math.nan
    rejected_steps: float = math.nan
    newton_iterations: float = math.nan
    max_constraint_error: float = math.nan
    energy_drift: float = math.nan
    failure: str = ""

    @property
    def variant(self) -> Variant:
        return Variant(self.method, self.project, self.version)


COLUMNS = [f.name for f in fields(Row)]


@dataclass
class Ladder:
    """The settings each kind of method runs at, coarsest first."""
    steps: tuple[float, ...]
    tolerances: tuple[float, ...] = (1e-4, 1e-6, 1e-8, 1e-10)
    atol_ratio: float = 1e-3          # atol = rtol * atol_ratio (the registry's 1e-9/1e-6)
    numeric_rungs: int = 1            # the numeric version runs the coarsest rungs only
    per_method: dict = field(default_factory=dict)   # method -> its own steps/tolerances

    def settings(self, method) -> list[tuple[str, float]]:
        """(setting name, value) of each rung of a :class:`fccgen.settings.methods.Method`."""
        name = "dt" if method.kind == "fixed" else "rtol"
        default = self.steps if method.kind == "fixed" else self.tolerances
        return [(name, v) for v in self.per_method.get(method.name, default)]


def default_steps(output_dt: float, n: int = 5) -> tuple[float, ...]:
    """``output_dt / 1, 2, 4, ...``: every rung lands on the output times."""
    return tuple(output_dt / 2 ** k for k in range(n))


def run_one(solver, variant: Variant, setting: str, value: float, reference: Reference,
            ladder: Ladder, model_name: str) -> Row:
    """Run one rung and measure it; failures are caught and recorded in the row:
    "unsupported" when this version does not offer the method (or its options),
    "failed" when the run stops (with the solver's message) or its state is not finite."""
    row = Row(model_name, variant.method, variant.version, variant.project, setting, value)
    kwargs = dict(t_end=reference.t_end, output_dt=reference.output_dt,
                  method=variant.method, project=variant.project, reactions=False)
    if setting == "dt":
        kwargs["dt"] = value
    else:
        kwargs.update(rtol=value, atol=value * ladder.atol_ratio)
    c0, w0 = time.process_time(), time.perf_counter()
    try:
        with np.errstate(all="ignore"):
            result = solver.simulate(**kwargs)
        row.error, row.error_time = reference.error(result)
    except Exception as exc:              # noqa: BLE001  (sorted out just below)
        row.status, row.failure = _failure(exc, variant.method), " ".join(str(exc).split())
        if row.status == "failed":
            row.cpu_time, row.wall_time = time.process_time() - c0, time.perf_counter() - w0
        return row
    row.cpu_time, row.wall_time = time.process_time() - c0, time.perf_counter() - w0
    _fill_info(row, result)
    if not math.isfinite(row.error):
        row.status, row.failure = "failed", "the state became non-finite"
    return row


def _failure(exc: Exception, method: str) -> str:
    """'unsupported' or 'failed' for an exception of a run; anything else (a bug) is
    raised again."""
    text = str(exc)
    if isinstance(exc, TypeError) and "unexpected keyword" in text:
        return "unsupported"
    if isinstance(exc, ValueError) and "unknown" in text and repr(method) in text:
        return "unsupported"
    if isinstance(exc, (FccgenError, ValueError, ArithmeticError, np.linalg.LinAlgError)):
        return "failed"
    raise exc


def _fill_info(row: Row, result) -> None:
    info = result.info
    for key in ("steps", "rhs_evaluations", "rejected_steps", "max_constraint_error"):
        if info.get(key) is not None:
            setattr(row, key, float(info[key]))
    newton = info.get("newton_iterations", info.get("max_newton_iterations"))
    if newton is not None:
        row.newton_iterations = float(newton)
    energy = np.asarray(result["energy"])
    drift = info.get("energy_drift")
    row.energy_drift = float(drift if drift is not None
                             else np.max(np.abs(energy - energy[0])))


def run_ladder(compiled, reference: Reference, ladder: Ladder, variants=None,
               numeric=None, progress=None, on_row=None) -> list[Row]:
    """Every variant at every rung of its kind (compiled), and the numeric version of the
    same variant at the coarsest ``ladder.numeric_rungs`` rungs when ``numeric`` is
    given (compiled None: the numeric rungs only). A method that a version does not
    offer gets one row "unsupported", with the reason, rather than being left out.
    on_row: called with the rows so far after each run (to save partial results)."""
    name = (compiled or numeric).plan.model.name
    rows = []
    unsupported = set()
    runs = []
    for v in (default_variants() if variants is None else variants):
        for k, (setting, value) in enumerate(ladder.settings(registry.get(v.method))):
            todo = [(compiled, v)] if compiled is not None else []
            if numeric is not None and k < ladder.numeric_rungs:
                todo.append((numeric, Variant(v.method, v.project, "numeric")))
            runs += [(solver, variant, setting, value) for solver, variant in todo]
    report = Reporter(progress, "accuracy", total=len(runs))
    for done, (solver, variant, setting, value) in enumerate(runs):
        if variant in unsupported:
            continue
        report(f"{name}: {variant.label}, {setting} = {value:g}", done=done)
        row = run_one(solver, variant, setting, value, reference, ladder, name)
        rows.append(row)
        if on_row is not None:
            on_row(rows)
        if row.status == "unsupported":     # one row says so; skip the rest
            unsupported.add(variant)
    report(f"{name}: {len(rows)} runs done", done=len(runs))
    return rows
