"""Simulation results (docs/design.md §4): time ``t`` and named columns, with
``info``, how the run was made (:mod:`fccgen.results.provenance`), written as CSV (with a JSON
sidecar ``<stem>.meta.json``), NPZ or HDF5 (:mod:`fccgen.results.files`).

Files are written atomically: into a temporary file of the same folder, named
``.<name>.<pid>.<random>.tmp`` (a suffix :meth:`Result.load` refuses), then renamed
over the target, with the permissions the user's umask gives. A result of a run that
did not finish is written only when asked, under ``<stem>.partial<suffix>``, and says
so inside: ``info["partial"]`` (and, in CSV, a last comment line). Loading flags it
(``result.partial``, a :class:`~fccgen.errors.PartialResultWarning`) and refuses a CSV
whose last line is cut.
"""
from __future__ import annotations

import errno
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import files
from ..errors import HostError, PartialResultWarning, SimulationError
from .files import INFO_ENTRY, PARTIAL_LINE, SUFFIXES  # noqa: F401 (re-exported)


def partial_path(path) -> Path:
    """Where the partial result of a run meant for ``path`` goes: run.csv ->
    run.partial.csv."""
    path = Path(path)
    return path.with_name(f"{path.stem}.partial{path.suffix}")


def check_output(path, option: str = "--out") -> Path:
    """Check, before a run, that results can be written to ``path``: a .csv, .npz or
    .h5 name (h5py installed for .h5), not a folder, in a folder that exists (created
    if missing) and takes a new file. Raises ValueError for a bad name, HostError for
    a place that cannot be written or a missing h5py.
    """
    path = Path(path)
    files.check_suffix(path)
    if path.is_dir():
        raise HostError(f"cannot write the results to {path}: it is a folder. To fix it, "
                        f"give a file name with {option} (e.g. {path / 'result'}"
                        f"{path.suffix})", errno=errno.EISDIR)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        probe = files.temp_name(path)
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        probe.unlink()
    except OSError as exc:
        raise HostError.from_os_error(exc, "write the results in", path.parent, option,
                                      name_file=False) from None
    return path


