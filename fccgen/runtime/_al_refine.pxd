# The sparse path's augmented-Lagrangian refinement (see _al_refine.pyx).
from ._sparse_blocks cimport SparseBlocks


cdef class ALRefinement(SparseBlocks):
    cdef double *w_n              # n-vectors: work, residual, correction, Q + M w
    cdef double *r1
    cdef double *dx
    cdef double *base
    cdef double *lz               # local: an element's row multipliers in a pass
    cdef double *lam              # m-vectors
    cdef double *lam_warm         # the last converged acceleration solve's multipliers
    cdef bint warm_valid          # lam_warm holds them (reset_warm_start: not)
    cdef double *r2
    cdef double *bdx
    cdef double *res
    cdef double *mu
    cdef double *p
    cdef double *sp
    cdef double *u                # n
    cdef long n_solves, n_iterations, n_unconverged
    cdef long n_beyond_rank       # corrections stopped beyond the decided rank
    cdef double beyond_quotient   # their Rayleigh-quotient bound (0: off)
    cdef bint beyond_hit          # the last correction stopped there
    cdef int most_iterations
    cdef int cg_max, refine_max, al_max    # caps (limit_refinement)
    cdef double rho               # r2^T diag(alpha) r2 of the last residual pass
    cdef int cg_steps             # conjugate-gradient steps of the last correction

    cdef void residual_pass(self, const double *x, const double *b, bint pending,
                            bint penalised, double *y, double *r2) noexcept nogil
    cdef void first_pass(self, const double *b, bint warm, double *y) noexcept nogil
    cdef int correction(self, double *rz_stop) noexcept nogil
    cdef bint kkt_solve(self, const double *Q, const double *w, const double *b,
                        double *x, bint warm, bint newton) noexcept nogil
    cdef int refine(self, const double *b, double *x, bint warm,
                    int *solves, double stop) noexcept nogil
