# cython: language_level=3
"""Dormand-Prince 5(4) with error control and dense output: the per-step loop in C,
without the GIL.

The method and its constants are those of Hairer, Norsett & Wanner, "Solving Ordinary
Differential Equations I" (2nd ed., 1993), section II.5 and the code DOPRI5: FSAL
stages, the error estimate of the embedded 4th-order solution measured in the norm
sqrt(mean((err_i / (atol + rtol max(|y0_i|, |y1_i|)))^2)) over y = (q, v), the step
factor 0.9 err^(-1/5) kept within [0.2, 10] (no growth right after a rejection), and
the 4th-order continuous extension for outputs at requested times.

With projection, every accepted step is followed by the Newton position projection
and the M-orthogonal velocity projection (as in _rk4.pyx); the first stage of the next
step is then evaluated at the projected state (FSAL only holds without projection),
reusing the velocity projection's factorisation. Outputs interpolated from the dense
output are projected the same way. The run pauses about every 0.5 s of wall time for
signals and an optional progress callback.
"""
from cpython.exc cimport PyErr_CheckSignals
from libc.math cimport fabs, fmax, fmin, pow, sqrt
from libc.string cimport memcpy

import numpy as np

from fccgen.errors import SimulationError

from ._cengine cimport fcc_assemble, fcc_put_time, fcc_max_abs_g, fcc_scaled_residual
from ._assemble cimport ASM_G
from ._engine cimport (AT_POSITIONS, AT_STAGE, AT_STEP, AT_VELOCITIES, ERR_NONE,
                       ERR_NONFINITE_INPUT, Engine, finite)
from ._events cimport Bracket, EvC, ev_apply, ev_bracket, ev_bracket_open, \
    ev_bracket_trial, ev_bracket_update, ev_constrain, ev_correct, ev_crossed, ev_crosses, \
    ev_leaving, ev_refresh, ev_state, ev_watch
from ._runloop cimport RUN_DONE, RUN_ERROR, RUN_PAUSE, now, write_record

from ._messages import error_message
from fccgen.results import keep_rows

cdef enum:
    RUN_UNDERFLOW = -2         # DOPRI5's step size underflowed

# Butcher tableau of DOPRI5 (Hairer, Norsett & Wanner, Table II.5.2).
cdef double C2 = 0.2, C3 = 0.3, C4 = 0.8, C5 = 8.0 / 9.0
cdef double A21 = 0.2
cdef double A31 = 3.0 / 40.0, A32 = 9.0 / 40.0
cdef double A41 = 44.0 / 45.0, A42 = -56.0 / 15.0, A43 = 32.0 / 9.0
cdef double A51 = 19372.0 / 6561.0, A52 = -25360.0 / 2187.0, A53 = 64448.0 / 6561.0
cdef double A54 = -212.0 / 729.0
cdef double A61 = 9017.0 / 3168.0, A62 = -355.0 / 33.0, A63 = 46732.0 / 5247.0
cdef double A64 = 49.0 / 176.0, A65 = -5103.0 / 18656.0
cdef double A71 = 35.0 / 384.0, A73 = 500.0 / 1113.0, A74 = 125.0 / 192.0
cdef double A75 = -2187.0 / 6784.0, A76 = 11.0 / 84.0
# error coefficients: 5th minus embedded 4th order weights
cdef double E1 = 71.0 / 57600.0, E3 = -71.0 / 16695.0, E4 = 71.0 / 1920.0
cdef double E5 = -17253.0 / 339200.0, E6 = 22.0 / 525.0, E7 = -1.0 / 40.0
# dense output (DOPRI5, CONTD5)
cdef double D1 = -12715105075.0 / 11282082432.0, D3 = 87487479700.0 / 32700410799.0
cdef double D4 = -10690763975.0 / 1880347072.0, D5 = 701980252875.0 / 199316789632.0
cdef double D6 = -1453857185.0 / 822651844.0, D7 = 69997945.0 / 29380423.0

