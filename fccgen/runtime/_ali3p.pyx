# cython: language_level=3
"""ALI3-P: the index-3 augmented Lagrangian formulation with mass-orthogonal
projections, integrated by the trapezoidal rule, the whole step loop in C.

References: E. Bayo, J. Garcia de Jalon, "Kinematic and Dynamic Simulation of
Multibody Systems", Springer 1994, ch. 4-5; J. Cuadrado, J. Cardenal, E. Bayo,
"Modeling and solution methods for efficient real-time simulation of multibody
dynamics", Multibody System Dynamics 1 (1997) 259-280.

Equations: M q'' + B^T (alpha g + lambda) = Q with Q = f - h, the multipliers lambda
iterated so that g -> 0. The trapezoidal rule over a step h gives
    q' = (2/h) q - (2/h) q_n - q'_n,   q'' = (4/h^2) q - (4/h^2) q_n - (4/h) q'_n - q''_n,
so the dynamic equations premultiplied by h^2/4 are a system in q alone,
    F(q) = (h^2/4) [M q'' + B^T (alpha g + lambda) - Q] = 0,
solved by Newton with the tangent T = M + (h/2) C + (h^2/4) (B^T alpha B + K),
K = -df/dq and C = -df/dq' (the force Jacobian kernels; the derivatives of M, B and h
are left out, as in the references). After each Newton correction lambda += alpha g.
A step converges when the last correction max |dq| and the constraint residual
max_k |g_k| / ||B_k|| are both at most newton_tol * L (L the largest body length): with
a small penalty the corrections can become small while g still shrinks only by a
constant factor per multiplier update. Steps that end max_newton iterations with g
within the tolerance and shrinking corrections are accepted under conditions given at
SLOW_FACTOR below (singular positions).
Then the speeds and accelerations are projected mass-orthogonally with the same T:
    T q'  = W q'~  - (h^2/4) B^T alpha (0),
    T q'' = W q''~ - (h^2/4) B^T alpha ((dB/dt) q'),   W = T - (h^2/4) B^T alpha B,
i.e. q' = q'~ - T^-1 (h^2/4) B^T alpha B q'~, and likewise for q''.

T is symmetrised, (T + T^T)/2, before its Cholesky factorisation: K and C of dampers
and follower torques are not symmetric; the iteration then is a quasi-Newton one whose
fixed point is unchanged. When a load's stiffness has negative directions larger than
the mass and penalty terms (a strongly compressed spring: K holds -T/L (E - n n^T)),
T is not positive definite and is factored by LU instead (counted in the stats).
M + (h^2/4) B^T alpha B is positive definite for a well
posed model even with redundant rows in B (M needs to be positive definite on the
null space of B only), so redundant constraints and singular positions pass.

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
"""
from cpython.exc cimport PyErr_CheckSignals
from libc.math cimport fabs, isfinite
from libc.string cimport memcpy
from scipy.linalg.cython_lapack cimport dgetrf, dgetrs, dpotrf, dpotrs

import numpy as np

from fccgen.errors import SimulationError

from fccgen.results import keep_rows

from ._cengine cimport fcc_assemble, fcc_put_time, fcc_max_abs_g, fcc_scaled_residual
from ._assemble cimport (ASM_B, ASM_C, ASM_F, ASM_G, ASM_H, ASM_KQ,
                         ASM_KV, ASM_M, ASM_T)
from ._engine cimport Engine, finite
from ._runloop cimport RUN_DONE, RUN_ERROR, RUN_PAUSE, now, write_record

from .ali3p_setup import DEFAULTS, failure_message, initial_state, run_options

cdef enum:                   # failure codes, explained by ali3p_setup.failure_message
    FAIL_NEWTON = 1          # Newton did not converge within max_newton
    FAIL_TANGENT = 2         # the tangent is singular (dgetrf info)
    FAIL_NONFINITE = 3       # a non-finite state or assembled quantity (detail)

