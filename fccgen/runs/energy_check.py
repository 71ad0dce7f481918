"""The energy as an independent check of a run (docs/reliability.md, "Energy").

E = T + V (kinetic plus the potentials of gravity, constant forces and springs)
changes only by the work W of the forces without potential -- dampers, constant
torques, loads of time or of joint quantities, drivers -- and by the kinetic energy L
that impacts take (the event table):

    E(t) - W(t) + L(t) = E(0).

The integrators add W up with their own quadrature from the stage powers
(runtime/_power.pyx; the NumPy version likewise), so an integration that follows the
motion keeps the balance to its truncation error, far below the kinetic energy. When
its largest error over the records exceeds DRIFT_FRACTION of the largest kinetic
energy the run met, the steps did not follow the motion (a step across a singular
position, a step too large for the speeds, an explicit step beyond its stability
limit), even where constraint errors and projections look right: the run says so.
A model whose forces all have a potential keeps E itself (W = 0).

Where W is not tracked the check says why in ``info["energy_check"]["reason"]``:
ali3p (its steps are not quadratures of the stage states), element kinds whose
potential the split below does not know.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import RunWarning
from ..events.table import energy_losses
from ..plan.classes import FUNCTION_KINDS

DRIFT_FRACTION = 1e-2      # of the peak kinetic energy: 1e4 times the drift of an
                           # RK4 run that follows the motion at the examples' dt
                           # (A02 1e-9 J, scissor boom 2.4e-11 J of 131.6 J)
DAMPED_KINDS = ("spring", "torsion_spring", "linear_spring",   # damping scalar "c"
                "cable")
# The parameters of an element's forces that have a potential (in V): zeroed, the
# element's applied forces are those without one (runtime/_power.pyx). A member's
# elastic, gravity and constant distributed forces all have one; its damping (c times
# the stiffness) does not, and vanishes with EA and EI, so a damped member's work is
# not split (work_split says so).
CONSERVATIVE = {"body": ("gx", "gy", "gz"), "force": ("Fx", "Fy", "Fz"),
                "spring": ("k",), "torsion_spring": ("k",), "linear_spring": ("k",),
                "cable": ("EA", "EI", "gx", "gy", "gz", "qx", "qy", "qz"),
                "point_force": ("Fx", "Fy", "Fz")}
# Loads without any potential: all their force does work.
NO_POTENTIAL = ("torque", "force_t", "torque_t", "force_q", "torque_q", "point_force_t")
# Positions that move by at most this fraction of their size (1 m floor) over a run:
# the bodies stayed at rest, and the energy's changes are rounding (a kinetic energy
# of 1e-32 J is no scale to measure them by).
AT_REST = 1e-12
RECORDS_FOR_PEAK = 2000    # records read for the kinetic energy peak (evenly spread)


def energy_exchange(plan) -> str | None:
    """Why the energy of ``plan``'s model need not stay constant (the first element
    that exchanges it), or None when it must."""
    for el in plan.elements:
        kind = el.cls.kind
        names = el.cls.param_names
        if kind in FUNCTION_KINDS:
            what = "driver" if kind.startswith("driver") else "load of time or joint quantities"
            return f"{el.label}: a {what} does work"
        if kind == "torque" and np.any(el.params[[names.index(c) for c in
                                                  ("Tx", "Ty", "Tz") if c in names]]):
            return f"{el.label}: a constant torque does work"
        if kind in DAMPED_KINDS and "c" in names and el.params[names.index("c")] != 0.0:
            return f"{el.label}: a damper takes energy"
    return None


def work_split(plan) -> tuple[list[int], str | None]:
    """(indices, in the concatenated element parameters, of the parameters of forces
    with a potential; None, or why some element's split is not known)."""
    zero, start = [], 0
    for el in plan.elements:
        kind, names = el.cls.kind, el.cls.param_names
        if kind == "cable" and el.params[names.index("c")] != 0.0:
            return zero, (f"{el.label}: the energy check does not split a damped "
                          "member's work (its damping is proportional to its stiffness)")
        if kind in CONSERVATIVE:
            zero += [start + names.index(n) for n in CONSERVATIVE[kind] if n in names]
        elif kind not in NO_POTENTIAL and el.cls.n_g == 0:
            return zero, (f"{el.label}: the energy check does not know which of a {kind} "
                          f"element's forces have a potential")
        start += len(el.params)
    return zero, None


def driven(plan) -> bool:
    return any(el.cls.kind.startswith("driver") for el in plan.elements)


def work_elements(plan) -> tuple[list[int], list[tuple[int, int]]]:
    """(the elements whose forces do work: loads without potential and damped springs;
    (element, parameter index) of each such spring's stiffness, to be zeroed)."""
    elements, zero = [], []
    for e, el in enumerate(plan.elements):
        kind, names = el.cls.kind, el.cls.param_names
        if kind in NO_POTENTIAL:
            elements.append(e)
        elif kind in DAMPED_KINDS and el.params[names.index("c")] != 0.0:
            elements.append(e)
            zero.append((e, names.index("k")))
    return elements, zero


def kinetic_peak(solver, result, engine_peak: float | None) -> float:
    """The largest kinetic energy of the run: the velocity projections' (engine_peak)
    and the records' (at most RECORDS_FOR_PEAK of them, evenly spread)."""
    peak = float(engine_peak or 0.0)
    n = len(result.t)
    if not n:
        return peak
    plan = solver.plan
    names = [f"{name}.{p}{c}" for name, _ in plan.triples for p in ("", "v")
             for c in "xyz"]
    if not all(c in result.columns for c in names):
        return peak
    # only the records read: (records, n_q), one record a contiguous row
    rows = np.unique(np.linspace(0, n - 1, min(n, RECORDS_FOR_PEAK)).astype(int))
    q = np.array([result.columns[f"{name}.{c}"][rows] for name, _ in plan.triples
                  for c in "xyz"]).T.copy()
    v = np.array([result.columns[f"{name}.v{c}"][rows] for name, _ in plan.triples
                  for c in "xyz"]).T.copy()
    for k in range(len(rows)):
        peak = max(peak, float(solver.kinetic_energy(q[k], v[k])))
    return peak


def check_energy(result, plan, kinetic: float | None, work=None,
                 untracked: str | None = None) -> None:
    """Record ``info["energy_check"]`` and warn when the balance of the module
    docstring drifts by more than DRIFT_FRACTION of ``kinetic`` (the largest kinetic
    energy). work: W at every record (None: not tracked, ``untracked`` says why)."""
    info = result.info
    reason = energy_exchange(plan)
    check = {"conservative": reason is None, "reason": reason,
             "kinetic_energy_peak": kinetic, "drift_fraction": None, "work": None}
    info["energy_check"] = check
    e = np.asarray(result["energy"], float)
    if not e.size or not kinetic or kinetic <= 0.0:
        return
    balance = e + energy_losses(result.t, result.events)
    if reason is not None:
        if work is None or len(work) != len(e):
            check["reason"] = f"{reason}; not checked: {untracked or 'its work is not tracked'}"
            return
        work = np.asarray(work, float)
        balance = balance - work
        check["work"] = float(work[-1])
    if info.get("events_dropped") and result.events:
        # the impacts past the event log's rows took energy the table does not list:
        # the balance holds up to the last event listed
        last = result.events[-1]["t"]
        balance = balance[np.asarray(result.t) <= last]
        check["until"] = last
    if _at_rest(result, plan):
        check["at_rest"] = True
        return
    drift = np.abs(balance - balance[0])
    k = int(np.argmax(drift))
    fraction = float(drift[k]) / float(kinetic)
    check["drift_fraction"] = fraction
    check["balance_drift"] = float(drift[k])
    if not fraction > DRIFT_FRACTION:
        return
    at = float(np.asarray(result.t)[k])
    if reason is None:
        what = (f"the energy changed by {drift[k]:.3g} ({fraction:.1%} of the largest "
                f"kinetic energy, {kinetic:.3g}; worst at t = {at:.6g}) in a model that "
                f"conserves it (no dampers, drivers, torques or loads of time)")
    else:
        what = (f"the energy balance E - W + impact losses changed by {drift[k]:.3g} "
                f"({fraction:.1%} of the largest kinetic energy, {kinetic:.3g}; worst at "
                f"t = {at:.6g}), W being the work of dampers, drivers and loads without "
                f"potential added up by the steps ({work[-1]:.6g} over the run)")
    text = (f"{what}: the steps did not follow the motion; rerun with a smaller --dt "
            f"or --method dopri5 and compare before using this result "
            f"(docs/reliability.md, \"Energy\")")
    info.setdefault("warnings", []).append(text)
    warnings.warn(text, RunWarning, stacklevel=3)


def _at_rest(result, plan) -> bool:
    """No coordinate of the run's records moved by more than AT_REST of the largest
    (at least 1): the bodies stayed where they started."""
    moved, size = 0.0, 1.0
    for name, _ in plan.triples:
        for c in "xyz":
            x = np.asarray(result.columns.get(f"{name}.{c}", ()), float)
            if x.size:
                moved = max(moved, float(np.max(np.abs(x - x[0]))))
                size = max(size, float(np.max(np.abs(x))))
    return moved <= AT_REST * size
