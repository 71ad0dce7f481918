"""``simulate(error=E)``: pilot, choice, the run, and its global error estimate.

The estimate is Richardson's: the run is repeated coarser (twice the step, or a
tolerance 16 times looser) on the same output times, and the distance of the two runs,
divided by ``R - 1`` where ``R`` is the ratio of their errors (``2^p``, or ``16^a``
with the exponent the pilot measured), estimates the run's own error at every output
time. Event times are compared the same way: a latch the coarse twin finds later by
``dt`` was found ``dt / (R - 1)`` late by the run, and moves every position after it
by about that time times the speed at the event (docs/accuracy.md).
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from ..errors import RunWarning
from . import pilot as pilots
from .choice import CANDIDATES, SAFETY, choose, twin_setting
from .compare import compared, distance, event_times, speeds

DEFAULT_OUTPUTS = 500      # output times of a run that names no output_dt
# Differences of pilot runs below NOISE eps L are rounding, not truncation: runs of
# the examples agree to 1e-13 L where their truncation errors are far smaller.
NOISE = 1000.0
EPS = float(np.finfo(float).eps)
# simulate() keywords the error target chooses itself
CHOSEN = ("dt", "rtol", "atol", "project")
STIFF_COST_EXPONENT = 0.1  # dopri5 steps that barely grow as rtol loosens: stability-bound
STIFF_MIN_STEPS = 50       # ... read from its finest pilot rung when it took this many


def simulate_to_error(solver, error, error_on=None, *, t_end=None, output_dt=None,
                      method=None, q0=None, v0=None, progress=None, reactions=True,
                      event_tol=None, rest_speed=None, **chosen):
    """A run whose largest position error over [0, t_end] is estimated to be at most
    ``error`` (model length units), with the method and setting the pilot chose
    (``method``: only that one is considered). ``result.info`` gets ``error_target``,
    ``error_estimate`` and ``accuracy`` (the choice, its reason, every candidate, the
    costs); an estimate above the target, singular positions and disagreeing events
    are warned about (RunWarning) and listed in ``info["warnings"]``."""
    error = _check_target(error, chosen)
    plan = solver.plan
    d = plan.model.simulate
    t_end = float(d.t_end if t_end is None else t_end)
    output_dt = float(output_dt or d.output_dt or t_end / DEFAULT_OUTPUTS)
    if q0 is None:
        init = solver.initial_state()
        q0, v0 = init.q, (init.v if v0 is None else v0)
    elif v0 is None:
        v0 = solver.project_velocities(q0, plan.v_target)
    frame = pilots.Pilot(solver, compared(plan, solver.length_scale, error_on), t_end,
                         output_dt, np.asarray(q0, float), np.asarray(v0, float),
                         solver.length_scale, noise=NOISE * EPS * solver.length_scale,
                         run_options={k: v for k, v in (("event_tol", event_tol),
                                                        ("rest_speed", rest_speed))
                                      if v is not None},
                         progress=progress)
    fits = measure_candidates(frame, error, [method] if method else None,
                              bool(plan.model.events))
    choice = choose(fits, error, t_end, output_dt)
    if progress is not None:
        progress(f"error target {error:g}: {choice.reason}")
    run_kwargs = pilots.settings_of(choice.method, choice.value, solver.length_scale)
    result = solver.simulate(t_end=t_end, output_dt=output_dt, method=choice.method,
                             q0=frame.q0, v0=frame.v0, progress=progress,
                             reactions=reactions, **frame.run_options, **run_kwargs)
    twin_value, twin_out = twin_setting(choice.method, choice.value, output_dt)
    twin = frame.run(choice.method, twin_value, t_end, twin_out, stage="error estimate")
    estimate(result, twin, frame, choice, error, twin_value)
    return result


def _check_target(error, chosen: dict) -> float:
    given = [k for k in CHOSEN if chosen.get(k) is not None]
    other = [k for k in chosen if k not in CHOSEN]
    if given or other:
        what = given + other
        raise ValueError(f"error={error!r} chooses the method's settings itself: leave "
                         f"out {', '.join(what)} (method= restricts the choice to one "
                         "method)")
    try:
        value = float(error)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"error must be a positive number, the largest position error "
                         f"accepted over the run in the model's length unit (got {error!r})")
    return value


def measure_candidates(frame, error: float, only, has_events: bool) -> list:
    """Pilot fits of dopri5 and rk4 (the step of rk4's rungs from dopri5's), and of
    ali3p when the model is stiff for them (dopri5's evaluations grow less than
    rtol^-0.1 as its tolerance tightens, where accuracy alone gives rtol^-0.2: its steps
    are held by stability; or rk4's coarse rung diverges) and has no events."""
    names = list(only) if only else ["dopri5", "rk4"]
    for name in names:
        if name not in CANDIDATES:
            raise ValueError(f"error=: method {name!r} cannot be chosen by an error "
                             f"target; choose among {', '.join(CANDIDATES)}")
    growth = frame.t_end / frame.t_piece
    tol = min(1e-5, max(1e-10, error / (frame.length_scale * 5 * growth)))
    fits, step = [], None
    if "dopri5" in names:
        fit = pilots.measure(frame, "dopri5", tol)
        fits.append(fit)
        if fit.rungs:
            steps = fit.rungs[min(1, len(fit.rungs) - 1)][2]
            step = frame.t_piece / max(steps, 1)
    step = step or frame.output_dt / 8
    if "rk4" in names:
        fits.append(pilots.measure(frame, "rk4", step / 2))
    if "ali3p" in names or (not only and not has_events and _stiff(fits)):
        fits.append(pilots.measure(frame, "ali3p", 4 * step))
    share_growth(fits)
    return fits


def share_growth(fits) -> None:
    """The error's growth in time belongs to the problem: every candidate takes the
    one measured on the fixed-step rk4 pilot, whose difference history is the
    smoothest (an adaptive step adds its own ripple), when rk4 was measured."""
    ref = next((f for f in fits if f.method == "rk4" and f.status == "ok"), None)
    if ref is not None:
        for fit in fits:
            fit.growth = ref.growth


def _stiff(fits) -> bool:
    d = next((f for f in fits if f.method == "dopri5"), None)
    r = next((f for f in fits if f.method == "rk4"), None)
    if r is not None and r.status == "failed" and "diverged" in r.note:
        return True
    if d is None or len(d.rungs) < 3:
        return False
    (s0, c0, _, _), _, (s2, c2, n2, _) = d.rungs
    # on a handful of steps the count is set by the output times, not the tolerance
    return (n2 >= STIFF_MIN_STEPS and c0 > 0
            and math.log(c2 / c0) / math.log(s0 / s2) < STIFF_COST_EXPONENT)


def estimate(result, twin, frame, choice, error: float, twin_value: float) -> None:
    """The run's global error estimate and what follows from it, into result.info."""
    ratio = pilots.KAPPA[choice.method] ** choice.order
    t, d = distance(result, twin, frame.what, frame.t_end)
    roundoff = choice.roundoff * float(result.info["steps"])
    est = d / (ratio - 1) + roundoff
    k = int(np.argmax(est)) if len(est) else 0
    value = float(est[k]) if len(est) else math.nan
    texts = []
    events = event_errors(result, twin, frame.what, ratio)
    if events is None:
        texts.append(
            f"the run and its coarse twin ({choice.setting} = {twin_value:.3g}) found "
            f"different events ({_names(result)} against {_names(twin)}): the error "
            "estimate does not cover what the events change; tighten the target")
        events = dict(event_time_error=math.nan, event_position_error=math.nan)
    elif events["event_position_error"] > value:
        value = events["event_position_error"]
    info = result.info
    info["error_target"] = error
    info["error_estimate"] = value
    info["error_estimate_time"] = float(t[k]) if len(t) else math.nan
    info["error_on"] = frame.what.columns
    info["accuracy"] = dict(
        choice=choice.reason, method=choice.method, setting=choice.setting,
        value=choice.value, predicted_error=choice.predicted_error,
        estimate=("Richardson: the distance of a coarse twin run "
                  f"({choice.setting} = {twin_value:.4g}) on the same output times, "
                  f"divided by {ratio:.4g} - 1"),
        order=choice.order, twin_value=twin_value, pilot_piece=frame.t_piece,
        roundoff=roundoff,
        candidates=choice.candidates, **events,
        cost=dict(pilot=frame.cost, run=pilots.evaluations(info),
                  estimate=pilots.evaluations(twin.info)))
    if value > error:
        texts.append(f"the estimated error {value:.2g} exceeds the target {error:g} "
                     f"(largest at t = {info['error_estimate_time']:.6g}); "
                     + _would_reach(choice, value, error, frame.output_dt, roundoff))
    texts += singular_warning(info)
    info.setdefault("warnings", []).extend(texts)
    for text in texts:
        warnings.warn(text, RunWarning, stacklevel=4)


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


def _would_reach(choice, value: float, error: float, output_dt: float,
                 roundoff: float) -> str:
    """What would reach the target: a setting, or why none of this method does."""
    if roundoff >= SAFETY * error or choice.predicted_error > SAFETY * error:
        return (f"no step of the candidates is predicted to reach it (the round-off of "
                f"this run's steps alone is about {roundoff:.2g}; the best prediction "
                f"was {choice.predicted_error:.2g}): this run is the closest one found")
    factor = (SAFETY * error / (value - roundoff)) ** (1 / choice.order)
    if choice.method == "dopri5":
        setting = f"dopri5 with rtol = {choice.value * factor:.2g}"
    else:
        setting = (f"{choice.method} with dt = "
                   f"{pilots.fixed_step(output_dt, choice.value * factor):.4g}")
    return f"{setting} would reach it (simulate(method=..., ...) or a tighter target)"



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
