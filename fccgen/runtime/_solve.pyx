# cython: language_level=3
"""The constrained solve of the runtime, robust to redundant constraints.

    x = argmin  x^T M x / 2 - Q^T x   subject to   B x = b

M (n x n, symmetric) may be singular on its own (a body's 9 x 9 block has rank 6); B
(m x n) may be rank-deficient (redundant constraints are normal in closed loops). Only
M restricted to the null space of B must be positive definite. The algorithm:

1. scale each row of B and b by 1 / max(||B_k||, ROW_FLOOR max_j ||B_j||), j over the
   rows of B_k's element (s.group; each row alone without it);
2. QR with column pivoting of the scaled B^T: B^T P = Q R; the rank r is the number of
   leading |R_kk| > rank_tol |R_00|;
3. Q1 = the first r columns of Q (a basis of the row space of B), Q2 the other n - r
   columns (a basis of its null space), formed by applying the first r Householder
   reflectors to [0; I] (no full Q is formed);
4. particular solution x_p = Q1 y with R11^T y = (P^T b)[:r];
5. S = Q2^T M Q2 = U^T U (Cholesky; a failure, or a pivot U_kk^2 at or below
   64 eps max_k S_kk, means M is singular on the constraint manifold),
   z = S^{-1} Q2^T (Q - M x_p), x = x_p + Q2 z.

The work is split into csolve_factor (steps 1-3 and S, depends on M and B only) and
csolve_apply (steps 4-5 for one right-hand side), so that several right-hand sides share
one factorisation. After the QR, everything costs O(n^2 (n - r)): cheap when the
mechanism has few degrees of freedom.

Rank. A threshold on the QR pivots alone cannot tell a redundant constraint (a zero
singular value perturbed by the position error) from an independent one: on Bricard's
linkage the first dropped pivot reaches 7.7e-8 while the smallest singular value of B is
1.6e-13, and a threshold of 1e-10 then counts one equation too many, leaving 0 degrees
of freedom: the linkage freezes. So the rank is decided once, by an SVD gap test at the
start of a run (rank_fixed, set from Python), and kept, with two exceptions:

* a pivot within the decided rank at or below rank_tol |R_00| is a singular position
  (the Jacobian really loses rank there): those rows are dropped for this factorisation
  only and counted in n_drop;
* a first dropped pivot above grow_trigger, at a state on the constraints (the velocity
  projection sets check_growth; the stage states of a step are off the constraints by
  O(dt^2), which lifts the singular values of redundant rows), starts an SVD of B; if it finds
  more than rank_fixed singular values above grow_tol sigma_1, the rank has grown (the
  run started at a singular position) and rank_fixed is raised (grew = 1); otherwise
  grow_trigger becomes ten times that pivot, so the SVD is repeated only when the pivot
  has grown a decade. The pivot bounds sigma_{r+1} <= sqrt(m - r) |R_rr|, so no growth
  beyond grow_tol goes unseen while the pivot stays below the trigger.

With rank_fixed < 0 the rank is the number of pivots above rank_tol |R_00| (for one-off
solves, and while the initial positions are assembled).
"""
from libc.math cimport fabs, sqrt
from libc.stdlib cimport free, malloc
from libc.string cimport memcpy, memset
from scipy.linalg.cython_blas cimport dgemm
from scipy.linalg.cython_lapack cimport dgeqp3, dgesvd, dormqr, dpotrf

import numpy as np

from fccgen.errors import SimulationError


# A Cholesky pivot d_k^2 at or below this fraction of the largest diagonal entry of the
# reduced mass matrix counts as zero (the numeric version uses the same rule).
cdef double PIVOT_TOL = 64 * 2.220446049250313e-16
# A rank increase is accepted when sigma_{r+1} > GROW_TOL sigma_1. Redundant equations
# perturbed by a position error e (relative to the body length; the projections keep
# e near 1e-11) have sigma ~ e, five decades below; a run that starts at a singular
# position moves sigma_{r+1} away from zero in proportion to the distance travelled,
# so it passes 1e-6 within the first steps.
cdef double GROW_TOL = 1e-6
# Rows are scaled to unit length for the rank decision, but no row by more than
# 1 / (ROW_FLOOR * the largest row norm of its element): a row whose gradient nearly
# vanishes (the component of point_on_line's cross product along the line) is a
# redundant combination of its element's other rows, and scaling it to unit length would
# blow the position error up into an apparent independent direction (fccgen.rank).
cdef double ROW_FLOOR = 1e-4
# Above this many coordinates the null-space basis is formed with LAPACK's blocked
# dormqr; below, plain loops over the reflectors cost less than the call overhead.
cdef int BLOCKED_MIN = 64


