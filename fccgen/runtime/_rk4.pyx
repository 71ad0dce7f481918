# cython: language_level=3
"""Classical RK4 with projection, and RK4 on the Baumgarte-stabilised equations
(engine/fcc_rk4.c: the whole per-step loop, events included, in C without the GIL).

This wrapper checks the arguments, allocates the records, and runs the C loop in
slices: it leaves C about every 0.5 s of wall time, for signals (Ctrl-C) and an
optional progress callback, and turns the engine's error record into a
SimulationError.
"""
from cpython.exc cimport PyErr_CheckSignals
from libc.string cimport memset

import numpy as np

from fccgen.errors import SimulationError
from fccgen.progress import reads_only

from ._cengine cimport (FCC_RUN_DONE, FCC_RUN_ERROR, fcc_rk4, fcc_rk4_advance,
                        fcc_rk4_record, fcc_rk4_start, fcc_run_finish)
from ._engine cimport Engine
from ._events cimport ev_state
from ._power cimport power_state
from ._sens cimport sens_events, sens_state
from ._runloop cimport array_data, now, past_deadline

from ._messages import error_message
from fccgen.results.result import keep_rows


cdef struct held_inputs:
    # the model's inputs held between records (fccgen.runs.inputs): after record j
    # the slots take row j of the table; then the run's wall-clock pause rule
    fcc_rk4 *r
    double *params
    double *deadline
    int n_slots, n_cols
    const int *slot
    const int *col
    const double *table
    long applied             # the record whose row the parameters hold
    double *evp              # the event kernels' parameters (NULL: no event reads one)
    int n_ev
    const int *ev_slot
    const int *ev_col


cdef int pause_holding_inputs(void *ctx) noexcept nogil:
    """The pause callback of a run with inputs (called after every step): a step
    that wrote record j sets the inputs to row j, for the steps up to the next one."""
    cdef held_inputs *h = <held_inputs *>ctx
    cdef long j = h.r.n_out - 1
    cdef int i
    if j != h.applied:
        for i in range(h.n_slots):
            h.params[h.slot[i]] = h.table[j * h.n_cols + h.col[i]]
        for i in range(h.n_ev):
            h.evp[h.ev_slot[i]] = h.table[j * h.n_cols + h.ev_col[i]]
        h.applied = j
    return past_deadline(h.deadline)


def simulate_rk4(Engine engine, q0, v0, double t_end, double dt, long n_steps,
                 long output_every, bint project, progress=None,
                 double progress_interval=0.5, events=None, work=None, inputs=None,
                 sens=None, bint interpolant=True, bint on_interpolant=False):
    """Classical RK4 from (q0, v0) (used as given) over n_steps steps of dt, the last
    one shortened to end at t_end; after each step, if project, position then velocity
    projection. Records t = 0, every output_every steps and t_end.

    progress(t) is called when the run pauses, at most every progress_interval seconds
    of wall time. work: a _power.WorkTracker (None: no work to track). Returns
    (arrays, stats): fresh arrays t, q, v, body, energy, constraint_error (and with a
    tracker work, of the forces without potential); stats steps, rhs_evaluations,
    newton_iterations (total), max_newton_iterations, projection_failures,
    max_constraint_error. Raises SimulationError (with the time and what failed) on a
    singular mass matrix, a non-finite state or one past the divergence bounds.

    inputs: None, or (slots, columns, table) of fccgen.runs.inputs: the parameter
    slots[i] holds table[j, columns[i]] from record j to record j + 1 (row 0 from the
    start; one row per record).

    sens: a _sens.Sensitivities (None: none) whose ``records`` the run fills, one per
    record (needs project, no events and the dense path).

    interpolant: an event's location places its trials (re-integrated partial steps)
    by the step's Hermite interpolant; False: by the Illinois iteration alone, twice
    the partial steps (the reference the tests compare the located times with).

    on_interpolant (needs interpolant): an event function's crossing is located on the
    step's interpolant, with the acceleration evaluated at the step's end, and the
    state there is the interpolant's, projected (event_location="interpolant" of
    simulate): an event step costs one evaluation more than a step and the rest of
    the step, whatever the crossing. Runs with sensitivities take the partial steps.
    """
    return _simulate(engine, q0, v0, t_end, dt, n_steps, output_every, project, False,
                     0.0, 0.0, progress, progress_interval, events, work, inputs, sens,
                     interpolant, on_interpolant)


