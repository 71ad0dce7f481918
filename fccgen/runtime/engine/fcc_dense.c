/* The dense path's constrained solve (fcc_dense.h), robust to redundant constraints.
 *
 *     x = argmin  x^T M x / 2 - Q^T x   subject to   B x = b
 *
 * M (n x n, symmetric) may be singular on its own (a body's 9 x 9 block has rank 6); B
 * (m x n) may be rank-deficient (redundant constraints are normal in closed loops).
 * Only M restricted to the null space of B must be positive definite. The algorithm:
 *
 * 1. scale each row of B and b by 1 / max(||B_k||, row_floor max_j ||B_j||), j over
 *    the rows of B_k's element (s->group; each row alone without it);
 * 2. QR with column pivoting of the scaled B^T: B^T P = Q R; the rank r is the number
 *    of leading |R_kk| > rank_tol |R_00|;
 * 3. Q1 = the first r columns of Q (a basis of the row space of B), Q2 the other
 *    n - r columns (a basis of its null space), formed by applying the first r
 *    Householder reflectors to [0; I] (no full Q is formed);
 * 4. particular solution x_p = Q1 y with R11^T y = (P^T b)[:r];
 * 5. S = Q2^T M Q2 = U^T U (Cholesky; a failure, or a pivot U_kk^2 at or below
 *    64 eps max_k S_kk, means M is singular on the constraint manifold),
 *    z = S^{-1} Q2^T (Q - M x_p), x = x_p + Q2 z.
 *
 * The work is split into fcc_dense_factor (steps 1-3 and S, depends on M and B only)
 * and fcc_dense_apply (steps 4-5 for one right-hand side), so that several
 * right-hand sides share one factorisation. After the QR, everything costs
 * O(n^2 (n - r)): cheap when the mechanism has few degrees of freedom.
 *
 * Rank. A threshold on the QR pivots alone cannot tell a redundant constraint (a zero
 * singular value perturbed by the position error) from an independent one: on
 * Bricard's linkage the first dropped pivot reaches 7.7e-8 while the smallest singular
 * value of B is 1.6e-13, and a threshold of 1e-10 then counts one equation too many,
 * leaving 0 degrees of freedom: the linkage freezes. So the rank is decided once, by
 * an SVD gap test at the start of a run (rank_fixed, set by the caller), and kept,
 * with two exceptions:
 *
 * - a pivot within the decided rank at or below rank_tol |R_00| is a singular position
 *   (the Jacobian really loses rank there): those rows are dropped for this
 *   factorisation only and counted in n_drop;
 * - a first dropped pivot above grow_trigger, at a state on the constraints (the
 *   velocity projection sets check_growth; the stage states of a step are off the
 *   constraints by O(dt^2), which lifts the singular values of redundant rows), starts
 *   an SVD of B; if it finds more than rank_fixed singular values above
 *   grow_tol sigma_1, the rank has grown (the run started at a singular position) and
 *   rank_fixed is raised (grew = 1); otherwise grow_trigger becomes ten times that
 *   pivot, so the SVD is repeated only when the pivot has grown a decade. The pivot
 *   bounds sigma_{r+1} <= sqrt(m - r) |R_rr|, so no growth beyond grow_tol goes unseen
 *   while the pivot stays below the trigger.
 *
 * With rank_fixed < 0 the rank is the number of pivots above rank_tol |R_00| (for
 * one-off solves, and while the initial positions are assembled).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fcc_dense.h"

/* A Cholesky pivot d_k^2 at or below this fraction of the largest diagonal entry of
 * the reduced mass matrix counts as zero (the numeric version uses the same rule). */
#define PIVOT_TOL (64 * 2.220446049250313e-16)
/* Above this many coordinates the null-space basis is formed with LAPACK's blocked
 * dormqr; below, plain loops over the reflectors cost less than the call overhead. */
#define BLOCKED_MIN 64

static int imax(int a, int b) { return a > b ? a : b; }

