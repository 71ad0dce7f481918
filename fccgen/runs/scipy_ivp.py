"""SciPy's ``solve_ivp`` integrators on fccgen's right-hand side: the reference path a
SciPy user would try first, for both the compiled and the numeric solver.

The first-order system is y = (q, v), y' = (v, a(q, v)), with a the constrained
accelerations; nothing projects the state back onto the constraints, so the reported
constraint violation is what a SciPy user gets. The right-hand side returns a fresh
array on every call: SciPy's solvers keep references to earlier values, and a reused
output buffer silently corrupts their results (docs/design.md §7).

The loop is solve_ivp's own (an ``OdeSolver`` stepped until t_end, outputs from each
step's dense output, as solve_ivp does for ``t_eval``), written out so that a run can
count its steps, report progress and stop with a clear error when the state diverges:
past the bounds the fixed-step methods use (1e6 times the state's reach,
fccgen/runs/guards.py), as for every other method.

The work of the forces without potential (the energy check, runtime/energy_check.py)
is one more component of y, W' = P(q, v, a), so that SciPy's own steps integrate it;
its tolerance is left out of the error control.
"""
from __future__ import annotations

import time

import numpy as np
import scipy.integrate

from ..errors import SimulationError

SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
WORK_ATOL = 1e300          # the work component's absolute tolerance: no say in the steps


def make_rhs(accelerations, n: int, counter: list | None = None, set_time=None,
             power=None):
    """fun(t, y) -> a fresh array (v, accelerations(q, v)) for y = (q, v) of length 2n
    (with power: (v, a, power(q, v, a)) for y = (q, v, W) of length 2n + 1).

    counter: a one-element list incremented at every call (the evaluation count);
    set_time: called with t before every evaluation (models with drivers).
    """
    def fun(t, y):
        if counter is not None:
            counter[0] += 1
        if set_time is not None:
            set_time(t)
        out = np.empty(2 * n + (power is not None))
        out[:n] = y[n:2 * n]
        try:
            out[n:2 * n] = accelerations(y[:n], y[n:2 * n])
        except SimulationError as exc:
            raise SimulationError(f"simulation stopped at t = {t:.10g}: {exc}") from None
        if power is not None:
            out[2 * n] = power(y[:n], y[n:2 * n], out[n:2 * n])
        return out
    return fun


def output_times(t_end: float, output_dt: float) -> np.ndarray:
    """0, output_dt, 2 output_dt, ... below t_end, then t_end."""
    n = int(t_end / output_dt * (1 + 1e-12))
    times = [k * output_dt for k in range(n + 1) if k * output_dt < t_end * (1 - 1e-12)]
    return np.array(times + [t_end])


