/* Sensitivities on the sparse path (fcc_sens_sparse.h). */
#include <math.h>
#include <string.h>

#include "fcc_sens_sparse.h"

/* Zero where the sparse view does not read it: max |u_k| over the k listed is at most
 * rounding (1e-12) of max |u| (all u zero there: exact zeros in practice, the tangent
 * kernels of a fixed row or pinned coordinate multiply zeros). */
static int unread(const double *u, int n, const int *list, int count)
{
    int i;
    double all = 0.0, left = 0.0;
    if (u == NULL || count == 0)
        return 1;
    for (i = 0; i < n; i++)
        if (fabs(u[i]) > all)
            all = fabs(u[i]);
    for (i = 0; i < count; i++)
        if (fabs(u[list[i]]) > left)
            left = fabs(u[list[i]]);
    return left <= 1e-12 * all;
}

/* -1 (FCC_ERR_ARGUMENT, err_detail 1) when on the sparse path w or b is not zero where
 * its view leaves them out (w, b may be NULL), else 0. */
static int outside_view(fcc_engine *e, const double *w, const double *b)
{
    const fcc_pattern *P = e->sp.pat;
    if (e->sparse && (!unread(w, e->n, P->pinned, P->n_pinned)
                      || !unread(b, e->m, P->fixed_rows, P->n_fixed_rows)))
        return fcc_fail(e, FCC_ERR_ARGUMENT, 0, 1);
    return 0;
}

int fcc_sens_solve(fcc_engine *e, const double *Q, const double *w, const double *b,
                   double *x)
{
    if (outside_view(e, w, b) < 0)
        return -1;
    fcc_solve_constrained(e, Q, w, b, x);
    return 0;
}

int fcc_sens_solve_from(fcc_engine *e, const double *Q, const double *b, double *x,
                        double *lam_io)
{
    int m = e->m;
    if (!e->sparse)
        return fcc_sens_solve(e, Q, NULL, b, x);
    if (outside_view(e, NULL, b) < 0)
        return -1;
    if (fcc_sp_kkt_solve_from(e, Q, NULL, b, x, lam_io, lam_io[m] != 0.0, 0)) {
        lam_io[m] = 1.0;
        return 0;
    }
    lam_io[m] = 0.0;                   /* not converged: from zero, else densely */
    fcc_solve_constrained(e, Q, NULL, b, x);
    return 0;
}

/* The sensitivities' stage multipliers: fcc_sp_correct_multipliers on the stage's
 * acceleration solve. One solve per stage, whatever the number of parameters. */
int fcc_sens_sparse_stage_lam(fcc_engine *e, fcc_sens *s, const double *a)
{
    fcc_sparse *sp = &e->sp;
    if (!sp->warm_valid)            /* the acceleration solve did not converge */
        return 0;
    memcpy(s->lam, sp->lam_warm, (size_t)e->m * sizeof(double));
    return fcc_sp_correct_multipliers(e, s->r, a, s->lam, s->y, s->b);
}
