/* Assembly of the global quantities from the element kernels (fcc_assemble.h).
 *
 * Each element gathers its local coordinates and speeds from the global ones, calls
 * its class's kernels (a NULL kernel is identically zero and skipped; a kernel writes
 * every entry of its output, fccgen_model.h) and scatters the results: M, h, f and the
 * force Jacobians are sums of element blocks; g, B and the constraint bias hold one
 * row per constraint equation, in element order. Every buffer is allocated once.
 */
#include <math.h>
#include <string.h>

#include "fcc_assemble.h"

int fcc_finite(const double *x, long n)
{
    long i;
    for (i = 0; i < n; i++)
        if (!isfinite(x[i]))
            return 0;
    return 1;
}

/* calloc of at least one item. */
static void *zalloc(size_t n, size_t size)
{
    return FCC_CALLOC(n > 0 ? n : 1, size);
}

static int imax(int a, int b) { return a > b ? a : b; }

int fcc_model_init(fcc_model *m, const fcc_model_table *table, int n_q, int n_el,
                   const int *class_of, const int *qptr, const int *qidx,
                   const int *pptr, int n_bodies, const int *body_elements,
                   int n_time, const int *time_slots)
{
    int e, j, k;
    const fcc_element_class *c;
    memset(m, 0, sizeof(*m));
    m->table = table;
    m->n_q = n_q;
    m->n_el = n_el;
    m->n_bodies = n_bodies;
    m->cls = zalloc((size_t)n_el, sizeof(*m->cls));
    m->qptr = zalloc((size_t)n_el + 1, sizeof(int));
    m->qidx = zalloc((size_t)qptr[n_el], sizeof(int));
    m->pptr = zalloc((size_t)n_el + 1, sizeof(int));
    m->gptr = zalloc((size_t)n_el + 1, sizeof(int));
    m->body_of = zalloc((size_t)n_el, sizeof(int));
    if (!m->cls || !m->qptr || !m->qidx || !m->pptr || !m->gptr || !m->body_of) {
        fcc_model_free(m);
        return FCC_ERR_MEMORY;
    }
    m->out_size = 6;
    m->local_size = 1;
    for (e = 0; e < n_el; e++) {
        c = &table->classes[class_of[e]];
        m->cls[e] = c;
        m->gptr[e + 1] = m->gptr[e] + c->n_g;
        m->body_of[e] = -1;
        m->out_size = imax(m->out_size, imax(imax(c->n_q * c->n_q, c->n_g * c->n_q),
                                             imax(c->n_q, c->n_g)));
        m->local_size = imax(m->local_size, c->n_q);   /* may exceed n_q: a triple
                                                          can appear twice */
        m->g_max = imax(m->g_max, c->n_g);
    }
    m->n_g = m->gptr[n_el];
    for (e = 0; e <= n_el; e++) {
        m->qptr[e] = qptr[e];
        m->pptr[e] = pptr[e];
    }
    m->n_p = pptr[n_el];
    for (j = 0; j < qptr[n_el]; j++)
        m->qidx[j] = qidx[j];
    for (j = 0; j < n_bodies; j++)
        m->body_of[body_elements[j]] = j;
    m->row_group = zalloc((size_t)m->n_g + 1, sizeof(int));
    if (!m->row_group) {
        fcc_model_free(m);
        return FCC_ERR_MEMORY;
    }
    for (e = 0; e < n_el; e++)
        for (k = m->gptr[e]; k < m->gptr[e + 1]; k++)
            m->row_group[k] = m->gptr[e];
    if (fcc_model_set_time_slots(m, n_time, time_slots) != FCC_OK) {
        fcc_model_free(m);
        return FCC_ERR_MEMORY;
    }
    return FCC_OK;
}

int fcc_model_set_time_slots(fcc_model *m, int n_time, const int *time_slots)
{
    int j;
    int *slots = zalloc((size_t)n_time, sizeof(int));
    if (!slots)
        return FCC_ERR_MEMORY;
    for (j = 0; j < n_time; j++)
        slots[j] = time_slots[j];
    FCC_FREE(m->time_slot);
    m->time_slot = slots;
    m->n_time = n_time;
    return FCC_OK;
}

void fcc_model_free(fcc_model *m)
{
    FCC_FREE((void *)m->cls);
    FCC_FREE(m->qptr);
    FCC_FREE(m->qidx);
    FCC_FREE(m->pptr);
    FCC_FREE(m->gptr);
    FCC_FREE(m->body_of);
    FCC_FREE(m->row_group);
    FCC_FREE(m->time_slot);
    memset(m, 0, sizeof(*m));
}

