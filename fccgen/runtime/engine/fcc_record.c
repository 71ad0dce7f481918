/* Records and divergence checks of the integrators (fcc_run.h). */
#include <math.h>
#include <string.h>

#include "fcc_run.h"

double fcc_write_record(fcc_engine *e, const fcc_records *out, long j, const double *q,
                        const double *v)
{
    long n = e->n, nb6 = 6 * (long)e->model->n_bodies;
    fcc_assembly *a = e->asmb;
    fcc_assemble(a, q, v, FCC_ASM_G | FCC_ASM_E | FCC_ASM_BODY);
    memcpy(out->q + j * n, q, (size_t)n * sizeof(double));
    memcpy(out->v + j * n, v, (size_t)n * sizeof(double));
    if (nb6)
        memcpy(out->body + j * nb6, a->body, (size_t)nb6 * sizeof(double));
    out->energy[j] = a->energy[0] + a->energy[1];
    out->cerr[j] = fcc_max_abs_g(a);
    return out->cerr[j];
}

int fcc_diverged(fcc_engine *e, const double *x, double bound)
{
    int i;
    double big = 0.0;
    for (i = 0; i < e->n; i++)
        if (fabs(x[i]) > big)
            big = fabs(x[i]);
    if (big > bound) {
        e->err_value = big;
        e->err_bound = bound;
        return 1;
    }
    return 0;
}

void fcc_divergence_bounds(int n, const double *q0, const double *v0, double t_end,
                           double dt, double *q_bound, double *v_bound)
{
    int i;
    double q_ref = 0.0, v_ref = 0.0;
    for (i = 0; i < n; i++) {
        if (fabs(q0[i]) > q_ref)
            q_ref = fabs(q0[i]);
        if (fabs(v0[i]) > v_ref)
            v_ref = fabs(v0[i]);
    }
    q_ref = q_ref > 0.0 ? q_ref : 1.0;
    *q_bound = 1e6 * (q_ref + v_ref * t_end);
    *v_bound = dt > 0.0 ? 1e6 * (v_ref + q_ref / dt) : INFINITY;
}
