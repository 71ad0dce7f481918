/* Forward sensitivities carried by DOPRI5 (fcc_sens_dopri5.c).
 *
 * The state's sensitivities s = (s_q, s_v) of each parameter live in the fcc_sens
 * (fcc_sens_sq, fcc_sens_sv), as for RK4. Each of the step's seven stages applies
 * the method's own tableau to s: the stage's argument s_y + h sum a_kl K_l (the
 * seventh: the fifth-order solution s_y1), and its stage K_k = (s_v, s_a) with s_a
 * from the stage's factorisation (fcc_sens_stage_acc). s_y changes only when a step
 * is accepted (a rejected step leaves nothing to undo). The same continuous extension
 * gives s at requested times and at located events (at a fixed fraction of the step:
 * it is linear in the stages), followed by the linearised projections at the
 * projected state.
 *
 * Error control (control = 1): the local error estimate of s, h sum e_k K_k, enters
 * the step's error as in CVODES's errconS: the norm is the largest of the state's
 * and each parameter's scaled RMS norms, parameter j's scaled by
 * atol / scale_j + rtol max(|s|, |s1|) (scale_j: the parameter's size, so that
 * p_j s_j is measured like the state).
 */
#ifndef FCC_SENS_DOPRI5_H
#define FCC_SENS_DOPRI5_H

#include "fcc_sens.h"

#define FCC_SENS_DOPRI5_WORK 15     /* work blocks of np x 2 n numbers each */

typedef struct fcc_sens_dp5 {
    /* settings (the caller's; s NULL: no sensitivities) */
    fcc_sens *s;
    int control;                /* the sensitivities' error in the step's error */
    const double *scale;        /* np: each parameter's size (control) */
    double *work;               /* FCC_SENS_DOPRI5_WORK x np x 2 n numbers */
    /* set by fcc_sens_dp5_start: np x 2 n each, parameter-major */
    double *y1, *yt, *keep;     /* 5th-order solution, stage argument, the state's s */
    double *k[7];               /* stages K1..K7 (s_v then s_a) */
    double *rc[5];              /* dense output coefficients of the last step */
} fcc_sens_dp5;

void fcc_sens_dp5_start(fcc_sens_dp5 *d);
/* Stage k (1..7) of a step of size h, after the motion's stage at (q, v) with
 * accelerations a: its argument s_y + h sum_{l < k-1} w[l] K_{l+1} (k = 1: s_y;
 * k = 7: into y1), then K_k. Returns 0 or -1 (the engine's error record). */
int fcc_sens_dp5_stage(fcc_engine *e, fcc_sens_dp5 *d, int k, double h,
                       const double *w, const double *q, const double *v,
                       const double *a);
/* The sensitivities' scaled error norm (the largest over the parameters) of the
 * step's stages with the error weights ew[0..6] (0 when control is off). */
double fcc_sens_dp5_error(const fcc_sens_dp5 *d, double h, const double *ew,
                          double atol, double rtol);
/* The continuous extension's coefficients over the step s_y -> y1 (dw: its weights
 * on K1..K7, as for the motion). */
void fcc_sens_dp5_dense(fcc_sens_dp5 *d, double h, const double *dw);
/* The state's s becomes the continuous extension at the step's fraction th
 * (th = 1: y1). */
void fcc_sens_dp5_take(fcc_sens_dp5 *d, double th);
/* An output at the step's fraction th: the state's s is kept and replaced by the
 * continuous extension there (for the output's projections and record), until
 * fcc_sens_dp5_restore puts it back. */
void fcc_sens_dp5_output(fcc_sens_dp5 *d, double th);
void fcc_sens_dp5_restore(fcc_sens_dp5 *d);

#endif