cdef int STEP_FLAGS = ASM_M | ASM_H | ASM_F | ASM_G | ASM_B | ASM_KQ | ASM_KV

# A step that ends max_newton iterations with the constraints met (max |g_k| / ||B_k||
# <= tol) and its corrections still shrinking is accepted if the last correction is at
# most SLOW_FACTOR * tol (counted in slow_newton_steps): at a position where B loses
# rank the multiplier iteration contracts only slowly (by 0.9-0.98 per iteration,
# whatever the penalty) in the lost directions, while the constraints already hold.
# fccgen's choice: on the N-four-bar (examples/a02_n_four_bar.yaml, h = 1e-3, penalty
# 1e12, 20 s) 50 steps end their 30 iterations with corrections of 1e-10 to 2e-9 L;
# with max_newton = 400 instead all but one converge, and B0 moves by at most
# 1.9e-6 m (the run's error against the benchmark reference is 4.4e-4 m).
cdef double SLOW_FACTOR = 1e3


cdef struct Run:
    int n, m
    long k, n_steps, every, n_out
    double dt, t_end, tol
    int max_newton
    long n_asm                # kernel assemblies
    long newton_total
    int newton_max
    long failures             # steps accepted with a constraint residual above tol
    long slow_steps           # steps accepted with shrinking corrections above tol
    double max_cerr
    int fail, fail_info, fail_detail
    double fail_t, fail_h, fail_dq
    double *q                 # state: q, q', q'', multipliers
    double *v
    double *a
    double *lam
    double *alpha             # penalty per constraint row
    double *q0                # q, q' at the start of the step
    double *v0
    double *a0
    double *T                 # tangent (n x n, column-major = row-major: symmetric)
    double *T2                # its copy, for the LU fallback
    int *ipiv                 # LU pivots
    bint lu                   # T holds an LU (not a Cholesky) factorisation
    long lu_steps             # tangents factored by LU
    double *r                 # residual / right-hand sides
    double *w                 # m numbers
    double *t_out             # records, in numpy arrays owned by the caller
    double *q_out
    double *v_out
    double *body_out
    double *e_out
    double *c_out


cdef int _failed(Run *r, int code, int info, int detail) noexcept nogil:
    r.fail, r.fail_info, r.fail_detail = code, info, detail
    return -1


cdef int _tangent(Engine e, Run *r, double h) noexcept nogil:
    """T = sym(M - (h/2) df/dq' - (h^2/4) df/dq) + (h^2/4) B^T alpha B, factored in
    place (upper Cholesky factor, LAPACK column-major = our row-major transpose)."""
    cdef int i, j, k, n = r.n, info = 0
    cdef double h2 = 0.5 * h, h4 = 0.25 * h * h, x, bk
    cdef char uplo = b'L'
    for i in range(n):
        for j in range(i, n):
            x = 0.5 * (e.asm.a.M[i * n + j] + e.asm.a.M[j * n + i]
                       - h2 * (e.asm.a.fv[i * n + j] + e.asm.a.fv[j * n + i])
                       - h4 * (e.asm.a.fq[i * n + j] + e.asm.a.fq[j * n + i]))
            r.T[i * n + j] = x
    for k in range(r.m):
        for i in range(n):
            bk = e.asm.a.B[k * n + i]
            if bk == 0.0:
                continue
            bk *= h4 * r.alpha[k]
            for j in range(i, n):
                r.T[i * n + j] += bk * e.asm.a.B[k * n + j]
    for i in range(n):
        for j in range(i, n):
            r.T2[i * n + j] = r.T2[j * n + i] = r.T[i * n + j]
    # row-major upper triangle = column-major lower triangle
    r.lu = False
    dpotrf(&uplo, &n, r.T, &n, &info)
    if info == 0:
        return 0
    # not positive definite: a load stiffness -df/dq with negative directions (a
    # compressed spring) larger than the mass and penalty terms; LU still solves
    memcpy(r.T, r.T2, <size_t>n * n * sizeof(double))
    dgetrf(&n, &n, r.T, &n, r.ipiv, &info)
    if info != 0:
        return _failed(r, FAIL_TANGENT, info, 0)
    r.lu = True
    r.lu_steps += 1
    return 0


