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
