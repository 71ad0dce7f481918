"""How a result was made (docs/design.md §4): the metadata every run adds to
``result.info`` and every result file keeps.

    fccgen_version   the fccgen that ran it
    created          when the run ended (UTC, ISO 8601)
    model            {"name", "source" (the file as given), "hash", "structure_hash"}
    method, kind, dt, output_dt, t_end, project, options   the method and its settings
    solver           {"rank_tol", "position_tol", "max_newton"}: the solver's tolerances
    steps, rhs_evaluations, ..., wall_time, dof, ...       the run statistics
    warnings         what the run warned about (text)
    events           the events table, when the run has events: one record each

``model.hash`` is a sha256 over what the run computed with: the element classes (the
structure), every element's numbers (masses, lengths, loads, ...), the initial
coordinates and speeds. Two runs with the same hash ran the same model, whichever file
or :meth:`~fccgen.runtime.CompiledSolver.with_parameters` call it came from; compare a
file with ``model_hash(fccgen.api.plan_model(path))``. ``structure_hash`` is the one
the compiled module was built for (numbers left out).
"""
from __future__ import annotations

import datetime
import hashlib

import numpy as np

from ..version import __version__


def structure_hash(plan) -> str:
    """sha256 of the element-class keys in order (as fccgen.build.cache computes it)."""
    return hashlib.sha256("\n".join(c.key for c in plan.classes).encode("utf-8")).hexdigest()


def model_hash(plan) -> str:
    """sha256 of the plan's structure, numbers and initial state (module docstring)."""
    h = hashlib.sha256()
    h.update(plan.model.name.encode("utf-8") + b"\0")
    for name, kind in plan.triples:
        h.update(f"{name}:{kind}\0".encode("utf-8"))
    for el in plan.elements:
        h.update(f"{el.label}\0{el.cls.key}\0".encode("utf-8"))
        h.update(np.ascontiguousarray(el.params, dtype="<f8").tobytes())
    for vector in (plan.q0, plan.v_target):
        h.update(np.ascontiguousarray(vector, dtype="<f8").tobytes())
    return h.hexdigest()


def provenance(plan, solver_settings: dict | None = None) -> dict:
    """The metadata of a run of ``plan`` (fccgen version, time, model, solver)."""
    info = {
        "fccgen_version": __version__,
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(
            timespec="seconds"),
        "model": {"name": plan.model.name, "source": str(plan.model.source),
                  "hash": model_hash(plan), "structure_hash": structure_hash(plan)},
    }
    if solver_settings:
        info["solver"] = dict(solver_settings)
    return info