@dataclass
class Result:
    t: np.ndarray                               # (n_out,)
    columns: dict[str, np.ndarray]              # name -> (n_out,), insertion order kept
    info: dict = field(default_factory=dict)    # run statistics: steps, method, timings...
    events: list = field(default_factory=list)  # event table rows (fccgen.events.table)
    # Columns of the points and vectors that the lowering of joints and pose-form bodies
    # made (``A_axis.x``, ``rod_center.vy``): kept in ``columns``, shown only on
    # request (:attr:`internal`, ``all_columns=True``).
    hidden: set = field(default_factory=set)

    def __getitem__(self, name: str) -> np.ndarray:
        if name == "t":
            return self.t
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"no column {name!r}; columns are: " + ", ".join(self.names)
                           + (" (and those of result.internal)" if self.hidden else "")
                           ) from None

    def sensitivity(self, column: str, param: str) -> np.ndarray:
        """d(column)/d(param) at every record, of a run with ``sensitivities=[...]``
        (its column ``d(<column>)/d(<param>)``, kept in the files; docs/sensitivities.md)."""
        name = f"d({column})/d({param})"
        if name in self.columns:
            return self.columns[name]
        keys = self.info.get("sensitivities") or []
        if not keys:
            raise KeyError("this result has no sensitivities: run with "
                           "sensitivities=[...] (fccgen sensitivity on the command line)")
        if param not in keys:
            raise KeyError(f"no sensitivity to {param!r}; the run's parameters are: "
                           + ", ".join(keys))
        if column == "t" or column in self.columns:
            raise KeyError(f"the column {column!r} has no sensitivity (constraint forces, "
                           "reactions and constraint_error have none)")
        raise KeyError(f"no column {column!r}; columns are: " + ", ".join(self.names))

    @property
    def names(self) -> list[str]:
        """``t`` and the columns of what the user named: points, vectors, bodies,
        joints, drivers, energy, constraint_error (docs/design.md §4)."""
        return ["t", *(n for n in self.columns if n not in self.hidden)]

    @property
    def internal(self) -> dict[str, np.ndarray]:
        """The columns of the points and vectors fccgen made when it lowered joints and
        pose-form bodies (none for a model given by points)."""
        return {n: v for n, v in self.columns.items() if n in self.hidden}

    def all_names(self) -> list[str]:
        """``t``, the user's columns, then the internal ones."""
        return [*self.names, *self.internal]

    def __repr__(self) -> str:
        """Rows, t range, columns (the first few named), method, events, partial."""
        from .summary import result_repr
        return result_repr(self)

    def _repr_html_(self) -> str:
        """The same summary as a small HTML table, for notebooks."""
        from .summary import result_html
        return result_html(self)

    def to_pandas(self, all_columns: bool = False):
        """The columns (:attr:`names`; ``all_columns``: the internal ones too) as a
        pandas DataFrame indexed by ``t``; ``info`` (how the run was made) in
        ``frame.attrs["fccgen"]``."""
        import pandas as pd
        names = (self.all_names() if all_columns else self.names)[1:]
        frame = pd.DataFrame({n: np.asarray(self.columns[n]) for n in names},
                             index=pd.Index(np.asarray(self.t), name="t"))
        frame.attrs["fccgen"] = dict(self.info)
        return frame

    def table(self, all_columns: bool = False) -> np.ndarray:
        """The columns side by side, ``t`` first: shape (n_out, 1 + n_columns); the
        user's (:attr:`names`), or ``all_columns``."""
        names = self.all_names() if all_columns else self.names
        return np.column_stack([self[n] for n in names])

    def plot(self, columns=None, ax=None):
        """Time histories of ``columns`` (names, or one comma-separated string; default:
        the first moving point's position), one panel per quantity, on a new pyplot
        figure, or all on ``ax``. Returns the matplotlib Figure; needs matplotlib."""
        from ..viz.plot import plot_columns, require_matplotlib
        require_matplotlib()
        if ax is not None:
            return plot_columns(self, columns, ax=ax)
        import matplotlib.pyplot as plt
        return plot_columns(self, columns, figure=plt.figure())

    @property
    def ok(self) -> bool:
        """True: a run's result (simulate_many puts a RunFailure, whose ok is False,
        in the place of a run that failed)."""
        return True

    @property
    def partial(self) -> bool:
        """Whether the run stopped before its end (Ctrl-C, a failure)."""
        return bool(self.info.get("partial", False))

    def save(self, path, *, partial: bool | None = None, all_columns: bool = False) -> Path:
        """Write CSV (and its sidecar ``<stem>.meta.json``), NPZ or HDF5 (.h5), chosen by
        the file's suffix, ``info`` included; written atomically, with the permissions
        of the user's umask. ``partial``: mark the file as the result of an unfinished
        run (default: ``self.partial``). The internal columns (:attr:`internal`) go
        into a CSV only with ``all_columns``; NPZ keeps them (listed as internal), HDF5
        in its group ``internal`` (``all_columns``: at the root with the others), so
        that ``fccgen animate --result`` can draw from those files."""
        path = Path(path)
        suffix = files.check_suffix(path)
        if partial is not None:
            self.info["partial"] = bool(partial)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            files.write(self, path, suffix, all_columns)
        except OSError as exc:
            raise HostError.from_os_error(exc, "write the results to", path, "--out",
                                          name_file=False) from None
        return path

    @classmethod
    def load(cls, path) -> "Result":
        """Read a file written by :meth:`save`, ``info`` included. A partial result
        loads with ``result.partial`` true and a PartialResultWarning; a temporary or
        cut file is refused (ValueError)."""
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix not in SUFFIXES:
            raise ValueError(f"{path}: not a result file (.csv, .npz or .h5)"
                             + ("; it is the temporary file of a save that did not end"
                                if suffix == ".tmp" else ""))
        arrays, info, hidden = files.read(path, suffix)
        events = info.get("events") if isinstance(info.get("events"), list) else []
        if path.name.endswith(f".partial{path.suffix}"):
            info["partial"] = True
        t = arrays.pop("t")
        result = cls(t, arrays, info, events, set(hidden))
        if result.partial:
            warnings.warn(PartialResultWarning(
                f"{path} holds a partial result: the run stopped at t = {t[-1]:.6g} "
                f"({info.get('stopped_by', 'unfinished')})"), stacklevel=2)
        return result


@dataclass
class InitialState:
    """Consistent initial conditions and how far the user's data had to move."""
    q: np.ndarray
    v: np.ndarray
    position_residual_given: float      # max |g| at the positions as given
    position_residual: float            # max |g| after assembly
    newton_iterations: int              # assembly iterations (0: positions were consistent)
    velocity_change: float              # max |v - v_given| made by the projection
    velocity_residual: float            # max |B v| after projection

    def report(self) -> str:
        lines = [f"positions: max |g| {self.position_residual_given:.3g} as given"]
        if self.newton_iterations:
            lines[0] += (f", {self.position_residual:.3g} after {self.newton_iterations} "
                         "Newton assembly iteration(s)")
        lines.append(f"velocities: changed by at most {self.velocity_change:.3g} to satisfy "
                     f"B q' = 0 (residual {self.velocity_residual:.3g})")
        return "\n".join(lines)


