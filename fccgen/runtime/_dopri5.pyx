# cython: language_level=3
"""Dormand-Prince 5(4) with error control and dense output (engine/fcc_dopri5.c: the
per-step loop, projections and events included, in C without the GIL).

This wrapper checks the arguments, allocates the records and the work arrays, and runs
the C loop in slices: it leaves C about every 0.5 s of wall time for signals and an
optional progress callback, and turns the engine's error record into a
SimulationError.
"""
from cpython.exc cimport PyErr_CheckSignals
from libc.string cimport memset

import numpy as np

from fccgen.errors import SimulationError

from ._cengine cimport (FCC_RUN_DONE, FCC_RUN_ERROR, FCC_RUN_UNDERFLOW,
                        fcc_dopri5, fcc_dopri5_advance, fcc_dopri5_start,
                        fcc_run_finish)
from ._engine cimport Engine
from ._events cimport ev_state
from ._power cimport power_state
from ._runloop cimport array_data, now, past_deadline
from ._sens cimport sens_events, sens_state

from ._messages import error_message
from fccgen.results.result import keep_rows

WORK_ARRAYS = 15                          # FCC_DOPRI5_WORK: arrays of 2 n numbers
SENS_WORK = 15                            # FCC_SENS_DOPRI5_WORK: np x 2 n numbers each


def output_times(double t_end, double output_dt):
    """0, output_dt, 2 output_dt, ... below t_end, then t_end."""
    n = int(t_end / output_dt * (1 + 1e-12))
    times = [k * output_dt for k in range(n + 1)
             if k * output_dt < t_end * (1 - 1e-12)]
    return np.array(times + [t_end])


