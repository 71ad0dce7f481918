# cython: language_level=3
"""The compiled engine: accelerations and projections, in C without the GIL.

An Engine owns an Assembler (the element kernels bound to a plan) and one constrained
solve (_solve.pyx); integrators (_rk4.pyx) drive its nogil building blocks. Every
work array is allocated once, with the Engine.

Failures (a singular reduced mass matrix, a non-finite quantity) set an error record
in C; the Python side turns it into a SimulationError saying what failed (and, in a
run, when), so nothing continues on NaN.
"""
from libc.math cimport INFINITY, isfinite
from libc.stdlib cimport calloc, free
from libc.string cimport memcpy

import time

import numpy as np

from fccgen.errors import SimulationError

from ._cengine cimport fcc_assemble, fcc_put_time, fcc_max_abs_g, fcc_scaled_residual
from ._assemble cimport ASM_B, ASM_C, ASM_F, ASM_G, ASM_H, ASM_M, ASM_T, Assembler
from ._solve cimport (CSolve, csolve_apply, csolve_factor, csolve_free, csolve_init,
                     csolve_reset_stats, csolve_svd_rank)

from ._messages import error_message


cdef bint finite(const double *x, Py_ssize_t n) noexcept nogil:
    cdef Py_ssize_t i
    for i in range(n):
        if not isfinite(x[i]):
            return False
    return True