def integrate(accelerations, q0, v0, t_end: float, output_dt: float, method: str,
              rtol: float, atol: float, first_step=None, progress=None,
              progress_interval: float = 0.5, set_time=None, refresh=None, power=None):
    """Integrate with SciPy's ``method`` (one of SCIPY_METHODS) from (q0, v0) to t_end.

    refresh(q): called after every accepted step (angle references of springs,
    fccgen.events.references); power(q, v, a): the power whose work W the run
    integrates (None: none). Returns (t, q, v, stats): outputs at
    :func:`output_times`, and stats steps, work (W at the outputs, with power),
    rejected_steps (None where SciPy does not expose it), rhs_evaluations, njev, nlu.
    Raises SimulationError when SciPy fails (step size too small) or the state
    stops being finite.
    """
    if method not in SCIPY_METHODS:
        raise ValueError(f"unknown SciPy method {method!r}; available: "
                         + ", ".join(SCIPY_METHODS))
    q0, v0 = np.asarray(q0, float), np.asarray(v0, float)
    n = q0.shape[0]
    calls = [0]
    fun = make_rhs(accelerations, n, calls, set_time, power)
    kwargs = {} if first_step is None else {"first_step": float(first_step)}
    y0 = np.concatenate([q0, v0] + ([[0.0]] if power is not None else []))
    if power is not None:           # W: no say in the error control
        atol = np.concatenate([np.full(2 * n, float(atol)), [WORK_ATOL]])
    ode = getattr(scipy.integrate, method)(fun, 0.0, y0, t_end, rtol=rtol, atol=atol,
                                           **kwargs)
    from .guards import divergence_bounds
    q_bound, v_bound = divergence_bounds(q0, v0, t_end, None)
    t_out = output_times(t_end, output_dt)
    y_out = np.empty((len(t_out), y0.size))
    y_out[0] = ode.y
    k, steps, step_calls, deadline = 1, 0, 0, time.monotonic() + progress_interval
    while ode.status == "running":
        before = calls[0]
        message = ode.step()
        step_calls += calls[0] - before
        if ode.status == "failed":
            raise SimulationError(f"simulation stopped at t = {ode.t:.10g}: SciPy {method} "
                                  f"failed: {message}")
        steps += 1
        if not np.all(np.isfinite(ode.y)):
            raise SimulationError(f"simulation stopped at t = {ode.t:.10g}: SciPy {method} "
                                  f"produced a non-finite state (the solution diverged)")
        big = (float(np.max(np.abs(ode.y[:n]), initial=0.0)),
               float(np.max(np.abs(ode.y[n:2 * n]), initial=0.0)))
        if big[0] > q_bound or big[1] > v_bound:
            what, value, bound = (("q", big[0], q_bound) if big[0] > q_bound else
                                  ("v", big[1], v_bound))
            raise SimulationError(
                f"simulation stopped at t = {ode.t:.10g}: the run diverged: max |{what}| "
                f"reached {value:.3g}, past the bound {bound:.3g} set at its start "
                f"(1e6 times the state's reach; docs/reliability.md): SciPy {method} "
                f"at rtol = {rtol:g} does not follow this model; try a smaller --rtol, "
                f"or rk4 or dopri5 with projection")
        if refresh is not None:
            refresh(ode.y[:n])
        stop = np.searchsorted(t_out, ode.t, side="right")
        if stop > k:
            y_out[k:stop] = ode.dense_output()(t_out[k:stop]).T
            k = stop
        if progress is not None and time.monotonic() >= deadline:
            progress(ode.t)
            deadline = time.monotonic() + progress_interval
    n_stages = getattr(ode, "n_stages", None)
    rejected = None
    if n_stages:                # explicit RK: n_stages evaluations per attempted step
        rejected = max(0, round(step_calls / n_stages) - steps)
    stats = dict(steps=steps, rejected_steps=rejected, rhs_evaluations=calls[0],
                 njev=int(getattr(ode, "njev", 0)), nlu=int(getattr(ode, "nlu", 0)))
    if power is not None:
        stats["work"] = y_out[:, 2 * n].copy()
    return t_out, y_out[:, :n].copy(), y_out[:, n:2 * n].copy(), stats


def run(solver, scipy_method: str, sched, opts: dict, q0, v0, progress=None,
        refresh=None, power=None, restart=None):
    """(arrays, stats) of a run of SciPy's ``scipy_method`` on ``solver.accelerations``
    (a compiled or numeric solver); sched: a fccgen.settings.methods.Schedule; opts: rtol, atol;
    refresh, power: see :func:`integrate` (arrays["work"]: W at the outputs);
    restart(): the angle references back at the start's, before the outputs are
    read along the run."""
    t, q, v, stats = integrate(solver.accelerations, q0, v0, sched.t_end, sched.output_dt,
                               scipy_method, opts["rtol"], opts["atol"], sched.dt, progress,
                               set_time=getattr(solver, "set_time", None), refresh=refresh,
                               power=power)
    if restart is not None:
        restart()
    arrays = record(solver, t, q, v, stats, refresh if restart is not None else None)
    if power is not None:
        arrays["work"] = stats.pop("work")
    return arrays, stats


def record(solver, t, q, v, info: dict, refresh=None):
    """Arrays of a run (body outputs, energy, max |g| at every output) from a solver's
    own per-state functions; ``info`` gains max_constraint_error. refresh(q): the
    angle references moved along the outputs (from the start's, which the caller
    set), so that a spring's energy is its angle's over turns."""
    body = np.array([solver.body_outputs(qi, vi) for qi, vi in zip(q, v)])
    body = body.reshape(len(t), len(solver.plan.bodies), 6)
    energy = []
    for qi, vi in zip(q, v):
        if refresh is not None:
            refresh(qi)
        energy.append(solver.energy(qi, vi))
    energy = np.array(energy)
    set_time = getattr(solver, "set_time", None)
    cerr = []
    for ti, qi in zip(t, q):
        if set_time is not None:
            set_time(ti)
        cerr.append(_amax(solver.constraints(qi)))
    cerr = np.array(cerr)
    info["max_constraint_error"] = float(cerr.max()) if cerr.size else 0.0
    return dict(t=t, q=q, v=v, body=body, energy=energy, constraint_error=cerr)


def _amax(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.max(np.abs(x))) if x.size else 0.0