cdef double SAFETY = 0.9, FACMIN = 0.2, FACMAX = 10.0
cdef double UROUND = 2.220446049250313e-16


cdef struct Run:
    bint project
    int n2                    # 2 n: length of y = (q, v)
    double rtol, atol
    double t, h, t_end
    bint last_rejected
    long accepted, rejected, n_rhs, newton_total, failures
    double max_cerr
    long n_out, n_req         # records written, records requested
    double *t_req             # requested output times (n_req, the first is 0)
    double *y                 # state at t
    double *y1                # trial state at t + h
    double *yt                # stage argument, then an output state
    double *k[7]              # stages K1..K7 (each 2n: velocity then acceleration)
    double *rc[5]             # dense output coefficients of the last accepted step
    double *q_out             # records, in numpy arrays owned by the caller
    double *v_out
    double *body_out
    double *e_out
    double *c_out
    EvC *ev                   # events (NULL: none)
    double t0                 # start of the last accepted step
    bint stopped              # a stop event ended the run at t_stop
    double t_stop


cdef int _f(Engine e, Run *r, int stage, double t, const double *y, double *k,
            bint reuse) noexcept nogil:
    """k = (v, a(t, q, v)) at y = (q, v)."""
    cdef int n = r.n2 // 2
    fcc_put_time(&e.asm.a, t)
    e.err_stage = stage
    r.n_rhs += 1
    memcpy(k, y + n, n * sizeof(double))
    if e.accelerations_at(y, y + n, k + n, reuse) < 0:
        return -1
    if r.ev != NULL:                          # active lock rows (events)
        return ev_constrain(e, r.ev, y, y + n, r.t, k + n)
    return 0


cdef void _combine(Run *r, double *out, double h, int s, const double *w) noexcept nogil:
    """out = y + h sum_{j < s} w[j] K_{j+1}."""
    cdef int i, j
    cdef double acc
    for i in range(r.n2):
        acc = 0.0
        for j in range(s):
            if w[j] != 0.0:
                acc += w[j] * r.k[j][i]
        out[i] = r.y[i] + h * acc


cdef int _stages(Engine e, Run *r, double h) noexcept nogil:
    """Stages 2..7 from K1 (already at y); leaves the 5th-order solution in y1."""
    cdef double w[6]
    w[0] = A21
    _combine(r, r.yt, h, 1, w)
    if _f(e, r, 2, r.t + C2 * h, r.yt, r.k[1], False) < 0: return -1
    w[0] = A31; w[1] = A32
    _combine(r, r.yt, h, 2, w)
    if _f(e, r, 3, r.t + C3 * h, r.yt, r.k[2], False) < 0: return -1
    w[0] = A41; w[1] = A42; w[2] = A43
    _combine(r, r.yt, h, 3, w)
    if _f(e, r, 4, r.t + C4 * h, r.yt, r.k[3], False) < 0: return -1
    w[0] = A51; w[1] = A52; w[2] = A53; w[3] = A54
    _combine(r, r.yt, h, 4, w)
    if _f(e, r, 5, r.t + C5 * h, r.yt, r.k[4], False) < 0: return -1
    w[0] = A61; w[1] = A62; w[2] = A63; w[3] = A64; w[4] = A65
    _combine(r, r.yt, h, 5, w)
    if _f(e, r, 6, r.t + h, r.yt, r.k[5], False) < 0: return -1
    w[0] = A71; w[1] = 0.0; w[2] = A73; w[3] = A74; w[4] = A75; w[5] = A76
    _combine(r, r.y1, h, 6, w)
    return _f(e, r, 7, r.t + h, r.y1, r.k[6], False)