int fcc_assembly_init(fcc_assembly *a, const fcc_model *m, const double *params)
{
    size_t n = (size_t)m->n_q, ng = (size_t)m->n_g;
    int j;
    memset(a, 0, sizeof(*a));
    a->model = m;
    a->params = zalloc((size_t)m->n_p, sizeof(double));
    a->out = zalloc((size_t)m->out_size, sizeof(double));
    a->lq = zalloc((size_t)m->local_size, sizeof(double));
    a->lv = zalloc((size_t)m->local_size, sizeof(double));
    a->zeros = zalloc(n, sizeof(double));
    a->M = zalloc(n * n, sizeof(double));
    a->h = zalloc(n, sizeof(double));
    a->f = zalloc(n, sizeof(double));
    a->g = zalloc(ng, sizeof(double));
    a->B = zalloc(ng * n, sizeof(double));
    a->c = zalloc(ng, sizeof(double));
    a->body = zalloc(6 * (size_t)m->n_bodies, sizeof(double));
    a->fq = zalloc(n * n, sizeof(double));
    a->fv = zalloc(n * n, sizeof(double));
    a->gt = zalloc(ng, sizeof(double));
    if (!a->params || !a->out || !a->lq || !a->lv || !a->zeros || !a->M || !a->h
            || !a->f || !a->g || !a->B || !a->c || !a->body || !a->fq || !a->fv
            || !a->gt) {
        fcc_assembly_free(a);
        return FCC_ERR_MEMORY;
    }
    for (j = 0; j < m->n_p; j++)
        a->params[j] = params[j];
    return FCC_OK;
}

void fcc_assembly_free(fcc_assembly *a)
{
    FCC_FREE(a->params); FCC_FREE(a->out); FCC_FREE(a->lq); FCC_FREE(a->lv);
    FCC_FREE(a->zeros); FCC_FREE(a->M); FCC_FREE(a->h); FCC_FREE(a->f);
    FCC_FREE(a->g); FCC_FREE(a->B); FCC_FREE(a->c); FCC_FREE(a->body);
    FCC_FREE(a->fq); FCC_FREE(a->fv); FCC_FREE(a->gt);
    memset(a, 0, sizeof(*a));
}

void fcc_put_time(fcc_assembly *a, double t)
{
    int j;
    a->t = t;
    for (j = 0; j < a->model->n_time; j++)
        a->params[a->model->time_slot[j]] = t;
}

/* Add an element's square block o (n x n) into the global N x N matrix at idx. */
static void scatter_square(double *G, int N, const int *idx, int n, const double *o)
{
    int i, j;
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++)
            G[idx[i] * N + idx[j]] += o[i * n + j];
}

void fcc_assemble(fcc_assembly *a, const double *q, const double *v, int flags)
{
    const fcc_model *m = a->model;
    int e, i, j, n, r, n_g, N = m->n_q, row;
    const fcc_element_class *k;
    const int *idx;
    const double *p;
    double *o = a->out;
    if (v == NULL)
        v = a->zeros;
    if (flags & FCC_ASM_M) memset(a->M, 0, (size_t)N * N * sizeof(double));
    if (flags & FCC_ASM_H) memset(a->h, 0, (size_t)N * sizeof(double));
    if (flags & FCC_ASM_F) memset(a->f, 0, (size_t)N * sizeof(double));
    if (flags & FCC_ASM_G) memset(a->g, 0, (size_t)m->n_g * sizeof(double));
    if (flags & FCC_ASM_B) memset(a->B, 0, (size_t)m->n_g * N * sizeof(double));
    if (flags & FCC_ASM_C) memset(a->c, 0, (size_t)m->n_g * sizeof(double));
    if (flags & FCC_ASM_E) { a->energy[0] = 0.0; a->energy[1] = 0.0; }
    if (flags & FCC_ASM_BODY) memset(a->body, 0, (size_t)m->n_bodies * 6 * sizeof(double));
    if (flags & FCC_ASM_KQ) memset(a->fq, 0, (size_t)N * N * sizeof(double));
    if (flags & FCC_ASM_KV) memset(a->fv, 0, (size_t)N * N * sizeof(double));
    if (flags & FCC_ASM_T) memset(a->gt, 0, (size_t)m->n_g * sizeof(double));
    for (e = 0; e < m->n_el; e++) {
        k = m->cls[e];
        n = k->n_q;
        n_g = k->n_g;
        idx = m->qidx + m->qptr[e];
        p = a->params + m->pptr[e];
        row = m->gptr[e];
        for (i = 0; i < n; i++) {
            a->lq[i] = q[idx[i]];
            a->lv[i] = v[idx[i]];
        }
        if (flags & FCC_ASM_M && k->mass_matrix != NULL) {
            k->mass_matrix(a->lq, p, o);
            scatter_square(a->M, N, idx, n, o);
        }
        fcc_element_vectors(k, a->lq, a->lv, p, idx, row, flags & (FCC_ASM_H | FCC_ASM_F),
                            o, a->h, a->f, a->c);
        if (flags & FCC_ASM_G && k->constraints != NULL) {
            k->constraints(a->lq, p, o);
            for (r = 0; r < n_g; r++)
                a->g[row + r] = o[r];
        }
        if (flags & FCC_ASM_B && k->constraint_jacobian != NULL) {
            k->constraint_jacobian(a->lq, p, o);
            for (r = 0; r < n_g; r++)
                for (j = 0; j < n; j++)
                    a->B[(row + r) * N + idx[j]] += o[r * n + j];
        }
        fcc_element_vectors(k, a->lq, a->lv, p, idx, row, flags & FCC_ASM_C, o, a->h,
                            a->f, a->c);
        if (flags & FCC_ASM_E && k->energy != NULL) {
            k->energy(a->lq, a->lv, p, o);
            a->energy[0] += o[0];
            a->energy[1] += o[1];
        }
        if (flags & FCC_ASM_BODY && k->body_outputs != NULL && m->body_of[e] >= 0) {
            k->body_outputs(a->lq, a->lv, p, o);
            for (i = 0; i < 6; i++)
                a->body[6 * m->body_of[e] + i] = o[i];
        }
        if (flags & FCC_ASM_KQ && k->force_jacobian_q != NULL) {
            k->force_jacobian_q(a->lq, a->lv, p, o);
            scatter_square(a->fq, N, idx, n, o);
        }
        if (flags & FCC_ASM_KV && k->force_jacobian_v != NULL) {
            k->force_jacobian_v(a->lq, p, o);
            scatter_square(a->fv, N, idx, n, o);
        }
        if (flags & FCC_ASM_T && k->constraint_rate != NULL) {
            k->constraint_rate(a->lq, p, o);
            for (r = 0; r < n_g; r++)
                a->gt[row + r] = o[r];
        }
    }
}