cdef inline int _imax(int a, int b) noexcept nogil:
    return a if a > b else b


cdef int _query_lwork(int n, int m) noexcept nogil:
    """Largest workspace dgeqp3, dormqr and dgesvd ask for at these sizes."""
    cdef int info = 0, lwork = -1, k = n if n < m else m, one = 1, ld = _imax(n, 1)
    cdef double q1 = 0.0, q2 = 0.0, q3 = 0.0, q4 = 0.0, dummy = 0.0
    cdef int idummy = 0
    if n > 0 and m > 0:
        dgeqp3(&n, &m, &dummy, &ld, &idummy, &dummy, &q1, &lwork, &info)
        dormqr(b"L", b"N", &n, &n, &k, &dummy, &ld, &dummy, &dummy, &ld, &q2, &lwork,
               &info)
        dormqr(b"L", b"N", &n, &one, &k, &dummy, &ld, &dummy, &dummy, &ld, &q3, &lwork,
               &info)
        dgesvd(b"N", b"N", &n, &m, &dummy, &ld, &dummy, &dummy, &one, &dummy, &one, &q4,
               &lwork, &info)
    return _imax(_imax(_imax(<int>q1, <int>q2), _imax(<int>q3, <int>q4)), 5 * (n + m) + 1)


cdef int csolve_init(CSolve *s, int n, int m, double rank_tol) except -1:
    """Allocate the work arrays of a solve with n coordinates and m constraint rows."""
    memset(s, 0, sizeof(CSolve))
    s.n = n
    s.m = m
    s.rank_tol = rank_tol
    s.rank_fixed = -1
    s.check_growth = 0
    s.group = NULL
    s.grow_tol = GROW_TOL
    csolve_reset_stats(s)
    s.lwork = _query_lwork(n, m)
    cdef size_t nn = <size_t>_imax(n, 1) * <size_t>_imax(n, 1)
    cdef size_t nm = <size_t>_imax(n, 1) * <size_t>_imax(m, 1)
    s.A = <double *>malloc(nm * sizeof(double))
    s.scale = <double *>malloc(_imax(m, 1) * sizeof(double))
    s.tau = <double *>malloc(_imax(m, 1) * sizeof(double))
    s.jpvt = <int *>malloc(_imax(m, 1) * sizeof(int))
    s.Q2 = <double *>malloc(nn * sizeof(double))
    s.MQ2 = <double *>malloc(nn * sizeof(double))
    s.S = <double *>malloc(nn * sizeof(double))
    s.xp = <double *>malloc(_imax(n, 1) * sizeof(double))
    s.rhs = <double *>malloc(_imax(n, 1) * sizeof(double))
    s.work = <double *>malloc(s.lwork * sizeof(double))
    s.sv = <double *>malloc(nm * sizeof(double))
    s.sigma = <double *>malloc(_imax(_imax(n, m), 1) * sizeof(double))
    if (s.sv == NULL or s.sigma == NULL or s.A == NULL or s.scale == NULL or s.tau == NULL or s.jpvt == NULL
            or s.Q2 == NULL or s.MQ2 == NULL or s.S == NULL or s.xp == NULL
            or s.rhs == NULL or s.work == NULL):
        csolve_free(s)
        raise MemoryError("cannot allocate the work arrays of the constrained solve")
    return 0


cdef void csolve_free(CSolve *s) noexcept nogil:
    free(s.A); free(s.scale); free(s.tau); free(s.jpvt); free(s.Q2); free(s.MQ2)
    free(s.S); free(s.xp); free(s.rhs); free(s.work); free(s.sv); free(s.sigma)
    s.sv = NULL; s.sigma = NULL
    s.A = NULL; s.scale = NULL; s.tau = NULL; s.jpvt = NULL; s.Q2 = NULL; s.MQ2 = NULL
    s.S = NULL; s.xp = NULL; s.rhs = NULL; s.work = NULL


