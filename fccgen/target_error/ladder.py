"""Which pilot rungs run, coarsest first, and when a candidate stops early.

Each candidate runs a pair: dopri5 at ``16 rtol`` and ``rtol``, a fixed-step method
(rk4, ali3p) at ``2h`` and ``h`` on the pilot's output times (fixed_pair). When a
reference (dopri5's finest rung) is at least REFERENCE_MARGIN times more accurate than
a fixed-step rung, the rung's distance from it is its error: the pair then gives order,
constant and growth, and no third rung runs. Otherwise a third rung runs where the
choice lies (_third): the pair alone, at the method's order, places the choice, and the
third rung is ``kappa`` times coarser than the pair, the cheapest rung, unless that
places the choice more than half a rung below the pair's finer rung; then it is
``kappa`` times finer. The rungs then bracket the setting the run will take (the
choice extrapolates no further than fccgen.target_error.choice.EXTRAPOLATION beyond
the coarsest rung that measured the method's order, _reach). A coarser rung that fails
gives way to the finer one. After each fixed-step rung, ``can_win`` sees the most
optimistic fit measured so far (the method's nominal order, no larger than any it can
measure); when it says the candidate cannot be the cheapest, no more rungs run and the
fit is "skipped", its growth measured all the same (the fixed-step history is the
smoothest one, see run.share_growth).
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import FccgenError
from .choice import ORDER_MATCH
from .compare import check_columns, distance
from .pilot import (KAPPA, NOMINAL_ORDER, PILOT_SAMPLES, REFERENCE_MARGIN,
                    ROUNDOFF_PER_STEP, Fit, Pilot, evaluations, fit_rungs, growth)


def measure(pilot: Pilot, method: str, s_mid: float, *, reference: Fit | None = None,
            aim: tuple[float, float] | None = None, can_win=None) -> Fit:
    """A candidate's fit from its rungs about s_mid over the pilot piece.

    reference: a measured candidate whose finest rung may judge this one's rungs;
    aim: (error, t_end) the choice will aim at (places dopri5's third rung);
    can_win: fit -> None, or the reason the candidate cannot be the cheapest."""
    fit = Fit(method, "rtol" if method == "dopri5" else "dt", pilot.t_piece)
    if method == "dopri5":
        _adaptive(pilot, fit, [KAPPA[method] * s_mid, s_mid], aim)
    else:
        usable = reference is not None and reference.status == "ok"
        _fixed(pilot, fit, fixed_pair(pilot, s_mid), reference if usable else None,
               can_win, aim)
    return fit


def fixed_pair(pilot: Pilot, s_mid: float) -> list:
    """The steps ``[2h, h]`` of a fixed-step candidate's pair about s_mid: h divides
    the pilot's output interval, or is a whole multiple of it as long as the coarse
    step still records PILOT_SAMPLES times in the piece (their difference history on
    those times gives the growth in time, run.share_growth)."""
    dt = pilot.sample_dt
    m = min(math.floor(s_mid / dt + 1e-9),
            math.floor(pilot.t_piece / (2 * PILOT_SAMPLES * dt) + 1e-9))
    if m >= 1:
        return [2 * m * dt, m * dt]
    n = max(2, 2 * math.ceil(dt / s_mid / 2 - 1e-9))   # even
    return [dt / (n // 2), dt / n]


def _adaptive(pilot: Pilot, fit: Fit, ladder: list, aim) -> None:
    results = [_rung(pilot, fit, s) for s in ladder]
    if None in results:
        return
    results = _third(pilot, fit, results, aim)
    if results is not None:
        _by_rungs(pilot, fit, results, KAPPA[fit.method])
        _reach(fit, ladder[0])


def _fixed(pilot: Pilot, fit: Fit, ladder: list, reference: Fit | None, can_win,
           aim) -> None:
    kappa = KAPPA[fit.method]
    coarse = _rung(pilot, fit, ladder[0])
    if coarse is None:
        return
    label = (f"{reference.method} {reference.setting} = {reference.rungs[-1][0]:.3g}"
             if reference is not None else "")
    judged = _judged(pilot, fit, coarse, reference)
    if judged is not None and _stops(fit, can_win, _trial(pilot, fit, 0, judged, 1.0,
                                                          label)):
        return
    mid = _rung(pilot, fit, ladder[1])
    if mid is None:
        return
    if judged is not None:
        judged_mid = _judged(pilot, fit, mid, reference)
        if judged_mid is not None:
            fit.judged_by = label
            fit_rungs(fit, pilot, [judged, judged_mid], kappa, direct=True)
            fit.finest = mid
            return
    pair = distance(coarse, mid, pilot.what, fit.t_piece)
    ratio = kappa ** NOMINAL_ORDER[fit.method]
    if _stops(fit, can_win, _trial(pilot, fit, 0, pair, ratio / (ratio - 1), "rungs")):
        return
    results = _third(pilot, fit, [coarse, mid], aim)
    if results is not None:
        # the growth from the pair on the pilot's own output times (a coarser third
        # rung records on fewer of them)
        _by_rungs(pilot, fit, results, kappa, growth_of=pair)
        _reach(fit, ladder[0])


def _reach(fit: Fit, pair_coarse: float) -> None:
    """A coarser third rung widens the settings the choice may take
    (choice.EXTRAPOLATION) only when the three rungs measured the method's order
    within ORDER_MATCH, or more: a lower one says the coarser rung may have left the
    range where the error follows the setting (dopri5 on Andrews' mechanism measures
    0.79 with a rung at 256 rtol), and the choice then extrapolates from the pair."""
    low = fit.measured_order < (1 - ORDER_MATCH) * NOMINAL_ORDER[fit.method]
    if fit.rungs[0][0] > pair_coarse * (1 + 1e-9) and low:
        fit.reach_rung = 1


def _judged(pilot: Pilot, fit: Fit, result, reference: Fit | None):
    """The error history of a rung against the reference, when the reference is
    accurate enough to judge it; None otherwise."""
    if reference is None:
        return None
    t, d = distance(result, reference.finest, pilot.what, fit.t_piece)
    return (t, d) if reference.finest_error * REFERENCE_MARGIN <= float(np.max(d)) else None


def _trial(pilot: Pilot, fit: Fit, rung: int, history, factor: float,
           judged_by: str) -> Fit:
    """The most optimistic fit of what is measured: rung ``rung``'s error (the history's
    largest value times ``factor``) at the method's nominal order."""
    t, d = history
    s, cost, steps, _ = fit.rungs[rung]
    return Fit(fit.method, fit.setting, fit.t_piece, rungs=list(fit.rungs), s0=s,
               err0=max(float(np.max(d)), pilot.noise) * factor,
               order=NOMINAL_ORDER[fit.method], cost0=cost, steps0=steps,
               growth=growth(t, d, pilot.noise), judged_by=judged_by,
               roundoff=ROUNDOFF_PER_STEP * float(np.finfo(float).eps) * pilot.length_scale)


