# cython: language_level=3
"""The Python face of the C engine (engine/fcc_engine.c): accelerations and
projections of one Assembler, on the dense path (this class) or the sparse one
(_sparse.SparseEngine).

The engine's work is C without the GIL; this wrapper checks arguments, hands arrays in
and out (every array returned is fresh), and turns the engine's error record into a
SimulationError saying what failed (and, in a run, when), so nothing continues on NaN.
"""
import time

import numpy as np

from fccgen import rank as _rank
from fccgen.errors import SimulationError

from ._cengine cimport (FCC_OK, fcc_accelerations, fcc_baumgarte, fcc_constraint_residual,
                        fcc_engine_decide_rank, fcc_engine_free, fcc_engine_init,
                        fcc_project_positions, fcc_project_velocities, fcc_put_time,
                        fcc_settings)
from ._solve cimport lapack_table

from ._messages import error_message


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
        cdef fcc_settings s
        s.rank_tol = rank_tol
        s.position_tol = position_tol
        s.max_newton = max_newton
        s.grow_tol = _rank.GROW_TOL
        s.decide_tol = _rank.DECIDE_TOL
        s.ambiguous_low = _rank.AMBIGUOUS_LOW
        s.row_floor = _rank.ROW_FLOOR
        if fcc_engine_init(&self.c, &asm.a, lapack_table(), &s) != FCC_OK:
            raise MemoryError("cannot allocate the engine's work arrays")
        self.live = True

    def __dealloc__(self):
        if self.live:
            fcc_engine_free(&self.c)

    @property
    def rank_tol(self):
        return self.c.set.rank_tol

    @property
    def position_tol(self):
        return self.c.set.position_tol

    @property
    def max_newton(self):
        return self.c.set.max_newton

    @property
    def rank(self):
        """Numerical rank of B at the last factorisation."""
        return self.c.sol.r

    @property
    def decided_rank(self):
        """The rank kept by the factorisations (-1: none decided, pivot threshold)."""
        return self.c.sol.rank_fixed

    def decide_rank(self, q, rank):
        """Keep ``rank`` as the rank of B from now on (see "Rank" in engine/fcc_dense.c;
        -1: back to the pivot threshold) and start the rank statistics anew."""
        if not -1 <= rank <= min(self.c.n, self.c.m):
            raise ValueError(f"rank must be in [-1, {min(self.c.n, self.c.m)}], got {rank}")
        fcc_engine_decide_rank(&self.c, rank)

    def rank_statistics(self):
        """What the factorisations since :meth:`decide_rank` saw: a dict with
        factorisations, drops (factorisations at a singular position, where a pivot
        within the decided rank fell to rank_tol or below), svd_checks, smallest_kept
        and largest_dropped pivot ratios, increases [(t, old rank, new rank)], and the
        largest fraction of the kinetic energy one velocity projection removed
        (kinetic_energy_cut, at kinetic_energy_cut_t) and the largest kinetic energy
        a velocity projection met (kinetic_energy_peak; 0 when none ran)."""
        n = min(self.c.n_rank_log, 64)
        return dict(factorisations=self.c.sol.n_factor, drops=self.c.sol.n_drop,
                    svd_checks=self.c.sol.n_svd, smallest_kept=self.c.sol.kept_min,
                    largest_dropped=self.c.sol.dropped_max,
                    increases=[(self.c.rank_log[k][0], int(self.c.rank_log[k][1]),
                                int(self.c.rank_log[k][2])) for k in range(n)],
                    increases_total=self.c.n_rank_log,
                    kinetic_energy_cut=self.c.ke_cut_max,
                    kinetic_energy_cut_t=self.c.ke_cut_t,
                    kinetic_energy_peak=self.c.ke_peak / 2.0)

    # -- Python access -------------------------------------------------------------
    cdef double[::1] vector(self, object x, str name, bint copy=True):
        """x as a contiguous float64 vector of length n; a private copy unless the
        caller only reads it."""
        a = np.array(x, dtype=float) if copy else np.ascontiguousarray(x, dtype=float)
        if not a.flags.writeable:                         # typed views need writeable
            a = a.copy()
        if a.shape != (self.c.n,):
            raise ValueError(f"{name} must have shape ({self.c.n},), got {a.shape}")
        return a

    cdef raise_error(self, int where):
        self.c.err_where = where
        raise SimulationError(error_message(self.error_record(), in_run=False))

    cdef dict error_record(self):
        return dict(code=self.c.err, info=self.c.err_info, detail=self.c.err_detail,
                    where=self.c.err_where, stage=self.c.err_stage, t=self.c.err_t,
                    h=self.c.err_h, value=self.c.err_value, bound=self.c.err_bound,
                    rank=self.c.sol.r, n_q=self.c.n, n_g=self.c.m,
                    nullity=self.c.sol.nr)

    def reset_warm_start(self):
        """Nothing to reset: the dense path's solves carry nothing from one to the next
        (the sparse path's carry the accelerations' multipliers)."""

    def set_time(self, double t):
        """Evaluate later calls at the time t (models with drivers; Assembler.set_time)."""
        fcc_put_time(self.c.asmb, t)

    def accelerations(self, q, v):
        """q'' at (q, v): a fresh array."""
        cdef double[::1] qv = self.vector(q, "q", False), vv = self.vector(v, "v", False)
        a = np.empty(self.c.n)
        cdef double[::1] av = a
        cdef int rc
        with nogil:
            rc = fcc_accelerations(&self.c, &qv[0], &vv[0], &av[0], False)
        if rc < 0:
            self.raise_error(AT_CALL)
        return a

    def baumgarte_accelerations(self, q, v, double alpha, double beta):
        """q'' of the Baumgarte-stabilised index-1 equations at (q, v): a fresh array."""
        cdef double[::1] qv = self.vector(q, "q", False), vv = self.vector(v, "v", False)
        a = np.empty(self.c.n)
        cdef double[::1] av = a
        cdef int rc
        with nogil:
            rc = fcc_baumgarte(&self.c, &qv[0], &vv[0], &av[0], alpha, beta)
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
            rc = fcc_project_positions(&self.c, &qv[0], &it, reuse)
        if rc < 0:
            self.raise_error(AT_POSITIONS)
        return np.asarray(qv), it, rc == 0, fcc_constraint_residual(&self.c)

    def project_velocities(self, q, v):
        """The M-orthogonal projection of v onto B(q) v = 0: a fresh array."""
        cdef double[::1] qv = self.vector(q, "q", False), vv = self.vector(v, "v")
        cdef int rc
        with nogil:
            rc = fcc_project_velocities(&self.c, &qv[0], &vv[0], False)
        if rc < 0:
            self.raise_error(AT_VELOCITIES)
        return np.asarray(vv)

    def time_accelerations(self, q, v, long batch):
        """Seconds taken by ``batch`` evaluations of the accelerations (assembly,
        factorisation, solve) in one compiled loop."""
        cdef double[::1] qv = self.vector(q, "q", False), vv = self.vector(v, "v", False)
        a = np.empty(self.c.n)
        cdef double[::1] av = a
        cdef long i
        cdef int rc = 0
        t0 = time.perf_counter()
        with nogil:
            for i in range(batch):
                rc = fcc_accelerations(&self.c, &qv[0], &vv[0], &av[0], False)
                if rc < 0:
                    break
        elapsed = time.perf_counter() - t0
        if rc < 0:
            self.raise_error(AT_CALL)
        return elapsed
