/* Sensitivities on the sparse path (fcc_sens_sparse.c): the solves of the stages and
 * of the linearised projections, and the stages' multipliers.
 *
 * The sensitivities' systems are the motion's own, M x + B^T lambda = Q + M w,
 * B x = b, with other right-hand sides: on the sparse path they are solved by the
 * same refinement (fcc_sp_kkt_solve, from zero multipliers) with the factor of
 * A = M + B^T diag(alpha) B the step holds, and a stage's multipliers are the
 * converged ones of its acceleration solve (fcc_sp_accelerations keeps them as its
 * warm start), so no dense matrix is formed. The sparse path's view leaves out the
 * pinned coordinates (x is 0 there) and the fixed rows (b is not read there): a
 * sensitivity that moves either (a parameter that moves a fixed point) cannot be
 * carried, and the solve refuses it instead of dropping it.
 */
#ifndef FCC_SENS_SPARSE_H
#define FCC_SENS_SPARSE_H

#include "fcc_sens.h"

/* x of M x + B^T lambda = Q + M w, B x = b (Q, w may be NULL) with the factorisation
 * at hand, on either path. Returns 0, or -1 (FCC_ERR_ARGUMENT, err_detail 1) when on
 * the sparse path w or b is not zero where its view leaves them out. */
int fcc_sens_solve(fcc_engine *e, const double *Q, const double *w, const double *b,
                   double *x);
/* The same with Q, b given and w = 0, on the sparse path from the multipliers lam_io
 * (m + 1 numbers: lam_io[m] != 0 when they are a converged solve's, e.g. the same
 * parameter's previous stage), which receive the converged ones: fewer refinement
 * steps than from zero. The answer is the refinement's to its tolerance either way. */
int fcc_sens_solve_from(fcc_engine *e, const double *Q, const double *b, double *x,
                        double *lam_io);
/* The sparse path: s->lam of the stage (a: its accelerations; s->r: f - h (+ G^T mu)
 * on entry) after fcc_sp_accelerations, the converged multipliers of that solve
 * corrected once (fcc_sens_sparse.c). Returns 1 when done, 0 when that solve did not
 * converge (the caller solves the stage's system again: fcc_sens_sparse_multipliers). */
int fcc_sens_sparse_stage_lam(fcc_engine *e, fcc_sens *s, const double *a);

#endif