def simulate_dopri5(Engine engine, q0, v0, double t_end, double output_dt, double rtol,
                    double atol, double h0, bint project, progress=None,
                    double progress_interval=0.5, events=None, work=None, sens=None,
                    sens_scale=None):
    """DOPRI5 from (q0, v0) (used as given) to t_end; records at 0, every output_dt and
    t_end by dense output. h0: the first step (0: Hairer's automatic choice). work: a
    _power.WorkTracker (None: none), whose work each record gets (array work).
    sens: a _sens.Sensitivities (None: none; needs project and the dense path) whose
    ``records`` the run fills, one per record; sens_scale: None, or each parameter's
    size (np numbers > 0), which puts the sensitivities into the error control with
    the absolute tolerance atol / size (engine/fcc_sens_dopri5.h).

    Returns (arrays, stats) like simulate_rk4, with stats steps (accepted),
    rejected_steps, rhs_evaluations, newton_iterations, projection_failures,
    max_constraint_error. Raises SimulationError on a singular mass matrix, a
    non-finite state or one past the divergence bound of the positions, or a step size
    below the rounding of t.
    """
    if engine.c.running:
        raise RuntimeError("this engine is already running a simulation")
    if not (t_end > 0 and output_dt > 0 and rtol > 0 and atol > 0 and h0 >= 0):
        raise ValueError("need t_end, output_dt, rtol, atol > 0 and h0 >= 0")
    # a set without event functions only re-bases angle references (springs)
    if events is not None and not project and events.n_events:
        raise ValueError("events need the projected DOPRI5 (projection on)")
    if work is not None:
        work.fits(engine)
    if sens is not None and (not project or engine.c.sparse):
        raise ValueError("sensitivities need the projected DOPRI5 on the dense path")
    cdef double[::1] qv = engine.vector(q0, "q0"), vv = engine.vector(v0, "v0")
    engine.reset_warm_start()           # a run does not depend on earlier solves
    if not (np.all(np.isfinite(qv)) and np.all(np.isfinite(vv))):
        raise ValueError("q0 and v0 must be finite")
    cdef Py_ssize_t n = engine.c.n
    t_req = output_times(t_end, output_dt)
    n_out = len(t_req)
    arrays = dict(t=t_req, q=np.zeros((n_out, n)), v=np.zeros((n_out, n)),
                  body=np.zeros((n_out, engine.asm.n_bodies, 6)), energy=np.zeros(n_out),
                  constraint_error=np.zeros(n_out))
    work_out = np.zeros(n_out)
    if work is not None:                # the work at the records (array "work")
        arrays["work"] = work_out
    stage_work = np.zeros((WORK_ARRAYS, 2 * n))
    cdef double deadline = 0.0
    cdef fcc_dopri5 r
    memset(&r, 0, sizeof(r))
    r.project, r.rtol, r.atol, r.t_end, r.h0 = project, rtol, atol, t_end, h0
    r.n_req = n_out
    r.out.t, r.out.q, r.out.v = (array_data(t_req), array_data(arrays["q"]),
                                 array_data(arrays["v"]))
    r.out.body, r.out.energy = array_data(arrays["body"]), array_data(arrays["energy"])
    r.out.cerr = array_data(arrays["constraint_error"])
    r.work = array_data(stage_work)
    r.pause, r.pause_ctx = past_deadline, &deadline
    r.ev = ev_state(events)
    r.pw = power_state(work)
    r.w_out = array_data(work_out)
    if sens is not None:
        n_sens = sens.n_params
        sens_work = np.zeros((SENS_WORK, n_sens, 2 * n))
        scale = np.ones(n_sens) if sens_scale is None else np.array(sens_scale, float)
        if scale.shape != (n_sens,) or not np.all(scale > 0) or not np.all(np.isfinite(scale)):
            raise ValueError(f"sens_scale must be {n_sens} finite numbers > 0")
        r.sens.s = sens_state(sens, n_out)
        r.sens.control = sens_scale is not None
        r.sens.scale = array_data(scale)
        r.sens.work = array_data(sens_work)
        if r.ev != NULL:
            sens_events(sens, r.ev, r.ev.spec.cap_log)
    r.n_out = r.accepted = r.rejected = r.n_rhs = r.newton_total = 0
    r.max_cerr = 0.0
    if events is not None:
        events.reset(qv, engine, fold=sens is None)
    cdef int status
    try:
        with nogil:
            status = fcc_dopri5_start(&r, &engine.c, &qv[0], &vv[0])
        if status < 0:
            raise SimulationError(_message(engine))
        while True:
            deadline = now() + progress_interval
            with nogil:
                status = fcc_dopri5_advance(&engine.c, &r)
            if status == FCC_RUN_DONE:
                break
            if status == FCC_RUN_ERROR:
                raise SimulationError(_message(engine))
            if status == FCC_RUN_UNDERFLOW:
                raise SimulationError(
                    f"simulation stopped at t = {r.t:.10g}: DOPRI5 step size underflow "
                    f"(h = {engine.c.err_h:.3g} after {r.rejected} rejected steps): the "
                    f"solution is diverging or the problem is too stiff for an explicit "
                    f"method at rtol = {rtol:g}, atol = {atol:g}")
            PyErr_CheckSignals()
            if progress is not None:
                progress(r.t)                 # K1 of the next step is already computed
    except (SimulationError, KeyboardInterrupt) as exc:
        keep_rows(exc, arrays, r.n_out,
                  dict(steps=r.accepted, rejected_steps=r.rejected, rhs_evaluations=r.n_rhs, newton_iterations=r.newton_total, max_constraint_error=r.max_cerr))
        raise
    finally:
        fcc_run_finish(&engine.c)
        if events is not None:
            events.unfold(engine)
    stats = dict(steps=r.accepted, rejected_steps=r.rejected, rhs_evaluations=r.n_rhs,
                 newton_iterations=r.newton_total, projection_failures=r.failures,
                 max_constraint_error=r.max_cerr, last_step=r.h)
    if r.stopped:                              # a stop event: the records so far
        arrays = {k: a[:r.n_out] for k, a in arrays.items()}
        stats["stopped_at"] = r.t_stop
    return arrays, stats


def _message(Engine engine):
    return error_message(engine.error_record(), in_run=True).replace(
        "RK4 stage", "DOPRI5 stage")
