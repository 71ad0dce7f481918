# cython: language_level=3
"""ALI3-P: the index-3 augmented Lagrangian formulation with mass-orthogonal
projections, integrated by the trapezoidal rule (engine/fcc_ali3p.c: the whole step
loop in C without the GIL; its docstring has the equations and the choices).

This wrapper checks the arguments, computes the starting accelerations, multipliers
and penalties (ali3p_setup.initial_state), and runs the C loop in slices: it leaves C
about every 0.5 s of wall time for signals and an optional progress callback, and words
a failure (ali3p_setup.failure_message).

The penalty is one number per constraint row: alpha_k = penalty * m_ref / ||B_k||^2,
with m_ref the largest diagonal entry of M and B_k the row of B, both at the initial
state, so that every row adds about (h^2/4) penalty * m_ref to the tangent whatever
the units of its equation (lengths squared, unit vectors, ...). The default penalty
1e9 (per time unit squared) makes that 250 m_ref at h = 1e-3, as the references' 1e7
does at their h = 1e-2: a multiplier update then shrinks g about 250-fold and steps
converge in 2-4 iterations on the examples. With 1e7 at h = 1e-3 (ratio 2.5) the
examples took 6-8 iterations per step and the four-bar did not converge at h = 5e-4.

Singular positions need more. A multiplier update shrinks the part of g along a
singular direction of the row-scaled B with singular value s by about
1 / (1 + (h^2/4) penalty s^2); near a position where B loses rank some s go to zero
and the iteration stalls. On the N-four-bar (examples/a02_n_four_bar.yaml, 162 rows of
rank 122, 40 more lost when the chain lies flat) at h = 1e-3, penalty 1e9 stops at
t = 0.64 s and 1e11 at 0.72 s (the first flat position) with corrections of 5e-10 and
3e-9 still above the tolerance, while 1e12 and 1e13 pass all 20 flat positions of its
20 s in 2.7 and 2.6 iterations per step (B0 error against the benchmark 4.4e-4 and
3.8e-4 m). The larger penalty is not the default because it costs accuracy on long
regular runs at this tolerance: on the A01 pendulum (2000 s, h = 1e-3) the position
error is 6.9e-3 m at 1e9 and 2.7e-2 m at 1e12 (and 0.33 m at 1e13); with
newton_tol = 1e-13 both 1e9 and 1e12 give 6.8-7.0e-3 m, so the difference comes from
the iterates accepted at the 1e-10 L tolerance, not from the penalty itself.

Long scissor chains have a small last kept singular value s_r of the row-scaled B at
every position, not only near singular ones (12-unit boom 3.0e-3, 50-bay mast
3.1e-4): with 1e9 their steps stalled from t = 0.013 and 0.031 s on. So the default
penalty is raised at the start of a run to PENALTY_RATIO 4 / (h^2 s_r^2) where that is
larger (ali3p_setup.conditioned_penalty: 1.1e12 for the boom, 1e14 for the mast; the
pendulum, the four-bars and Bricard keep 1e9), and a step that still stalls is taken
again with a tenfold penalty (FCC_ALI3P_PENALTY_RAISE, engine/fcc_ali3p.c). The boom
then runs its 4 s in at most 4 iterations per step, 1.1e-5 m from dopri5 at rtol 1e-10
(2.8e-6 m at h = 5e-4: second order), and the mast its 2 s in 2.
"""
from cpython.exc cimport PyErr_CheckSignals

import numpy as np

from fccgen.errors import SimulationError

from fccgen.results.result import keep_rows

from ._cengine cimport (FCC_ALI3P_PENALTY_RAISE, FCC_RUN_DONE, FCC_RUN_ERROR, fcc_ali3p,
                        fcc_ali3p_advance, fcc_ali3p_record, fcc_ali3p_start,
                        fcc_run_finish)
from ._engine cimport Engine
from ._runloop cimport array_data, now, past_deadline

from .ali3p_setup import DEFAULTS, failure_message, initial_state, run_options


cdef str _message(fcc_ali3p *r):
    return failure_message(r.fail, r.fail_info, r.fail_detail, r.fail_t, r.fail_h,
                           r.fail_dq, r.tol)