cdef void _solve(Run *r, double *x) noexcept nogil:
    """x <- T^-1 x with the factored tangent."""
    cdef int n = r.n, one = 1, info = 0
    cdef char uplo = b'L', trans = b'N'
    if r.lu:
        dgetrs(&trans, &n, &one, r.T, &n, r.ipiv, x, &n, &info)
    else:
        dpotrs(&uplo, &n, &one, r.T, &n, x, &n, &info)


cdef void _add_bt_alpha(Engine e, Run *r, const double *y, double scale,
                        double *out) noexcept nogil:
    """out += scale B^T (alpha * y) (y: one number per constraint row)."""
    cdef int k, j, n = r.n
    cdef double c
    for k in range(r.m):
        c = scale * r.alpha[k] * y[k]
        if c == 0.0:
            continue
        for j in range(n):
            out[j] += c * e.asm.a.B[k * n + j]


cdef int _assemble(Engine e, Run *r, const double *q, const double *v,
                   int flags) noexcept nogil:
    """Assemble and check that the state and what was assembled are finite."""
    cdef int bad
    r.n_asm += 1
    fcc_assemble(&e.asm.a, q, v, flags)
    bad = e.nonfinite_input(q, v, flags)
    if bad == 0 and flags & ASM_KQ and not finite(e.asm.a.fq, r.n * r.n):
        bad = 9
    if bad == 0 and flags & ASM_KV and not finite(e.asm.a.fv, r.n * r.n):
        bad = 10
    if bad:
        return _failed(r, FAIL_NONFINITE, 0, bad)
    return 0


cdef int _newton(Engine e, Run *r, double h, int *iterations) noexcept nogil:
    """Positions, speeds and accelerations at the end of the step (before the
    projections), from the predictor q = q_n + h q'_n (the trapezoidal relations then
    give q' = q'_n, q'' = -q''_n). The references' predictor adds h^2/2 q''_n; with
    stiff loads (k h^2 / m >> 1) that lands far outside Newton's basin, while on the
    examples the simpler one costs under one more iteration per step.

    Converged when the last correction max |dq| and the constraint residual
    max_k |g_k| / ||B_k|| are both within the tolerance. When max_newton iterations
    end with converged corrections but a residual above it, the step is accepted and
    counted as a failure; when they end with the residual within it and corrections
    shrinking, at most SLOW_FACTOR times it, the step is accepted and counted as
    slow; otherwise the run stops. Leaves everything
    assembled at the final positions (and g in the multipliers)."""
    cdef int i, j, it = 0, n = r.n
    cdef double h4 = 0.25 * h * h, dqmax = 0.0, dqlast = 0.0, x, res
    for i in range(n):
        r.q[i] = r.q0[i] + h * r.v0[i]
        r.v[i] = r.v0[i]
        r.a[i] = -r.a0[i]
    while True:
        if _assemble(e, r, r.q, r.v, STEP_FLAGS) < 0:
            return -1
        if it > 0:
            for i in range(r.m):
                r.lam[i] += r.alpha[i] * e.asm.a.g[i]
            if dqmax <= r.tol or it >= r.max_newton:
                res = fcc_scaled_residual(&e.asm.a)
                if dqmax <= r.tol and res <= r.tol:
                    break
                if it >= r.max_newton and dqmax <= r.tol:
                    r.failures += 1
                    break
                if (it >= r.max_newton and res <= r.tol and dqmax < dqlast
                        and dqmax <= SLOW_FACTOR * r.tol):
                    r.slow_steps += 1
                    break
        if it >= r.max_newton:
            r.fail_dq = dqmax
            return _failed(r, FAIL_NEWTON, it, 0)
        # -F = -(h^2/4) [M q'' + h - f + B^T (alpha g + lambda)]
        for i in range(n):
            x = e.asm.a.h[i] - e.asm.a.f[i]
            for j in range(n):
                x += e.asm.a.M[i * n + j] * r.a[j]
            r.r[i] = -h4 * x
        for i in range(r.m):
            r.w[i] = e.asm.a.g[i] + r.lam[i] / r.alpha[i]
        _add_bt_alpha(e, r, r.w, -h4, r.r)
        if _tangent(e, r, h) < 0:
            return -1
        _solve(r, r.r)
        dqlast, dqmax = dqmax, 0.0
        for i in range(n):
            r.q[i] += r.r[i]
            r.v[i] += 2.0 / h * r.r[i]
            r.a[i] += 4.0 / (h * h) * r.r[i]
            if not fabs(r.r[i]) <= dqmax:
                dqmax = fabs(r.r[i])
        it += 1
        if not isfinite(dqmax):
            return _failed(r, FAIL_NONFINITE, 0, 1)
    iterations[0] = it
    return 0


