"""The energy as an independent check of a run (docs/reliability.md, "Energy").

A model whose forces all come from a potential (gravity, constant forces, springs
without damping) and whose constraints do not depend on time keeps its energy
T + V exactly; an integration keeps it to its truncation error, which is far below
the kinetic energy wherever the steps follow the motion. When such a run's energy
drift (max |E - E0| over the outputs, impacts' losses added back) exceeds
DRIFT_FRACTION of the largest kinetic energy the run met, the steps did not follow the
motion (a step across a singular position, a step too large for the speeds), even
where constraint errors and projections look right: the run says so.

Models that exchange energy on purpose (dampers, drivers, torques, loads of time or of
joint quantities) are not checked; ``info["energy_check"]`` says which and why.
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


def check_energy(result, plan, kinetic_peak: float | None) -> None:
    """Record ``info["energy_check"]`` and warn when a conservative model's drift
    exceeds DRIFT_FRACTION of ``kinetic_peak`` (module docstring)."""
    info = result.info
    reason = energy_exchange(plan)
    drift = info.get("energy_drift")
    check = {"conservative": reason is None, "reason": reason,
             "kinetic_energy_peak": kinetic_peak, "drift_fraction": None}
    info["energy_check"] = check
    if reason is not None or drift is None or not kinetic_peak or kinetic_peak <= 0.0:
        return
    fraction = float(drift) / float(kinetic_peak)
    check["drift_fraction"] = fraction
    if not fraction > DRIFT_FRACTION:
        return
    e = np.asarray(result["energy"], float) + energy_losses(result.t, result.events)
    at = float(np.asarray(result.t)[int(np.argmax(np.abs(e - e[0])))])
    text = (f"the energy changed by {float(drift):.3g} ({fraction:.1%} of the largest "
            f"kinetic energy, {kinetic_peak:.3g}; worst at t = {at:.6g}) in a model that "
            f"conserves it (no dampers, drivers, torques or loads of time): the steps "
            f"did not follow the motion, although the constraints hold; rerun with a "
            f"smaller --dt or --method dopri5 and compare before using this result "
            f"(docs/reliability.md, \"Energy\")")
    info.setdefault("warnings", []).append(text)
    warnings.warn(text, RunWarning, stacklevel=3)
