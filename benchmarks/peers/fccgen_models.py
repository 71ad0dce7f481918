"""The comparison's systems in fccgen, through its public API.

``fccgen.load(model file, **solver options)`` builds (or finds in the cache) the
compiled solver; a run is ``solver.simulate(method="rk4", dt, t_end = n_steps dt)``
from the consistent initial state, recording only at the start and the end (output_dt
= t_end), so that its time is that of the steps: per step, RK4's four accelerations
(dense or sparse constrained solve) and the Newton position and velocity projections.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

import fccgen
from systems import ROOT, model_file, tracked_point

MODELS = ROOT / "generated" / "peers"


def load_solver(path, build_dir, linear_solver: str = "auto"):
    """``fccgen.load`` with ``linear_solver`` passed only when it is not "auto"; a build
    without that option says so instead of failing obscurely."""
    options = {} if linear_solver in (None, "auto") else {"linear_solver": linear_solver}
    try:
        return fccgen.load(path, build_dir, **options)
    except (TypeError, ValueError) as exc:
        if not options:
            raise
        raise SystemExit(f"this fccgen does not take linear_solver={linear_solver!r} "
                         f"({exc}); run with --fccgen-solver auto") from None


class FccgenModel:
    """One system in fccgen: ``advance(n_steps)`` from the initial state each time,
    ``point()`` the tracked point's (x, y) at the end of the last run."""

    def __init__(self, system: str, n: int, dt: float, *, build_dir=None,
                 linear_solver: str = "auto", models: Path = MODELS, project: bool = True):
        path = model_file(system, n, models)
        self.solver = load_solver(path, str(build_dir or ROOT / "generated"), linear_solver)
        init = self.solver.initial_state()
        self.q0, self.v0 = init.q, init.v
        self.dt = dt
        self.project = project
        self.name = tracked_point(system, n)
        self.result = None

    def advance(self, n_steps: int, method: str = "rk4", **options) -> None:
        t_end = n_steps * self.dt
        options.setdefault("project", self.project)
        self.result = self.solver.simulate(t_end=t_end, dt=self.dt, method=method,
                                           output_dt=t_end, q0=self.q0, v0=self.v0,
                                           **options)

    def point(self) -> np.ndarray:
        r = self.result
        return np.array([r[f"{self.name}.x"][-1], r[f"{self.name}.y"][-1]])


def make(system: str, n: int, dt: float, **options) -> FccgenModel:
    return FccgenModel(system, n, dt, **options)