def simulate_baumgarte(Engine engine, q0, v0, double t_end, double dt, long n_steps,
                       long output_every, double alpha, double beta, progress=None,
                       double progress_interval=0.5, events=None, work=None,
                       inputs=None):
    """RK4 on the index-1 equations with Baumgarte stabilisation,
    B q'' = -(dB/dt) q' - 2 alpha B q' - beta^2 g, without projection; otherwise as
    :func:`simulate_rk4` (same arguments, records and stats; events: a set without
    event functions, whose angle references it re-bases after every step)."""
    if not (alpha >= 0 and beta >= 0):
        raise ValueError("Baumgarte alpha and beta must be non-negative")
    return _simulate(engine, q0, v0, t_end, dt, n_steps, output_every, False, True,
                     alpha, beta, progress, progress_interval, events, work, inputs)


def _simulate(Engine engine, q0, v0, double t_end, double dt, long n_steps,
              long output_every, bint project, bint baumgarte, double alpha, double beta,
              progress, double progress_interval, events=None, work=None, inputs=None,
              sens=None, bint interpolant=True, bint on_interpolant=False):
    """The shared driver of simulate_rk4 and simulate_baumgarte."""
    if engine.c.running:
        raise RuntimeError("this engine is already running a simulation")
    if not (n_steps >= 1 and output_every >= 1 and dt > 0 and t_end > 0):
        raise ValueError("need n_steps >= 1, output_every >= 1, dt > 0, t_end > 0")
    if not (0 < t_end - (n_steps - 1) * dt <= dt * (1 + 1e-9)):
        raise ValueError(f"{n_steps} steps of {dt!r} do not end at t_end = {t_end!r}")
    # a set without event functions only re-bases angle references (springs)
    if events is not None and (baumgarte or not project) and events.n_events:
        raise ValueError("events need the projected RK4 (method rk4, projection on)")
    if work is not None:
        work.fits(engine)
    if sens is not None and (baumgarte or not project):
        raise ValueError("sensitivities need the projected RK4")
    cdef double[::1] qv = engine.vector(q0, "q0"), vv = engine.vector(v0, "v0")
    engine.reset_warm_start()           # a run does not depend on earlier solves
    if not (np.all(np.isfinite(qv)) and np.all(np.isfinite(vv))):
        raise ValueError("q0 and v0 must be finite")
    cdef Py_ssize_t n = engine.c.n
    n_out = 1 + n_steps // output_every + (1 if n_steps % output_every else 0)
    arrays = dict(t=np.zeros(n_out), q=np.zeros((n_out, n)), v=np.zeros((n_out, n)),
                  body=np.zeros((n_out, engine.asm.n_bodies, 6)), energy=np.zeros(n_out),
                  constraint_error=np.zeros(n_out))
    work_out = np.zeros(n_out)
    if work is not None:                # the work at the records (array "work")
        arrays["work"] = work_out
    saved = np.zeros(2 * n)             # an event's step start
    dense = np.zeros(6 * n)             # the step's interpolant (event location)
    cdef double deadline = 0.0
    cdef fcc_rk4 r
    memset(&r, 0, sizeof(r))
    r.project, r.n_steps, r.every, r.dt, r.t_end = project, n_steps, output_every, dt, t_end
    r.baumgarte, r.alpha, r.beta = baumgarte, alpha, beta
    r.out.t, r.out.q, r.out.v = (array_data(arrays["t"]), array_data(arrays["q"]),
                                 array_data(arrays["v"]))
    r.out.body, r.out.energy = array_data(arrays["body"]), array_data(arrays["energy"])
    r.out.cerr = array_data(arrays["constraint_error"])
    r.saved = array_data(saved)
    r.dense = array_data(dense) if interpolant else NULL
    r.on_interpolant = on_interpolant and interpolant
    r.pause, r.pause_ctx = past_deadline, &deadline
    cdef held_inputs held
    cdef int i
    cdef int[::1] in_slot, in_col, ev_slot, ev_col
    cdef double[::1] in_table
    r.ev = ev_state(events)
    if inputs is not None:
        # (element slots, columns, table[, event-parameter slots, columns])
        in_slot = np.ascontiguousarray(inputs[0], dtype=np.intc)
        in_col = np.ascontiguousarray(inputs[1], dtype=np.intc)
        table = np.ascontiguousarray(inputs[2], dtype=float)
        ev_slot = np.ascontiguousarray(inputs[3] if len(inputs) > 3 else (), dtype=np.intc)
        ev_col = np.ascontiguousarray(inputs[4] if len(inputs) > 4 else (), dtype=np.intc)
        if (table.ndim != 2 or table.shape[0] != n_out or in_slot.shape[0] != in_col.shape[0]
                or in_slot.shape[0] + ev_slot.shape[0] == 0
                or ev_slot.shape[0] != ev_col.shape[0]
                or (ev_slot.shape[0] and (r.ev == NULL or np.any(np.asarray(ev_slot) < 0)
                                          or np.any(np.asarray(ev_slot) >= r.ev.spec.np)))
                or np.any(np.asarray(in_col) < 0) or np.any(np.asarray(ev_col) < 0)
                or np.any(np.asarray(in_col) >= table.shape[1])
                or np.any(np.asarray(ev_col) >= table.shape[1])
                or np.any(np.asarray(in_slot) < 0)
                or np.any(np.asarray(in_slot) >= engine.asm.model.n_p)):
            raise ValueError("inputs: slots, columns and a table of one row per record")
        in_table = table.reshape(-1)
        held.r, held.params, held.deadline = &r, engine.c.asmb.params, &deadline
        held.n_slots, held.n_cols = in_slot.shape[0], table.shape[1]
        held.slot = &in_slot[0] if in_slot.shape[0] else NULL
        held.col = &in_col[0] if in_col.shape[0] else NULL
        held.table = &in_table[0]
        held.n_ev = ev_slot.shape[0]
        held.evp = r.ev.p if held.n_ev else NULL
        held.ev_slot = &ev_slot[0] if held.n_ev else NULL
        held.ev_col = &ev_col[0] if held.n_ev else NULL
        held.applied = 0
        for i in range(held.n_slots):              # row 0 from the start
            held.params[held.slot[i]] = held.table[held.col[i]]
        for i in range(held.n_ev):
            held.evp[held.ev_slot[i]] = held.table[held.ev_col[i]]
        r.pause, r.pause_ctx = pause_holding_inputs, &held
    r.pw = power_state(work)
    r.w_out = array_data(work_out)
    r.sens = sens_state(sens, n_out)
    if r.sens != NULL and r.ev != NULL:
        sens_events(sens, r.ev, r.ev.spec.cap_log)
    if events is not None:
        events.reset(qv, engine, fold=sens is None)
    cdef int status
    try:
        with nogil:
            fcc_rk4_start(&r, &engine.c, &qv[0], &vv[0])
            fcc_rk4_record(&engine.c, &r, 0.0)
        while True:
            deadline = now() + progress_interval
            with nogil:
                status = fcc_rk4_advance(&engine.c, &r)
            if status == FCC_RUN_DONE:
                break
            if status == FCC_RUN_ERROR:
                raise SimulationError(error_message(engine.error_record(), in_run=True))
            PyErr_CheckSignals()
            if progress is not None:
                progress(r.k * dt)
                if not reads_only(progress):
                    # the callback may have used the engine; without one (or with one
                    # that only reads, fccgen.progress.reads_only) the factorisation
                    # held stays, so that a run's numbers do not depend on when it
                    # paused (a fresh factorisation after a pause counts down the
                    # raised penalties' hold: A02 ended 1.8e-5 m apart)
                    engine.c.factor_valid = False
    except (SimulationError, KeyboardInterrupt) as exc:
        keep_rows(exc, arrays, r.n_out,
                  dict(steps=r.k, rhs_evaluations=r.n_rhs, newton_iterations=r.newton_total, max_constraint_error=r.max_cerr))
        raise
    finally:
        fcc_run_finish(&engine.c)
        if events is not None:
            events.unfold(engine)
    stats = dict(steps=r.k, rhs_evaluations=r.n_rhs, rejected_steps=0,
                 newton_iterations=r.newton_total, max_newton_iterations=r.newton_max,
                 projection_failures=r.failures, max_constraint_error=r.max_cerr)
    if r.stopped:                              # a stop event: the records so far
        arrays = {k: a[:r.n_out] for k, a in arrays.items()}
        stats["stopped_at"] = r.t_stop
    return arrays, stats
