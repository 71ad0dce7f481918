/* fccgen's per-step engine: what every part shares.
 *
 * Plain C99 (libm and libc alone). Every external symbol starts with "fcc_"; a build
 * that links two engines into one program renames them (docs/engine.md). No static
 * mutable data: all state lives in the structs the caller owns, so the engine is
 * reentrant. Heap allocation happens only in the *_init / *_alloc functions, through
 * FCC_CALLOC and FCC_FREE (a build may redirect them); stepping never allocates.
 * Failures are return codes; nothing here prints or exits.
 */
#ifndef FCC_BASE_H
#define FCC_BASE_H

#include <stddef.h>

#include "fccgen_model.h"

#ifndef FCC_CALLOC
#include <stdlib.h>
#define FCC_CALLOC(n, size) calloc((n), (size))
#define FCC_FREE(p) free(p)
#endif

/* What to assemble (fcc_assemble): a bit mask. */
enum {
    FCC_ASM_M = 1,          /* mass matrix M (n_q x n_q) */
    FCC_ASM_H = 2,          /* inertia terms h */
    FCC_ASM_F = 4,          /* applied forces f */
    FCC_ASM_G = 8,          /* constraints g */
    FCC_ASM_B = 16,         /* constraint Jacobian B (n_g x n_q, rows in element order) */
    FCC_ASM_C = 32,         /* constraint bias (dB/dt) v */
    FCC_ASM_E = 64,         /* energy [kinetic, potential] */
    FCC_ASM_BODY = 128,     /* body outputs, 6 per body */
    FCC_ASM_KQ = 256,       /* df/dq of the applied forces */
    FCC_ASM_KV = 512,       /* df/dq' of the applied forces */
    FCC_ASM_T = 1024        /* partial dg/dt of the constraints (rheonomic rows) */
};

/* Error codes of the engine's record (fcc_engine.err; fccgen/runtime/_messages.py
 * words them for Python). */
enum {
    FCC_OK = 0,
    FCC_ERR_SINGULAR = 1,         /* reduced mass matrix not positive definite */
    FCC_ERR_LAPACK = 2,           /* LAPACK argument error (a bug) */
    FCC_ERR_NONFINITE_INPUT = 3,  /* a state or assembled quantity is not finite */
    FCC_ERR_NONFINITE_RESULT = 4, /* the solve produced a non-finite result */
    FCC_ERR_DIVERGED = 5,         /* the state grew past the run's bound */
    FCC_ERR_PATTERN = 6,          /* sparse path: the pattern of A no longer holds */
    FCC_ERR_MEMORY = 7,           /* an allocation in an init function failed */
    FCC_ERR_NO_LAPACK = 8,        /* a dense-path feature without a LAPACK table */
    FCC_ERR_ARGUMENT = 9          /* a call the engine cannot take (err_info says) */
};

/* Where an error happened (fcc_engine.err_where). */
enum {
    FCC_AT_CALL = 0,              /* a direct call */
    FCC_AT_STAGE = 1,             /* integrator stage err_stage */
    FCC_AT_POSITIONS = 2,         /* position projection */
    FCC_AT_VELOCITIES = 3,        /* velocity projection */
    FCC_AT_STEP = 4               /* the state after a step */
};

/* What an integrator's advance function returns. */
enum {
    FCC_RUN_DONE = 0,             /* reached the end (or a stop event) */
    FCC_RUN_PAUSE = 1,            /* the pause callback asked to return */
    FCC_RUN_ERROR = -1,           /* stopped; the engine's error record says why */
    FCC_RUN_UNDERFLOW = -2        /* DOPRI5: the step size underflowed */
};

/* LAPACK and BLAS, as Fortran routines take their arguments (pointers). The engine
 * never links them: the caller hands a table of function pointers (the Python build
 * fills it from scipy.linalg.cython_lapack). A NULL table leaves the dense path's
 * features out (docs/engine.md, "LAPACK"). */
typedef void fcc_dgeqp3_fn(int *m, int *n, double *a, int *lda, int *jpvt,
                           double *tau, double *work, int *lwork, int *info);
typedef void fcc_dormqr_fn(char *side, char *trans, int *m, int *n, int *k, double *a,
                           int *lda, double *tau, double *c, int *ldc, double *work,
                           int *lwork, int *info);
typedef void fcc_dgesvd_fn(char *jobu, char *jobvt, int *m, int *n, double *a, int *lda,
                           double *s, double *u, int *ldu, double *vt, int *ldvt,
                           double *work, int *lwork, int *info);
typedef void fcc_dpotrf_fn(char *uplo, int *n, double *a, int *lda, int *info);
typedef void fcc_dpotrs_fn(char *uplo, int *n, int *nrhs, double *a, int *lda,
                           double *b, int *ldb, int *info);
typedef void fcc_dgetrf_fn(int *m, int *n, double *a, int *lda, int *ipiv, int *info);
typedef void fcc_dgetrs_fn(char *trans, int *n, int *nrhs, double *a, int *lda,
                           int *ipiv, double *b, int *ldb, int *info);
typedef void fcc_dgemm_fn(char *transa, char *transb, int *m, int *n, int *k,
                          double *alpha, double *a, int *lda, double *b, int *ldb,
                          double *beta, double *c, int *ldc);

typedef struct fcc_lapack {
    fcc_dgeqp3_fn *dgeqp3;
    fcc_dormqr_fn *dormqr;
    fcc_dgesvd_fn *dgesvd;
    fcc_dpotrf_fn *dpotrf;
    fcc_dpotrs_fn *dpotrs;
    fcc_dgetrf_fn *dgetrf;
    fcc_dgetrs_fn *dgetrs;
    fcc_dgemm_fn *dgemm;
} fcc_lapack;

/* The engine's tolerances and the rank rule's numbers (fccgen/rank.py holds the
 * rule's values; the Python build copies them in, an export writes them). */
typedef struct fcc_settings {
    double rank_tol;          /* QR pivot ratio at or below which a row is dropped */
    double position_tol;      /* Newton stops at max_k |g_k| / ||B_k|| <= this */
    int max_newton;           /* Newton iteration cap of the position projection */
    double grow_tol;          /* sigma_{r+1} > grow_tol sigma_1: the rank grew */
    double decide_tol;        /* sigma_k > decide_tol sigma_1: independent (events) */
    double ambiguous_low;     /* [ambiguous_low, grow_tol]: an uncertain decision */
    double row_floor;         /* no row scaled by more than 1 / (this x its element's
                                 largest row norm) */
} fcc_settings;

/* 1 when x[0..n) are all finite. */
int fcc_finite(const double *x, long n);

#endif