cdef int _project(Engine e, Run *r, double h) noexcept nogil:
    """The speed and acceleration projections with the last factored tangent and B
    at the converged positions (assembled by _newton)."""
    cdef int i, j, k, n = r.n
    cdef double h4 = 0.25 * h * h, x
    for k in range(2):
        if k == 0 and e.asm.model.n_time and _assemble(e, r, r.q, r.v, ASM_T) < 0:
            return -1
        if k == 1 and _assemble(e, r, r.q, r.v, ASM_C) < 0:
            return -1
        for i in range(r.m):       # B x + dg/dt for speeds, B x + bias for accelerations
            x = e.asm.a.c[i] if k == 1 else (e.asm.a.gt[i] if e.asm.model.n_time else 0.0)
            for j in range(n):
                x += e.asm.a.B[i * n + j] * (r.a[j] if k == 1 else r.v[j])
            r.w[i] = x
        for i in range(n):
            r.r[i] = 0.0
        _add_bt_alpha(e, r, r.w, h4, r.r)
        _solve(r, r.r)
        for i in range(n):
            if k == 0:
                r.v[i] -= r.r[i]
            else:
                r.a[i] -= r.r[i]
    if not (finite(r.v, n) and finite(r.a, n)):
        return _failed(r, FAIL_NONFINITE, 0, 2)
    return 0


cdef void _record(Engine e, Run *r, double t) noexcept nogil:
    """Write record r.n_out: t, q, v, body outputs, energy, max |g|."""
    r.n_asm += 1
    r.t_out[r.n_out] = t
    cdef double cerr = write_record(e, r.n_out, r.q, r.v, r.q_out, r.v_out, r.body_out,
                                    r.e_out, r.c_out)
    if not cerr <= r.max_cerr:
        r.max_cerr = cerr
    r.n_out += 1


cdef int _run(Engine e, Run *r, double deadline) noexcept nogil:
    """Steps until the end (RUN_DONE), an error (RUN_ERROR) or the wall-clock deadline
    (RUN_PAUSE)."""
    cdef double t, h
    cdef int it = 0, n = r.n
    while r.k < r.n_steps:
        t = r.k * r.dt
        h = r.dt if r.k < r.n_steps - 1 else r.t_end - t
        r.fail_t, r.fail_h = t, h
        memcpy(r.q0, r.q, n * sizeof(double))
        memcpy(r.v0, r.v, n * sizeof(double))
        memcpy(r.a0, r.a, n * sizeof(double))
        fcc_put_time(&e.asm.a, t + h)
        if _newton(e, r, h, &it) < 0 or _project(e, r, h) < 0:
            return RUN_ERROR
        r.newton_total += it
        if it > r.newton_max:
            r.newton_max = it
        r.k += 1
        t = r.k * r.dt if r.k < r.n_steps else r.t_end
        if r.k % r.every == 0 or r.k == r.n_steps:
            _record(e, r, t)
        if r.k < r.n_steps and now() >= deadline:
            return RUN_PAUSE
    return RUN_DONE


