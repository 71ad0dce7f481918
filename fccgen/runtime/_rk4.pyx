# cython: language_level=3
"""Classical RK4 with projection, and RK4 on the Baumgarte-stabilised equations: the
whole per-step loop in C, without the GIL.

After each step (if asked): Newton position projection onto g(q) = 0, then the
M-orthogonal velocity projection onto B v = 0; the factorisation of the velocity
projection is the one the next step's first stage needs (same M and B), so it is
reused. The run leaves C only to pause about every 0.5 s of wall time, for signals
(Ctrl-C) and an optional progress callback.
"""
from cpython.exc cimport PyErr_CheckSignals
from libc.string cimport memcpy

import numpy as np

from fccgen.errors import SimulationError

from ._cengine cimport fcc_assemble, fcc_put_time, fcc_max_abs_g, fcc_scaled_residual
from ._assemble cimport ASM_G
from libc.math cimport fabs

from ._events cimport Bracket, EvC, ev_apply, ev_bracket, ev_bracket_open, \
    ev_bracket_trial, ev_bracket_update, ev_constrain, ev_correct, ev_crossed, ev_crosses, \
    ev_leaving, ev_refresh, ev_state, ev_watch
from ._engine cimport (AT_POSITIONS, AT_STAGE, AT_STEP, AT_VELOCITIES, ERR_DIVERGED,
                       ERR_NONE, ERR_NONFINITE_INPUT, Engine, finite)
from ._runloop cimport RUN_DONE, RUN_ERROR, RUN_PAUSE, now, write_record

from ._messages import error_message
from fccgen.results import keep_rows


cdef struct Run:
    bint project
    bint baumgarte            # stages use Engine.baumgarte_at (alpha, beta)
    double alpha
    double beta
    long newton_total         # Newton iterations of all projections
    long k                    # steps done
    long n_steps
    long every                # record every this many steps
    long n_out                # records written
    double dt
    double t_end
    long n_rhs                # acceleration evaluations
    long failures             # position projections that did not converge
    int newton_max            # most Newton iterations in one projection
    double max_cerr           # largest max |g| of a recorded or stepped state
    double q_bound            # max |q| and max |v| past these: the run diverged
    double v_bound
    double *q                 # state, stage states, stage accelerations (engine.stages)
    double *v
    double *qs
    double *v2
    double *v3
    double *v4
    double *a1
    double *a2
    double *a3
    double *a4
    double *t_out             # records, in numpy arrays owned by the caller
    double *q_out
    double *v_out
    double *body_out
    double *e_out
    double *c_out
    EvC *ev                   # events (NULL: none); their saved step start:
    double *eq                # q, v at the start of the step being located
    double *evv
    double t0                 # time at the start of the step (stage times)
    bint stopped              # a stop event ended the run at t_stop
    double t_stop


cdef int _stage(Engine e, Run *r, int stage, const double *q, const double *v, double *a,
                bint reuse) noexcept nogil:
    e.err_stage = stage
    r.n_rhs += 1
    if r.baumgarte:
        return e.baumgarte_at(q, v, a, r.alpha, r.beta)
    if e.accelerations_at(q, v, a, reuse) < 0:
        return -1
    if r.ev != NULL:                          # active lock rows (events)
        return ev_constrain(e, r.ev, q, v, r.t0, a)
    return 0


