"""The global error estimate of an error-target run, and what it says.

The estimate is Richardson's: the run is repeated coarser (twice the step, or a
tolerance 16 times looser) on the same output times, and the distance of the two runs,
divided by ``R - 1`` where ``R`` is the ratio of their errors (``2^p``, or ``16^a``
with the exponent the pilot measured), estimates the run's own error at every output
time. A run repeated at a finer setting (fccgen.target_error.run) takes its first run
as that twin, with ``R`` the ratio of the two settings to the measured order. Event times are compared the same way: a latch the coarse twin finds later by
``dt`` was found ``dt / (R - 1)`` late by the run, and moves every position after it
by about that time times the speed at the event (docs/accuracy.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import pilot as pilots
from .choice import SAFETY
from .compare import distance, event_times, speeds

# A repeated run whose estimate stays above this multiple of what the measured order
# predicts from the first run's has an error that does not fall with the step.
CONVERGENCE_SLACK = 4.0
# A repeated run takes its first run as the coarse twin when the two settings' errors
# are predicted at least this ratio apart (a repeat aims at E / 2 from an estimate above
# E, so it always is unless a tolerance limit clamps it): the estimate then divides
# their distance by R - 1 >= 1, and no second twin runs.
MIN_RATIO = 2.0
# A wide twin (choice.WIDE_TWIN) whose estimate over the pilot's piece is more than
# PIECE_SLACK times off the classic twin's there is replaced by the classic one; below
# PIECE_NOISE times the projections' noise the piece cannot judge it.
PIECE_SLACK = 2.0
PIECE_NOISE = 10.0


@dataclass
class Estimate:
    """A run's estimated largest error, where it occurs, and its parts."""
    value: float
    time: float
    ratio: float                   # R: the twin's error over the run's
    roundoff: float
    twin_value: float
    events: dict | None            # event_time_error, event_position_error; None: differ
    texts: list = field(default_factory=list)      # what the estimate says (warnings)
    reused: bool = False           # the twin is the first run of a repeat (no cost)
    check: dict | None = None      # piece_check of a wide twin (None: the classic twin)


def global_estimate(result, twin, frame, choice, twin_value: float,
                    reused: bool = False) -> Estimate:
    """The Richardson estimate of a run from its coarse twin, with the event times:
    R = (twin's setting / run's setting) ** order (KAPPA ** order for a twin run for
    the purpose, at least MIN_RATIO for a first run reused as the twin)."""
    ratio = (twin_value / choice.value) ** choice.order
    t, d = distance(result, twin, frame.what, frame.t_end)
    roundoff = choice.roundoff * float(result.info["steps"])
    est = d / (ratio - 1) + roundoff
    k = int(np.argmax(est)) if len(est) else 0
    found = Estimate(float(est[k]) if len(est) else math.nan,
                     float(t[k]) if len(t) else math.nan, ratio, roundoff, twin_value,
                     event_errors(result, twin, frame.what, ratio), reused=reused)
    if found.events is None:
        found.texts.append(
            f"the run and its coarse twin ({choice.setting} = {twin_value:.3g}) found "
            f"different events ({_names(result)} against {_names(twin)}): the error "
            "estimate does not cover what the events change; tighten the target")
    elif found.events["event_position_error"] > found.value:
        found.value = found.events["event_position_error"]
    return found


def piece_check(result, wide, piece, frame, choice, wide_value: float,
                piece_value: float, t_check: float) -> dict:
    """A wide twin checked against an independent one: over [0, t_check] (the pilot's
    piece, in whole output intervals of the wide twin) the classic twin ``piece`` (twice
    the step, or a tolerance 16 times looser) runs too, and the two Richardson
    estimates of the run's error there must agree within PIECE_SLACK: a wide twin that
    left the range where the error follows the order (beyond its stability or its
    asymptotic range) disagrees. ``ok`` None: both are within PIECE_NOISE times the
    projections' noise, too small to judge."""
    found = []
    for twin, value in ((wide, wide_value), (piece, piece_value)):
        t, d = distance(result, twin, frame.what, frame.t_end)
        near = t <= t_check * (1 + 1e-9)
        ratio = (value / choice.value) ** choice.order
        found.append(float(np.max(d[near])) / (ratio - 1) if np.any(near) else math.nan)
    w, c = found
    out = dict(wide=w, classic=c, t_check=t_check, ratio=math.nan, ok=False)
    if not (math.isfinite(w) and math.isfinite(c)):
        return out
    if max(w, c) <= PIECE_NOISE * frame.noise:
        out["ok"] = None
        return out
    out["ratio"] = max(w, frame.noise) / max(c, frame.noise)
    out["ok"] = bool(1 / PIECE_SLACK <= out["ratio"] <= PIECE_SLACK)
    return out


