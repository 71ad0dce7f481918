# The constrained solve x = argmin x^T M x / 2 - Q^T x subject to B x = b, split into a
# factorisation of (M, B) and its application to right-hand sides (see _solve.pyx).

cdef struct CSolve:
    int n                 # coordinates (columns of B)
    int m                 # constraint rows
    int r                 # numerical rank of B at the last factorisation
    int nr                # n - r: dimension of the null space of B
    double rank_tol       # a pivot |R_kk| <= rank_tol |R_00| counts as zero
    # The rank decision (see "Rank" in _solve.pyx). rank_fixed < 0: threshold only.
    int rank_fixed        # the decided rank of B, kept unless a signal says otherwise
    double grow_tol       # sigma_k > grow_tol sigma_1 counts for a rank increase
    double grow_trigger   # a first dropped pivot above this starts an SVD check
    int check_growth      # this factorisation is at a projected state: growth may be
                          # checked (stage states are off the constraints by O(dt^2))
    int grew              # the last factorisation raised rank_fixed (the engine logs it)
    long n_factor         # factorisations since the rank was decided
    long n_drop           # ... with a pivot below rank_tol within the decided rank
    long n_svd            # SVD checks done
    double kept_min       # smallest last kept pivot ratio |R_{r-1}| / |R_00|
    double dropped_max    # largest first dropped pivot ratio |R_r| / |R_00|
    double *sv            # n x m copy of the scaled B^T for the SVD check
    double *sigma         # min(n, m) singular values
    const int *group      # m or NULL: first row of the element each row belongs to
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
cdef void csolve_reset_stats(CSolve *s) noexcept nogil
cdef int csolve_svd_rank(CSolve *s, const double *B, double tol) noexcept nogil
cdef int csolve_factor(CSolve *s, const double *M, const double *B) noexcept nogil
cdef void csolve_apply(CSolve *s, const double *Q, const double *w, const double *b,
                       double *x) noexcept nogil