cdef int _step(Engine e, Run *r, double t, double h) noexcept nogil:
    """One classical RK4 step of (q' = v, v' = a(t, q, v)) of size h from t, in
    place; leaves the time at t + h."""
    cdef int i, n = e.n
    cdef double h2 = 0.5 * h, h6 = h / 6.0
    fcc_put_time(&e.asm.a, t)
    if _stage(e, r, 1, r.q, r.v, r.a1, e.factor_valid) < 0: return -1
    for i in range(n):
        r.qs[i] = r.q[i] + h2 * r.v[i]
        r.v2[i] = r.v[i] + h2 * r.a1[i]
    fcc_put_time(&e.asm.a, t + h2)
    if _stage(e, r, 2, r.qs, r.v2, r.a2, False) < 0: return -1
    for i in range(n):
        r.qs[i] = r.q[i] + h2 * r.v2[i]
        r.v3[i] = r.v[i] + h2 * r.a2[i]
    if _stage(e, r, 3, r.qs, r.v3, r.a3, False) < 0: return -1
    for i in range(n):
        r.qs[i] = r.q[i] + h * r.v3[i]
        r.v4[i] = r.v[i] + h * r.a3[i]
    fcc_put_time(&e.asm.a, t + h)
    if _stage(e, r, 4, r.qs, r.v4, r.a4, False) < 0: return -1
    for i in range(n):
        r.q[i] += h6 * (r.v[i] + 2.0 * r.v2[i] + 2.0 * r.v3[i] + r.v4[i])
        r.v[i] += h6 * (r.a1[i] + 2.0 * r.a2[i] + 2.0 * r.a3[i] + r.a4[i])
    return 0


cdef int _after_step(Engine e, Run *r) noexcept nogil:
    """Check the new state, project it (if asked) and track max |g|. Follows a
    _step, whose last stage left M, B and their factorisation at q + h v3."""
    cdef int rc, it = 0
    cdef double cerr
    if not (finite(r.q, e.n) and finite(r.v, e.n)):
        e.err_where = AT_STEP
        return e.fail(ERR_NONFINITE_INPUT, 0, 1 if not finite(r.q, e.n) else 2)
    if _diverged(e, r.q, r.q_bound) or _diverged(e, r.v, r.v_bound):
        e.err_where = AT_STEP
        return e.fail(ERR_DIVERGED, 0, 1 if e.err_bound == r.q_bound else 2)
    if r.project:
        e.err_where = AT_POSITIONS
        rc = e.project_positions_at(r.q, &it, True)  # M, B, factor held: stage 4's
        if rc < 0:
            return -1
        r.failures += rc
        r.newton_total += it
        if it > r.newton_max:
            r.newton_max = it
        cerr = fcc_max_abs_g(&e.asm.a)             # g is left assembled at the final q
        e.err_where = AT_VELOCITIES
        if e.project_velocities_at(r.q, r.v, e.b_fresh) < 0:
            return -1
        if r.ev != NULL and ev_correct(e, r.ev, r.q, r.v) < 0:
            return -1
    else:
        fcc_assemble(&e.asm.a, r.q, NULL, ASM_G)
        cerr = fcc_max_abs_g(&e.asm.a)
    if not cerr <= r.max_cerr:
        r.max_cerr = cerr
    return 0


cdef bint _diverged(Engine e, const double *x, double bound) noexcept nogil:
    """max |x_i| > bound; the value and bound go to the engine's error record."""
    cdef int i
    cdef double big = 0.0
    for i in range(e.n):
        if fabs(x[i]) > big:
            big = fabs(x[i])
    if big > bound:
        e.err_value = big
        e.err_bound = bound
        return True
    return False


def divergence_bounds(q0, v0, double t_end, double dt):
    """(q_bound, v_bound) of a fixed-step run: 1e6 times the size the state can reach
    by moving at its initial speed, q_ref + |v0| t_end, and 1e6 times the speed that
    crosses the model's size in one step, |v0| + q_ref / dt (q_ref = max |q0|, or 1).
    An unstable explicit step grows the state by a constant factor per step, so it
    passes these within tens of steps, while no accurate run comes near them."""
    q_ref = float(np.max(np.abs(q0))) if len(q0) else 1.0
    q_ref = q_ref if q_ref > 0.0 else 1.0
    v_ref = float(np.max(np.abs(v0))) if len(v0) else 0.0
    return 1e6 * (q_ref + v_ref * t_end), 1e6 * (v_ref + q_ref / dt)


cdef void _record(Engine e, Run *r, double t) noexcept nogil:
    """Write record r.n_out: t, q, v, body outputs, energy, max |g|."""
    r.t_out[r.n_out] = t
    cdef double cerr = write_record(e, r.n_out, r.q, r.v, r.q_out, r.v_out, r.body_out,
                                    r.e_out, r.c_out)
    if not cerr <= r.max_cerr:
        r.max_cerr = cerr
    r.n_out += 1


