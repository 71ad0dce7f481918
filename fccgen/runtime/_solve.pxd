# The constrained solve x = argmin x^T M x / 2 - Q^T x subject to B x = b, split into a
# factorisation of (M, B) and its application to right-hand sides (see _solve.pyx).

cdef struct CSolve:
    int n                 # coordinates (columns of B)
    int m                 # constraint rows
    int r                 # numerical rank of B at the last factorisation
    int nr                # n - r: dimension of the null space of B
    double rank_tol
    double *A             # n x m column-major: scaled B^T, then its pivoted QR
    double *scale         # m: 1 / ||B_k|| (1 for zero rows)
    double *tau           # min(n, m) Householder factors
    int *jpvt             # m column pivots (1-based, LAPACK's)
    double *Q2            # n x nr column-major: orthonormal basis of the null space
    double *MQ2           # n x nr: M Q2
    double *S             # nr x nr: Cholesky factor of Q2^T M Q2 (upper)
    double *xp            # n: particular solution
    double *rhs           # n: reduced right-hand side
    double *work
    int lwork


cdef int csolve_init(CSolve *s, int n, int m, double rank_tol) except -1
cdef void csolve_free(CSolve *s) noexcept nogil
cdef int csolve_factor(CSolve *s, const double *M, const double *B) noexcept nogil
cdef void csolve_apply(CSolve *s, const double *Q, const double *w, const double *b,
                       double *x) noexcept nogil
