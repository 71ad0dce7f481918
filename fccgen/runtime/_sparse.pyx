# cython: language_level=3
"""The sparse path: accelerations and projections in time linear in the model's size.

SparseEngine is an Engine (same building blocks, same integrators) whose constrained
solves are the augmented-Lagrangian refinement of _al_refine.pyx over the element
blocks and the LDL^T of A = M + B^T diag(alpha) B of _sparse_blocks.pyx:

* accelerations: M a + B^T lambda = f - h, B a = -c (Baumgarte:
  B a = -c - 2 alpha g' - beta^2 g, formed in :meth:`SparseEngine.baumgarte_targets`);
* velocity projection: M w + B^T mu = M v, B w = b with b from
  :meth:`SparseEngine.velocity_targets` (-dg/dt of time-dependent constraints);
* each Newton step of the position projection: M dq + B^T mu = 0, B dq = -g.

Solves whose constraint residual did not converge (a singular position: b outside the
range of B) are counted as the dense path's dropped rows are.
"""
from libc.math cimport isfinite
from libc.string cimport memcpy, memset

from ._al_refine cimport ALRefinement
from ._assemble cimport ASM_B, ASM_C, ASM_F, ASM_G, ASM_H, ASM_M, ASM_T
from ._engine cimport (ERR_DIVERGED, ERR_NONFINITE_INPUT, ERR_NONFINITE_RESULT, Engine,
                       finite)