cdef double _error_norm(Run *r, double h) noexcept nogil:
    """The scaled RMS norm of the local error estimate (NaN stays NaN: a rejection)."""
    cdef int i
    cdef double d, sk, acc = 0.0
    for i in range(r.n2):
        d = h * (E1 * r.k[0][i] + E3 * r.k[2][i] + E4 * r.k[3][i] + E5 * r.k[4][i]
                 + E6 * r.k[5][i] + E7 * r.k[6][i])
        sk = r.atol + r.rtol * fmax(fabs(r.y[i]), fabs(r.y1[i]))
        acc += (d / sk) * (d / sk)
    return sqrt(acc / r.n2)


cdef void _dense(Run *r, double h) noexcept nogil:
    """Coefficients of the continuous extension over the step y -> y1."""
    cdef int i
    cdef double dy, bspl
    for i in range(r.n2):
        dy = r.y1[i] - r.y[i]
        bspl = h * r.k[0][i] - dy
        r.rc[0][i] = r.y[i]
        r.rc[1][i] = dy
        r.rc[2][i] = bspl
        r.rc[3][i] = dy - h * r.k[6][i] - bspl
        r.rc[4][i] = h * (D1 * r.k[0][i] + D3 * r.k[2][i] + D4 * r.k[3][i]
                          + D5 * r.k[4][i] + D6 * r.k[5][i] + D7 * r.k[6][i])


cdef int _project(Engine e, Run *r, double *y, bint reuse) noexcept nogil:
    """Position then velocity projection of y = (q, v), in place; reuse: M, B and the
    factorisation held are the last stage's, at y (Engine.project_positions_at)."""
    cdef int rc, it = 0, n = r.n2 // 2
    e.err_where = AT_POSITIONS
    rc = e.project_positions_at(y, &it, reuse)
    if rc < 0:
        return -1
    r.failures += rc
    r.newton_total += it
    e.err_where = AT_VELOCITIES
    if e.project_velocities_at(y, y + n, e.b_fresh) < 0:
        return -1
    if r.ev != NULL:
        return ev_correct(e, r.ev, y, y + n)
    return 0


cdef void _dense_at(Run *r, double th, double *out) noexcept nogil:
    """The continuous extension of the last step at its fraction th."""
    cdef int i
    cdef double th1 = 1.0 - th
    for i in range(r.n2):
        out[i] = r.rc[0][i] + th * (r.rc[1][i] + th1 * (
            r.rc[2][i] + th * (r.rc[3][i] + th1 * r.rc[4][i])))


cdef int _locate(Engine e, Run *r, int k, double h, double *theta) noexcept nogil:
    """Illinois (ev_bracket) on th -> s_k(dense output at th) over [0, 1] of the step
    of size h from r.t0 (s_k crosses between ev.s0 and ev.s1); stops when the bracket
    is below tol / h. Returns the end of the bracket past the crossing."""
    cdef EvC *ev = r.ev
    cdef int n = r.n2 // 2
    cdef Bracket br
    cdef double c
    ev_bracket(ev, k, &br, 1.0)
    while ev_bracket_open(ev, &br, h):
        c = ev_bracket_trial(&br)
        _dense_at(r, c, r.yt)
        if ev_watch(e, ev, r.yt, r.yt + n, r.t0 + c * h, ev.s1 + 2 * ev.ne) < 0:
            return -1
        ev_bracket_update(ev, k, &br, c, ev.s1[2 * ev.ne + k])
    theta[0] = br.b
    return 0


cdef int _first_event(Engine e, Run *r, double h, double t1, double *theta) noexcept nogil:
    """The earliest event that crosses in the step r.t0 -> t1 (-1: none; -2: a solve
    failed), and where."""
    cdef EvC *ev = r.ev
    cdef int n = r.n2 // 2, k, j, first
    cdef double th
    if ev_watch(e, ev, r.y1, r.y1 + n, t1, ev.s1) < 0:
        return -2
    k = ev_crossed(ev, ev.s0, ev.s1)
    if k < 0:
        return -1
    theta[0], first = 1.0, k
    for j in range(k, 2 * ev.ne):
        if j > k and not ev_crosses(ev, j, ev.s0[j], ev.s1[j]):
            continue
        if _locate(e, r, j, h, &th) < 0:
            return -2
        if th < theta[0] or j == k:
            theta[0], first = th, j
    return first


