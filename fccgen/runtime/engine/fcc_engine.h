/* The engine: accelerations and projections for one instance (fcc_engine.c).
 *
 * An fcc_engine works on an fcc_assembly (the kernels bound to one instance's
 * parameters) with the dense path's constrained solve (fcc_dense) or, after
 * fcc_sparse_init, the sparse path's (fcc_sparse). The integrators (fcc_rk4.c,
 * fcc_dopri5.c, fcc_ali3p.c) and the events (fcc_events.c) drive its building blocks.
 * Every work array is allocated by fcc_engine_init (and fcc_sparse_init); failures
 * fill the error record and return -1.
 */
#ifndef FCC_ENGINE_H
#define FCC_ENGINE_H

#include "fcc_assemble.h"
#include "fcc_dense.h"
#include "fcc_sparse.h"

#define FCC_RANK_LOG_SIZE 64
#define FCC_MESSAGE_SIZE 320

typedef struct fcc_engine {
    fcc_assembly *asmb;          /* the instance's assembly (not owned) */
    const fcc_model *model;
    const fcc_lapack *lapack;    /* NULL: no dense path */
    fcc_settings set;
    int n, m;                    /* coordinates, constraint rows */
    fcc_dense sol;               /* the dense solve (its rank decision on both paths) */
    double diverge_residual;     /* a projection starting above this: diverged */
    double *work;                /* one block for rhs, nb, dq, vtmp */
    double *rhs, *nb, *dq, *vtmp;
    double *stages;              /* 10 n numbers for an integrator's stages */
    int factor_valid;            /* the solve holds the factorisation at the state */
    int b_fresh;                 /* the last position projection left B at its q */
    int running;                 /* an integrator is using the engine */
    double ke_peak;              /* largest 2 x kinetic energy a projection met */
    double ke_cut_max;           /* largest fraction of it one projection removed */
    double ke_cut_t;             /* ... and when */
    int n_rank_log;              /* increases of the decided rank: (t, old, new) */
    double rank_log[FCC_RANK_LOG_SIZE][3];
    /* the error record */
    int err, err_info, err_where, err_stage, err_detail;
    double err_t, err_h, err_value, err_bound;
    char message[FCC_MESSAGE_SIZE];
    /* the sparse path (fcc_sparse_init) */
    int sparse;
    fcc_sparse sp;
} fcc_engine;

/* An engine for the assembly a; lapack may be NULL (the sparse path only). */
int fcc_engine_init(fcc_engine *e, fcc_assembly *a, const fcc_lapack *lapack,
                    const fcc_settings *settings);
void fcc_engine_free(fcc_engine *e);
/* Keep rank as the rank of B (-1: the pivot threshold) and start the statistics
 * anew (the sparse path: fcc_sparse_reset_stats too). */
void fcc_engine_decide_rank(fcc_engine *e, int rank);
/* The error record in one sentence (written into e->message). */
const char *fcc_engine_message(fcc_engine *e);

/* -- building blocks (both paths) ------------------------------------------------- */
int fcc_fail(fcc_engine *e, int code, int info, int detail);
/* 1-based index of the first non-finite input (q, v, M, h, f, B, c, g), 0 if none. */
int fcc_nonfinite_input(fcc_engine *e, const double *q, const double *v, int flags);
/* 0, or the error of a non-finite result a (blaming a non-finite input first). */
int fcc_check_result(fcc_engine *e, const double *q, const double *v, const double *a,
                     int flags);
/* Factor the assembled M and B; on failure, blame a non-finite input first. */
int fcc_factor(fcc_engine *e, const double *q);
/* a = q'' at (q, v); reuse: the factorisation at q is held. */
int fcc_accelerations(fcc_engine *e, const double *q, const double *v, double *a,
                      int reuse);
/* a = q'' of the Baumgarte-stabilised index-1 equations at (q, v). */
int fcc_baumgarte(fcc_engine *e, const double *q, const double *v, double *a,
                  double alpha, double beta);
/* Newton on g(q) = 0 in place: 0 converged, 1 not within max_newton, -1 error. */
int fcc_project_positions(fcc_engine *e, double *q, int *iterations, int reuse);
/* v <- the M-orthogonal projection of v onto B v = -dg/dt, in place. */
int fcc_project_velocities(fcc_engine *e, const double *q, double *v, int have_B);
/* max_k |g_k| / ||B_k|| with the g and B assembled last. */
double fcc_constraint_residual(fcc_engine *e);
/* x of M x + B^T lambda = Q + M w, B x = b with the factorisation at hand. */
void fcc_solve_constrained(fcc_engine *e, const double *Q, const double *w,
                           const double *b, double *x);
/* The dense path's energy watch of a velocity projection v -> w (fcc_engine.c). */
void fcc_note_energy_cut(fcc_engine *e, double before, double cut);

#endif