cdef class SparseEngine(ALRefinement):
    """An Engine whose solves use the sparse augmented-Lagrangian refinement (module
    docstring). Call :meth:`set_structure` (fccgen.runtime.sparsity) before use."""

    def decide_rank(self, q, rank):
        """Keep the decision for the reports (the solve itself needs no rank) and start
        the statistics anew."""
        Engine.decide_rank(self, q, rank)
        self.n_factor = self.n_solves = self.n_iterations = self.n_unconverged = 0
        self.most_iterations = 0

    def rank_statistics(self):
        """As Engine.rank_statistics; drops are solves whose constraint residual did
        not converge (a singular position)."""
        stats = Engine.rank_statistics(self)
        stats.update(factorisations=self.n_factor, drops=self.n_unconverged,
                     svd_checks=0, smallest_kept=1.0, largest_dropped=0.0)
        return stats

    cdef int finish(self, const double *q, const double *v, const double *a,
                    int flags) noexcept nogil:
        """0, or the error of a non-finite result (blaming an input first)."""
        cdef int i
        if finite(a, self.n):
            return 0
        i = self.nonfinite_input(q, v, flags)
        return self.fail(ERR_NONFINITE_INPUT if i else ERR_NONFINITE_RESULT, 0, i)

    cdef int accelerations_at(self, const double *q, const double *v, double *a,
                              bint reuse) noexcept nogil:
        cdef int i, flags = ASM_H | ASM_F | ASM_C
        self.asm.assemble(q, v, flags)
        if not reuse:
            flags |= ASM_M | ASM_B
            self.assemble_mb(q, ASM_M | ASM_B)
            if self.factor(q) < 0:
                return -1
        for i in range(self.n):
            self.rhs[i] = self.asm.f[i] - self.asm.h[i]
        for i in range(self.m):
            self.nb[i] = -self.asm.c[i]
        self.kkt_solve(self.rhs, NULL, self.nb, a)
        return self.finish(q, v, a, flags)

    cdef int baumgarte_at(self, const double *q, const double *v, double *a,
                          double alpha, double beta) noexcept nogil:
        cdef int i, flags = ASM_M | ASM_B | ASM_H | ASM_F | ASM_C | ASM_G
        self.asm.assemble(q, v, ASM_H | ASM_F | ASM_C | ASM_G
                          | (ASM_T if self.asm.n_time else 0))
        self.assemble_mb(q, ASM_M | ASM_B)
        if self.factor(q) < 0:
            return -1
        for i in range(self.n):
            self.rhs[i] = self.asm.f[i] - self.asm.h[i]
        self.baumgarte_targets(v, alpha, beta, self.nb)
        self.kkt_solve(self.rhs, NULL, self.nb, a)
        return self.finish(q, v, a, flags)

    cdef void baumgarte_targets(self, const double *v, double alpha, double beta,
                                double *b) noexcept nogil:
        """b = -c - 2 alpha g' - beta^2 g, the right-hand side of B a = b in
        Baumgarte's stabilisation, with g' = B v + dg/dt (assembled c, g and, for
        time-dependent constraints, dg/dt; blocks of B)."""
        cdef int i
        self.mult_b(v, b)
        if self.asm.n_time:
            for i in range(self.m):
                b[i] += self.asm.gt[i]
        for i in range(self.m):
            b[i] = -self.asm.c[i] - 2.0 * alpha * b[i] - beta * beta * self.asm.g[i]

    cdef int project_positions_at(self, double *q, int *iterations) noexcept nogil:
        cdef int i, it = 0
        cdef double res
        self.asm.assemble(q, NULL, ASM_G)
        self.assemble_mb(q, ASM_B)
        res = self.scaled_residual_sparse()
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
            if it == 0:
                self.assemble_mb(q, ASM_M)
            if self.factor(q) < 0:
                iterations[0] = it
                return -1
            for i in range(self.m):
                self.nb[i] = -self.asm.g[i]
            self.kkt_solve(NULL, NULL, self.nb, self.dq)
            for i in range(self.n):
                q[i] += self.dq[i]
            it += 1
            self.asm.assemble(q, NULL, ASM_G)
            self.assemble_mb(q, ASM_B)
            res = self.scaled_residual_sparse()
        iterations[0] = it
        return 0

    cdef int project_velocities_at(self, const double *q, double *v,
                                   bint have_B) noexcept nogil:
        self.assemble_mb(q, ASM_M if have_B else ASM_M | ASM_B)
        if self.factor(q) < 0:
            return -1
        self.velocity_targets(q, self.nb)
        self.kkt_solve(NULL, v, self.nb, self.vtmp)
        if self.finish(q, v, self.vtmp, ASM_M | ASM_B) < 0:
            return -1
        self.watch_kinetic_energy(v, self.vtmp)
        memcpy(v, self.vtmp, self.n * sizeof(double))
        self.factor_valid = True
        return 0

    cdef void velocity_targets(self, const double *q, double *b) noexcept nogil:
        """b of the velocity projection's B w = b: -dg/dt at the time set last
        (zero when no constraint depends on time)."""
        cdef int i
        if not self.asm.n_time:
            memset(b, 0, <size_t>self.m * sizeof(double))
            return
        self.asm.assemble(q, NULL, ASM_T)
        for i in range(self.m):
            b[i] = -self.asm.gt[i]

    cdef void watch_kinetic_energy(self, const double *v, const double *w) noexcept nogil:
        """As Engine.watch_kinetic_energy, with M v from the blocks."""
        cdef int i, n = self.n
        cdef double before = 0.0, cut = 0.0
        self.mult_m(v, self.r1, False)
        for i in range(n):
            self.dx[i] = v[i] - w[i]
        self.mult_m(self.dx, self.t, False)
        for i in range(n):
            before += v[i] * self.r1[i]
            cut += self.dx[i] * self.t[i]
        if before > self.ke_peak:
            self.ke_peak = before
        if before > 1e-6 * self.ke_peak and before > 0.0 and cut / before > self.ke_cut_max:
            self.ke_cut_max = cut / before
            self.ke_cut_t = self.err_t

    cdef dict error_record(self):
        rec = Engine.error_record(self)
        rank = self.sol.rank_fixed
        rec.update(rank=rank, nullity=self.n - rank if rank >= 0 else self.n)
        return rec

