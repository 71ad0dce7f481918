"""The pilot's data: what a candidate's short runs measured (:class:`Fit`: how its
error falls with its setting, how fast it grows over the run, what a step costs), the
frame the pilot and the run share (:class:`Pilot`), and the fit of order, error
constant and growth from the rungs' error histories. Which rungs run is
fccgen.target_error.ladder's business.

If the error is ``C s^a``, the difference of rungs at ``kappa s`` and ``s`` is
``C s^a (kappa^a - 1)`` and the ratio of two neighbouring differences is ``kappa^a``
(step doubling): the order ``a`` is measured, not assumed; with a reference run more
accurate than the rungs, their distances from it are their errors and two rungs give
order and constant. The error's history over the piece gives its growth in time,
fitted as ``t^beta``. Costs are deterministic counts (:func:`evaluations`), never
seconds, so a choice is the same on every machine.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..progress import restaged

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
PILOT_SAMPLES = 10           # the pilot records at least this many times in its piece
# Round-off: every step leaves a rounding error that no smaller step removes, and
# more steps add more of it. Measured on A01 (pendulum, 2000 s, closed-form
# reference): rk4 at dt = 1e-4 and 5.5e-5 ends 1.6e-9 and 2.6e-9 m off, where its
# truncation error is below 1e-11: 8e-17 and 7e-17 m per step, about 0.35 eps L.
# Predictions and estimates add ROUNDOFF_PER_STEP * eps * L per step (docs/accuracy.md).
ROUNDOFF_PER_STEP = 0.5
ATOL_RATIO = 1e-3            # dopri5: atol = rtol * ATOL_RATIO * length scale
# A reference run judges a rung directly when its own estimated error is at most this
# share of the rung's: the rung's measured error is then within 10 % of its own.
REFERENCE_MARGIN = 10.0


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
    # (setting, evaluations, steps, rejected) over the piece, coarsest first
    rungs: list = field(default_factory=list)
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
    judged_by: str = ""            # "rungs" (step doubling) or the reference's label
    finest: object = field(default=None, repr=False)    # the finest rung's result
    reach_rung: int = 0            # the rung the choice may extrapolate from (its index)

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
                "roundoff", "judged_by", "rungs", "reach_rung")
        return {k: getattr(self, k) for k in keys}

    @property
    def reach(self) -> float:
        """The coarsest setting whose rung the choice extrapolates from
        (choice.EXTRAPOLATION, choice.twin_factor)."""
        return self.rungs[self.reach_rung][0]

    @property
    def finest_error(self) -> float:
        """The estimated error of the finest rung over the piece."""
        if self.status != "ok" or not self.rungs:
            return math.inf
        return self.err0 * (self.rungs[-1][0] / self.s0) ** self.order


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
    run_options: dict = field(default_factory=dict)    # event_tol, rest_speed, event_location
    progress: object = None
    cost: float = 0.0              # evaluations spent in pilot runs
    singular: dict | None = None   # singular.approach of the pilot's positions

    @property
    def sample_dt(self) -> float:
        """The pilot's output interval: the run's, divided so that a tenth of the run
        holds at least PILOT_SAMPLES of them (the growth in time is fitted to the
        second half of them); fixed steps of the pilot divide it, so they divide the
        run's output interval too."""
        piece = self.t_end * PILOT_FRACTION
        return self.output_dt / max(1, math.ceil(PILOT_SAMPLES * self.output_dt / piece
                                                 - 1e-9))

    @property
    def t_piece(self) -> float:
        """The pilot piece [0, t_piece]: a tenth of the run, in whole sample_dt."""
        n = math.ceil(self.t_end * PILOT_FRACTION / self.sample_dt - 1e-9)
        return min(self.t_end, n * self.sample_dt)

    def run(self, method: str, setting: float, t_end: float, output_dt=None,
            stage: str = "pilot"):
        """One quiet run (its warnings are the pilot's business, not the user's)."""
        kwargs = dict(t_end=t_end, output_dt=output_dt or self.sample_dt, method=method,
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


def fit_rungs(fit: Fit, pilot: Pilot, histories, kappa: float,
              direct: bool = False, growth_of=None) -> None:
    """Order, error constant, growth and cost law from two error histories: the
    differences of neighbouring rungs (coarse-middle, middle-fine), or with ``direct``
    the errors of the coarse and the middle rung against a reference. growth_of: the
    history the growth is fitted to (default: the first)."""
    (t, d1), (_, d2) = histories
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
        fit.note = "; ".join(filter(None, (
            fit.note, "the pilot's finest rungs agree to the projections' noise: the "
            "order was not measured, the method's nominal order is used")))
    ratio = kappa ** fit.order
    fit.s0 = fit.rungs[rung][0]
    # error of a rung = its difference from the next finer rung * R / (R - 1), or its
    # distance from the reference
    fit.err0 = max(e, pilot.noise) * (1.0 if direct else ratio / (ratio - 1))
    # growth belongs to the problem, not the setting: measured on the coarse pair (or
    # the coarse rung's error), whose difference stands furthest above the noise
    fit.growth = growth(*(growth_of or (t, d1)), pilot.noise)
    c0, c2 = fit.rungs[0][1], fit.rungs[-1][1]
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
