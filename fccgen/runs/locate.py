"""Which item of the model file a solver failure comes from.

A failure met while a model runs (the compiled engine's or the NumPy version's) is told
in the solver's words: a singular reduced mass matrix, a non-finite force, a
projection that does not converge, a run that diverges. The user needs the place in
the file, as a ModelError gives it: ``file:line: item: rule (got value)``. The item is
found from the failure and the state it happened at, independently of the solver that
failed (the NumPy kernels of each element, evaluated on the error path only):

- a singular mass matrix: the model item (a body first) using the coordinates of the
  motion without inertia (fccgen.runs.massless.massless_motion), value those coordinates;
- a non-finite input or result: the first element whose kernels are not finite at the
  last recorded state, value its first non-finite entry;
- a position projection (the assembly) that does not converge: the constraint with
  the largest scaled residual max |g_k| / ||B_k||, value that residual;
- anything else (a run that diverges, a step size underflow, Newton of ALI3-P): the
  step setting the message advises to change, ``simulate.dt`` (or ``dt (--dt)`` when
  the command line or the API gave it), value its number.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Location:
    line: int | None
    item: str
    value: object


def locate(solver, text: str, q, v=None, t: float = 0.0, setting=None) -> Location:
    """The model item behind the failure ``text`` at the state (q, v, t). setting:
    (name, value, given) of the step setting of the run, given true when the caller
    (command line, API) chose it rather than the model file."""
    plan = solver.plan
    lowered = text.lower()
    try:
        if "singular" in lowered:
            found = _massless_item(solver, q)
            if found is not None:
                return found
        if "finite" in lowered or "cannot be evaluated" in lowered:
            found = _non_finite_item(solver, q, v, t)
            if found is not None:
                return found
        if "position projection" in lowered or "assembled" in lowered:
            found = _largest_residual_item(solver, q)
            if found is not None:
                return found
    except (ArithmeticError, ValueError, np.linalg.LinAlgError):
        pass                            # the message keeps the setting below
    if setting is None and "simulation stopped" not in lowered:
        return section_location(plan.model)
    return setting_location(plan.model, setting)


def section_location(model) -> Location:
    """The first of the model file's sections that place its bodies (a failure at
    the start that no single item explains: numbers too far apart in size)."""
    for key in ("bodies", "joints", "points", "name"):
        where = model.where.get(key)
        if where is not None:
            return Location(where.line, key, f"{len(getattr(model, key, ()) or ())} items"
                            if key != "name" else model.name)
    return Location(None, "name", model.name)


def setting_location(model, setting=None) -> Location:
    """The step setting as a located item: ``simulate.NAME`` at the line of the
    model file's simulate section, or ``NAME (--flag)`` when given elsewhere."""
    from ..settings.run import flag
    name, value, given = setting if setting is not None else (
        "dt", getattr(model.simulate, "dt", None), False)
    where = model.where.get("simulate")
    if given:                           # no line of the file holds it
        return Location(None, f"{name} ({flag(name)})", value)
    return Location(None if where is None else where.line, f"simulate.{name}", value)


def loads_location(model) -> Location:
    """The loads of a model (a failure of statics): its ``loads`` section, else its
    gravity, else its name."""
    for key, value in (("loads", f"{len(model.loads)} loads"),
                       ("gravity", [float(x) for x in model.gravity]),
                       ("name", model.name)):
        where = model.where.get(key)
        if where is not None:
            return Location(where.line, key, value)
    return Location(None, "name", model.name)


def _element_location(el, value) -> Location:
    return Location(el.where.line, el.label, value)


def _massless_item(solver, q) -> Location | None:
    from .massless import massless_users
    found = massless_users(solver.plan, solver.mass_matrix(q),
                           solver.constraint_jacobian(q))
    if found is None:
        return None
    names, users = found
    plan = solver.plan
    by_label = {el.label: el for el in plan.elements}
    ranked = sorted(users, key=lambda label: not label.startswith("bodies."))
    for label in ranked:
        el = by_label.get(label)
        if el is not None and el.where is not None:
            return _element_location(el, ", ".join(names))
    return None


def _kernel_sets(solver, q, v, t):
    """(element, kernels object) of every element at (q, v, t), by the NumPy kernels
    (``solver.element_kernels``: fccgen.numeric.element_kernels for either solver)."""
    plan = solver.plan
    q = np.asarray(q, float)
    v = np.zeros_like(q) if v is None else np.asarray(v, float)
    for el in plan.elements:
        params = np.array(el.params, float)
        if "t" in el.cls.param_names:
            params[el.cls.param_names.index("t")] = t
        idx = el.q_index()
        yield el, solver.element_kernels(el.cls, q[idx], v[idx], params)


def _non_finite_item(solver, q, v, t) -> Location | None:
    import warnings
    from ..plan.kernels import KERNELS
    if not (np.all(np.isfinite(q)) and (v is None or np.all(np.isfinite(v)))):
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for el, kernels in _kernel_sets(solver, q, v, t):
            for spec in KERNELS:
                try:
                    out = kernels.evaluate(spec.name)
                except (ArithmeticError, ValueError) as exc:
                    return _element_location(el, f"{type(exc).__name__}: {exc}")
                if out is not None and not np.all(np.isfinite(out)):
                    bad = next(float(x) for x in out if not np.isfinite(x))
                    return _element_location(el, bad)
    return None


def _largest_residual_item(solver, q) -> Location | None:
    worst, where = -1.0, None
    for el, kernels in _kernel_sets(solver, q, None, 0.0):
        g = kernels.evaluate("constraints")
        B = kernels.evaluate("constraint_jacobian")
        if g is None or B is None or g.size == 0:
            continue
        norms = np.linalg.norm(B.reshape(g.size, -1), axis=1)
        r = np.abs(g) / np.where(norms > 0.0, norms, 1.0)
        if np.max(r) > worst:
            worst, where = float(np.max(r)), el
    if where is None:
        return None
    return _element_location(where, float(f"{worst:.3g}"))


def failure_state(exc, q, v=None, t: float = 0.0):
    """(q, v, t) of the last recorded row of an interrupted run (``exc.partial``), else
    the state given."""
    rows = getattr(exc, "partial", None)
    try:
        arrays = rows[0]
        if len(arrays["t"]):
            return arrays["q"][-1], arrays["v"][-1], float(arrays["t"][-1])
    except (TypeError, KeyError, IndexError):
        pass
    return q, v, t


def step_setting(method, sched, options, dt=None):
    """(name, value, given) of the setting that sets a run's step: dt for fixed-step
    methods, rtol for adaptive ones; given: the caller chose it."""
    if method.kind == "fixed":
        return "dt", sched.dt, dt is not None
    given = getattr(options, "given", frozenset())
    return "rtol", options.get("rtol"), "rtol" in given