cdef double *_data(object array):
    """Pointer to the data of a fresh C-contiguous float64 array (NULL if empty)."""
    cdef double[::1] flat = array.reshape(-1)
    return &flat[0] if flat.shape[0] else NULL


cdef str _message(Run *r):
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
    SLOW_FACTOR times it), max_constraint_error, lu_factorizations, penalty,
    newton_tol. Raises SimulationError (with the time and what failed) when Newton
    does not converge, the tangent is not positive definite or a value is not finite.
    """
    if engine.running:
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
    opts = run_options(options, length_scale)
    engine.set_time(0.0)
    a0, lam, alpha, hint = initial_state(engine, q0, v0, opts["penalty"])
    n_out = 1 + n_steps // output_every + (1 if n_steps % output_every else 0)
    arrays = dict(t=np.zeros(n_out), q=np.zeros((n_out, n)), v=np.zeros((n_out, n)),
                  body=np.zeros((n_out, engine.asm.n_bodies, 6)), energy=np.zeros(n_out),
                  constraint_error=np.zeros(n_out))
    state = np.zeros(6 * n + 2 * m + 2 * n * n + n + m + 1)    # kept alive for the run
    pivots = np.zeros(n, dtype=np.intc)
    cdef int[::1] piv = pivots
    cdef Run r
    r.n, r.m = n, m
    r.k = r.n_out = r.n_asm = r.newton_total = r.failures = r.slow_steps = 0
    r.n_steps, r.every, r.dt, r.t_end = n_steps, output_every, dt, t_end
    r.tol, r.max_newton = opts["tolerance"], opts["max_newton"]
    r.newton_max = r.fail = r.fail_info = r.fail_detail = 0
    r.max_cerr = r.fail_dq = 0.0
    cdef double *p = _data(state)
    r.q, r.v, r.a, r.q0, r.v0, r.a0 = p, p + n, p + 2 * n, p + 3 * n, p + 4 * n, p + 5 * n
    r.lam, r.alpha = p + 6 * n, p + 6 * n + m
    r.T = p + 6 * n + 2 * m
    r.T2 = r.T + n * n
    r.ipiv = &piv[0]
    r.lu = False
    r.lu_steps = 0
    r.r = r.T2 + n * n
    r.w = r.r + n
    state[:n], state[n:2 * n], state[2 * n:3 * n] = q0, v0, a0
    state[6 * n:6 * n + m], state[6 * n + m:6 * n + 2 * m] = lam, alpha
    r.t_out, r.q_out, r.v_out = _data(arrays["t"]), _data(arrays["q"]), _data(arrays["v"])
    r.body_out, r.e_out = _data(arrays["body"]), _data(arrays["energy"])
    r.c_out = _data(arrays["constraint_error"])
    cdef int status
    cdef double deadline
    engine.running = True
    try:
        _record(engine, &r, 0.0)
        while True:
            deadline = now() + progress_interval
            with nogil:
                status = _run(engine, &r, deadline)
            if status == RUN_DONE:
                break
            if status == RUN_ERROR:
                raise SimulationError(_message(&r) + (hint if r.k < 3 else ""))
            PyErr_CheckSignals()
            if progress is not None:
                progress(r.k * dt)
    except (SimulationError, KeyboardInterrupt) as exc:
        keep_rows(exc, arrays, r.n_out,
                  dict(steps=r.k, rhs_evaluations=r.n_asm, newton_iterations=r.newton_total, max_constraint_error=r.max_cerr))
        raise
    finally:
        engine.running = False
        engine.factor_valid = False
    stats = dict(steps=r.k, rhs_evaluations=r.n_asm, newton_iterations=r.newton_total,
                 max_newton_iterations=r.newton_max, projection_failures=r.failures,
                 slow_newton_steps=r.slow_steps,
                 max_constraint_error=r.max_cerr, lu_factorizations=r.lu_steps,
                 penalty=opts["penalty"],
                 newton_tol=opts["newton_tol"])
    return arrays, stats