def simulate_ali3p(Engine engine, q0, v0, double t_end, double dt, long n_steps,
                   long output_every, options=None, progress=None,
                   double progress_interval=0.5, double length_scale=1.0):
    """ALI3-P (module docstring) from (q0, v0), used as given, over n_steps steps of
    dt, the last one shortened to end at t_end. Records t = 0, every output_every steps
    and t_end.

    options: penalty (default 1e9, per time unit squared), newton_tol (default 1e-10,
    relative to length_scale, the largest body length), max_newton (default 30). progress(t) is
    called when the run pauses, at most every progress_interval seconds of wall time.
    Returns (arrays, stats): fresh arrays t, q, v, body, energy, constraint_error;
    stats steps, rhs_evaluations (kernel assemblies), newton_iterations (total),
    max_newton_iterations, projection_failures (steps accepted after max_newton
    iterations with converged corrections but max_k |g_k| / ||B_k|| still above the
    tolerance), slow_newton_steps (steps accepted after max_newton iterations with
    the residual within the tolerance and corrections shrinking but above it, at most
    SLOW_FACTOR times it: engine/fcc_ali3p.c), max_constraint_error, lu_factorizations,
    penalty (the last, after raises), penalty_start, penalty_raises, newton_tol. Raises SimulationError (with the time and what failed) when Newton
    does not converge, the tangent is not positive definite or a value is not finite.
    """
    if engine.c.running:
        raise RuntimeError("this engine is already running a simulation")
    if not (n_steps >= 1 and output_every >= 1 and dt > 0 and t_end > 0):
        raise ValueError("need n_steps >= 1, output_every >= 1, dt > 0, t_end > 0")
    if not (0 < t_end - (n_steps - 1) * dt <= dt * (1 + 1e-9)):
        raise ValueError(f"{n_steps} steps of {dt!r} do not end at t_end = {t_end!r}")
    q0 = np.array(q0, dtype=float).reshape(-1)
    v0 = np.array(v0, dtype=float).reshape(-1)
    cdef int n = engine.asm.n_q, m = engine.asm.n_g
    if q0.shape != (n,) or v0.shape != (n,):
        raise ValueError(f"q0 and v0 must have shape ({n},)")
    if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(v0))):
        raise ValueError("q0 and v0 must be finite")
    if not length_scale > 0:
        raise ValueError("length_scale must be positive")
    given = getattr(options, "given", None)
    auto = "penalty" not in (given if given is not None else (options or {}))
    opts = run_options(options, length_scale)
    engine.set_time(0.0)
    a0, lam, alpha, hint, penalty = initial_state(engine, q0, v0, opts["penalty"],
                                                  dt if auto else None)
    n_out = 1 + n_steps // output_every + (1 if n_steps % output_every else 0)
    arrays = dict(t=np.zeros(n_out), q=np.zeros((n_out, n)), v=np.zeros((n_out, n)),
                  body=np.zeros((n_out, engine.asm.n_bodies, 6)), energy=np.zeros(n_out),
                  constraint_error=np.zeros(n_out))
    state = np.zeros(7 * n + 4 * m + 2 * n * n + 1)    # FCC_ALI3P_STATE, kept for the run
    state[:n], state[n:2 * n], state[2 * n:3 * n] = q0, v0, a0
    state[6 * n:6 * n + m], state[6 * n + m:6 * n + 2 * m] = lam, alpha
    pivots = np.zeros(n, dtype=np.intc)
    cdef int[::1] piv = pivots
    cdef double deadline = 0.0
    cdef fcc_ali3p r
    r.n_steps, r.every, r.dt, r.t_end = n_steps, output_every, dt, t_end
    r.tol, r.max_newton = opts["tolerance"], opts["max_newton"]
    # no raise where a stiff spring, not the constraints, stalls Newton (hint given):
    # measured on the rod of tests/test_ali3p.py with k/m = 1e10, raising to 1e11 ran
    # on with its energy down to 9% of the start, and at 1e12 diverged
    r.max_raises = 0 if hint else opts["max_penalty_raises"]
    r.state, r.ipiv = array_data(state), &piv[0]
    r.out.t, r.out.q, r.out.v = (array_data(arrays["t"]), array_data(arrays["q"]),
                                 array_data(arrays["v"]))
    r.out.body, r.out.energy = array_data(arrays["body"]), array_data(arrays["energy"])
    r.out.cerr = array_data(arrays["constraint_error"])
    r.pause, r.pause_ctx = past_deadline, &deadline
    cdef int status
    fcc_ali3p_start(&r, &engine.c)
    try:
        fcc_ali3p_record(&engine.c, &r, 0.0)
        while True:
            deadline = now() + progress_interval
            with nogil:
                status = fcc_ali3p_advance(&engine.c, &r)
            if status == FCC_RUN_DONE:
                break
            if status == FCC_RUN_ERROR:
                raise SimulationError(_message(&r) + (hint if r.k < 3 else ""))
            PyErr_CheckSignals()
            if progress is not None:
                progress(r.k * dt)
    except (SimulationError, KeyboardInterrupt) as exc:
        keep_rows(exc, arrays, r.n_out,
                  dict(steps=r.k, rhs_evaluations=r.n_asm, newton_iterations=r.newton_total, max_constraint_error=r.max_cerr))
        raise
    finally:
        fcc_run_finish(&engine.c)
        engine.c.factor_valid = False
    stats = dict(steps=r.k, rhs_evaluations=r.n_asm, newton_iterations=r.newton_total,
                 max_newton_iterations=r.newton_max, projection_failures=r.failures,
                 slow_newton_steps=r.slow_steps,
                 max_constraint_error=r.max_cerr, lu_factorizations=r.lu_steps,
                 penalty=float(penalty) * FCC_ALI3P_PENALTY_RAISE ** r.raises,
                 penalty_start=float(penalty),
                 penalty_raises=r.raises, newton_tol=opts["newton_tol"])
    return arrays, stats