cdef void _row_scales(CSolve *s, const double *B) noexcept nogil:
    """scale[k] = 1 / max(||B_k||, ROW_FLOOR * the largest row norm of B_k's element)
    (each row its own element when s.group is NULL; 1 for a zero row)."""
    cdef int i, k, j, n = s.n
    cdef double norm, largest
    for k in range(s.m):
        norm = 0.0
        for i in range(n):
            norm += B[k * n + i] * B[k * n + i]
        s.scale[k] = sqrt(norm)
    if s.group != NULL:
        k = 0
        while k < s.m:                     # the rows of one element are consecutive
            j, largest = k, 0.0
            while j < s.m and s.group[j] == s.group[k]:
                largest = s.scale[j] if s.scale[j] > largest else largest
                j += 1
            for i in range(k, j):
                s.sigma[i] = ROW_FLOOR * largest
            k = j
    for k in range(s.m):
        norm = s.scale[k]
        if s.group != NULL and s.sigma[k] > norm:
            norm = s.sigma[k]
        s.scale[k] = 1.0 / norm if norm > 0.0 else 1.0


cdef void _scaled_transpose(CSolve *s, const double *B) noexcept nogil:
    """A = B^T with each column (row of B) scaled by _row_scales. A row-major m x n
    array is the column-major n x m transpose, so this is a scaled copy."""
    cdef int i, k, n = s.n
    _row_scales(s, B)
    for k in range(s.m):
        for i in range(n):
            s.A[k * n + i] = B[k * n + i] * s.scale[k]


cdef void csolve_reset_stats(CSolve *s) noexcept nogil:
    """Start the rank statistics anew (when the rank has been decided)."""
    s.grow_trigger = s.rank_tol
    s.grew = 0
    s.n_factor = 0
    s.n_drop = 0
    s.n_svd = 0
    s.kept_min = 1.0
    s.dropped_max = 0.0


cdef int csolve_svd_rank(CSolve *s, const double *B, double tol) noexcept nogil:
    """Number of singular values of the row-scaled B above tol sigma_1 (-1 on a LAPACK
    failure); the singular values are left in s.sigma, largest first."""
    cdef int i, k, info = 0, one = 1, n = s.n, m = s.m, kmax = s.n if s.n < s.m else s.m
    cdef int ld = _imax(s.n, 1), rank = 0
    cdef double dummy = 0.0
    if kmax == 0:
        return 0
    _row_scales(s, B)
    for k in range(m):
        for i in range(n):
            s.sv[k * n + i] = B[k * n + i] * s.scale[k]
    dgesvd(b"N", b"N", &n, &m, s.sv, &ld, s.sigma, &dummy, &one, &dummy, &one, s.work,
           &s.lwork, &info)
    if info != 0:
        return -1
    while rank < kmax and s.sigma[rank] > tol * s.sigma[0]:
        rank += 1
    return rank


cdef int _pivoted_qr(CSolve *s, const double *B) noexcept nogil:
    """QR with column pivoting of A; sets the rank (see "Rank" above). Returns LAPACK's
    info."""
    cdef int k, info = 0, kmax = s.n if s.n < s.m else s.m, cap, svd
    cdef double r00, first_dropped
    s.r = 0
    s.grew = 0
    if kmax == 0:
        return 0
    for k in range(s.m):
        s.jpvt[k] = 0
    dgeqp3(&s.n, &s.m, s.A, &s.n, s.jpvt, s.tau, s.work, &s.lwork, &info)
    if info != 0:
        return info
    r00 = fabs(s.A[0])
    if r00 == 0.0:
        return 0
    cap = kmax if s.rank_fixed < 0 else (s.rank_fixed if s.rank_fixed < kmax else kmax)
    while s.r < cap and fabs(s.A[s.r * s.n + s.r]) > s.rank_tol * r00:
        s.r += 1
    if s.rank_fixed < 0:
        return 0
    s.n_factor += 1
    if s.r < cap:
        s.n_drop += 1
    if s.r > 0 and fabs(s.A[(s.r - 1) * s.n + s.r - 1]) / r00 < s.kept_min:
        s.kept_min = fabs(s.A[(s.r - 1) * s.n + s.r - 1]) / r00
    if cap >= kmax:
        return 0
    first_dropped = fabs(s.A[cap * s.n + cap]) / r00
    if first_dropped > s.dropped_max:
        s.dropped_max = first_dropped
    if first_dropped > s.grow_trigger and s.check_growth:
        s.n_svd += 1
        svd = csolve_svd_rank(s, B, s.grow_tol)
        if svd > s.rank_fixed:
            s.rank_fixed = svd
            s.grew = 1
            while s.r < kmax and s.r < svd and fabs(s.A[s.r * s.n + s.r]) > s.rank_tol * r00:
                s.r += 1
        else:
            s.grow_trigger = 10.0 * first_dropped
    return 0