cdef int _after_event(Engine e, Run *r, int k) noexcept nogil:
    """Act on event k at the (projected) state r.y, r.t; the next step's values."""
    cdef EvC *ev = r.ev
    cdef int n = r.n2 // 2, rc = 0
    if k >= 0:
        e.err_t = r.t
        rc = ev_apply(e, ev, k, r.y, r.y + n, r.t)
        if rc < 0:
            return -1
        if ev.stop:
            r.stopped, r.t_stop = True, r.t
            if r.n_out < r.n_req:             # the last record: the stop
                r.t_req[r.n_out] = r.t
                write_record(e, r.n_out, r.y, r.y + n, r.q_out, r.v_out, r.body_out,
                             r.e_out, r.c_out)
                r.n_out += 1
            return 0
    ev_refresh(ev, r.y)
    if ev_watch(e, ev, r.y, r.y + n, r.t, ev.s0) < 0:
        return -1
    if k >= 0 and rc == 0:
        ev.s0[k] = ev_leaving(ev, k, r.y, r.y + n, r.t)
    return 0


cdef int _record(Engine e, Run *r) noexcept nogil:
    """Write the requested output r.n_out from the dense output of the last step."""
    cdef Py_ssize_t j = r.n_out, n = r.n2 // 2
    cdef double th, th1, cerr
    cdef int i
    if j > 0:
        _dense_at(r, (r.t_req[j] - r.t0) / r.h, r.yt)
        if r.project:
            fcc_put_time(&e.asm.a, r.t_req[j])
            if _project(e, r, r.yt, False) < 0:
                return -1
            e.factor_valid = False        # the factorisation is not the one at r.y
    else:
        memcpy(r.yt, r.y, r.n2 * sizeof(double))
    cerr = write_record(e, j, r.yt, r.yt + n, r.q_out, r.v_out, r.body_out, r.e_out,
                        r.c_out)
    if not cerr <= r.max_cerr:
        r.max_cerr = cerr
    r.n_out += 1
    return 0


cdef int _accept(Engine e, Run *r, double h) noexcept nogil:
    """Take the accepted step y -> y1: outputs in (t, t + h], projection, next K1."""
    cdef int n = r.n2 // 2, k = -1
    cdef long recorded
    cdef double th = 1.0, t1
    _dense(r, h)
    r.t0 = r.t
    t1 = r.t + h if r.t_end - (r.t + h) > 4 * UROUND * r.t_end else r.t_end
    if r.ev != NULL:
        k = _first_event(e, r, h, t1, &th)
        if k == -2:
            return -1
        if k >= 0:                            # the step ends at the event
            t1 = r.t0 + th * h
            _dense_at(r, th, r.y1)
    r.t = t1
    r.accepted += 1
    recorded = r.n_out
    while r.n_out < r.n_req and r.t_req[r.n_out] <= r.t * (1 + 4 * UROUND):
        if _record(e, r) < 0:
            return -1
    memcpy(r.y, r.y1, r.n2 * sizeof(double))
    e.err_t = r.t
    if not finite(r.y, r.n2):
        e.err_where = AT_STEP
        return e.fail(ERR_NONFINITE_INPUT, 0, 1 if not finite(r.y, n) else 2)
    if r.project:
        fcc_put_time(&e.asm.a, r.t)
        # stage 7's M, B and factorisation are at y1, unless a record projected since
        if _project(e, r, r.y, r.n_out == recorded and r.ev == NULL) < 0:
            return -1
        if r.ev != NULL:
            if _after_event(e, r, k) < 0:
                return -1
            if r.stopped:
                return 0
        e.err_where = AT_STAGE
        return _f(e, r, 1, r.t, r.y, r.k[0], e.factor_valid)
    memcpy(r.k[0], r.k[6], r.n2 * sizeof(double))        # FSAL
    fcc_assemble(&e.asm.a, r.y, NULL, ASM_G)
    if not fcc_max_abs_g(&e.asm.a) <= r.max_cerr:
        r.max_cerr = fcc_max_abs_g(&e.asm.a)
    return 0