def _stops(fit: Fit, can_win, trial: Fit) -> bool:
    """Whether the candidate stops here (can_win gave a reason): the fit is then
    "skipped", with the reason and the trial's growth."""
    why = can_win(trial) if can_win is not None and math.isfinite(trial.err0) else None
    if why:
        fit.status, fit.note = "skipped", why
        fit.growth, fit.judged_by = trial.growth, trial.judged_by
    return bool(why)


def _by_rungs(pilot: Pilot, fit: Fit, results: list, kappa: float,
              growth_of=None) -> None:
    fit.judged_by = "rungs"
    fit_rungs(fit, pilot, [distance(a, b, pilot.what, fit.t_piece)
                           for a, b in zip(results, results[1:])], kappa,
              growth_of=growth_of)
    fit.finest = results[-1]


def _third(pilot: Pilot, fit: Fit, results: list, aim) -> list | None:
    """The pair's results with the third rung, coarsest first, or None (the fit
    failed). The third rung lies where the choice does: ``kappa`` times coarser than
    the coarse rung (the cheapest rung) unless the pair places the choice more than
    half a rung (sqrt(kappa)) below its finer rung, else ``kappa`` times finer. A
    coarser rung that fails (it diverges, its step underflows) gives way to the finer
    one."""
    kappa = KAPPA[fit.method]
    coarse, fine = fit.rungs[0][0], fit.rungs[1][0]
    if aim is not None and (_provisional(fit, pilot, results, aim)
                            >= fine / math.sqrt(kappa)):
        kept = len(fit.rungs)
        third = _rung(pilot, fit, coarse * kappa)
        if third is not None and math.isfinite(
                float(np.max(distance(third, results[0], pilot.what, fit.t_piece)[1]))):
            fit.rungs.insert(0, fit.rungs.pop())
            return [third, *results]
        why = (fit.note if third is None
               else f"{fit.setting} = {coarse * kappa:.3g}: it left the motion")
        del fit.rungs[kept:]
        fit.status = "ok"
        fit.note = f"a coarser rung failed ({why}); a finer one ran"
    third = _rung(pilot, fit, fine / kappa)
    return None if third is None else [*results, third]


