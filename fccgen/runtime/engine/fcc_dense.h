/* The dense path's constrained solve, robust to redundant constraints:
 *
 *     x = argmin  x^T M x / 2 - Q^T x   subject to   B x = b
 *
 * by a pivoted QR of the row-scaled B^T, a null-space basis and the Cholesky factor of
 * the reduced mass matrix (fcc_dense.c says how, and how the rank is decided). Needs
 * LAPACK (dgeqp3, dormqr, dgesvd, dpotrf) and BLAS (dgemm) through an fcc_lapack table.
 */
#ifndef FCC_DENSE_H
#define FCC_DENSE_H

#include "fcc_base.h"

typedef struct fcc_dense {
    const fcc_lapack *lapack;
    int n;                 /* coordinates (columns of B) */
    int m;                 /* constraint rows */
    int r;                 /* numerical rank of B at the last factorisation */
    int nr;                /* n - r: dimension of the null space of B */
    double rank_tol;       /* a pivot |R_kk| <= rank_tol |R_00| counts as zero */
    double grow_tol;       /* sigma_k > grow_tol sigma_1 counts for a rank increase */
    double row_floor;      /* row scaling floor within an element */
    int rank_fixed;        /* the decided rank of B (< 0: threshold only) */
    double grow_trigger;   /* a first dropped pivot above this starts an SVD check */
    int check_growth;      /* this factorisation is at a projected state */
    int grew;              /* the last factorisation raised rank_fixed */
    long n_factor;         /* factorisations since the rank was decided */
    long n_drop;           /* ... with a pivot below rank_tol within the decided rank */
    long n_svd;            /* SVD checks done */
    double kept_min;       /* smallest last kept pivot ratio |R_{r-1}| / |R_00| */
    double dropped_max;    /* largest first dropped pivot ratio |R_r| / |R_00| */
    double *sv;            /* n x m copy of the scaled B^T for the SVD check */
    double *sigma;         /* min(n, m) singular values (max(n, m) room) */
    const int *group;      /* m or NULL: first row of the element each row belongs to */
    double *A;             /* n x m column-major: scaled B^T, then its pivoted QR */
    double *scale;         /* m: 1 / ||B_k|| (1 for zero rows) */
    double *tau;           /* min(n, m) Householder factors */
    int *jpvt;             /* m column pivots (1-based, LAPACK's) */
    double *Q2;            /* n x nr column-major: orthonormal basis of the null space */
    double *MQ2;           /* n x nr: M Q2 */
    double *S;             /* nr x nr: Cholesky factor of Q2^T M Q2 (upper) */
    double *xp;            /* n: particular solution */
    double *rhs;           /* n: reduced right-hand side */
    double *work;
    int lwork;
} fcc_dense;

/* Allocate the work arrays of a solve with n coordinates and m rows; lapack may be
 * NULL (no factorisation then: fcc_dense_factor returns FCC_DENSE_NO_LAPACK). */
int fcc_dense_init(fcc_dense *s, int n, int m, double rank_tol, double grow_tol,
                   double row_floor, const fcc_lapack *lapack);
void fcc_dense_free(fcc_dense *s);
/* Start the rank statistics anew (when the rank has been decided). */
void fcc_dense_reset_stats(fcc_dense *s);
/* Number of singular values of the row-scaled B above tol sigma_1 (-1 on a LAPACK
 * failure or without LAPACK); they are left in s->sigma, largest first. */
int fcc_dense_svd_rank(fcc_dense *s, const double *B, double tol);
/* Factor (M, B). Returns 0, dpotrf's info > 0 when the reduced mass matrix is not
 * positive definite, a negative LAPACK error code, or FCC_DENSE_NO_LAPACK. */
int fcc_dense_factor(fcc_dense *s, const double *M, const double *B);
/* x for the right-hand side Q + M w (Q or w may be NULL: zero) and B x = b (b may be
 * NULL: zero), with the factorisation of fcc_dense_factor. */
void fcc_dense_apply(fcc_dense *s, const double *Q, const double *w, const double *b,
                     double *x);

/* Multipliers lam of B^T lam = r (r in the range of B^T: r = Q - M x of a solve) by the
 * pivoted QR of the last factorisation; rows past the rank get 0. y: n numbers of room. */
void fcc_dense_multipliers(const fcc_dense *s, const double *r, double *lam, double *y);

#define FCC_DENSE_NO_LAPACK (-100000)

#endif