cdef class Engine:
    """Accelerations and projections for one Assembler.

    rank_tol: relative rank threshold of the constraint Jacobian; position_tol: Newton
    stops when max_k |g_k| / ||B_k|| <= position_tol; max_newton: iteration limit.
    """

    def __cinit__(self, Assembler asm, double rank_tol=1e-10, double position_tol=1e-11,
                  int max_newton=20):
        if asm.n_q <= 0:
            raise ValueError("the model has no moving coordinates: nothing to simulate")
        if not (rank_tol > 0 and position_tol > 0 and max_newton >= 0):
            raise ValueError("rank_tol and position_tol must be positive, max_newton >= 0")
        self.asm = asm
        self.n = asm.n_q
        self.m = asm.n_g
        self.position_tol = position_tol
        self.max_newton = max_newton
        self.diverge_residual = INFINITY
        csolve_init(&self.sol, self.n, self.m, rank_tol)
        self.row_group = <int *>calloc(self.m + 1, sizeof(int))
        if self.row_group == NULL:
            raise MemoryError("cannot allocate the engine's work arrays")
        cdef int e, k
        for e in range(asm.n_el):
            for k in range(asm.model.gptr[e], asm.model.gptr[e + 1]):
                self.row_group[k] = asm.model.gptr[e]
        self.sol.group = self.row_group
        self.work = <double *>calloc(4 * self.n + self.m + 1, sizeof(double))
        if self.work == NULL:
            raise MemoryError("cannot allocate the engine's work arrays")
        self.rhs = self.work
        self.nb = self.rhs + self.n
        self.dq = self.nb + self.m
        self.vtmp = self.dq + self.n
        self.stages = <double *>calloc(10 * self.n, sizeof(double))
        if self.stages == NULL:
            raise MemoryError("cannot allocate the engine's work arrays")

    def __dealloc__(self):
        csolve_free(&self.sol)
        free(self.row_group)
        free(self.work)
        free(self.stages)

    @property
    def rank_tol(self):
        return self.sol.rank_tol

    @property
    def rank(self):
        """Numerical rank of B at the last factorisation."""
        return self.sol.r

    @property
    def decided_rank(self):
        """The rank kept by the factorisations (-1: none decided, pivot threshold)."""
        return self.sol.rank_fixed

    def decide_rank(self, q, rank):
        """Keep ``rank`` as the rank of B from now on (see "Rank" in _solve.pyx; -1:
        back to the pivot threshold) and start the rank statistics anew."""
        if not -1 <= rank <= min(self.n, self.m):
            raise ValueError(f"rank must be in [-1, {min(self.n, self.m)}], got {rank}")
        self.sol.rank_fixed = rank
        csolve_reset_stats(&self.sol)
        self.n_rank_log = 0
        self.ke_peak = 0.0
        self.ke_cut_max = 0.0
        self.ke_cut_t = 0.0
        self.factor_valid = False

    def rank_statistics(self):
        """What the factorisations since :meth:`decide_rank` saw: a dict with
        factorisations, drops (factorisations at a singular position, where a pivot
        within the decided rank fell to rank_tol or below), svd_checks, smallest_kept
        and largest_dropped pivot ratios, increases [(t, old rank, new rank)], and the
        largest fraction of the kinetic energy one velocity projection removed
        (kinetic_energy_cut, at kinetic_energy_cut_t) and the largest kinetic energy
        a velocity projection met (kinetic_energy_peak; 0 when none ran)."""
        n = min(self.n_rank_log, RANK_LOG_SIZE)
        return dict(factorisations=self.sol.n_factor, drops=self.sol.n_drop,
                    svd_checks=self.sol.n_svd, smallest_kept=self.sol.kept_min,
                    largest_dropped=self.sol.dropped_max,
                    increases=[(self.rank_log[k][0], int(self.rank_log[k][1]),
                                int(self.rank_log[k][2])) for k in range(n)],
                    increases_total=self.n_rank_log,
                    kinetic_energy_cut=self.ke_cut_max, kinetic_energy_cut_t=self.ke_cut_t,
                    kinetic_energy_peak=self.ke_peak / 2.0)

    # -- building blocks (nogil) ---------------------------------------------------
    cdef int fail(self, int code, int info, int detail) noexcept nogil:
        self.err = code
        self.err_info = info
        self.err_detail = detail
        return -1

    cdef int nonfinite_input(self, const double *q, const double *v, int flags) noexcept nogil:
        """1-based index (see _messages.INPUTS) of the first non-finite input, 0 if none."""
        cdef int n = self.n, m = self.m
        if q != NULL and not finite(q, n): return 1
        if v != NULL and not finite(v, n): return 2
        if flags & ASM_M and not finite(self.asm.a.M, n * n): return 3
        if flags & ASM_H and not finite(self.asm.a.h, n): return 4
        if flags & ASM_F and not finite(self.asm.a.f, n): return 5
        if flags & ASM_B and not finite(self.asm.a.B, m * n): return 6
        if flags & ASM_C and not finite(self.asm.a.c, m): return 7
        if flags & ASM_G and not finite(self.asm.a.g, m): return 8
        return 0

    cdef int factor(self, const double *q) noexcept nogil:
        """Factor the assembled M and B; on failure, blame a non-finite input first."""
        cdef int old = self.sol.rank_fixed, bad, k
        cdef int info = csolve_factor(&self.sol, self.asm.a.M, self.asm.a.B)
        self.factor_valid = False
        if self.sol.grew:
            k = self.n_rank_log
            if k < RANK_LOG_SIZE:
                self.rank_log[k][0] = self.err_t      # the integrators keep it current
                self.rank_log[k][1] = old
                self.rank_log[k][2] = self.sol.rank_fixed
            self.n_rank_log += 1
        if info == 0:
            return 0
        bad = self.nonfinite_input(q, NULL, ASM_M | ASM_B)
        if bad:
            return self.fail(ERR_NONFINITE_INPUT, 0, bad)
        return self.fail(ERR_SINGULAR if info > 0 else ERR_LAPACK, info, 0)

    cdef int accelerations_at(self, const double *q, const double *v, double *a,
                              bint reuse) noexcept nogil:
        """a = q'' at (q, v); reuse: sol already holds the factorisation at q."""
        cdef int i, flags = ASM_H | ASM_F | ASM_C
        if not reuse:
            flags |= ASM_M | ASM_B
        fcc_assemble(&self.asm.a, q, v, flags)
        if not reuse and self.factor(q) < 0:
            return -1
        for i in range(self.n):
            self.rhs[i] = self.asm.a.f[i] - self.asm.a.h[i]
        for i in range(self.m):
            self.nb[i] = -self.asm.a.c[i]
        csolve_apply(&self.sol, self.rhs, NULL, self.nb, a)
        if not finite(a, self.n):
            i = self.nonfinite_input(q, v, flags)
            return self.fail(ERR_NONFINITE_INPUT if i else ERR_NONFINITE_RESULT, 0, i)
        return 0

    cdef int baumgarte_at(self, const double *q, const double *v, double *a,
                          double alpha, double beta) noexcept nogil:
        """a = q'' of the index-1 equations with Baumgarte stabilisation:
        M a + B^T lambda = f - h, B a = -c - 2 alpha g' - beta^2 g(q), with
        g' = B v + dg/dt and c the constraint bias (g'' - B a)."""
        cdef int i, j, n = self.n
        cdef int flags = ASM_M | ASM_B | ASM_H | ASM_F | ASM_C | ASM_G
        if self.asm.model.n_time:
            flags |= ASM_T
        cdef double bv
        cdef const double *row
        fcc_assemble(&self.asm.a, q, v, flags)
        if self.factor(q) < 0:
            return -1
        for i in range(n):
            self.rhs[i] = self.asm.a.f[i] - self.asm.a.h[i]
        for i in range(self.m):
            row = self.asm.a.B + i * n
            bv = self.asm.a.gt[i] if self.asm.model.n_time else 0.0
            for j in range(n):
                bv += row[j] * v[j]
            self.nb[i] = -self.asm.a.c[i] - 2.0 * alpha * bv - beta * beta * self.asm.a.g[i]
        csolve_apply(&self.sol, self.rhs, NULL, self.nb, a)
        if not finite(a, n):
            i = self.nonfinite_input(q, v, flags)
            return self.fail(ERR_NONFINITE_INPUT if i else ERR_NONFINITE_RESULT, 0, i)
        return 0

    cdef void assemble_constraints(self, const double *q, int flags) noexcept nogil:
        """Assemble at q what the position projection asks for: g (ASM_G), B (ASM_B)
        and M (ASM_M), where this engine's solves read them (here: the assembler's
        dense arrays; the sparse path keeps M and B as element blocks)."""
        fcc_assemble(&self.asm.a, q, NULL, flags)

    cdef double constraint_residual(self) noexcept nogil:
        """max_k |g_k| / ||B_k|| with the g and B assembled last."""
        return fcc_scaled_residual(&self.asm.a)

    cdef void solve_constrained(self, const double *Q, const double *w, const double *b,
                                double *x) noexcept nogil:
        """x of M x + B^T lambda = Q + M w, B x = b (Q, w, b may be NULL: zero) with
        the factorisation at hand."""
        csolve_apply(&self.sol, Q, w, b, x)

    cdef void solve_newton(self, const double *b, double *x) noexcept nogil:
        """x of a Newton step, M x + B^T mu = 0, B x = b, with the factorisation at
        hand. Its accuracy need only be far below the step's own (the next residual
        check judges the step): the sparse path stops its refinement sooner."""
        self.solve_constrained(NULL, NULL, b, x)

    cdef int project_positions_at(self, double *q, int *iterations,
                                  bint reuse) noexcept nogil:
        """Newton on g(q) = 0, in place: dq = argmin dq^T M dq / 2 subject to
        B dq = -g, with g and B at every iterate and the metric M at the starting
        point. Returns 0 (converged), 1 (not within max_newton) or -1 (error). Leaves g
        assembled at the final q, and B when b_fresh. One loop for both paths: the
        assembly, the residual and the solve are the engine's own
        (assemble_constraints, constraint_residual, solve_newton). reuse: M, B and the
        factorisation held are an integrator's last stage's, near q; an engine that can
        (chord_ready) first takes chord steps with them (chord_step), and the first one
        that does not converge as it should is undone: exact steps from there."""
        cdef int i, it = 0
        cdef double res
        cdef bint exact = False
        reuse = reuse and self.chord_ready()
        self.b_fresh = not reuse
        self.assemble_constraints(q, ASM_G if reuse else ASM_G | ASM_B)
        res = self.constraint_residual()
        while True:
            if not isfinite(res):
                iterations[0] = it
                return self.fail(ERR_NONFINITE_INPUT, 0,
                                 self.nonfinite_input(q, NULL, ASM_G | ASM_B) or 8)
            if res <= self.position_tol:
                break
            if it == 0 and res > self.diverge_residual:
                iterations[0] = it
                self.err_value = res
                self.err_bound = self.diverge_residual
                return self.fail(ERR_DIVERGED, 0, 3)
            if it >= self.max_newton:
                iterations[0] = it
                return 1
            if reuse:
                i = self.chord_step(q, &res)
                if i < 0:
                    iterations[0] = it
                    return -1
                if i == 1:
                    it += 1
                    continue
                reuse = False
            if not exact:                       # the metric: M at the first exact step
                self.assemble_constraints(q, ASM_M if self.b_fresh else ASM_M | ASM_B)
                self.b_fresh = exact = True
            if self.factor(q) < 0:
                iterations[0] = it
                return -1
            for i in range(self.m):
                self.nb[i] = -self.asm.a.g[i]
            self.solve_newton(self.nb, self.dq)
            for i in range(self.n):
                q[i] += self.dq[i]
            it += 1
            self.assemble_constraints(q, ASM_G | ASM_B)
            res = self.constraint_residual()
        iterations[0] = it
        return 0

    cdef bint chord_ready(self) noexcept nogil:
        """Whether chord_step can be taken (the dense path: never; its factorisation
        is a pivoted QR of one B, without the M and B it was made from)."""
        return False

    cdef int chord_step(self, double *q, double *res) noexcept nogil:
        """A chord step from q (g assembled there, residual res[0]) with the M, B and
        factorisation held: 1 when kept (q moved, g assembled there, res[0] its
        residual), 0 when undone (q and g as they were), -1 on an error."""
        return 0

    cdef int project_velocities_at(self, const double *q, double *v,
                                   bint have_B) noexcept nogil:
        """v <- the M-orthogonal projection of v onto B v = -dg/dt (0 unless the model
        has drivers: set_time first), in place. Leaves the factorisation of (M, B) at q
        in sol; have_B: B is already assembled at q."""
        cdef int i
        cdef int flags = ASM_M if have_B else ASM_M | ASM_B
        if self.asm.model.n_time:
            flags |= ASM_T
        fcc_assemble(&self.asm.a, q, NULL, flags)
        self.sol.check_growth = 1             # q has just been projected (or is given)
        i = self.factor(q)
        self.sol.check_growth = 0
        if i < 0:
            return -1
        if self.asm.model.n_time:
            for i in range(self.m):
                self.nb[i] = -self.asm.a.gt[i]
        csolve_apply(&self.sol, NULL, v, self.nb if self.asm.model.n_time else NULL,
                     self.vtmp)
        if not finite(self.vtmp, self.n):
            i = self.nonfinite_input(q, v, ASM_M | ASM_B)
            return self.fail(ERR_NONFINITE_INPUT if i else ERR_NONFINITE_RESULT, 0, i)
        self.watch_kinetic_energy(v, self.vtmp)
        memcpy(v, self.vtmp, self.n * sizeof(double))
        self.factor_valid = True
        return 0

    cdef void watch_kinetic_energy(self, const double *v, const double *w) noexcept nogil:
        """Track the fraction of the kinetic energy v^T M v / 2 that the projection
        v -> w removes, (v - w)^T M (v - w) / 2 (M-orthogonal: the energy lost).
        Accurate steps lose O(local error^2); a finite fraction means the constraints
        forbid a motion the integrator made (a wrong rank, a locked mechanism).
        Fractions are counted once the energy is above 1e-6 of its peak."""
        cdef int i, j, n = self.n
        cdef double before = 0.0, cut = 0.0, mv, md
        cdef const double *row
        for i in range(n):
            row = self.asm.a.M + i * n
            mv = 0.0
            md = 0.0
            for j in range(n):
                mv += row[j] * v[j]
                md += row[j] * (v[j] - w[j])
            before += v[i] * mv
            cut += (v[i] - w[i]) * md
        if before > self.ke_peak:
            self.ke_peak = before
        if before > 1e-6 * self.ke_peak and before > 0.0 and cut / before > self.ke_cut_max:
            self.ke_cut_max = cut / before
            self.ke_cut_t = self.err_t

    # -- Python access -------------------------------------------------------------
    cdef double[::1] vector(self, object x, str name, bint copy=True):
        """x as a contiguous float64 vector of length n; a private copy unless the
        caller only reads it."""
        a = np.array(x, dtype=float) if copy else np.ascontiguousarray(x, dtype=float)
        if not a.flags.writeable:                         # typed views need writeable
            a = a.copy()
        if a.shape != (self.n,):
            raise ValueError(f"{name} must have shape ({self.n},), got {a.shape}")
        return a

    cdef raise_error(self, int where):
        self.err_where = where
        raise SimulationError(error_message(self.error_record(), in_run=False))

    cdef dict error_record(self):
        return dict(code=self.err, info=self.err_info, detail=self.err_detail,
                    where=self.err_where, stage=self.err_stage, t=self.err_t,
                    h=self.err_h, value=self.err_value, bound=self.err_bound,
                    rank=self.sol.r, n_q=self.n, n_g=self.m,
                    nullity=self.sol.nr)

    def reset_warm_start(self):
        """Nothing to reset: the dense path's solves carry nothing from one to the next
        (the sparse path's carry the accelerations' multipliers, _al_refine.pyx)."""

    def set_time(self, double t):
        """Evaluate later calls at the time t (models with drivers; Assembler.set_time)."""
        fcc_put_time(&self.asm.a, t)

    def accelerations(self, q, v):
        """q'' at (q, v): a fresh array."""
        cdef double[::1] qv = self.vector(q, "q", False), vv = self.vector(v, "v", False)
        a = np.empty(self.n)
        cdef double[::1] av = a
        cdef int rc
        with nogil:
            rc = self.accelerations_at(&qv[0], &vv[0], &av[0], False)
        if rc < 0:
            self.raise_error(AT_CALL)
        return a

    def baumgarte_accelerations(self, q, v, double alpha, double beta):
        """q'' of the Baumgarte-stabilised index-1 equations at (q, v): a fresh array."""
        cdef double[::1] qv = self.vector(q, "q", False), vv = self.vector(v, "v", False)
        a = np.empty(self.n)
        cdef double[::1] av = a
        cdef int rc
        with nogil:
            rc = self.baumgarte_at(&qv[0], &vv[0], &av[0], alpha, beta)
        if rc < 0:
            self.raise_error(AT_CALL)
        return a

    def project_positions(self, q, bint reuse=False):
        """(q_new, iterations, converged, residual): Newton projection of q onto
        g(q) = 0; residual is max_k |g_k| / ||B_k|| at q_new. reuse: chord steps first
        with the M, B and factorisation held (as after an integrator's step; for
        tests)."""
        cdef double[::1] qv = self.vector(q, "q")
        cdef int rc, it = 0
        with nogil:
            rc = self.project_positions_at(&qv[0], &it, reuse)
        if rc < 0:
            self.raise_error(AT_POSITIONS)
        return np.asarray(qv), it, rc == 0, self.constraint_residual()

    def project_velocities(self, q, v):
        """The M-orthogonal projection of v onto B(q) v = 0: a fresh array."""
        cdef double[::1] qv = self.vector(q, "q", False), vv = self.vector(v, "v")
        cdef int rc
        with nogil:
            rc = self.project_velocities_at(&qv[0], &vv[0], False)
        if rc < 0:
            self.raise_error(AT_VELOCITIES)
        return np.asarray(vv)

    def time_accelerations(self, q, v, long batch):
        """Seconds taken by ``batch`` evaluations of the accelerations (assembly,
        factorisation, solve) in one compiled loop."""
        cdef double[::1] qv = self.vector(q, "q", False), vv = self.vector(v, "v", False)
        a = np.empty(self.n)
        cdef double[::1] av = a
        cdef long i
        cdef int rc = 0
        t0 = time.perf_counter()
        with nogil:
            for i in range(batch):
                rc = self.accelerations_at(&qv[0], &vv[0], &av[0], False)
                if rc < 0:
                    break
        elapsed = time.perf_counter() - t0
        if rc < 0:
            self.raise_error(AT_CALL)
        return elapsed