def result_from_arrays(plan, t, q, v, body_out, energy, constraint_error, info=None) -> Result:
    """Name the columns of a run (docs/design.md §4).

    q, v: (n_out, n_q); body_out: (n_out, n_bodies, 6); energy, constraint_error: (n_out,).
    """
    cols: dict[str, np.ndarray] = {}
    # each column a contiguous row of one transposed copy per array (one copy, not
    # one per column: a short run of a large model named thousands of columns)
    q_rows, v_rows = np.array(np.asarray(q).T), np.array(np.asarray(v).T)
    body_rows = np.array(np.asarray(body_out).transpose(1, 2, 0))
    for k, (name, _) in enumerate(plan.triples):
        for c in range(3):
            cols[f"{name}.{'xyz'[c]}"] = q_rows[3 * k + c]
        for c in range(3):
            cols[f"{name}.v{'xyz'[c]}"] = v_rows[3 * k + c]
    for b, (name, _) in enumerate(plan.bodies):
        for c, col in enumerate(("cx", "cy", "cz", "wx", "wy", "wz")):
            cols[f"{name}.{col}"] = body_rows[b, c]
    cols["energy"] = np.array(energy)
    cols["constraint_error"] = np.array(constraint_error)
    return Result(np.array(t), cols, dict(info or {}), hidden=internal_columns(plan, cols))


def internal_columns(plan, cols) -> set[str]:
    """The columns of the points and vectors the lowering made (none for a model
    given by points): ``N.x`` ... ``N.vz`` of each."""
    mechanism = getattr(plan.model, "mechanism", None)
    if mechanism is None:
        return set()
    return {f"{n}.{c}" for n in mechanism.internal() for c in
            ("x", "y", "z", "vx", "vy", "vz") if f"{n}.{c}" in cols}


def timed_run(plan, method, sched, options, project, run, settings=None) -> Result:
    """Call ``run()`` -> (arrays, stats) with single-threaded BLAS, time it, and name
    the result's columns; ``result.info`` from :func:`fccgen.settings.methods.run_info` and
    :func:`fccgen.results.provenance.provenance` (``settings``: the solver's tolerances)."""
    import time

    from ..threads import single_threaded_blas
    start = time.perf_counter()
    try:
        with single_threaded_blas():
            arrays, stats = run()
    except (KeyboardInterrupt, SimulationError) as exc:
        _attach_partial(plan, method, sched, options, project, start, exc, settings)
        raise
    info = _info(plan, method, sched, options, project, stats, arrays, start, settings)
    result = result_from_arrays(plan, arrays["t"], arrays["q"], arrays["v"],
                                arrays["body"], arrays["energy"],
                                arrays["constraint_error"], info)
    # the angles' lost turns are said once the run's events are known
    # (fccgen.mechanism.outputs.settle_turns)
    return _with_joint_columns(plan, result, warn=False)


def _with_joint_columns(plan, result, warn: bool = True):
    """Add the joint columns (J.angle, J.rate, ...) of a mechanism-level model, and
    the strain and curvature at the nodes of flexible members; warn: say which
    angles' turns the records cannot count (else only in info)."""
    if getattr(plan.model, "mechanism", None) is not None:
        from ..mechanism.outputs import add_joint_columns
        add_joint_columns(plan, result, warn)
    if getattr(plan.model, "cables", None):
        from ..mechanism.cable_outputs import add_cable_columns
        add_cable_columns(plan, result)
    return result


def keep_rows(exc: BaseException, arrays: dict, n_rows: int, stats: dict) -> None:
    """What an integrator that stops early hands back: copies of the first ``n_rows``
    records of ``arrays`` and its ``stats`` (steps, rhs_evaluations,
    max_constraint_error, ...) as ``exc.partial``, read by :func:`_attach_partial`."""
    exc.partial = ({name: a[:n_rows].copy() for name, a in arrays.items()}, dict(stats))


def _info(plan, method, sched, options, project, stats, arrays, start, settings) -> dict:
    """result.info of a run: how it was made, then the method's statistics."""
    import time

    from ..settings.methods import run_info
    from .provenance import provenance
    info = provenance(plan, settings)
    info.update(run_info(method, stats, arrays["energy"], time.perf_counter() - start,
                         dt=sched.dt, output_dt=sched.output_dt, t_end=sched.t_end,
                         project=project, options=options))
    return info


def _attach_partial(plan, method, sched, options, project, start, exc, settings=None) -> None:
    """Name the rows an interrupted integrator handed back, if any.

    An integrator that stops early may set ``exc.partial = (arrays, stats)`` with
    arrays cut to the rows recorded; this sets ``exc.partial_result``, a Result with
    ``info["partial"]`` true and ``info["stopped_by"]`` saying why.
    """
    rows = getattr(exc, "partial", None)
    if rows is None:
        return
    arrays, stats = rows
    if len(arrays["t"]) == 0:
        return
    info = _info(plan, method, sched, options, project, stats, arrays, start, settings)
    why = "interrupted (Ctrl-C)" if isinstance(exc, KeyboardInterrupt) else str(exc)
    info.update(partial=True, stopped_by=why.splitlines()[0] if why else type(exc).__name__)
    exc.partial_result = _with_joint_columns(plan, result_from_arrays(
        plan, arrays["t"], arrays["q"], arrays["v"], arrays["body"], arrays["energy"],
        arrays["constraint_error"], info), warn=False)
