# The dense constrained solve (engine/fcc_dense.c) and the LAPACK table the C engine
# calls through (see _solve.pyx).
from ._cengine cimport (fcc_dense, fcc_dense_apply, fcc_dense_factor, fcc_dense_free,
                        fcc_dense_init, fcc_dense_reset_stats, fcc_dense_svd_rank,
                        fcc_lapack)

cdef const fcc_lapack *lapack_table() noexcept nogil
cdef int csolve_init(fcc_dense *s, int n, int m, double rank_tol) except -1

# The names the other modules use (until they call the C engine directly).
ctypedef fcc_dense CSolve

cdef inline void csolve_free(CSolve *s) noexcept nogil:
    fcc_dense_free(s)

cdef inline void csolve_reset_stats(CSolve *s) noexcept nogil:
    fcc_dense_reset_stats(s)

cdef inline int csolve_svd_rank(CSolve *s, const double *B, double tol) noexcept nogil:
    return fcc_dense_svd_rank(s, B, tol)

cdef inline int csolve_factor(CSolve *s, const double *M, const double *B) noexcept nogil:
    return fcc_dense_factor(s, M, B)

cdef inline void csolve_apply(CSolve *s, const double *Q, const double *w, const double *b,
                              double *x) noexcept nogil:
    fcc_dense_apply(s, Q, w, b, x)
