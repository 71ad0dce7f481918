"""The pilot: short runs that measure, for each candidate method, how its error falls
with its setting, how fast it grows over the run, and what a step costs.

Each candidate runs over a piece of the run ``[0, T_p]`` at three settings, a ratio
``kappa`` apart (rk4 and ali3p: steps ``2h, h, h/2``; dopri5: tolerances
``16 rtol, rtol, rtol / 16``), all recording on the run's output times. The differences
of neighbouring rungs are step-doubling (Richardson) estimates: if the error is
``C s^a``, the difference of the rungs at ``kappa s`` and ``s`` is ``C s^a (kappa^a - 1)``
and the two differences' ratio is ``kappa^a``, so the order ``a`` is measured, not
assumed. The fine pair's difference over the piece gives the error's growth in time,
fitted as ``t^beta``. Costs are deterministic counts (:func:`evaluations`), never
seconds, so a choice is the same on every machine.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import FccgenError
from ..progress import restaged
from .compare import check_columns, distance

# Setting ratio between pilot rungs, and the nominal exponent of the error in the
# setting: rk4 error ~ dt^4, ali3p (trapezoidal rule) ~ dt^2, dopri5 with error-per-step
# control ~ rtol^1 (tolerance proportionality: h ~ rtol^(1/5) for its 5th-order step).
KAPPA = {"rk4": 2.0, "ali3p": 2.0, "dopri5": 16.0}
NOMINAL_ORDER = {"rk4": 4.0, "ali3p": 2.0, "dopri5": 1.0}
# Growth exponent limits: an error that accumulates grows at least like t (local
# errors add up; a phase error grows linearly); beyond t^4 the growth is fitted as is
# and the final estimate checks it.
GROWTH_MIN, GROWTH_MAX = 1.0, 4.0
PILOT_FRACTION = 1 / 10      # the pilot piece, as a share of the run
# Round-off: every step leaves a rounding error that no smaller step removes, and
# more steps add more of it. Measured on A01 (pendulum, 2000 s, closed-form
# reference): rk4 at dt = 1e-4 and 5.5e-5 ends 1.6e-9 and 2.6e-9 m off, where its
# truncation error is below 1e-11: 8e-17 and 7e-17 m per step, about 0.35 eps L.
# Predictions and estimates add ROUNDOFF_PER_STEP * eps * L per step (docs/accuracy.md).
ROUNDOFF_PER_STEP = 0.5
ATOL_RATIO = 1e-3            # dopri5: atol = rtol * ATOL_RATIO * length scale


def evaluations(info: dict) -> float:
    """A run's cost in evaluations, deterministic: right-hand-side evaluations
    (accelerations: assembly, factorisation and solve; for ali3p its kernel
    assemblies; rejected steps included), plus one per Newton iteration (each
    assembles the constraints and factorises: the projections of rk4 and dopri5, the
    Newton steps of ali3p), plus one velocity projection per step when projecting."""
    n = float(info["rhs_evaluations"]) + float(info.get("newton_iterations") or 0)
    if info.get("project"):
        n += float(info["steps"])
    return n


@dataclass
class Fit:
    """What the pilot measured of one candidate; predictions for the whole run."""
    method: str
    setting: str                   # "dt" or "rtol"
    t_piece: float
    rungs: list = field(default_factory=list)   # (setting, evaluations, steps, rejected)
    s0: float = math.nan           # middle rung's setting
    err0: float = math.nan         # its estimated error at the end of the piece
    order: float = math.nan        # error exponent used in predictions
    measured_order: float = math.nan
    cost0: float = math.nan        # middle rung's evaluations over the piece
    cost_exponent: float = 1.0     # evaluations ~ setting^-cost_exponent
    growth: float = 1.0            # error ~ t^growth
    status: str = "ok"             # ok | failed | unsupported
    note: str = ""

    steps0: float = math.nan       # middle rung's steps over the piece
    roundoff: float = 0.0          # round-off per step (length units)

    def truncation_at(self, s: float, t_end: float) -> float:
        return (self.err0 * (s / self.s0) ** self.order
                * (t_end / self.t_piece) ** self.growth)

    def steps_at(self, s: float, t_end: float) -> float:
        return self.steps0 * (s / self.s0) ** (-self.cost_exponent) * t_end / self.t_piece

    def error_at(self, s: float, t_end: float) -> float:
        """Predicted error at t_end: truncation plus round-off of every step."""
        return self.truncation_at(s, t_end) + self.roundoff * self.steps_at(s, t_end)

    def setting_for(self, target: float, t_end: float) -> float:
        """The largest (cheapest) setting whose predicted error at t_end is at most
        ``target``; where round-off keeps every setting above it, the setting of the
        smallest predicted error."""
        s1 = self.s0 * (target / self.truncation_at(self.s0, t_end)) ** (1 / self.order)
        grid = s1 * np.logspace(-3, 1, 401)
        err = np.array([self.error_at(s, t_end) for s in grid])
        ok = np.flatnonzero(err <= target)
        return float(grid[ok[-1]] if ok.size else grid[int(np.argmin(err))])

    def cost_at(self, s: float, t_end: float) -> float:
        return self.cost0 * (s / self.s0) ** (-self.cost_exponent) * t_end / self.t_piece

    def as_dict(self) -> dict:
        keys = ("method", "setting", "status", "note", "s0", "err0", "order",
                "measured_order", "cost0", "steps0", "cost_exponent", "growth", "t_piece",
                "roundoff")
        return {k: getattr(self, k) for k in keys}


@dataclass
class Pilot:
    """The shared frame of the pilot runs and the final run."""
    solver: object
    what: object                   # compare.Compared
    t_end: float
    output_dt: float
    q0: np.ndarray
    v0: np.ndarray
    length_scale: float
    noise: float                   # differences below this are the projections' noise
    run_options: dict = field(default_factory=dict)    # event_tol, rest_speed
    progress: object = None
    cost: float = 0.0              # evaluations spent in pilot runs

    @property
    def t_piece(self) -> float:
        n = max(2, math.ceil(self.t_end * PILOT_FRACTION / self.output_dt - 1e-9))
        return min(self.t_end, n * self.output_dt)

    def run(self, method: str, setting: float, t_end: float, output_dt=None,
            stage: str = "pilot"):
        """One quiet run (its warnings are the pilot's business, not the user's)."""
        kwargs = dict(t_end=t_end, output_dt=output_dt or self.output_dt, method=method,
                      q0=self.q0, v0=self.v0, reactions=False,
                      progress=restaged(self.progress, f"{stage} {method}"),
                      **self.run_options)
        kwargs.update(settings_of(method, setting, self.length_scale))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with np.errstate(all="ignore"):
                return self.solver.simulate(**kwargs)


def settings_of(method: str, s: float, length_scale: float) -> dict:
    """simulate() keywords of a method at setting s."""
    if method == "dopri5":
        return dict(rtol=s, atol=s * ATOL_RATIO * length_scale, project=True)
    if method == "ali3p":
        return dict(dt=s)
    return dict(dt=s, project=True)


def fixed_step(output_dt: float, h: float) -> float:
    """The largest step at most h that divides output_dt a whole number of times."""
    return output_dt / max(1, math.ceil(output_dt / h - 1e-9))


def measure(pilot: Pilot, method: str, s_mid: float) -> Fit:
    """Run a candidate's three rungs about s_mid over the piece and fit its error."""
    kappa = KAPPA[method]
    fit = Fit(method, "rtol" if method == "dopri5" else "dt", pilot.t_piece)
    if method == "dopri5":
        ladder = [s_mid * kappa, s_mid, s_mid / kappa]
    else:
        n = max(2, 2 * math.ceil(pilot.output_dt / s_mid / 2 - 1e-9))   # even
        ladder = [pilot.output_dt / (n // 2), pilot.output_dt / n, pilot.output_dt / (2 * n)]
    results = []
    for s in ladder:
        try:
            r = pilot.run(method, s, fit.t_piece)
        except (FccgenError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            fit.status = ("unsupported" if isinstance(exc, ValueError)
                          and "unknown method" in str(exc) else "failed")
            fit.note = f"{fit.setting} = {s:.3g}: " + " ".join(str(exc).split())
            return fit
        if not results:
            check_columns(pilot.what, r)
        cost = evaluations(r.info)
        pilot.cost += cost
        fit.rungs.append((s, cost, int(r.info["steps"]), int(r.info.get("rejected_steps") or 0)))
        results.append(r)
    _fit(fit, pilot, [distance(a, b, pilot.what, fit.t_piece)
                      for a, b in zip(results, results[1:])], kappa)
    return fit


def _fit(fit: Fit, pilot: Pilot, diffs, kappa: float) -> None:
    """Order, error constant, growth and cost law from the rung differences."""
    (t, d1), (_, d2) = diffs
    e1, e2 = float(np.max(d1)), float(np.max(d2))
    nominal = NOMINAL_ORDER[fit.method]
    if not (math.isfinite(e1) and math.isfinite(e2)):
        fit.status, fit.note = "failed", "a pilot run left the motion (non-finite state)"
        return
    rung, e = 1, e2                  # the middle rung, judged by the fine one
    if e2 > pilot.noise and e1 > e2:
        fit.measured_order = math.log(e1 / e2) / math.log(kappa)
        # Never more optimistic than the method's order; at least half of it (a lower
        # measured order is a pre-asymptotic pilot, not the method).
        fit.order = min(nominal, max(0.5 * nominal, fit.measured_order))
    else:
        fit.order = nominal
        if e1 > pilot.noise:         # the coarse rung, judged by the middle one
            rung, e = 0, e1
        fit.note = ("the pilot's finest rungs agree to the projections' noise: the order "
                    "was not measured, the method's nominal order is used")
    ratio = kappa ** fit.order
    fit.s0 = fit.rungs[rung][0]
    # error of a rung = its difference from the next finer rung * R / (R - 1)
    fit.err0 = max(e, pilot.noise) * ratio / (ratio - 1)
    # growth belongs to the problem, not the setting: measured on the coarse pair,
    # whose difference stands furthest above the noise
    fit.growth = growth(t, d1, pilot.noise)
    c0, c2 = fit.rungs[0][1], fit.rungs[2][1]
    fit.cost0, fit.steps0 = fit.rungs[rung][1], fit.rungs[rung][2]
    fit.roundoff = ROUNDOFF_PER_STEP * float(np.finfo(float).eps) * pilot.length_scale
    if fit.method == "dopri5":
        b = math.log(c2 / c0) / math.log(kappa ** 2) if c0 > 0 else 0.2
        fit.cost_exponent = min(0.5, max(0.05, b))
    else:
        fit.cost_exponent = 1.0


def growth(t: np.ndarray, d: np.ndarray, noise: float) -> float:
    """The exponent beta of the error's growth ``t^beta``: the slope of a least-squares
    line through log(envelope) against log(t) over the second half of the piece (the
    envelope is the running largest value of a difference history)."""
    env = np.maximum.accumulate(d)
    keep = (t >= t[-1] / 2) & (t > 0) & (env > noise)
    if np.count_nonzero(keep) < 3:
        return GROWTH_MIN
    beta = float(np.polyfit(np.log(t[keep]), np.log(env[keep]), 1)[0])
    return min(GROWTH_MAX, max(GROWTH_MIN, beta))