cdef int csolve_factor(CSolve *s, const double *M, const double *B) noexcept nogil:
    """Factor (M, B): pivoted QR of the scaled B^T, null-space basis Q2, M Q2 and the
    Cholesky factor of Q2^T M Q2. Returns 0, or dpotrf's info > 0 when the reduced mass
    matrix is not positive definite, or a negative LAPACK error code."""
    cdef int c, info = 0, n = s.n, ld = _imax(s.n, 1), nr, ldnr
    cdef double one = 1.0, zero = 0.0
    if s.m > 0:
        _scaled_transpose(s, B)
    info = _pivoted_qr(s, B)
    if info != 0:
        return -abs(info)
    nr = s.n - s.r
    s.nr = nr
    if nr == 0:
        return 0
    ldnr = _imax(nr, 1)
    memset(s.Q2, 0, <size_t>n * nr * sizeof(double))
    for c in range(nr):
        s.Q2[c * n + s.r + c] = 1.0
    if s.r > 0 and n > BLOCKED_MIN:
        dormqr(b"L", b"N", &s.n, &nr, &s.r, s.A, &ld, s.tau, s.Q2, &ld, s.work, &s.lwork,
               &info)
        if info != 0:
            return -abs(info)
    elif s.r > 0:
        for c in range(nr):
            _apply_q(s, s.Q2 + c * n)
    dgemm(b"N", b"N", &s.n, &nr, &s.n, &one, <double *>M, &ld, s.Q2, &ld, &zero, s.MQ2,
          &ld)
    dgemm(b"T", b"N", &nr, &nr, &s.n, &one, s.Q2, &ld, s.MQ2, &ld, &zero, s.S, &ldnr)
    return _cholesky(s.S, nr)


cdef int _cholesky(double *S, int n) noexcept nogil:
    """Upper Cholesky factor of S (n x n) in place. Returns 0, or k + 1 for the first
    pivot k that is not positive or below PIVOT_TOL of the largest diagonal entry
    (rounding leaves exactly singular matrices with pivots of a few ulps, which dpotrf
    alone would accept)."""
    cdef int k, info = 0
    cdef double dmax = 0.0
    for k in range(n):
        if fabs(S[k * n + k]) > dmax:
            dmax = fabs(S[k * n + k])
    dpotrf(b"U", &n, S, &n, &info)
    if info != 0:
        return info
    for k in range(n):
        if not S[k * n + k] * S[k * n + k] > PIVOT_TOL * dmax:
            return k + 1
    return 0


cdef inline void _reflect(const CSolve *s, int k, double *y) noexcept nogil:
    """y <- H_k y, H_k = I - tau_k v v^T with v = [0..0, 1, A[k+1:, k]] (LAPACK's
    storage of the reflectors below the diagonal of A)."""
    cdef int i, n = s.n
    cdef const double *v = s.A + k * n
    cdef double d = y[k]
    for i in range(k + 1, n):
        d += v[i] * y[i]
    d *= s.tau[k]
    y[k] -= d
    for i in range(k + 1, n):
        y[i] -= d * v[i]


cdef inline void _apply_q(const CSolve *s, double *y) noexcept nogil:
    """y <- Q y with Q = H_0 H_1 ... H_{r-1} (the first r reflectors)."""
    cdef int k
    for k in range(s.r - 1, -1, -1):
        _reflect(s, k, y)


