"""``simulate(error=E)``: pilot, choice, the run, its global error estimate
(fccgen.target_error.estimate), and one repeat when the estimate ends above E.

The pilot sees only the first tenth of the run, so its prediction of the error at
t_end extrapolates the error's growth in time; a motion that speeds up later grows its
error faster than the pilot saw (Andrews' mechanism: its crank turns about 20 times
faster at the end than at the end of the pilot). The estimate sees the whole run: when it
ends above E, the run is repeated once at the setting the estimate names (its
truncation part scaled by the measured order), the first run serving as the repeat's
coarse twin, and that run and its estimate are the result; when the repeat's estimate did not fall as the order says, the error does not
converge with the step there, and the run says so rather than promising.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from ..errors import FccgenError, RunWarning, SimulationError
from . import estimate as estimates
from . import pilot as pilots
from .choice import (CANDIDATES, RTOL_MAX, RTOL_MIN, SAFETY, Choice, choose, predict,
                     twin_factor, twin_setting)
from .compare import compared
from .estimate import singular_warning
from .ladder import measure
from .pilot import KAPPA, evaluations
from .singular import approach, approach_warning

DEFAULT_OUTPUTS = 500      # output times of a run that names no output_dt
# Differences of pilot runs below NOISE eps L are rounding, not truncation: runs of
# the examples agree to 1e-13 L where their truncation errors are far smaller.
NOISE = 1000.0
EPS = float(np.finfo(float).eps)
# simulate() keywords the error target chooses itself
CHOSEN = ("dt", "rtol", "atol", "project")
STIFF_COST_EXPONENT = 0.1  # dopri5 steps that barely grow as rtol loosens: stability-bound
STIFF_MIN_STEPS = 50       # ... read from its finest pilot rung when it took this many
# A fixed-step candidate stops measuring when its most optimistic prediction costs more
# than this multiple of dopri5's: its order, measured above 4 on A02 (4.9), can make
# the full fit up to 1.2 times cheaper than the optimistic one at order 4.
DOMINANCE = 1.25
# A wide twin (choice.WIDE_TWIN) is checked against the classic one over the pilot's
# piece; when that piece, in whole output intervals of the wide twin, is more than this
# share of the run, the check would cost what the wide twin saves: the classic one runs.
CHECK_SHARE = 0.25
WIDE_FAILURES = (FccgenError, ArithmeticError, np.linalg.LinAlgError)
# A repeat that fails (dopri5's step underflows at A02's first flat position at the
# tightest tolerance) leaves the first run as the result, with a warning that says so.
REPEAT_FAILURES = (SimulationError, ArithmeticError, np.linalg.LinAlgError)


def simulate_to_error(solver, error, error_on=None, *, t_end=None, output_dt=None,
                      method=None, q0=None, v0=None, progress=None, reactions=True,
                      event_tol=None, rest_speed=None, event_location=None, **chosen):
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
                                                        ("rest_speed", rest_speed),
                                                        ("event_location", event_location))
                                      if v is not None},
                         progress=progress)
    fits = measure_candidates(frame, error, [method] if method else None,
                              bool(plan.model.events))
    sampled = next((f.finest for f in fits if f.finest is not None), None)
    frame.singular = approach(solver, sampled) if sampled is not None else None
    choice = choose(fits, error, t_end, output_dt)
    if progress is not None:
        progress(f"error target {error:g}: {choice.reason}")
    options = dict(progress=progress, reactions=reactions)
    result, twin, found = _attempt(solver, frame, choice, **options)
    first = failed = None
    if found.value > error:
        again = _repeat(choice, found, error, output_dt)
        if again is not None:
            if progress is not None:
                progress(f"error target {error:g}: {again.reason}")
            spent = (pilots.evaluations(result.info) + pilots.evaluations(twin.info)
                     + (found.check or {}).get("cost", 0))
            reuse = (choice.value / again.value) ** again.order >= estimates.MIN_RATIO
            try:
                repeated = _attempt(solver, frame, again,
                                    twin=(result, choice.value) if reuse else None,
                                    **options)
            except REPEAT_FAILURES as exc:
                # the first run is finished work: it stays the result, and says why
                failed = (again, " ".join(str(exc).split()))
            else:
                first = (choice, found, spent)
                choice = again
                result, twin, found = repeated
    report(result, twin, frame, choice, found, error, first, failed)
    return result


def _attempt(solver, frame, choice, progress, reactions, twin=None):
    """The run at the choice, its coarse twin and the estimate they give; twin:
    (result, setting) of a coarser run already made (a repeat's first run), which
    then serves as the twin."""
    run_kwargs = pilots.settings_of(choice.method, choice.value, solver.length_scale)
    result = solver.simulate(t_end=frame.t_end, output_dt=frame.output_dt,
                             method=choice.method, q0=frame.q0, v0=frame.v0,
                             progress=progress, reactions=reactions,
                             **frame.run_options, **run_kwargs)
    if twin is not None:
        twin, twin_value = twin
        return result, twin, estimates.global_estimate(result, twin, frame, choice,
                                                       twin_value, reused=True)
    factor = twin_factor(choice.method, choice.value, choice.fit)
    classic = twin_setting(choice.method, choice.value, frame.output_dt)
    check = None
    if factor != KAPPA[choice.method]:
        wide_value, wide_out = twin_setting(choice.method, choice.value, frame.output_dt,
                                            factor)
        t_check = wide_out * math.ceil(frame.t_piece / wide_out - 1e-9)
        if t_check <= CHECK_SHARE * frame.t_end:
            # both twins over the piece first: the whole wide twin runs only if they agree
            check = _check_wide(frame, choice, result, (wide_value, wide_out), classic,
                                t_check)
            twin = None
            if check["ok"] is not False:
                try:
                    twin = frame.run(choice.method, wide_value, frame.t_end, wide_out,
                                     stage="error estimate")
                except WIDE_FAILURES as exc:
                    check.update(ok=False, failed=" ".join(str(exc).split()))
            if twin is not None:
                found = estimates.global_estimate(result, twin, frame, choice, wide_value)
                found.check = check
                return result, twin, found
            check.update(replaced=wide_value)
    twin_value, twin_out = classic
    twin = frame.run(choice.method, twin_value, frame.t_end, twin_out,
                     stage="error estimate")
    found = estimates.global_estimate(result, twin, frame, choice, twin_value)
    found.check = check
    return result, twin, found


def _check_wide(frame, choice, result, wide, classic, t_check: float) -> dict:
    """estimate.piece_check of the wide twin against the classic one over [0, t_check]
    (both run there), with the cost of the two short runs; a wide twin that fails
    (leaves the motion, the step underflows) fails the check."""
    try:
        pieces = [frame.run(choice.method, value, t_check, out,
                            stage="error estimate check") for value, out in (wide, classic)]
    except WIDE_FAILURES as exc:
        return dict(wide=math.inf, classic=math.nan, t_check=t_check, ratio=math.nan,
                    ok=False, cost=0.0, failed=" ".join(str(exc).split()))
    check = estimates.piece_check(result, *pieces, frame, choice, wide[0], classic[0],
                                  t_check)
    check.update(cost=sum(evaluations(p.info) for p in pieces))
    return check


def _repeat(choice, found, error: float, output_dt: float):
    """The choice of the repeated run: the setting the estimate names, when one is
    named and it is finer than the first run's; None otherwise."""
    s = estimates.rescaled(choice, found, error)
    if s is None:
        return None
    if choice.method == "dopri5":
        s = min(RTOL_MAX, max(RTOL_MIN, s))
    else:
        s = pilots.fixed_step(output_dt, s)
    if not s < choice.value * (1 - 1e-9):
        return None
    again = Choice(choice.method, choice.setting, s, SAFETY * error,
                   math.nan, choice.order, roundoff=choice.roundoff,
                   candidates=choice.candidates, fit=choice.fit)
    again.reason = (f"{again.label}, repeated: {choice.label} ended with an estimated "
                    f"error {found.value:.2g} above the target (the pilot sees the first "
                    f"part of the run only); {again.setting} scaled by the order "
                    f"{choice.order:.3g} from that estimate. First choice: {choice.reason}")
    return again


def _checked(check, choice) -> str:
    """What the check over the pilot's piece said of a wide twin (estimate.piece_check)."""
    if check is None:
        return ""
    where = f"over [0, {check['t_check']:.4g}]"
    if check.get("failed"):
        return (f"; a wider twin ({choice.setting} = {check['replaced']:.4g}) failed "
                f"({check['failed']}), so it was not used")
    if check.get("replaced") is not None:
        return (f"; a wider twin ({choice.setting} = {check['replaced']:.4g}) estimated "
                f"{check['wide']:.3g} {where} where this twin estimated "
                f"{check['classic']:.3g}, so it was not used")
    if check["ok"] is None:
        return (f"; checked {where} against this twin's setting: both at the "
                "projections' noise there")
    return (f"; {where} its estimate was {check['ratio']:.3g} times that of a twin at "
            "the classic setting (twice the step, or a tolerance 16 times looser)")


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
    """Pilot fits of dopri5 and rk4 (the step of rk4's rungs from dopri5's, its rungs
    judged by dopri5's finest when that is accurate enough, and stopped when it cannot
    be the cheapest), and of ali3p when the model is stiff for them (dopri5's
    evaluations grow less than rtol^-0.1 as its tolerance tightens, where accuracy alone
    gives rtol^-0.2: its steps are held by stability; or rk4's coarse rung diverges)
    and has no events."""
    names = list(only) if only else ["dopri5", "rk4"]
    for name in names:
        if name not in CANDIDATES:
            raise ValueError(f"error=: method {name!r} cannot be chosen by an error "
                             f"target; choose among {', '.join(CANDIDATES)}")
    growth = frame.t_end / frame.t_piece
    tol = min(1e-5, max(1e-10, error / (frame.length_scale * 5 * growth)))
    fits, step, dopri = [], None, None
    aim = (SAFETY * error, frame.t_end)
    if "dopri5" in names:
        dopri = measure(frame, "dopri5", tol, aim=aim)
        fits.append(dopri)
        if dopri.rungs:
            steps = dopri.rungs[min(1, len(dopri.rungs) - 1)][2]
            step = frame.t_piece / max(steps, 1)
    step = step or frame.output_dt / 8
    if "rk4" in names:
        fits.append(measure(frame, "rk4", step / 2, reference=dopri, aim=aim,
                            can_win=None if only else _can_win(frame, dopri, error)))
    if "ali3p" in names or (not only and not has_events and _stiff(fits)):
        fits.append(measure(frame, "ali3p", 4 * step, reference=dopri, aim=aim))
    share_growth(fits)
    return fits


def _can_win(frame, dopri, error: float):
    """can_win for the fixed-step candidates: the reason a trial fit cannot be the
    cheapest, when even its most optimistic prediction costs more than DOMINANCE times
    dopri5's (predicted to meet the target); None when dopri5 is not."""
    if dopri is None or dopri.status != "ok":
        return None
    best = predict(dopri, error, frame.t_end, frame.output_dt)
    if best["predicted_error"] > error:
        return None

    def why(trial):
        mine = predict(trial, error, frame.t_end, frame.output_dt)
        if mine["predicted_cost"] <= DOMINANCE * best["predicted_cost"]:
            return None
        return (f"not measured further: at best about {mine['predicted_cost']:.3g} "
                f"evaluations with its estimate ({trial.setting} = {mine['value']:.3g}), "
                f"dopri5 about {best['predicted_cost']:.3g}")
    return why


def share_growth(fits) -> None:
    """The error's growth in time belongs to the problem: every candidate takes the
    one measured on the fixed-step rk4 pilot, whose difference history is the
    smoothest (an adaptive step adds its own ripple), when rk4 was measured."""
    ref = next((f for f in fits if f.method == "rk4" and f.judged_by
                and f.status in ("ok", "skipped")), None)
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


def report(result, twin, frame, choice, found, error: float, first, failed=None) -> None:
    """The estimate, the choice and the costs into result.info, and the warnings;
    failed: (the repeat's choice, why it failed) when a repeat was tried and failed."""
    info = result.info
    info["error_target"] = error
    info["error_estimate"] = found.value
    info["error_estimate_time"] = found.time
    info["error_on"] = frame.what.columns
    events = found.events or dict(event_time_error=math.nan, event_position_error=math.nan)
    check = found.check
    cost = dict(pilot=frame.cost, run=pilots.evaluations(info),
                estimate=0.0 if found.reused else (pilots.evaluations(twin.info)
                                                   + (check or {}).get("cost", 0)),
                repeat=first[2] if first else 0.0)
    cost["whole"] = sum(cost.values())
    info["accuracy"] = dict(
        choice=choice.reason, method=choice.method, setting=choice.setting,
        value=choice.value, predicted_error=choice.predicted_error,
        estimate=("Richardson: the distance of a coarse twin run "
                  f"({choice.setting} = {found.twin_value:.4g}"
                  f"{', the first run' if found.reused else ''}) on the same output "
                  f"times, divided by {found.ratio:.4g} - 1" + _checked(check, choice)),
        twin_check=check,
        order=choice.order, twin_value=found.twin_value, pilot_piece=frame.t_piece,
        roundoff=found.roundoff, candidates=choice.candidates, **events,
        singular_approach=frame.singular,
        repeated=(dict(value=first[0].value, estimate=first[1].value,
                       estimate_time=first[1].time) if first else None),
        repeat_failed=(dict(value=failed[0].value, error=failed[1]) if failed else None),
        cost=cost)
    texts = list(found.texts)
    if found.value > error:
        text = (f"the estimated error {found.value:.2g} exceeds the target {error:g} "
                f"(largest at t = {found.time:.6g}); ")
        if failed:
            text += (f"a repeat at {failed[0].label} failed ({failed[1]}), so the result "
                     f"is the first run ({choice.label}) and its estimate; another method "
                     "(method=) may reach the target")
        elif first and not estimates.converged(first[0], choice, first[1], found):
            text += (f"it fell only from {first[1].value:.2g} ({first[0].label}) where "
                     f"the order {choice.order:.3g} says about "
                     f"{SAFETY * error:.2g}: the error does not fall with the step here "
                     "(singular positions, a branch point of the motion, chaos), so "
                     "the estimate is not a promise")
        else:
            text += estimates.would_reach(choice, found, error, frame.output_dt,
                                          predicted=first is None)
        texts.append(text)
    texts += singular_warning(info)
    texts += approach_warning(frame.singular, found.value)
    info.setdefault("warnings", []).extend(texts)
    for text in texts:
        warnings.warn(text, RunWarning, stacklevel=4)