cdef int _state_at(Engine e, Run *r, double t0, double tau) noexcept nogil:
    """The state at t0 + tau by one step of size tau from the saved step start
    (a re-integrated partial step), into r.q, r.v."""
    memcpy(r.q, r.eq, e.n * sizeof(double))
    memcpy(r.v, r.evv, e.n * sizeof(double))
    e.factor_valid = False
    r.t0 = t0
    return _step(e, r, t0, tau)


cdef int _locate(Engine e, Run *r, int k, double t0, double h, double *tau) noexcept nogil:
    """Illinois (modified regula falsi, ev_bracket) on tau -> s_k(state(t0 + tau)) over
    [0, h], where s_k crosses between the saved start (ev.s0) and the step's end
    (ev.s1): the bracket [a, b] always holds the crossing; stops when b - a <= tol.
    Returns b, the earliest time found past the crossing."""
    cdef EvC *ev = r.ev
    cdef Bracket br
    cdef double c
    ev_bracket(ev, k, &br, h)
    while ev_bracket_open(ev, &br, 1.0):
        c = ev_bracket_trial(&br)
        if _state_at(e, r, t0, c) < 0:
            return -1
        if ev_watch(e, ev, r.q, r.v, t0 + c, ev.s1 + 2 * ev.ne) < 0:   # work after s1
            return -1
        ev_bracket_update(ev, k, &br, c, ev.s1[2 * ev.ne + k])
    tau[0] = br.b
    return 0


cdef int _events(Engine e, Run *r, double t0, double h) noexcept nogil:
    """After a step from t0 of size h (state projected): find the first event that
    crossed, locate it, act, and integrate the rest of the step again; repeat.
    ev.s0 holds the event values at the step's start."""
    cdef EvC *ev = r.ev
    cdef int k, j, first, rc, count = 0, loops = 0
    cdef double tau, best
    while True:
        if ev_watch(e, ev, r.q, r.v, t0 + h, ev.s1) < 0:
            return -1
        k = ev_crossed(ev, ev.s0, ev.s1)
        loops += 1
        if k < 0 or loops > 4 * ev.max_per_step:    # none (more) in this step
            ev_refresh(ev, r.q)
            return ev_watch(e, ev, r.q, r.v, t0 + h, ev.s0)
        best, first = h, k
        for j in range(k, 2 * ev.ne):           # the earliest of those that crossed
            if j > k and not ev_crosses(ev, j, ev.s0[j], ev.s1[j]):
                continue
            if _locate(e, r, j, t0, h, &tau) < 0:
                return -1
            if tau < best or j == k:
                best, first = tau, j
        if _state_at(e, r, t0, best) < 0 or _after_step(e, r) < 0:
            return -1
        count += 1
        e.err_t = t0 + best
        rc = ev_apply(e, ev, first if count <= ev.max_per_step else -1 - first, r.q, r.v,
                      t0 + best)
        if rc < 0:
            return -1
        count -= rc                          # an impact that was none does not count
        if ev.stop:
            r.stopped, r.t_stop = True, t0 + best
            return 0
        ev_refresh(ev, r.q)
        if ev_watch(e, ev, r.q, r.v, t0 + best, ev.s0) < 0:
            return -1
        ev.s0[first] = ev_leaving(ev, first, r.q, r.v, t0 + best)
        t0, h = t0 + best, h - best
        memcpy(r.eq, r.q, e.n * sizeof(double))
        memcpy(r.evv, r.v, e.n * sizeof(double))
        if h <= 0.0:
            return 0
        r.t0 = t0
        if _step(e, r, t0, h) < 0 or _after_step(e, r) < 0:
            return -1