/* Largest workspace dgeqp3, dormqr and dgesvd ask for at these sizes. */
static int query_lwork(const fcc_lapack *lp, int n, int m)
{
    int info = 0, lwork = -1, k = n < m ? n : m, one = 1, ld = imax(n, 1);
    double q1 = 0.0, q2 = 0.0, q3 = 0.0, q4 = 0.0, dummy = 0.0;
    int idummy = 0;
    char L = 'L', N = 'N';
    if (lp != NULL && n > 0 && m > 0) {
        lp->dgeqp3(&n, &m, &dummy, &ld, &idummy, &dummy, &q1, &lwork, &info);
        lp->dormqr(&L, &N, &n, &n, &k, &dummy, &ld, &dummy, &dummy, &ld, &q2, &lwork,
                   &info);
        lp->dormqr(&L, &N, &n, &one, &k, &dummy, &ld, &dummy, &dummy, &ld, &q3, &lwork,
                   &info);
        lp->dgesvd(&N, &N, &n, &m, &dummy, &ld, &dummy, &dummy, &one, &dummy, &one, &q4,
                   &lwork, &info);
    }
    return imax(imax(imax((int)q1, (int)q2), imax((int)q3, (int)q4)), 5 * (n + m) + 1);
}

int fcc_dense_init(fcc_dense *s, int n, int m, double rank_tol, double grow_tol,
                   double row_floor, const fcc_lapack *lapack)
{
    size_t nn = (size_t)imax(n, 1) * (size_t)imax(n, 1);
    size_t nm = (size_t)imax(n, 1) * (size_t)imax(m, 1);
    memset(s, 0, sizeof(*s));
    s->lapack = lapack;
    s->n = n;
    s->m = m;
    s->rank_tol = rank_tol;
    s->grow_tol = grow_tol;
    s->row_floor = row_floor;
    s->rank_fixed = -1;
    s->check_growth = 0;
    s->group = NULL;
    fcc_dense_reset_stats(s);
    s->lwork = query_lwork(lapack, n, m);
    s->A = FCC_CALLOC(nm, sizeof(double));
    s->scale = FCC_CALLOC((size_t)imax(m, 1), sizeof(double));
    s->tau = FCC_CALLOC((size_t)imax(m, 1), sizeof(double));
    s->jpvt = FCC_CALLOC((size_t)imax(m, 1), sizeof(int));
    s->Q2 = FCC_CALLOC(nn, sizeof(double));
    s->MQ2 = FCC_CALLOC(nn, sizeof(double));
    s->S = FCC_CALLOC(nn, sizeof(double));
    s->xp = FCC_CALLOC((size_t)imax(n, 1), sizeof(double));
    s->rhs = FCC_CALLOC((size_t)imax(n, 1), sizeof(double));
    s->work = FCC_CALLOC((size_t)s->lwork, sizeof(double));
    s->sv = FCC_CALLOC(nm, sizeof(double));
    s->sigma = FCC_CALLOC((size_t)imax(imax(n, m), 1), sizeof(double));
    if (!s->sv || !s->sigma || !s->A || !s->scale || !s->tau || !s->jpvt || !s->Q2
            || !s->MQ2 || !s->S || !s->xp || !s->rhs || !s->work) {
        fcc_dense_free(s);
        return FCC_ERR_MEMORY;
    }
    return FCC_OK;
}

void fcc_dense_free(fcc_dense *s)
{
    FCC_FREE(s->A); FCC_FREE(s->scale); FCC_FREE(s->tau); FCC_FREE(s->jpvt);
    FCC_FREE(s->Q2); FCC_FREE(s->MQ2); FCC_FREE(s->S); FCC_FREE(s->xp);
    FCC_FREE(s->rhs); FCC_FREE(s->work); FCC_FREE(s->sv); FCC_FREE(s->sigma);
    s->sv = s->sigma = s->A = s->scale = s->tau = s->Q2 = s->MQ2 = s->S = NULL;
    s->xp = s->rhs = s->work = NULL;
    s->jpvt = NULL;
}