def _rung(pilot: Pilot, fit: Fit, s: float):
    """One rung's result (its cost and steps over the piece recorded in fit.rungs), or
    None with the fit marked failed (or unsupported) and why. A fixed step coarser
    than the pilot's output interval records on the multiples of it that it divides,
    over the piece rounded to them (its cost and steps scaled to the piece)."""
    t_end, out = fit.t_piece, None
    try:
        if fit.method != "dopri5":
            out = recording_interval(pilot.sample_dt, s)
            t_end = _span(pilot, fit.t_piece, out)
        r = pilot.run(fit.method, s, t_end, out)
    except (FccgenError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        fit.status = ("unsupported" if isinstance(exc, ValueError)
                      and "unknown method" in str(exc) else "failed")
        fit.note = f"{fit.setting} = {s:.3g}: " + " ".join(str(exc).split())
        return None
    if not fit.rungs:
        check_columns(pilot.what, r)
    cost = evaluations(r.info)
    pilot.cost += cost
    share = fit.t_piece / t_end
    fit.rungs.append((s, cost * share, int(round(r.info["steps"] * share)),
                      int(r.info.get("rejected_steps") or 0)))
    return r


def _span(pilot: Pilot, t_piece: float, out: float) -> float:
    """The piece in whole recording intervals: rounded up, or down where up would
    pass the end of the run."""
    n = math.ceil(t_piece / out - 1e-9)
    if n * out > pilot.t_end * (1 + 1e-9):
        n = math.floor(pilot.t_end / out + 1e-9)
    if n < 1:
        raise ValueError(f"a pilot step records every {out:g}, longer than the run")
    return n * out


def recording_interval(sample_dt: float, h: float) -> float:
    """The shortest multiple of the pilot's output interval that a fixed step h
    divides a whole number of times (h itself when h is a multiple of it)."""
    for k in range(1, 65):
        n = k * sample_dt / h
        if n >= 1 - 1e-9 and abs(n - round(n)) <= 1e-9 * n:
            return k * sample_dt
    raise ValueError(f"a pilot step {h:g} shares no output time with {sample_dt:g}")


def _provisional(fit: Fit, pilot: Pilot, results, aim) -> float:
    """The setting a fit of the first two rungs alone (the method's nominal order)
    would choose for ``aim`` = (error, t_end)."""
    t, d = distance(results[0], results[1], pilot.what, fit.t_piece)
    e = float(np.max(d))
    if not math.isfinite(e):
        return 0.0
    if e <= pilot.noise:             # the pair agrees to the noise: the choice lies above
        return math.inf
    ratio = KAPPA[fit.method] ** NOMINAL_ORDER[fit.method]
    trial = _trial(pilot, fit, 0, (t, d), ratio / (ratio - 1), "rungs")
    return trial.s0 * (aim[0] / trial.truncation_at(trial.s0, aim[1])) ** (1 / trial.order)