cdef int _run(Engine e, Run *r, double deadline) noexcept nogil:
    """Steps until the end (RUN_DONE), an error (RUN_ERROR) or the wall-clock deadline
    (RUN_PAUSE)."""
    cdef double t, h
    while r.k < r.n_steps:
        t = r.k * r.dt
        h = r.dt if r.k < r.n_steps - 1 else r.t_end - t
        e.err_where = AT_STAGE
        e.err_t = t
        e.err_h = h
        if r.ev != NULL:
            memcpy(r.eq, r.q, e.n * sizeof(double))
            memcpy(r.evv, r.v, e.n * sizeof(double))
        r.t0 = t
        if _step(e, r, t, h) < 0:
            return RUN_ERROR
        r.k += 1
        t = r.k * r.dt if r.k < r.n_steps else r.t_end
        e.err_t = t
        if _after_step(e, r) < 0:
            return RUN_ERROR
        if r.ev != NULL:
            if _events(e, r, t - h, h) < 0:
                return RUN_ERROR
            if r.stopped:
                _record(e, r, r.t_stop)
                return RUN_DONE
        if r.k % r.every == 0 or r.k == r.n_steps:
            _record(e, r, t)
        if r.k < r.n_steps and now() >= deadline:
            return RUN_PAUSE
    return RUN_DONE


cdef double *_data(object array):
    """Pointer to the data of a fresh C-contiguous float64 array (NULL if empty)."""
    cdef double[::1] flat = array.reshape(-1)
    return &flat[0] if flat.shape[0] else NULL


cdef void _start(Engine e, Run *r, double[::1] q0, double[::1] v0, dict arrays):
    cdef int n = e.n
    r.q, r.v, r.qs, r.v2, r.v3 = e.stages, e.stages + n, e.stages + 2 * n, \
        e.stages + 3 * n, e.stages + 4 * n
    r.v4, r.a1, r.a2, r.a3, r.a4 = e.stages + 5 * n, e.stages + 6 * n, \
        e.stages + 7 * n, e.stages + 8 * n, e.stages + 9 * n
    memcpy(r.q, &q0[0], n * sizeof(double))
    memcpy(r.v, &v0[0], n * sizeof(double))
    r.t_out, r.q_out, r.v_out = _data(arrays["t"]), _data(arrays["q"]), _data(arrays["v"])
    r.body_out, r.e_out = _data(arrays["body"]), _data(arrays["energy"])
    r.c_out = _data(arrays["constraint_error"])
    e.factor_valid = False
    e.err = ERR_NONE
    fcc_put_time(&e.asm.a, 0.0)


def simulate_rk4(Engine engine, q0, v0, double t_end, double dt, long n_steps,
                 long output_every, bint project, progress=None,
                 double progress_interval=0.5, events=None):
    """Classical RK4 from (q0, v0) (used as given) over n_steps steps of dt, the last
    one shortened to end at t_end; after each step, if project, position then velocity
    projection. Records t = 0, every output_every steps and t_end.

    progress(t) is called when the run pauses, at most every progress_interval seconds
    of wall time. Returns (arrays, stats): fresh arrays t, q, v, body, energy,
    constraint_error; stats steps, rhs_evaluations, newton_iterations (total),
    max_newton_iterations, projection_failures, max_constraint_error. Raises
    SimulationError (with the time and what failed) on a singular mass matrix or a
    non-finite state.
    """
    return _simulate(engine, q0, v0, t_end, dt, n_steps, output_every, project, False,
                     0.0, 0.0, progress, progress_interval, events)


def simulate_baumgarte(Engine engine, q0, v0, double t_end, double dt, long n_steps,
                       long output_every, double alpha, double beta, progress=None,
                       double progress_interval=0.5):
    """RK4 on the index-1 equations with Baumgarte stabilisation,
    B q'' = -(dB/dt) q' - 2 alpha B q' - beta^2 g, without projection; otherwise as
    :func:`simulate_rk4` (same arguments, records and stats)."""
    if not (alpha >= 0 and beta >= 0):
        raise ValueError("Baumgarte alpha and beta must be non-negative")
    return _simulate(engine, q0, v0, t_end, dt, n_steps, output_every, False, True,
                     alpha, beta, progress, progress_interval)