/* scale[k] = 1 / max(||B_k||, row_floor * the largest row norm of B_k's element)
 * (each row its own element when s->group is NULL; 1 for a zero row). */
static void row_scales(fcc_dense *s, const double *B)
{
    int i, k, j, n = s->n;
    double norm, largest;
    for (k = 0; k < s->m; k++) {
        norm = 0.0;
        for (i = 0; i < n; i++)
            norm += B[k * n + i] * B[k * n + i];
        s->scale[k] = sqrt(norm);
    }
    if (s->group != NULL) {
        k = 0;
        while (k < s->m) {               /* the rows of one element are consecutive */
            j = k;
            largest = 0.0;
            while (j < s->m && s->group[j] == s->group[k]) {
                largest = s->scale[j] > largest ? s->scale[j] : largest;
                j++;
            }
            for (i = k; i < j; i++)
                s->sigma[i] = s->row_floor * largest;
            k = j;
        }
    }
    for (k = 0; k < s->m; k++) {
        norm = s->scale[k];
        if (s->group != NULL && s->sigma[k] > norm)
            norm = s->sigma[k];
        s->scale[k] = norm > 0.0 ? 1.0 / norm : 1.0;
    }
}

/* A = B^T with each column (row of B) scaled by row_scales. A row-major m x n array
 * is the column-major n x m transpose, so this is a scaled copy. */
static void scaled_transpose(fcc_dense *s, const double *B)
{
    int i, k, n = s->n;
    row_scales(s, B);
    for (k = 0; k < s->m; k++)
        for (i = 0; i < n; i++)
            s->A[k * n + i] = B[k * n + i] * s->scale[k];
}

void fcc_dense_reset_stats(fcc_dense *s)
{
    s->grow_trigger = s->rank_tol;
    s->grew = 0;
    s->n_factor = 0;
    s->n_drop = 0;
    s->n_svd = 0;
    s->kept_min = 1.0;
    s->dropped_max = 0.0;
}

int fcc_dense_svd_rank(fcc_dense *s, const double *B, double tol)
{
    int i, k, info = 0, one = 1, n = s->n, m = s->m, kmax = s->n < s->m ? s->n : s->m;
    int ld = imax(s->n, 1), rank = 0;
    double dummy = 0.0;
    char N = 'N';
    if (kmax == 0)
        return 0;
    if (s->lapack == NULL)
        return -1;
    row_scales(s, B);
    for (k = 0; k < m; k++)
        for (i = 0; i < n; i++)
            s->sv[k * n + i] = B[k * n + i] * s->scale[k];
    s->lapack->dgesvd(&N, &N, &n, &m, s->sv, &ld, s->sigma, &dummy, &one, &dummy, &one,
                      s->work, &s->lwork, &info);
    if (info != 0)
        return -1;
    while (rank < kmax && s->sigma[rank] > tol * s->sigma[0])
        rank++;
    return rank;
}

/* QR with column pivoting of A; sets the rank (the file's docstring, "Rank"). Returns
 * LAPACK's info. */