double fcc_scaled_residual(const fcc_assembly *a)
{
    int k, j, N = a->model->n_q;
    double worst = 0.0, norm, val;
    for (k = 0; k < a->model->n_g; k++) {
        norm = 0.0;
        for (j = 0; j < N; j++)
            norm += a->B[k * N + j] * a->B[k * N + j];
        val = fabs(a->g[k]);
        if (norm > 0.0)
            val /= sqrt(norm);
        if (!(val <= worst)) {          /* larger, or NaN (kept as NaN) */
            worst = val;
            if (val != val)
                return val;
        }
    }
    return worst;
}

double fcc_max_abs_g(const fcc_assembly *a)
{
    int k;
    double worst = 0.0;
    for (k = 0; k < a->model->n_g; k++) {
        if (!(fabs(a->g[k]) <= worst)) {
            worst = fabs(a->g[k]);
            if (worst != worst)
                return worst;
        }
    }
    return worst;
}

int fcc_kernel_flags(const fcc_model *m)
{
    int e, present = 0;
    const fcc_element_class *k;
    for (e = 0; e < m->n_el; e++) {
        k = m->cls[e];
        present |= ((k->mass_matrix ? FCC_ASM_M : 0) | (k->h_vector ? FCC_ASM_H : 0)
                    | (k->applied_forces ? FCC_ASM_F : 0)
                    | (k->constraints ? FCC_ASM_G : 0)
                    | (k->constraint_jacobian ? FCC_ASM_B : 0)
                    | (k->constraint_bias ? FCC_ASM_C : 0) | (k->energy ? FCC_ASM_E : 0)
                    | (k->body_outputs && m->body_of[e] >= 0 ? FCC_ASM_BODY : 0)
                    | (k->force_jacobian_q ? FCC_ASM_KQ : 0)
                    | (k->force_jacobian_v ? FCC_ASM_KV : 0)
                    | (k->constraint_rate ? FCC_ASM_T : 0));
    }
    return present;
}

long fcc_jacobian_size(const fcc_model *m)
{
    int e;
    long total = 0;
    for (e = 0; e < m->n_el; e++)
        if (m->cls[e]->constraint_jacobian != NULL)
            total += (long)m->cls[e]->n_g * m->cls[e]->n_q;
    return total;
}

void fcc_jacobian_triplets(fcc_assembly *a, const double *q, int *rows, int *cols,
                           double *vals)
{
    const fcc_model *m = a->model;
    int e, i, r, n, n_g;
    long at = 0;
    const fcc_element_class *k;
    const int *idx;
    for (e = 0; e < m->n_el; e++) {
        k = m->cls[e];
        if (k->constraint_jacobian == NULL)
            continue;
        n = k->n_q;
        n_g = k->n_g;
        idx = m->qidx + m->qptr[e];
        for (i = 0; i < n; i++)
            a->lq[i] = q[idx[i]];
        k->constraint_jacobian(a->lq, a->params + m->pptr[e], a->out);
        for (r = 0; r < n_g; r++) {
            for (i = 0; i < n; i++) {
                rows[at] = m->gptr[e] + r;
                cols[at] = idx[i];
                vals[at] = a->out[r * n + i];
                at++;
            }
        }
    }
}