cdef int _run(Engine e, Run *r, double deadline) noexcept nogil:
    """Steps until the end (RUN_DONE), an error (RUN_ERROR, RUN_UNDERFLOW) or the
    wall-clock deadline (RUN_PAUSE)."""
    cdef double h, err, fac
    while r.t < r.t_end:
        h = fmin(r.h, r.t_end - r.t)
        if 0.1 * h <= fabs(r.t) * UROUND or h <= 0.0:
            e.err_t, e.err_h = r.t, h
            return RUN_UNDERFLOW
        e.err_where, e.err_t, e.err_h = AT_STAGE, r.t, h
        if _stages(e, r, h) < 0:
            return RUN_ERROR
        err = _error_norm(r, h)
        if err <= 1.0:
            fac = FACMAX if err == 0.0 else fmin(FACMAX, fmax(FACMIN, SAFETY * pow(err, -0.2)))
            if r.last_rejected and fac > 1.0:
                fac = 1.0
            r.h = h
            if _accept(e, r, h) < 0:
                return RUN_ERROR
            if r.stopped:
                return RUN_DONE
            r.h = h * fac
            r.last_rejected = False
        else:
            # NaN fails "err <= 1" too and shrinks the step by FACMIN
            fac = FACMIN if not err == err else fmax(FACMIN, SAFETY * pow(err, -0.2))
            r.h = h * fac
            r.rejected += 1
            r.last_rejected = True
        if r.t < r.t_end and now() >= deadline:
            return RUN_PAUSE
    return RUN_DONE


cdef double _initial_step(Engine e, Run *r) noexcept nogil:
    """Hairer's starting step (HINIT): h0 from |y|/|f|, refined by one more stage."""
    cdef int i
    cdef double sk, d0 = 0.0, d1 = 0.0, d2 = 0.0, h0, h1
    for i in range(r.n2):
        sk = r.atol + r.rtol * fabs(r.y[i])
        d0 += (r.y[i] / sk) ** 2
        d1 += (r.k[0][i] / sk) ** 2
    d0, d1 = sqrt(d0 / r.n2), sqrt(d1 / r.n2)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = fmin(h0, r.t_end)
    for i in range(r.n2):
        r.yt[i] = r.y[i] + h0 * r.k[0][i]
    if _f(e, r, 2, h0, r.yt, r.k[1], False) < 0:
        return -1.0
    for i in range(r.n2):
        sk = r.atol + r.rtol * fabs(r.y[i])
        d2 += ((r.k[1][i] - r.k[0][i]) / sk) ** 2
    d2 = sqrt(d2 / r.n2) / h0
    if fmax(d1, d2) <= 1e-15:
        h1 = fmax(1e-6, h0 * 1e-3)
    else:
        h1 = pow(0.01 / fmax(d1, d2), 0.2)
    return fmin(100.0 * h0, fmin(h1, r.t_end))


cdef double *_data(object array):
    """Pointer to the data of a C-contiguous float64 array (NULL if empty)."""
    cdef double[::1] flat = array.reshape(-1)
    return &flat[0] if flat.shape[0] else NULL


def output_times(double t_end, double output_dt):
    """0, output_dt, 2 output_dt, ... below t_end, then t_end."""
    n = int(t_end / output_dt * (1 + 1e-12))
    times = [k * output_dt for k in range(n + 1)
             if k * output_dt < t_end * (1 - 1e-12)]
    return np.array(times + [t_end])


