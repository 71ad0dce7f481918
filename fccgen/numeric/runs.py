"""The NumPy version's fixed-step loops (RK4, Baumgarte) and its SciPy runs, with the
guards every method has (docs/reliability.md): the bounds past which a run has
diverged, the work of the forces without potential for the energy check (integrated
by the step's own quadrature), the turn-counting references, and events located in
the step (RK4, as docs/events.md describes: the crossing bracketed on re-integrated
partial steps from the step's start, by SciPy's brentq to event_tol).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from ..errors import SimulationError
from ..results.result import keep_rows


@dataclass
class RunContext:
    """What a run of the NumPy version carries besides the state: its events (a
    numeric.events.NumericEvents, or None), the power whose work it integrates (None:
    none), the divergence bounds of q and v (fccgen/runs/guards.py), and the
    re-basing of the elements' angle references."""
    events: object = None
    power: object = None
    q_bound: float = np.inf
    v_bound: float = np.inf
    rebase: object = None

    def after_step(self, q) -> None:
        if self.rebase is not None:
            self.rebase(q)
        if self.events is not None:
            self.events.refresh(q)

    def check(self, q, v) -> None:
        """A non-finite state, or one past the bounds, stops the run."""
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise SimulationError("the state is not finite (the solution diverged)")
        for name, x, bound in (("q", q, self.q_bound), ("v", v, self.v_bound)):
            big = float(np.max(np.abs(x), initial=0.0))
            if big > bound:
                raise SimulationError(
                    f"the run diverged: max |{name}| reached {big:.3g}, past the bound "
                    f"{bound:.3g} set at its start from the initial state (see "
                    f"docs/reliability.md); use a smaller dt or dopri5")


class Recorder:
    """Records t, q, v, body outputs, energy, max |g| and the work of output states."""

    def __init__(self, solver, tracked: bool = False):
        self.solver, self.tracked = solver, tracked
        self.rows: dict[str, list] = {k: [] for k in ("t", "q", "v", "body", "energy",
                                                      "constraint_error", "work")}

    def __call__(self, t, q, v, work: float = 0.0):
        s, out = self.solver, self.rows
        out["t"].append(t)
        out["q"].append(np.array(q))
        out["v"].append(np.array(v))
        out["body"].append(s.body_outputs(q, v))
        out["energy"].append(s.energy(q, v))
        out["constraint_error"].append(_amax(s.constraints(q)))
        out["work"].append(float(work))
        hold = getattr(s, "hold_inputs", None)  # solvers with inputs (NumericSolver)
        if hold is not None:
            hold(len(out["t"]) - 1)             # the inputs' row of this record

    def arrays(self) -> dict[str, np.ndarray]:
        """The records (with "work" only when a power was integrated: tracked)."""
        a = {k: np.array(v, float) for k, v in self.rows.items()}
        a["body"] = a["body"].reshape(len(a["t"]), len(self.solver.plan.bodies), 6)
        if not self.tracked:
            del a["work"]
        return a


def rk4_step(accelerations, q, v, h, t=0.0, set_time=None, power=None):
    """One classical Runge-Kutta step of q' = v, v' = accelerations(q, v) from t;
    set_time(t) (if given) before each stage, leaving it at t + h. Returns (q, v, the
    work h/6 (P1 + 2 P2 + 2 P3 + P4) of power(q, v, a) at the stages; 0 without)."""
    set_time = set_time or (lambda _t: None)
    power = power or (lambda *_: 0.0)
    set_time(t)
    a1 = accelerations(q, v)
    p1 = power(q, v, a1)
    v2 = v + 0.5 * h * a1
    set_time(t + 0.5 * h)
    q2 = q + 0.5 * h * v
    a2 = accelerations(q2, v2)
    p2 = power(q2, v2, a2)
    v3 = v + 0.5 * h * a2
    q3 = q + 0.5 * h * v2
    a3 = accelerations(q3, v3)
    p3 = power(q3, v3, a3)
    v4 = v + h * a3
    set_time(t + h)
    q4 = q + h * v3
    a4 = accelerations(q4, v4)
    p4 = power(q4, v4, a4)
    return (q + h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4),
            v + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
            h / 6.0 * (p1 + 2.0 * p2 + 2.0 * p3 + p4))


