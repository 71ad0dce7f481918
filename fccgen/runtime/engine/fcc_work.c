/* The power of the forces without potential at a stage (fcc_work.h). */
#include <string.h>

#include "fcc_work.h"

int fcc_power_init(fcc_power *w, fcc_assembly *nc, int n, const int *src, int n_zero,
                   const int *zero, int constraints)
{
    int i;
    memset(w, 0, sizeof(*w));
    w->nc = nc;
    w->n = n;
    w->n_params = nc->model->n_p;
    w->n_zero = n_zero;
    w->constraints = constraints;
    for (i = 0; i < n_zero; i++)
        if (!(0 <= zero[i] && zero[i] < w->n_params))
            return FCC_ERR_ARGUMENT;
    w->src = FCC_CALLOC((size_t)w->n_params + 1, sizeof(int));
    w->zero = FCC_CALLOC((size_t)n_zero + 1, sizeof(int));
    w->ma = FCC_CALLOC((size_t)n + 1, sizeof(double));
    if (!w->src || !w->zero || !w->ma) {
        fcc_power_free(w);
        return FCC_ERR_MEMORY;
    }
    for (i = 0; i < w->n_params; i++)
        w->src[i] = src[i];
    for (i = 0; i < n_zero; i++)
        w->zero[i] = zero[i];
    return FCC_OK;
}

void fcc_power_free(fcc_power *w)
{
    FCC_FREE(w->src);
    FCC_FREE(w->zero);
    FCC_FREE(w->ma);
    memset(w, 0, sizeof(*w));
}

int fcc_power_fits(const fcc_power *w, const fcc_engine *e)
{
    int i;
    if (w->n != e->n || w->nc->model->n_q != e->n)
        return FCC_ERR_ARGUMENT;
    for (i = 0; i < w->n_params; i++)
        if (!(0 <= w->src[i] && w->src[i] < e->model->n_p))
            return FCC_ERR_ARGUMENT;
    return FCC_OK;
}

double fcc_stage_power(fcc_engine *e, fcc_power *w, const double *q, const double *v,
                       const double *a)
{
    int i, j, n = e->n;
    double p = 0.0, acc;
    const fcc_assembly *as = e->asmb;
    if (w->constraints) {
        if (e->sparse) {
            fcc_sp_mult_m_full(e, a, w->ma, 0);
        } else {
            for (i = 0; i < n; i++) {
                acc = 0.0;
                for (j = 0; j < n; j++)
                    acc += as->M[(long)i * n + j] * a[j];
                w->ma[i] = acc;
            }
        }
        for (i = 0; i < n; i++)
            p += v[i] * (w->ma[i] + as->h[i] - as->f[i]);
    }
    for (i = 0; i < w->n_params; i++)
        w->nc->params[i] = as->params[w->src[i]];
    for (i = 0; i < w->n_zero; i++)
        w->nc->params[w->zero[i]] = 0.0;
    fcc_assemble(w->nc, q, v, FCC_ASM_F);
    for (i = 0; i < n; i++)
        p += v[i] * w->nc->f[i];
    return p;
}
