"""The compiled work tracker of a run: the work of dampers, drivers and loads that the
energy check adds back (fccgen.runs.energy_check), integrated in the engine's steps."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ..runs.energy_check import driven, energy_exchange, work_elements, work_split
from ._power import WorkTracker
from .assembler import make_assembler


def work_tracker(plan, module, method: str, sparse: bool):
    """(the runtime/_power.WorkTracker of a compiled run of ``method``, or None; why
    the work is not tracked, or None)."""
    if energy_exchange(plan) is None:
        return None, None
    _, unknown = work_split(plan)
    if unknown:
        return None, unknown
    if method == "ali3p":
        return None, "ali3p's steps are not quadratures of stage states"
    elements, zero = work_elements(plan)
    starts = np.cumsum([0] + [len(el.params) for el in plan.elements])
    subset = SimpleNamespace(elements=[plan.elements[e] for e in elements],
                             classes=plan.classes, n_q=plan.n_q, bodies=[],
                             class_of=[plan.class_of[e] for e in elements])
    src = [int(starts[e]) + k for e in elements for k in range(len(plan.elements[e].params))]
    local = np.cumsum([0] + [len(plan.elements[e].params) for e in elements])
    zero_local = [int(local[elements.index(e)]) + k for e, k in zero]
    return WorkTracker(make_assembler(subset, module), src, zero_local, driven(plan),
                       sparse, plan.n_q), None