def project(solver, q, v, stats: dict, events=None):
    """Position then velocity projection (counting the Newton iterations in stats),
    then the events' held rows."""
    q, iterations = solver.project_positions(q)
    stats["newton_iterations"] += iterations
    stats["max_newton_iterations"] = max(stats["max_newton_iterations"], iterations)
    v = solver.project_velocities(q, v)
    return events.hold(q, v) if events is not None else (q, v)


def simulate_rk4(solver, q, v, sched, opts, project_on, progress=None,
                 accelerations=None, ctx: RunContext | None = None):
    """Fixed-step RK4, the last step shortened to land on t_end; after each step the
    positions and then the speeds are projected onto the constraints (if
    ``project_on``), and the events in the step are located and acted on.
    progress(t) about every 0.5 s of wall time. Returns (arrays, stats)."""
    ctx = ctx or RunContext()
    ev = ctx.events
    accelerations = accelerations or (ev.accelerations if ev is not None
                                      else solver.accelerations)
    set_time = getattr(solver, "set_time", None)
    n_steps, every, dt, t_end = sched.n_steps, sched.every, sched.dt, sched.t_end
    record = Recorder(solver, ctx.power is not None)
    record(0.0, q, v)
    deadline = time.monotonic() + 0.5
    stats = dict(steps=n_steps, rhs_evaluations=4 * n_steps, rejected_steps=0,
                 newton_iterations=0, max_newton_iterations=0)

    def step(q0, v0, w0, t0, h):
        """The state after a (projected) step of h from (q0, v0) at t0, and the work."""
        q1, v1, dw = rk4_step(accelerations, q0, v0, h, t0, set_time, ctx.power)
        ctx.check(q1, v1)
        solver._rank.t = t0 + h                # the projected state is at the step's end
        if project_on:
            q1, v1 = project(solver, q1, v1, stats, ev)
        return q1, v1, w0 + dw

    work = 0.0
    if ev is not None:
        ev.start(q)
        ev.s0 = ev.watch(q, v, 0.0)
    for k in range(1, n_steps + 1):
        t0 = (k - 1) * dt
        t = k * dt if k < n_steps else t_end
        h = dt if k < n_steps else t_end - t0
        solver._rank.t = t0                    # step start, as the compiled loop logs it
        try:
            start = (q, v, work)
            q, v, work = step(q, v, work, t0, h)
            stop = None
            if ev is not None:
                q, v, work, stop = _events(ctx, step, accelerations, set_time, start,
                                           q, v, work, t0, h)
            else:
                ctx.after_step(q)
        except SimulationError as exc:
            stopped = SimulationError(f"simulation stopped at t = {t:.10g} (step {k}): "
                                      f"{exc}")
            rows = record.arrays()
            keep_rows(stopped, rows, len(rows["t"]),
                      dict(stats, steps=k - 1, max_constraint_error=float(
                          rows["constraint_error"].max())))
            raise stopped from None
        if stop is not None:
            record(stop, q, v, work)
            stats.update(steps=k, stopped_at=stop)
            break
        if k % every == 0 or k == n_steps:
            record(t, q, v, work)
        if progress is not None and time.monotonic() >= deadline:
            progress(t)
            deadline = time.monotonic() + 0.5
    arrays = record.arrays()
    stats["max_constraint_error"] = float(arrays["constraint_error"].max())
    return arrays, stats


