/* Forward sensitivities of a run with respect to design parameters (fcc_sens.c).
 *
 * For each design parameter p_j (a with_parameters key), the state's derivative
 * s = (dq/dp_j, dv/dp_j) is carried through the integrator's own stages: at each stage
 * the accelerations' derivative s_a solves, with the stage's factorisation of (M, B),
 *
 *     M s_a + B^T s_lam = dR1,    B s_a = dR2
 *
 * where dR1, dR2 are the residuals' directional derivatives along (s_q, s_v, dP_j)
 * (the generated tangent kernels, fcc_dp.h; lam from the stage's solve, dP_j the
 * elements' parameters' derivative). Applying the step's own stage formulas to s
 * makes s the derivative of the discrete step itself. After the step's projections,
 * s is projected by their linearisations at the projected state (same factorisation):
 *
 *     s_q <- argmin |s_q' - s_q|_M  with  B s_q' = -(dg/dp) dP_j
 *     s_v <- argmin |s_v' - s_v|_M  with  B s_v' = -dPhi[s_q', dP_j],  Phi = B v + dg/dt
 *
 * The dense path only. All work arrays come from fcc_sens_init; every other call
 * returns 0 or -1 with the engine's error record filled.
 */
#ifndef FCC_SENS_H
#define FCC_SENS_H

#include "fcc_dp.h"
#include "fcc_engine.h"

typedef struct fcc_sens {
    const fcc_dp_table *dp;        /* the model's tangent kernels (not owned) */
    const fcc_model *model;
    int n, m, np;                  /* coordinates, constraint rows, design parameters */
    const double *dP;              /* np x model->n_p: d(element parameters)/dp_j */
    double *out;                   /* records x np x 2n (the caller's; NULL: none) */
    double *S;                     /* per p_j, 10 n: sq sv sqs sv2 sv3 sv4 sa1..sa4 */
    double *lam, *r, *rhs, *b, *gp, *phi, *y, *zero;   /* work */
    double *lq, *lv, *la, *lsq, *lsv, *llam, *lout;    /* an element's */
    double h;                      /* the step being taken */
} fcc_sens;

/* Allocate for np parameters of the model (dP: np x model->n_p numbers, kept by
 * the caller). Returns FCC_OK, FCC_ERR_MEMORY, or FCC_ERR_ARGUMENT when dp does not
 * hold the model's classes in its order. */
int fcc_sens_init(fcc_sens *s, const fcc_model *model, const fcc_dp_table *dp, int np,
                  const double *dP);
void fcc_sens_free(fcc_sens *s);
/* The sensitivities at the start, S0: np x 2n ([dq0/dp_j; dv0/dp_j] per j). */
void fcc_sens_start(fcc_sens *s, const double *S0);
/* A step of size h begins (the stages' combinations use it). */
void fcc_sens_begin_step(fcc_sens *s, double h);
/* RK4 stage k (1..4) at (q, v) with its accelerations a, after fcc_accelerations (f,
 * h assembled at (q, v), M and B and their factorisation at q): s_a of every
 * parameter, then the next stage's sensitivities (after k = 4: the step's end). */
int fcc_sens_rk4_stage(fcc_engine *e, fcc_sens *s, int k, const double *q,
                       const double *v, const double *a);
/* The linearised projections at the projected (q, v), after fcc_project_velocities
 * (its factorisation held). */
int fcc_sens_project(fcc_engine *e, fcc_sens *s, const double *q, const double *v);
/* Copy the state's sensitivities into record rec of out. */
void fcc_sens_record(const fcc_sens *s, long rec);

#endif
