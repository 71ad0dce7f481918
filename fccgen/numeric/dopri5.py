"""Dormand-Prince 5(4) in NumPy: the same algorithm as the compiled runtime's
_dopri5.pyx (Hairer, Norsett & Wanner, "Solving Ordinary Differential Equations I",
section II.5, code DOPRI5), written as plainly as possible to cross-check it.

FSAL stages, the RMS error norm with atol + rtol max(|y0|, |y1|) over y = (q, v), the
step factor 0.9 err^(-1/5) within [0.2, 10] (no growth right after a rejection),
Hairer's starting step, the 4th-order continuous extension for outputs, and (if
projecting) position then velocity projection after each accepted step and of each
interpolated output.
"""
from __future__ import annotations

import time

import numpy as np

from ..errors import SimulationError
from .runs import locate

A = [[],
     [1 / 5],
     [3 / 40, 9 / 40],
     [44 / 45, -56 / 15, 32 / 9],
     [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729],
     [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
     [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]]
C = [0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0]       # stage times (fractions of h)
E = np.array([71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])
D = np.array([-12715105075 / 11282082432, 0.0, 87487479700 / 32700410799,
              -10690763975 / 1880347072, 701980252875 / 199316789632,
              -1453857185 / 822651844, 69997945 / 29380423])
SAFETY, FACMIN, FACMAX = 0.9, 0.2, 10.0
UROUND = np.finfo(float).eps


def _initial_step(f, y, k1, t_end, rtol, atol):
    """Hairer's HINIT: h0 from |y|/|f|, refined with one more evaluation."""
    sk = atol + rtol * np.abs(y)
    d0, d1 = np.sqrt(np.mean((y / sk) ** 2)), np.sqrt(np.mean((k1 / sk) ** 2))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, t_end)
    d2 = np.sqrt(np.mean(((f(y + h0 * k1, h0) - k1) / sk) ** 2)) / h0
    h1 = max(1e-6, h0 * 1e-3) if max(d1, d2) <= 1e-15 else (0.01 / max(d1, d2)) ** 0.2
    return min(100.0 * h0, h1, t_end)


def _stages(f, y, k1, h, t=0.0):
    """Stages K1..K7 (at the times t + c_i h) and the 5th-order solution y1."""
    k = [k1]
    for row, c in zip(A[1:], C[1:]):
        k.append(f(y + h * sum(a * kj for a, kj in zip(row, k) if a != 0.0), t + c * h))
    y1 = y + h * sum(a * kj for a, kj in zip(A[6], k) if a != 0.0)
    return k, y1