def _events(ctx, step, accelerations, set_time, start, q, v, work, t0, h):
    """After a step from t0 of size h: the first event that crossed in it, located on
    re-integrated partial steps from its start, acted on, and the rest of the step
    integrated again; repeated. Returns (q, v, work, the stop's time or None)."""
    ev = ctx.events
    count = loops = 0
    while True:
        s1 = ev.watch(q, v, t0 + h)
        k = ev.first_crossing(ev.s0, s1)
        loops += 1
        if k < 0 or loops > 4 * ev.max_per_step:
            ctx.after_step(q)
            ev.s0 = ev.watch(q, v, t0 + h)
            return q, v, work, None

        def partial(tau, j, q0=start[0], v0=start[1], t_start=t0):
            if tau <= 0.0:
                return ev.s0[j]
            qt, vt, _ = rk4_step(accelerations, q0, v0, tau, t_start, set_time)
            return ev.watch(qt, vt, t_start + tau)[j]
        best, first = h, k
        for j in range(k, 2 * ev.ne):
            if j > k and not ev.watched(j, ev.s0, s1):
                continue
            tau = locate(ev, j, lambda x, j=j: partial(x, j), s1[j], h, ev.tol)
            if tau < best or j == k:
                best, first = tau, j
        q, v, work = step(*start, t0, best)
        count += 1
        t_event = t0 + best
        q, v, done = ev.apply(first if count <= ev.max_per_step else -1 - first, q, v,
                              t_event)
        count -= not done
        if ev.stopped:
            return q, v, work, t_event
        ctx.after_step(q)
        prev = ev.s0
        ev.s0 = ev.watch(q, v, t_event)
        ev.s0[first] = ev.leaving(first, q, v, t_event, prev[first])
        ties = ev.ties(first, prev, ev.s0)
        for j in ties:                       # crossed by this instant too: act now
            count += 1
            q, v, done = ev.apply(j if count <= ev.max_per_step else -1 - j, q, v,
                                  t_event)
            count -= not done
            if ev.stopped:
                return q, v, work, t_event
        if ties:
            ctx.after_step(q)
            ev.s0 = ev.watch(q, v, t_event)
            for j in [first, *ties]:
                ev.s0[j] = ev.leaving(j, q, v, t_event, prev[j])
        t0, h = t_event, h - best
        start = (q, v, work)
        if h <= 0.0:
            return q, v, work, None
        q, v, work = step(*start, t0, h)


def locate(ev, j: int, value, end: float, span: float, tol: float) -> float:
    """The earliest point of [0, span] past the crossing of watched value j, which
    crosses between ev.s0[j] (at 0) and ``end`` (at span); value(x) is its value at x.
    A start just after an event (its value +-1e-300) counts as before the crossing."""
    a = ev.s0[j]
    a = -end if abs(a) < 1e-200 else a

    def f(x):
        return a if x <= 0.0 else end if x >= span else value(x)
    x = brentq(f, 0.0, span, xtol=tol, rtol=4 * np.finfo(float).eps, maxiter=200)
    for b in (x, x + tol, x + 2.0 * tol):
        b = min(b, span)
        if ev.crosses(j, a, f(b)):
            return b
    return span


def simulate_baumgarte(solver, q, v, sched, opts, project_on, progress=None, ctx=None):
    """RK4 on the Baumgarte-stabilised index-1 equations, without projection."""
    alpha, beta = opts["alpha"], opts["beta"]
    return simulate_rk4(solver, q, v, sched, opts, False, progress,
                        lambda q, v: solver.baumgarte_accelerations(q, v, alpha, beta),
                        ctx)


def simulate_scipy(method: str):
    """The integrator of SciPy's ``method`` on the numeric right-hand side."""
    def run(solver, q, v, sched, opts, project_on, progress=None, ctx=None):
        from ..runs import scipy_ivp
        ctx = ctx or RunContext()
        references = getattr(solver, "references", None)
        return scipy_ivp.run(solver, method, sched, opts, q, v, progress,
                             refresh=ctx.rebase, power=ctx.power,
                             restart=references.start if references else None)
    return run


def _amax(x) -> float:
    x = np.asarray(x, float)
    return float(np.max(np.abs(x))) if x.size else 0.0
