"""Simulation results (DESIGN section 4): time ``t`` and named columns, written as CSV
(header = column names) or NPZ (one array per name)."""
from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Result:
    t: np.ndarray                               # (n_out,)
    columns: dict[str, np.ndarray]              # name -> (n_out,), insertion order kept
    info: dict = field(default_factory=dict)    # run statistics: steps, method, timings...

    def __getitem__(self, name: str) -> np.ndarray:
        if name == "t":
            return self.t
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"no column {name!r}; columns are: t, "
                           + ", ".join(self.columns)) from None

    @property
    def names(self) -> list[str]:
        return ["t", *self.columns]

    def table(self) -> np.ndarray:
        """All columns side by side, ``t`` first: shape (n_out, 1 + n_columns)."""
        return np.column_stack([self.t, *self.columns.values()])

    def save(self, path) -> Path:
        """Write CSV or NPZ, chosen by the file's suffix; written atomically."""
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix not in (".csv", ".npz"):
            raise ValueError(f"{path}: results are written as .csv or .npz (got {suffix!r})")
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
        os.close(fd)
        try:
            if suffix == ".csv":
                np.savetxt(tmp, self.table(), delimiter=",", header=",".join(self.names),
                           comments="", fmt="%.17g")
            else:
                np.savez(tmp, **{n: self[n] for n in self.names})
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def load(cls, path) -> "Result":
        """Read a file written by :meth:`save`."""
        path = Path(path)
        if path.suffix.lower() == ".npz":
            with np.load(path) as data:
                names = list(data.files)
                arrays = {n: data[n] for n in names}
        else:
            with open(path) as fh:
                names = fh.readline().strip().split(",")
            table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
            arrays = {n: table[:, k] for k, n in enumerate(names)}
        t = arrays.pop("t")
        return cls(t, arrays)


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
    """Name the columns of a run (DESIGN section 4).

    q, v: (n_out, n_q); body_out: (n_out, n_bodies, 6); energy, constraint_error: (n_out,).
    """
    cols: dict[str, np.ndarray] = {}
    for k, (name, _) in enumerate(plan.triples):
        for c in range(3):
            cols[f"{name}.{'xyz'[c]}"] = np.array(q[:, 3 * k + c])
        for c in range(3):
            cols[f"{name}.v{'xyz'[c]}"] = np.array(v[:, 3 * k + c])
    for b, (name, _) in enumerate(plan.bodies):
        for c, col in enumerate(("cx", "cy", "cz", "wx", "wy", "wz")):
            cols[f"{name}.{col}"] = np.array(body_out[:, b, c])
    cols["energy"] = np.array(energy)
    cols["constraint_error"] = np.array(constraint_error)
    return Result(np.array(t), cols, dict(info or {}))


def timed_run(plan, method, sched, options, project, run) -> Result:
    """Call ``run()`` -> (arrays, stats) with single-threaded BLAS, time it, and name
    the result's columns; ``result.info`` from :func:`fccgen.methods.run_info`."""
    import time

    from .methods import run_info
    from .threads import single_threaded_blas
    start = time.perf_counter()
    with single_threaded_blas():
        arrays, stats = run()
    info = run_info(method, stats, arrays["energy"], time.perf_counter() - start,
                    dt=sched.dt, output_dt=sched.output_dt, project=project, options=options)
    result = result_from_arrays(plan, arrays["t"], arrays["q"], arrays["v"],
                                arrays["body"], arrays["energy"],
                                arrays["constraint_error"], info)
    if getattr(plan.model, "mechanism", None) is not None:     # joint columns
        from .mechanism.outputs import add_joint_columns
        add_joint_columns(plan, result)
    return result