def event_errors(result, twin, what, ratio: float):
    """Event time errors (None when the two runs' events differ in names or order):
    the largest |t - t_twin| / (R - 1), and it times the largest compared speed at the
    output times around the event (the position error a late event leaves)."""
    a, b = event_times(result), event_times(twin)
    if [n for n, _ in a] != [n for n, _ in b]:
        return None
    v = speeds(result, what)
    t = np.asarray(result.t)
    dt, dx = 0.0, 0.0
    for (_, ta), (_, tb) in zip(a, b):
        late = abs(ta - tb) / (ratio - 1)
        k = int(np.clip(np.searchsorted(t, ta), 1, len(t) - 1))
        dt, dx = max(dt, late), max(dx, late * float(max(v[k - 1], v[k])))
    return dict(event_time_error=dt, event_position_error=dx)


def _names(result) -> str:
    names = [n for n, _ in event_times(result)]
    return "[" + ", ".join(names) + "]" if names else "none"


def rescaled(choice, found: Estimate, error: float) -> float | None:
    """The setting of choice's method that the estimate says reaches SAFETY * error
    (the estimate's truncation part scaled by the measured order), or None when the
    round-off of the run's steps alone is too large for any."""
    if found.roundoff >= SAFETY * error or not math.isfinite(found.value):
        return None
    factor = (SAFETY * error / (found.value - found.roundoff)) ** (1 / choice.order)
    return choice.value * factor


def converged(first, retried, found_first: Estimate, found: Estimate) -> bool:
    """Whether a repeated run's estimate fell as the measured order says it should
    (within CONVERGENCE_SLACK) from the first run's."""
    expected = ((found_first.value - found_first.roundoff)
                * (retried.value / first.value) ** retried.order + found.roundoff)
    return found.value <= CONVERGENCE_SLACK * expected


def would_reach(choice, found: Estimate, error: float, output_dt: float,
                predicted: bool = True) -> str:
    """What would reach the target: a setting, or why none of this method does."""
    setting = rescaled(choice, found, error)
    if setting is None or (predicted and choice.predicted_error > SAFETY * error):
        return (f"no step of the candidates is predicted to reach it (the round-off of "
                f"this run's steps alone is about {found.roundoff:.2g}; the best "
                f"prediction was {choice.predicted_error:.2g}): this run is the closest "
                "one found")
    if choice.method == "dopri5":
        text = f"dopri5 with rtol = {setting:.2g}"
    else:
        text = f"{choice.method} with dt = {pilots.fixed_step(output_dt, setting):.4g}"
    return f"{text} would reach it (simulate(method=..., ...) or a tighter target)"


def singular_warning(info: dict) -> list[str]:
    """A warning when the run met singular positions (the runtime's rank signals):
    there a step may pick another branch, and no estimate is a promise."""
    drops = int(info.get("singular_position_factorisations") or 0)
    changes = info.get("dof_changes") or []
    if not drops and not changes:
        return []
    where = (f"{drops} factorisations dropped constraint rows" if drops else "")
    if changes:
        where += ("; " if where else "") + "degrees of freedom changed at t = " + ", ".join(
            f"{c['t']:.6g}" for c in changes[:5])
    return [f"the run passed singular positions of the constraints ({where}): near them "
            "a small error can choose another branch of the motion, so the error "
            f"estimate {info['error_estimate']:.2g} is not a promise there; compare with "
            "a run at a tighter target"]