def simulate_dopri5(Engine engine, q0, v0, double t_end, double output_dt, double rtol,
                    double atol, double h0, bint project, progress=None,
                    double progress_interval=0.5, events=None):
    """DOPRI5 from (q0, v0) (used as given) to t_end; records at 0, every output_dt and
    t_end by dense output. h0: the first step (0: Hairer's automatic choice).

    Returns (arrays, stats) like simulate_rk4, with stats steps (accepted),
    rejected_steps, rhs_evaluations, newton_iterations, projection_failures,
    max_constraint_error. Raises SimulationError on a singular mass matrix, a
    non-finite state, or a step size below the rounding of t.
    """
    if engine.running:
        raise RuntimeError("this engine is already running a simulation")
    if not (t_end > 0 and output_dt > 0 and rtol > 0 and atol > 0 and h0 >= 0):
        raise ValueError("need t_end, output_dt, rtol, atol > 0 and h0 >= 0")
    cdef double[::1] qv = engine.vector(q0, "q0"), vv = engine.vector(v0, "v0")
    engine.reset_warm_start()           # a run does not depend on earlier solves
    if not (np.all(np.isfinite(qv)) and np.all(np.isfinite(vv))):
        raise ValueError("q0 and v0 must be finite")
    cdef Py_ssize_t n = engine.n
    t_req = output_times(t_end, output_dt)
    n_out = len(t_req)
    arrays = dict(t=t_req, q=np.zeros((n_out, n)), v=np.zeros((n_out, n)),
                  body=np.zeros((n_out, engine.asm.n_bodies, 6)), energy=np.zeros(n_out),
                  constraint_error=np.zeros(n_out))
    work = np.zeros((15, 2 * n))
    cdef Run r
    cdef int i
    r.project, r.n2, r.rtol, r.atol, r.t_end = project, 2 * n, rtol, atol, t_end
    r.t, r.h, r.last_rejected = 0.0, h0, False
    r.accepted = r.rejected = r.n_rhs = r.newton_total = r.failures = 0
    r.max_cerr = 0.0
    r.n_out, r.n_req, r.t_req = 0, n_out, _data(t_req)
    r.y, r.y1, r.yt = _data(work[0]), _data(work[1]), _data(work[2])
    for i in range(7):
        r.k[i] = _data(work[3 + i])
    for i in range(5):
        r.rc[i] = _data(work[10 + i])
    r.q_out, r.v_out = _data(arrays["q"]), _data(arrays["v"])
    r.body_out, r.e_out = _data(arrays["body"]), _data(arrays["energy"])
    r.c_out = _data(arrays["constraint_error"])
    memcpy(r.y, &qv[0], n * sizeof(double))
    memcpy(r.y + n, &vv[0], n * sizeof(double))
    engine.factor_valid = False
    engine.err = ERR_NONE
    r.ev, r.stopped, r.t_stop, r.t0 = NULL, False, t_end, 0.0
    if events is not None:
        if not project:
            raise ValueError("events need the projected DOPRI5 (projection on)")
        r.ev = ev_state(events)
        events.reset(qv, engine)
        with nogil:
            ev_watch(engine, r.ev, r.y, r.y + n, 0.0, r.ev.s0)
    cdef int status
    cdef double deadline
    engine.running = True
    try:
        _record(engine, &r)
        engine.err_where, engine.err_t, engine.err_h = AT_STAGE, 0.0, h0
        with nogil:
            status = _f(engine, &r, 1, 0.0, r.y, r.k[0], False)
            if status == 0 and r.h == 0.0:
                r.h = _initial_step(engine, &r)
                status = -1 if r.h < 0 else 0
        if status < 0:
            raise SimulationError(_message(engine))
        while True:
            deadline = now() + progress_interval
            with nogil:
                status = _run(engine, &r, deadline)
            if status == RUN_DONE:
                break
            if status == RUN_ERROR:
                raise SimulationError(_message(engine))
            if status == RUN_UNDERFLOW:
                raise SimulationError(
                    f"simulation stopped at t = {r.t:.10g}: DOPRI5 step size underflow "
                    f"(h = {engine.err_h:.3g} after {r.rejected} rejected steps): the "
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
        engine.running = False
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