def simulate_dopri5(solver, q, v, sched, opts, project, progress=None, ctx=None):
    """DOPRI5 from (q, v) to sched.t_end, outputs at multiples of sched.output_dt;
    sched.dt: the first step (None: automatic); progress(t) about every 0.5 s
    of wall time; ctx: a numeric.runs.RunContext (events located on the continuous
    extension, the work integrated by the fifth-order weights, bounds). Returns
    (arrays, stats)."""
    from .runs import Recorder, RunContext
    from .runs import project as _project
    ctx = ctx or RunContext()
    ev = ctx.events
    n, rtol, atol, t_end = len(q), opts["rtol"], opts["atol"], sched.t_end
    stats = dict(steps=0, rejected_steps=0, rhs_evaluations=0, newton_iterations=0,
                 max_newton_iterations=0)
    constraint_max = [0.0]
    set_time = getattr(solver, "set_time", lambda _t: None)   # models with drivers
    accelerations = ev.accelerations if ev is not None else solver.accelerations
    power = ctx.power or (lambda *_: 0.0)
    stage_power: list[float] = []

    def f(y, t):
        stats["rhs_evaluations"] += 1
        set_time(t)
        a = accelerations(y[:n], y[n:])
        stage_power.append(power(y[:n], y[n:], a))
        return np.concatenate([y[n:], a])

    t_req = _output_times(t_end, sched.output_dt)
    record = Recorder(solver, ctx.power is not None)
    record(0.0, q, v)
    y, t, last_rejected, work = np.concatenate([q, v]), 0.0, False, 0.0
    if ev is not None:
        ev.start(q)
        ev.s0 = ev.watch(q, v, 0.0)
    deadline = time.monotonic() + 0.5
    stop = None
    try:
        stage_power.clear()
        k1 = f(y, 0.0)
        p1 = stage_power[-1]
        h = sched.dt if sched.dt else _initial_step(f, y, k1, t_end, rtol, atol)
        j = 1
        while t < t_end:
            h = min(h, t_end - t)
            if 0.1 * h <= abs(t) * UROUND or h <= 0.0:
                raise SimulationError(f"DOPRI5 step size underflow (h = {h:.3g})")
            if hasattr(solver, "_rank"):       # step start, for the rank log
                solver._rank.t = t
            stage_power.clear()
            stage_power.append(p1)
            k, y1 = _stages(f, y, k1, h, t)
            d = h * sum(e * kj for e, kj in zip(E, k) if e != 0.0)
            err = np.sqrt(np.mean((d / (atol + rtol * np.maximum(abs(y), abs(y1)))) ** 2))
            if not err <= 1.0:
                h *= FACMIN if np.isnan(err) else max(FACMIN, SAFETY * err ** -0.2)
                stats["rejected_steps"] += 1
                last_rejected = True
                continue
            fac = FACMAX if err == 0.0 else min(FACMAX, max(FACMIN, SAFETY * err ** -0.2))
            fac = min(fac, 1.0) if last_rejected else fac
            rc = _dense(y, y1, k, h)
            rw = _dense(np.array([work]), np.array([work + h * sum(
                a * p for a, p in zip(A[6], stage_power) if a != 0.0)]),
                [np.array([p]) for p in stage_power], h)
            t_old, th, first = t, 1.0, -1
            t = t + h if t_end - (t + h) > 4 * UROUND * t_end else t_end
            if ev is not None:
                first, th = _first_event(ev, rc, h, t_old, y1[:n], y1[n:], t)
                if first >= 0:                 # the step ends at the event
                    t = t_old + th * h
                    y1 = _interpolate(rc, th)
            stats["steps"] += 1
            # a record at an event's time shows the state after it: the next step's
            while j < len(t_req) and (t_req[j] < t if first >= 0 else
                                      t_req[j] <= t * (1 + 4 * UROUND)):
                x = (t_req[j] - t_old) / h
                yo = _interpolate(rc, x)
                qo, vo = yo[:n], yo[n:]
                set_time(t_req[j])
                if project:
                    qo, vo = _project(solver, qo, vo, stats, ev)
                record(t_req[j], qo, vo, float(_interpolate(rw, x)[0]))
                j += 1
            y, work = y1, float(_interpolate(rw, th)[0])
            ctx.check(y[:n], y[n:])
            set_time(t)
            if project:
                qp, vp = _project(solver, y[:n], y[n:], stats, ev)
                y = np.concatenate([qp, vp])
            else:
                constraint_max[0] = max(constraint_max[0],
                                        float(np.max(np.abs(solver.constraints(y[:n])),
                                                     initial=0.0)))
            if first >= 0:
                qe, ve, _ = ev.apply(first, y[:n], y[n:], t)
                y = np.concatenate([qe, ve])
                if ev.stopped:
                    stop = t
                    record(t, y[:n], y[n:], work)
                    break
            ctx.after_step(y[:n])
            if ev is not None:
                prev = ev.s0
                ev.s0 = ev.watch(y[:n], y[n:], t)
                if first >= 0:
                    ev.s0[first] = ev.leaving(first, y[:n], y[n:], t, prev[first])
                    ties = ev.ties(first, prev, ev.s0)
                    for tie in ties:           # crossed by this instant too: act now
                        qe, ve, _ = ev.apply(tie, y[:n], y[n:], t)
                        y = np.concatenate([qe, ve])
                        if ev.stopped:
                            break
                    if ev.stopped:
                        stop = t
                        record(t, y[:n], y[n:], work)
                        break
                    if ties:
                        ctx.after_step(y[:n])
                        ev.s0 = ev.watch(y[:n], y[n:], t)
                        for tie in [first, *ties]:
                            ev.s0[tie] = ev.leaving(tie, y[:n], y[n:], t, prev[tie])
            if project or first >= 0:
                stage_power.clear()
                k1 = f(y, t)
                p1 = stage_power[-1]
            else:
                k1, p1 = k[6], stage_power[6]
            h, last_rejected = h * fac, False
            if progress is not None and time.monotonic() >= deadline:
                progress(t)
                deadline = time.monotonic() + 0.5
        while stop is None and j < len(t_req):      # an event at t_end: after it
            record(t_req[j], y[:n], y[n:], work)
            j += 1
    except SimulationError as exc:
        raise SimulationError(f"simulation stopped at t = {t:.10g}: {exc}") from None
    arrays = record.arrays()
    stats["max_constraint_error"] = max(float(arrays["constraint_error"].max()),
                                        constraint_max[0])
    if stop is not None:
        stats["stopped_at"] = stop
    return arrays, stats


def _first_event(ev, rc, h, t0, q1, v1, t1):
    """(the earliest watched value that crosses in the step t0 -> t1, or -1; the
    fraction of the step where, located on the continuous extension)."""
    n = len(q1)
    s1 = ev.watch(q1, v1, t1)
    k = ev.first_crossing(ev.s0, s1)
    if k < 0:
        return -1, 1.0
    theta, first = 1.0, k

    def value(x, j):
        y = _interpolate(rc, x)
        return ev.watch(y[:n], y[n:], t0 + x * h)[j]
    for j in range(k, 2 * ev.ne):
        if j > k and not ev.watched(j, ev.s0, s1):
            continue
        x = locate(ev, j, lambda x, j=j: value(x, j), s1[j], 1.0, ev.tol / h)
        if x < theta or j == k:
            theta, first = x, j
    return first, theta


def _dense(y, y1, k, h):
    dy = y1 - y
    bspl = h * k[0] - dy
    return (y, dy, bspl, dy - h * k[6] - bspl, h * sum(c * kj for c, kj in zip(D, k)
                                                       if c != 0.0))


def _interpolate(rc, th):
    th1 = 1.0 - th
    return rc[0] + th * (rc[1] + th1 * (rc[2] + th * (rc[3] + th1 * rc[4])))


def _output_times(t_end: float, output_dt: float) -> np.ndarray:
    """0, output_dt, 2 output_dt, ... below t_end, then t_end (as the compiled run)."""
    n = int(t_end / output_dt * (1 + 1e-12))
    times = [k * output_dt for k in range(n + 1) if k * output_dt < t_end * (1 - 1e-12)]
    return np.array(times + [t_end])