static int pivoted_qr(fcc_dense *s, const double *B)
{
    int k, info = 0, kmax = s->n < s->m ? s->n : s->m, cap, svd;
    double r00, first_dropped;
    s->r = 0;
    s->grew = 0;
    if (kmax == 0)
        return 0;
    for (k = 0; k < s->m; k++)
        s->jpvt[k] = 0;
    s->lapack->dgeqp3(&s->n, &s->m, s->A, &s->n, s->jpvt, s->tau, s->work, &s->lwork,
                      &info);
    if (info != 0)
        return info;
    r00 = fabs(s->A[0]);
    if (r00 == 0.0)
        return 0;
    cap = s->rank_fixed < 0 ? kmax : (s->rank_fixed < kmax ? s->rank_fixed : kmax);
    while (s->r < cap && fabs(s->A[s->r * s->n + s->r]) > s->rank_tol * r00)
        s->r++;
    if (s->rank_fixed < 0)
        return 0;
    s->n_factor++;
    if (s->r < cap)
        s->n_drop++;
    if (s->r > 0 && fabs(s->A[(s->r - 1) * s->n + s->r - 1]) / r00 < s->kept_min)
        s->kept_min = fabs(s->A[(s->r - 1) * s->n + s->r - 1]) / r00;
    if (cap >= kmax)
        return 0;
    first_dropped = fabs(s->A[cap * s->n + cap]) / r00;
    if (first_dropped > s->dropped_max)
        s->dropped_max = first_dropped;
    if (first_dropped > s->grow_trigger && s->check_growth) {
        s->n_svd++;
        svd = fcc_dense_svd_rank(s, B, s->grow_tol);
        if (svd > s->rank_fixed) {
            s->rank_fixed = svd;
            s->grew = 1;
            while (s->r < kmax && s->r < svd
                   && fabs(s->A[s->r * s->n + s->r]) > s->rank_tol * r00)
                s->r++;
        } else {
            s->grow_trigger = 10.0 * first_dropped;
        }
    }
    return 0;
}

/* y <- H_k y, H_k = I - tau_k v v^T with v = [0..0, 1, A[k+1:, k]] (LAPACK's storage
 * of the reflectors below the diagonal of A). */
static void reflect(const fcc_dense *s, int k, double *y)
{
    int i, n = s->n;
    const double *v = s->A + k * n;
    double d = y[k];
    for (i = k + 1; i < n; i++)
        d += v[i] * y[i];
    d *= s->tau[k];
    y[k] -= d;
    for (i = k + 1; i < n; i++)
        y[i] -= d * v[i];
}

/* y <- Q y with Q = H_0 H_1 ... H_{r-1} (the first r reflectors). */
static void apply_q(const fcc_dense *s, double *y)
{
    int k;
    for (k = s->r - 1; k >= 0; k--)
        reflect(s, k, y);
}

/* Upper Cholesky factor of S (n x n) in place. Returns 0, or k + 1 for the first
 * pivot k that is not positive or below PIVOT_TOL of the largest diagonal entry
 * (rounding leaves exactly singular matrices with pivots of a few ulps, which dpotrf
 * alone would accept). */
static int cholesky(const fcc_lapack *lp, double *S, int n)
{
    int k, info = 0;
    double dmax = 0.0;
    char U = 'U';
    for (k = 0; k < n; k++)
        if (fabs(S[k * n + k]) > dmax)
            dmax = fabs(S[k * n + k]);
    lp->dpotrf(&U, &n, S, &n, &info);
    if (info != 0)
        return info;
    for (k = 0; k < n; k++)
        if (!(S[k * n + k] * S[k * n + k] > PIVOT_TOL * dmax))
            return k + 1;
    return 0;
}

int fcc_dense_factor(fcc_dense *s, const double *M, const double *B)
{
    int c, info = 0, n = s->n, ld = imax(s->n, 1), nr, ldnr;
    double one = 1.0, zero = 0.0;
    char L = 'L', N = 'N', T = 'T';
    if (s->lapack == NULL)
        return FCC_DENSE_NO_LAPACK;
    if (s->m > 0)
        scaled_transpose(s, B);
    info = pivoted_qr(s, B);
    if (info != 0)
        return -abs(info);
    nr = s->n - s->r;
    s->nr = nr;
    if (nr == 0)
        return 0;
    ldnr = imax(nr, 1);
    memset(s->Q2, 0, (size_t)n * nr * sizeof(double));
    for (c = 0; c < nr; c++)
        s->Q2[c * n + s->r + c] = 1.0;
    if (s->r > 0 && n > BLOCKED_MIN) {
        s->lapack->dormqr(&L, &N, &s->n, &nr, &s->r, s->A, &ld, s->tau, s->Q2, &ld,
                          s->work, &s->lwork, &info);
        if (info != 0)
            return -abs(info);
    } else if (s->r > 0) {
        for (c = 0; c < nr; c++)
            apply_q(s, s->Q2 + c * n);
    }
    s->lapack->dgemm(&N, &N, &s->n, &nr, &s->n, &one, (double *)M, &ld, s->Q2, &ld,
                     &zero, s->MQ2, &ld);
    s->lapack->dgemm(&T, &N, &nr, &nr, &s->n, &one, s->Q2, &ld, s->MQ2, &ld, &zero,
                     s->S, &ldnr);
    return cholesky(s->lapack, s->S, nr);
}

