/* The power of the forces without potential at an integrator's stage (fcc_work.c),
 * for the energy check with the work added back (docs/reliability.md, "Energy").
 *
 * Along a motion dE/dt = v . f_nc + (driven models) lambda . dg/dt: the applied forces
 * without potential (dampers, constant torques, loads of time or of joint quantities)
 * and the drivers' constraint forces do work; gravity, constant forces and springs do
 * not change E = T + V. The integrators add the stage powers with their own weights
 * (RK4: h/6 (P1 + 2 P2 + 2 P3 + P4); DOPRI5: its fifth-order weights and its
 * continuous extension for the records), so that E(t) - W(t) + (the impacts' losses)
 * stays E(0) to the integration's own error.
 *
 * f_nc comes from a second assembly, over a model of only the elements whose forces
 * do work (loads without potential, damped springs), set up once with the same
 * kernel table: its parameters are copied from the engine's at every stage (the
 * time, the angle references) and those of forces with a potential (a damped
 * spring's stiffness) set to zero. The constraint forces' power is
 * -v . (B^T lambda) = v . (M a + h - f), with the stage's M, h and f (M dense, or the
 * sparse path's element blocks).
 */
#ifndef FCC_WORK_H
#define FCC_WORK_H

#include "fcc_engine.h"

typedef struct fcc_power {
    fcc_assembly *nc;         /* the elements with forces without potential (not owned) */
    int n_params;             /* its parameters: how many (nc->model->n_p), */
    int *src;                 /* ... each one's index among the engine's parameters, */
    int n_zero;               /* ... and which are set to zero (spring stiffnesses) */
    int *zero;
    int constraints;          /* add the constraint forces' power (driven models) */
    int n;                    /* coordinates */
    double *ma;               /* n numbers of work: M a */
} fcc_power;

/* The power of the assembly nc (the subset model over the engine's coordinates, n
 * of them): src[i], the engine's parameter behind nc's parameter i; zero[0..n_zero),
 * nc's parameters to zero; constraints: add the constraint forces' power. Set-up:
 * allocates. Returns FCC_OK, FCC_ERR_ARGUMENT (a zero slot out of range) or
 * FCC_ERR_MEMORY. */
int fcc_power_init(fcc_power *w, fcc_assembly *nc, int n, const int *src, int n_zero,
                   const int *zero, int constraints);
void fcc_power_free(fcc_power *w);
/* 0 when every src index is below the engine's parameter count and the coordinates
 * agree; FCC_ERR_ARGUMENT otherwise. */
int fcc_power_fits(const fcc_power *w, const fcc_engine *e);
/* P = v . f_nc(q, v, t) [+ v . (M a + h - f)] at the stage (q, v) whose accelerations
 * a the engine has just solved (M, h, f still assembled there). */
double fcc_stage_power(fcc_engine *e, fcc_power *w, const double *q, const double *v,
                       const double *a);

#endif
