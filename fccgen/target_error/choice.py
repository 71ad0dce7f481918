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

from .pilot import KAPPA, NOMINAL_ORDER, PILOT_FRACTION, Fit, fixed_step

# Aim at half the target: the pilot's prediction is an extrapolation (in the setting
# and in time); the final estimate checks it. Halving the error costs 2^(1/4) = 1.19x
# the steps of rk4 and 2^(1/5) = 1.15x those of dopri5.
SAFETY = 0.5
RTOL_MIN, RTOL_MAX = 1e-13, 1e-3     # the tolerances the choice may take
CANDIDATES = ("dopri5", "rk4", "ali3p")
# The coarsest setting the choice may take, as a multiple of the coarsest pilot rung
# that measured the method's order (Fit.reach):
# half a rung (dopri5) or two rungs (fixed steps) beyond what the pilot measured.
# Beyond it a method may leave its asymptotic range (dopri5 at loose tolerances: the
# error no longer follows the tolerance, and the twin's estimate with it; measured on
# Andrews' mechanism) or its stability (rk4 on the heavy top: stable at dt = 5 ms,
# diverging at 10 ms).
EXTRAPOLATION = {"dopri5": 4.0, "rk4": 4.0, "ali3p": 4.0}
# The coarse twin of the estimate, widest first: rk4 at 4, 3 or 2 times the run's step
# (a quarter, a third or half a run), dopri5 at a tolerance 256, 64 or 16 times looser
# (about 0.33, 0.44 or 0.57 of a run); the widest whose setting the pilot's rungs cover
# (twin_factor), checked on the pilot's piece (estimate.piece_check).
WIDE_TWIN = {"rk4": (4, 3, 2), "dopri5": (256.0, 64.0, 16.0)}
# ... only when the pilot measured an order within this share of the nominal one: a
# lower or higher one (A01 at 1e-3: rk4 3.5, A02: dopri5 0.77) is a pre-asymptotic
# range, where the wide twin's estimate was 2.2 to 2.9 times the classic one's.
ORDER_MATCH = 0.1


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
    fit: Fit | None = field(default=None, repr=False)   # the pilot's fit of the method

    @property
    def label(self) -> str:
        return f"{self.method} with {self.setting} = {self.value:.4g}"


def twin_factor(method: str, value: float, fit: Fit | None) -> float:
    """How much coarser the twin of a run is: the widest of WIDE_TWIN[method] whose
    setting stays within one pilot rung (KAPPA) beyond the pilot's coarsest rung, where
    the order the estimate divides by was measured (the fit's rungs), when the pilot
    measured the method's nominal order (within ORDER_MATCH: the rungs are in the
    asymptotic range); KAPPA (a step twice the run's, a tolerance 16 times looser)
    otherwise."""
    if (fit is None or not fit.rungs or method not in WIDE_TWIN
            or not abs(fit.measured_order / NOMINAL_ORDER[method] - 1) <= ORDER_MATCH):
        return KAPPA[method]
    bound = KAPPA[method] * fit.reach
    classic = twin_share(fit)
    # the check runs both twins over about the pilot's piece: worth it only if the wide
    # twin saves more than that (dopri5 on the solar array: its steps barely follow rtol)
    return next((k for k in WIDE_TWIN[method] if k * value <= bound * (1 + 1e-9)
                 and twin_share(fit, k) + PILOT_FRACTION * (twin_share(fit, k) + classic)
                 < classic), KAPPA[method])


def twin_setting(method: str, value: float, output_dt: float,
                 factor: float | None = None) -> tuple[float, float]:
    """(setting, output_dt) of the coarse twin of a run: ``factor`` (default KAPPA)
    times the step, on every output time the coarser step still divides (every
    m-th one otherwise), or a tolerance ``factor`` times looser."""
    k = KAPPA[method] if factor is None else factor
    if method == "dopri5":
        return value * k, output_dt
    n, k = round(output_dt / value), int(round(k))
    return k * value, output_dt * (k // math.gcd(n, k))


def twin_share(fit: Fit, factor: float | None = None) -> float:
    """The twin's cost as a share of the run's."""
    k = KAPPA[fit.method] if factor is None else factor
    return k ** -fit.cost_exponent


def predict(fit: Fit, target: float, t_end: float, output_dt: float) -> dict:
    """The setting a candidate would take and what the fit predicts for it."""
    s = min(fit.setting_for(SAFETY * target, t_end),
            EXTRAPOLATION[fit.method] * fit.reach)
    if fit.method == "dopri5":
        s = min(RTOL_MAX, max(RTOL_MIN, s))
    else:
        s = fixed_step(output_dt, s)
    run_cost = fit.cost_at(s, t_end)
    share = twin_share(fit, twin_factor(fit.method, s, fit))
    return dict(method=fit.method, setting=fit.setting, value=s,
                predicted_error=fit.error_at(s, t_end),
                predicted_roundoff=fit.roundoff * fit.steps_at(s, t_end),
                predicted_cost=run_cost * (1 + share), run_cost=run_cost)


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
                    roundoff=fit.roundoff, candidates=rows, fit=fit)
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
