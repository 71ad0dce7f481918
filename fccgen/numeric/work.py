"""The power of the forces without potential in the NumPy version, for the energy
check with the work added back (fccgen/runs/energy_check.py; the compiled
runtime's runtime/_power.pyx, written independently): the applied forces assembled
with the parameters of the forces that have a potential set to zero (gravity,
constant forces, spring stiffnesses), and for driven models the constraint forces'
power v . (M a + h - f) = -v . (B^T lambda)."""
from __future__ import annotations

import numpy as np

from ..runs.energy_check import driven, energy_exchange, work_split


class WorkPower:
    """power(q, v, a) of a NumPy solver's model (see the module docstring)."""

    def __init__(self, solver):
        self.solver = solver
        zero, _ = work_split(solver.plan)
        starts = np.cumsum([0] + [len(el.params) for el in solver.plan.elements])
        element = np.searchsorted(starts, zero, side="right") - 1
        self.zero = [(int(e), int(z - starts[e])) for e, z in zip(element, zero)]
        self.driven = driven(solver.plan)

    def __call__(self, q, v, a) -> float:
        s = self.solver
        saved = s._params
        s._params = [p.copy() for p in saved]
        try:
            for e, k in self.zero:
                s._params[e][k] = 0.0
            power = float(np.asarray(v) @ s.applied_forces(q, v))
        finally:
            s._params = saved
        if self.driven:
            x = s._assemble(q, v, ("mass_matrix", "h_vector", "applied_forces"))
            power += float(np.asarray(v) @ (x["mass_matrix"] @ a + x["h_vector"]
                                            - x["applied_forces"]))
        return power


def work_power(solver):
    """(a WorkPower, or None; why the work is not tracked, or None)."""
    if energy_exchange(solver.plan) is None:
        return None, None
    _, unknown = work_split(solver.plan)
    if unknown:
        return None, unknown
    return WorkPower(solver), None