void fcc_dense_apply(fcc_dense *s, const double *Q, const double *w, const double *b,
                     double *x)
{
    int i, j, k, n = s->n, nr = s->nr, r = s->r;
    const double *col;
    double acc;
    int has_xp = b != NULL && r > 0;
    int has_rhs = Q != NULL || w != NULL || has_xp;
    /* particular solution x_p = Q1 y, R11^T y = (P^T b_scaled)[:r]  (R = upper A) */
    memset(s->xp, 0, (size_t)n * sizeof(double));
    if (has_xp) {
        for (i = 0; i < r; i++) {
            acc = b[s->jpvt[i] - 1] * s->scale[s->jpvt[i] - 1];
            for (k = 0; k < i; k++)
                acc -= s->A[i * n + k] * s->xp[k];
            s->xp[i] = acc / s->A[i * n + i];
        }
        apply_q(s, s->xp);
    }
    memcpy(x, s->xp, (size_t)n * sizeof(double));
    if (nr == 0 || !has_rhs)
        return;
    /* rhs = Q2^T Q + (M Q2)^T (w - x_p)   (M symmetric) */
    for (j = 0; j < nr; j++) {
        acc = 0.0;
        if (Q != NULL) {
            col = s->Q2 + j * n;
            for (i = 0; i < n; i++)
                acc += col[i] * Q[i];
        }
        col = s->MQ2 + j * n;
        if (w != NULL)
            for (i = 0; i < n; i++)
                acc += col[i] * w[i];
        if (has_xp)
            for (i = 0; i < n; i++)
                acc -= col[i] * s->xp[i];
        s->rhs[j] = acc;
    }
    /* z = S^{-1} rhs with S = U^T U (U upper, column-major nr x nr) */
    for (i = 0; i < nr; i++) {
        acc = s->rhs[i];
        for (k = 0; k < i; k++)
            acc -= s->S[i * nr + k] * s->rhs[k];
        s->rhs[i] = acc / s->S[i * nr + i];
    }
    for (i = nr - 1; i >= 0; i--) {
        acc = s->rhs[i];
        for (k = i + 1; k < nr; k++)
            acc -= s->S[k * nr + i] * s->rhs[k];
        s->rhs[i] = acc / s->S[i * nr + i];
    }
    /* x = x_p + Q2 z */
    for (j = 0; j < nr; j++) {
        col = s->Q2 + j * n;
        acc = s->rhs[j];
        for (i = 0; i < n; i++)
            x[i] += col[i] * acc;
    }
}

void fcc_dense_multipliers(const fcc_dense *s, const double *r, double *lam, double *y)
{
    int i, k, n = s->n, rank = s->r;
    double acc;
    memcpy(y, r, (size_t)n * sizeof(double));
    for (k = 0; k < rank; k++)              /* y <- Q^T r = H_{r-1} ... H_0 r */
        reflect(s, k, y);
    for (i = rank - 1; i >= 0; i--) {       /* R11 z = y[:r], R upper in A */
        acc = y[i];
        for (k = i + 1; k < rank; k++)
            acc -= s->A[k * n + i] * y[k];
        y[i] = acc / s->A[i * n + i];
    }
    memset(lam, 0, (size_t)s->m * sizeof(double));
    for (i = 0; i < rank; i++)              /* A = B^T diag(scale): lam = scale P z */
        lam[s->jpvt[i] - 1] = y[i] * s->scale[s->jpvt[i] - 1];
}