cdef void csolve_apply(CSolve *s, const double *Q, const double *w, const double *b,
                       double *x) noexcept nogil:
    """x for the right-hand side Q + M w (Q or w may be NULL: zero) and the constraint
    B x = b (b may be NULL: zero), with the factorisation of csolve_factor."""
    cdef int i, j, k, n = s.n, nr = s.nr, r = s.r
    cdef const double *col
    cdef double acc
    cdef bint has_xp = b != NULL and r > 0
    cdef bint has_rhs = Q != NULL or w != NULL or has_xp
    # particular solution x_p = Q1 y, R11^T y = (P^T b_scaled)[:r]  (R = upper A)
    memset(s.xp, 0, <size_t>n * sizeof(double))
    if has_xp:
        for i in range(r):
            acc = b[s.jpvt[i] - 1] * s.scale[s.jpvt[i] - 1]
            for k in range(i):
                acc -= s.A[i * n + k] * s.xp[k]
            s.xp[i] = acc / s.A[i * n + i]
        _apply_q(s, s.xp)
    memcpy(x, s.xp, <size_t>n * sizeof(double))
    if nr == 0 or not has_rhs:
        return
    # rhs = Q2^T Q + (M Q2)^T (w - x_p)   (M symmetric)
    for j in range(nr):
        acc = 0.0
        if Q != NULL:
            col = s.Q2 + j * n
            for i in range(n):
                acc += col[i] * Q[i]
        col = s.MQ2 + j * n
        if w != NULL:
            for i in range(n):
                acc += col[i] * w[i]
        if has_xp:
            for i in range(n):
                acc -= col[i] * s.xp[i]
        s.rhs[j] = acc
    # z = S^{-1} rhs with S = U^T U (U upper, column-major nr x nr)
    for i in range(nr):
        acc = s.rhs[i]
        for k in range(i):
            acc -= s.S[i * nr + k] * s.rhs[k]
        s.rhs[i] = acc / s.S[i * nr + i]
    for i in range(nr - 1, -1, -1):
        acc = s.rhs[i]
        for k in range(i + 1, nr):
            acc -= s.S[k * nr + i] * s.rhs[k]
        s.rhs[i] = acc / s.S[i * nr + i]
    # x = x_p + Q2 z
    for j in range(nr):
        col = s.Q2 + j * n
        acc = s.rhs[j]
        for i in range(n):
            x[i] += col[i] * acc


def constrained_solve(M, B, Q, b, double rank_tol=1e-10, int rank=-1):
    """Solve one problem from Python (for tests and checks): returns (x, rank).

    M: (n, n), B: (m, n), Q: (n,), b: (m,). rank >= 0: the decided rank (see "Rank"
    above), else the pivot threshold alone. Raises SimulationError when M is singular
    on the null space of B.
    """
    cdef double[:, ::1] Mv = np.ascontiguousarray(M, dtype=float)
    cdef double[:, ::1] Bv = np.ascontiguousarray(B, dtype=float).reshape(-1, Mv.shape[0])
    cdef double[::1] Qv = np.ascontiguousarray(Q, dtype=float)
    cdef double[::1] bv = np.ascontiguousarray(b, dtype=float)
    cdef int n = Mv.shape[0], m = Bv.shape[0], info
    if Mv.shape[1] != n or Qv.shape[0] != n or bv.shape[0] != m:
        raise ValueError(f"inconsistent shapes: M {np.shape(M)}, B {np.shape(B)}, "
                         f"Q {np.shape(Q)}, b {np.shape(b)}")
    x = np.zeros(n)
    cdef double[::1] xv = x
    cdef CSolve s
    csolve_init(&s, n, m, rank_tol)
    s.rank_fixed = rank
    try:
        with nogil:
            info = csolve_factor(&s, &Mv[0, 0] if n > 0 else NULL,
                                 &Bv[0, 0] if m * n > 0 else NULL)
            if info == 0 and n > 0:
                csolve_apply(&s, &Qv[0], NULL, &bv[0] if m > 0 else NULL, &xv[0])
        if info > 0:
            raise SimulationError(
                f"mass matrix singular on the constraint manifold (reduced mass matrix of "
                f"size {s.nr} not positive definite at pivot {info}; rank of B {s.r})")
        if info < 0:
            raise SimulationError(f"LAPACK error {info} in the constrained solve")
        return x, s.r
    finally:
        csolve_free(&s)


def singular_values(B):
    """Singular values of B with each row scaled to unit length, largest first (the
    matrix the rank decision looks at)."""
    cdef double[:, ::1] Bv = np.ascontiguousarray(B, dtype=float)
    cdef int m = Bv.shape[0], n = Bv.shape[1] if Bv.ndim == 2 else 0, k
    cdef CSolve s
    csolve_init(&s, n, m, 1e-10)
    try:
        if n * m > 0:
            with nogil:
                k = csolve_svd_rank(&s, &Bv[0, 0], 0.0)
            if k < 0:
                raise SimulationError("LAPACK's SVD (dgesvd) did not converge")
        return np.array([s.sigma[i] for i in range(min(n, m))])
    finally:
        csolve_free(&s)