def _simulate(Engine engine, q0, v0, double t_end, double dt, long n_steps,
              long output_every, bint project, bint baumgarte, double alpha, double beta,
              progress, double progress_interval, events=None):
    """The shared driver of simulate_rk4 and simulate_baumgarte."""
    if engine.running:
        raise RuntimeError("this engine is already running a simulation")
    if not (n_steps >= 1 and output_every >= 1 and dt > 0 and t_end > 0):
        raise ValueError("need n_steps >= 1, output_every >= 1, dt > 0, t_end > 0")
    if not (0 < t_end - (n_steps - 1) * dt <= dt * (1 + 1e-9)):
        raise ValueError(f"{n_steps} steps of {dt!r} do not end at t_end = {t_end!r}")
    cdef double[::1] qv = engine.vector(q0, "q0"), vv = engine.vector(v0, "v0")
    engine.reset_warm_start()           # a run does not depend on earlier solves
    if not (np.all(np.isfinite(qv)) and np.all(np.isfinite(vv))):
        raise ValueError("q0 and v0 must be finite")
    cdef Py_ssize_t n = engine.n
    n_out = 1 + n_steps // output_every + (1 if n_steps % output_every else 0)
    arrays = dict(t=np.zeros(n_out), q=np.zeros((n_out, n)), v=np.zeros((n_out, n)),
                  body=np.zeros((n_out, engine.asm.n_bodies, 6)), energy=np.zeros(n_out),
                  constraint_error=np.zeros(n_out))
    cdef Run r
    r.project, r.n_steps, r.every, r.dt, r.t_end = project, n_steps, output_every, dt, t_end
    r.baumgarte, r.alpha, r.beta = baumgarte, alpha, beta
    r.k = r.n_out = r.n_rhs = r.failures = r.newton_total = 0
    r.newton_max = 0
    r.max_cerr = 0.0
    r.q_bound, r.v_bound = divergence_bounds(np.asarray(qv), np.asarray(vv), t_end, dt)
    _start(engine, &r, qv, vv, arrays)
    r.ev, r.stopped, r.t_stop = NULL, False, t_end
    if events is not None:
        if baumgarte or not project:
            raise ValueError("events need the projected RK4 (method rk4, projection on)")
        saved = np.zeros(2 * n)
        r.eq, r.evv = _data(saved), _data(saved) + n
        r.ev = ev_state(events)
        events.reset(qv, engine)
        with nogil:
            ev_watch(engine, r.ev, r.q, r.v, 0.0, r.ev.s0)
    cdef int status
    cdef double deadline
    engine.running = True
    # A step that leaves the constraints by 1% of the model's size (an accurate one
    # leaves them by its local error, orders below) has diverged.
    engine.diverge_residual = 1e-2 * max(float(np.max(np.abs(qv))), 1e-300)
    try:
        _record(engine, &r, 0.0)
        while True:
            deadline = now() + progress_interval
            with nogil:
                status = _run(engine, &r, deadline)
            if status == RUN_DONE:
                break
            if status == RUN_ERROR:
                raise SimulationError(error_message(engine.error_record(), in_run=True))
            PyErr_CheckSignals()
            if progress is not None:
                progress(r.k * dt)
            engine.factor_valid = False     # the callback may have used the engine
    except (SimulationError, KeyboardInterrupt) as exc:
        keep_rows(exc, arrays, r.n_out,
                  dict(steps=r.k, rhs_evaluations=r.n_rhs, newton_iterations=r.newton_total, max_constraint_error=r.max_cerr))
        raise
    finally:
        engine.running = False
        engine.diverge_residual = np.inf
    stats = dict(steps=r.k, rhs_evaluations=r.n_rhs, rejected_steps=0,
                 newton_iterations=r.newton_total, max_newton_iterations=r.newton_max,
                 projection_failures=r.failures, max_constraint_error=r.max_cerr)
    if r.stopped:                              # a stop event: the records so far
        arrays = {k: a[:r.n_out] for k, a in arrays.items()}
        stats["stopped_at"] = r.t_stop
    return arrays, stats
