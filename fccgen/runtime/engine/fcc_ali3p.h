/* ALI3-P: the index-3 augmented Lagrangian formulation with mass-orthogonal
 * projections, integrated by the trapezoidal rule (fcc_ali3p.c). Works on the dense
 * assembly and needs LAPACK (dpotrf/dpotrs, dgetrf/dgetrs for an indefinite tangent). */
#ifndef FCC_ALI3P_H
#define FCC_ALI3P_H

#include "fcc_run.h"

/* failure codes (fccgen/runtime/ali3p_setup.py words them) */
enum {
    FCC_ALI3P_NEWTON = 1,     /* Newton did not converge within max_newton */
    FCC_ALI3P_TANGENT = 2,    /* the tangent is singular (dgetrf info) */
    FCC_ALI3P_NONFINITE = 3,  /* a non-finite state or assembled quantity (detail) */
    FCC_ALI3P_NO_LAPACK = 4   /* the engine has no LAPACK table */
};

/* State numbers of a run: q, q', q'', q_n, q'_n, q''_n, r (n each), lambda, alpha, w,
 * lambda_n (m each) and the tangent and its copy (n x n each). */
#define FCC_ALI3P_STATE(n, m) (7 * (long)(n) + 4 * (long)(m) + 2 * (long)(n) * (n))
/* A step whose Newton iteration does not converge is taken again from its start with
 * every row's penalty this many times larger (fcc_ali3p.c). */
#define FCC_ALI3P_PENALTY_RAISE 10.0

typedef struct fcc_ali3p {
    /* settings (the caller's) */
    long n_steps, every;
    double dt, t_end;
    double tol;               /* Newton tolerance (absolute) */
    int max_newton;
    int max_raises;           /* penalty raises a run may make (0: none) */
    double *state;            /* FCC_ALI3P_STATE(n, m) numbers: q, v, a (the initial
                                 state), lambda, alpha set by the caller (see below) */
    int *ipiv;                /* n LU pivots */
    fcc_records out;
    fcc_pause_fn pause;
    void *pause_ctx;
    /* state and statistics */
    int n, m;
    long k, n_out;
    long n_asm;               /* kernel assemblies */
    long newton_total;
    int newton_max;
    long failures;            /* steps accepted with a constraint residual above tol */
    long slow_steps;          /* steps accepted with shrinking corrections above tol */
    double max_cerr;
    int fail, fail_info, fail_detail;
    double fail_t, fail_h, fail_dq;
    int raises;               /* times the penalty was raised */
    double *q, *v, *a, *lam, *alpha, *q0, *v0, *a0, *T, *T2, *r, *w, *lam0;
    int lu;                   /* T holds an LU (not a Cholesky) factorisation */
    long lu_steps;
} fcc_ali3p;

/* Lay out the state (state: q, v, a at [0, n), [n, 2n), [2n, 3n); lambda and alpha at
 * [6n, 6n + m), [6n + m, 6n + 2m), as the caller wrote them). */
void fcc_ali3p_start(fcc_ali3p *r, fcc_engine *e);
/* Write record r->n_out at time t. */
void fcc_ali3p_record(fcc_engine *e, fcc_ali3p *r, double t);
/* Steps until the end (FCC_RUN_DONE), a failure (FCC_RUN_ERROR: r->fail and the
 * numbers after it say what) or a pause (FCC_RUN_PAUSE). */
int fcc_ali3p_advance(fcc_engine *e, fcc_ali3p *r);

#endif
