"""The rule: of the candidates the pilot measured, the cheapest one expected to meet
the error target over the whole run.

For each candidate the pilot's fit (:class:`~fccgen.target_error.pilot.Fit`) gives the
setting whose predicted error at t_end is ``SAFETY * E`` (the error constant and order
it measured, extrapolated in time by the growth it measured), and that setting's cost
in evaluations: the run plus its coarse twin (the global error estimate). The cheapest
wins; ties go to the first in :data:`CANDIDATES` order.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .pilot import KAPPA, Fit, fixed_step

# Aim at half the target: the pilot's prediction is an extrapolation (in the setting
# and in time); the final estimate checks it. Halving the error costs 2^(1/4) = 1.19x
# the steps of rk4 and 2^(1/5) = 1.15x those of dopri5.
SAFETY = 0.5
RTOL_MIN, RTOL_MAX = 1e-13, 1e-3     # the tolerances the choice may take
CANDIDATES = ("dopri5", "rk4", "ali3p")


@dataclass
class Choice:
    method: str
    setting: str                  # "dt" or "rtol"
    value: float
    predicted_error: float
    predicted_cost: float         # evaluations of the run and its twin
    order: float                  # error exponent in the setting (for the estimate)
    roundoff: float = 0.0         # round-off per step (pilot.ROUNDOFF_PER_STEP)
    reason: str = ""
    candidates: list = field(default_factory=list)

    @property
    def label(self) -> str:
        return f"{self.method} with {self.setting} = {self.value:.4g}"


def twin_setting(method: str, value: float, output_dt: float) -> tuple[float, float]:
    """(setting, output_dt) of the coarse twin of a run: twice the step (on every
    output time when the doubled step still divides the output interval, else on
    every other one), or a tolerance KAPPA times looser."""
    if method == "dopri5":
        return value * KAPPA[method], output_dt
    n = round(output_dt / value)
    return 2 * value, (output_dt if n % 2 == 0 else 2 * output_dt)


def twin_share(fit: Fit) -> float:
    """The twin's cost as a share of the run's."""
    return KAPPA[fit.method] ** -fit.cost_exponent


def predict(fit: Fit, target: float, t_end: float, output_dt: float) -> dict:
    """The setting a candidate would take and what the fit predicts for it."""
    s = fit.setting_for(SAFETY * target, t_end)
    if fit.method == "dopri5":
        s = min(RTOL_MAX, max(RTOL_MIN, s))
    else:
        s = fixed_step(output_dt, s)
    run_cost = fit.cost_at(s, t_end)
    return dict(method=fit.method, setting=fit.setting, value=s,
                predicted_error=fit.error_at(s, t_end),
                predicted_roundoff=fit.roundoff * fit.steps_at(s, t_end),
                predicted_cost=run_cost * (1 + twin_share(fit)), run_cost=run_cost)


def choose(fits: list[Fit], target: float, t_end: float, output_dt: float) -> Choice:
    """The cheapest candidate predicted to meet the target; ValueError listing each
    candidate's failure when none could be measured."""
    rows = []
    for fit in fits:
        row = fit.as_dict()
        if fit.status == "ok":
            row.update(predict(fit, target, t_end, output_dt))
        rows.append(row)
    ok = [r for r in rows if r["status"] == "ok" and math.isfinite(r["predicted_cost"])]
    if not ok:
        raise ValueError("no method could be measured for the error target: "
                         + "; ".join(f"{r['method']}: {r['note']}" for r in rows))
    meets = [r for r in ok if r["predicted_error"] <= target]
    best = (min(meets, key=lambda r: r["predicted_cost"]) if meets
            else min(ok, key=lambda r: r["predicted_error"]))
    fit = next(f for f in fits if f.method == best["method"])
    choice = Choice(best["method"], best["setting"], best["value"],
                    best["predicted_error"], best["predicted_cost"], fit.order,
                    roundoff=fit.roundoff, candidates=rows)
    others = "; ".join(f"{r['method']}: {_line(r)}" for r in rows if r is not best)
    choice.reason = (f"{choice.label}: predicted error {best['predicted_error']:.2g} "
                     f"(target {target:.3g}) for about {best['predicted_cost']:.3g} "
                     f"evaluations with its estimate, the cheapest"
                     + ("" if meets else " (none is predicted to meet the target: this "
                              "one comes closest)")
                     + (f"; {others}" if others else ""))
    return choice


def _line(row: dict) -> str:
    if row["status"] != "ok":
        return f"{row['status']} in the pilot ({row['note']})"
    return (f"{row['setting']} = {row['value']:.3g}, about {row['predicted_cost']:.3g} "
            "evaluations")
