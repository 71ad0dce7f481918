/* Switchable rows folded into the sparse path's factorisation.
 *
 * A joint that an event locks (or a limit, or a bounce that rests) adds the row
 * G_j x = b_j to the engine's solves. On the sparse path the set-up puts every such row
 * into the fixed pattern of A = M + B^T diag(alpha) B (fccgen.runtime.paths,
 * make_engine's switchable rows): its pairs of coordinates are entries of A from the
 * start, and its fill is in the symbolic factorisation. Each row is then one more row
 * of the augmented-Lagrangian refinement (fcc_al_refine.c), numbered m + j, with its
 * weight alpha_{m+j} = RHO SW_BOOST m_ref / ||G_j||^2 while it is held, zero while free
 * (its values are zero then: a free row adds nothing to A, its residual is zero and
 * its multiplier stays zero). A switch changes values and weights only: the next
 * factorisation is numeric, with no new analysis, and no solve is added per row. The
 * refinement enforces the held rows as it does the engine's own: their multipliers are
 * iterated with the others, redundant rows need no rank decision (A stays positive
 * definite on the null space of the rows), and the conjugate-gradient corrections see
 * them as rows of B.
 *
 * The rows' values come from the events (fcc_events.c, fcc_events_fold) through
 * sw_fill at every assembly of B, and their targets in the accelerations,
 * -(dG/dt) v, before each acceleration solve; every other solve holds them still
 * (targets zero) unless the caller sets sw_b around it (fcc_ev_correct).
 */
#include <math.h>
#include <string.h>

#include "fcc_engine.h"

/* The held rows' weight over the engine rows' RHO: a lock's row is weak in the
 * refinement (t = alpha sigma^2 / m about 2.5 on the boom of 12 units, whose one
 * degree of freedom moves all its bars: a rate of 0.28 per step, every solve slow and
 * boosted), so it is weighted as a boosted factor weights every row
 * (fcc_al_refine.c, "Near a singular position"): the rate falls to about 4e-6, and
 * A's condition grows along that row as a boost's does, which the refinement's true
 * residuals remove. */
#define SW_BOOST FCC_AL_BOOST

int fcc_pattern_set_switchable(fcc_pattern *P, int n_sw, const int *sw_ptr,
                               const int *sw_idx, const int *sw_ent_ptr,
                               const int *sw_ent_a, const int *sw_ent_b,
                               const int *sw_ent_pos)
{
    int j, t, k, nk, n_idx, n_ent;
    FCC_FREE(P->sw_ptr); FCC_FREE(P->sw_idx); FCC_FREE(P->sw_ent_ptr);
    FCC_FREE(P->sw_ent_a); FCC_FREE(P->sw_ent_b); FCC_FREE(P->sw_ent_pos);
    P->sw_ptr = P->sw_idx = P->sw_ent_ptr = NULL;
    P->sw_ent_a = P->sw_ent_b = P->sw_ent_pos = NULL;
    P->n_sw = 0;
    if (n_sw <= 0)
        return FCC_OK;
    if (!P->ready || sw_ptr[0] != 0 || sw_ent_ptr[0] != 0)
        return FCC_ERR_ARGUMENT;
    for (j = 0; j < n_sw; j++) {
        nk = sw_ptr[j + 1] - sw_ptr[j];
        if (nk < 0 || sw_ent_ptr[j + 1] < sw_ent_ptr[j])
            return FCC_ERR_ARGUMENT;
        for (k = sw_ptr[j]; k < sw_ptr[j + 1]; k++)
            if (sw_idx[k] < 0 || sw_idx[k] >= P->n)
                return FCC_ERR_ARGUMENT;
        for (t = sw_ent_ptr[j]; t < sw_ent_ptr[j + 1]; t++)
            if (sw_ent_a[t] < 0 || sw_ent_a[t] >= nk || sw_ent_b[t] < 0
                    || sw_ent_b[t] >= nk || sw_ent_pos[t] < 0
                    || sw_ent_pos[t] >= P->nnz_a)
                return FCC_ERR_ARGUMENT;
    }
    n_idx = sw_ptr[n_sw];
    n_ent = sw_ent_ptr[n_sw];
    P->sw_ptr = fcc_sp_copy_ints(sw_ptr, n_sw + 1);
    P->sw_idx = fcc_sp_copy_ints(sw_idx, n_idx);
    P->sw_ent_ptr = fcc_sp_copy_ints(sw_ent_ptr, n_sw + 1);
    P->sw_ent_a = fcc_sp_copy_ints(sw_ent_a, n_ent);
    P->sw_ent_b = fcc_sp_copy_ints(sw_ent_b, n_ent);
    P->sw_ent_pos = fcc_sp_copy_ints(sw_ent_pos, n_ent);
    if (!P->sw_ptr || !P->sw_idx || !P->sw_ent_ptr || !P->sw_ent_a || !P->sw_ent_b
            || !P->sw_ent_pos)
        return FCC_ERR_MEMORY;
    P->n_sw = n_sw;
    return FCC_OK;
}

void fcc_sp_sw_fill(fcc_engine *e, const double *q)
{
    /* The rows' values at q (with B's blocks); zero when nothing fills them. */
    fcc_sparse *s = &e->sp;
    int j, n_sw = s->ms - e->m;
    if (n_sw <= 0)
        return;
    if (s->sw_fill != NULL) {
        s->sw_fill(s->sw_ctx, e, q, NULL);
    } else {
        memset(s->sw_val, 0, (size_t)s->pat->sw_ptr[n_sw] * sizeof(double));
        for (j = 0; j < n_sw; j++)
            s->rnorm[e->m + j] = 0.0;
    }
}

void fcc_sp_sw_penalties(fcc_engine *e)
{
    /* alpha_{m+j} = RHO SW_BOOST mref / ||G_j||^2, zero for a free (zero) row. */
    fcc_sparse *s = &e->sp;
    int j, row;
    double sk;
    s->sw_live = 0;
    for (j = 0; j < s->ms - e->m; j++) {
        row = e->m + j;
        sk = s->rnorm[row];
        s->alpha[row] = sk > 0.0 ? FCC_RHO * SW_BOOST * s->mref / (sk * sk) : 0.0;
        if (sk > 0.0)
            s->sw_live = 1;
    }
}

void fcc_sp_sw_factor(fcc_engine *e)
{
    /* A += alpha_{m+j} G_j^T G_j over the held rows, through their places in Ax. */
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int j, t;
    const double *g;
    double w;
    for (j = 0; j < s->ms - e->m; j++) {
        w = s->alpha[e->m + j];
        if (w == 0.0)
            continue;
        g = s->sw_val + P->sw_ptr[j];
        for (t = P->sw_ent_ptr[j]; t < P->sw_ent_ptr[j + 1]; t++)
            s->Ax[P->sw_ent_pos[t]] += w * g[P->sw_ent_a[t]] * g[P->sw_ent_b[t]];
    }
}

void fcc_sp_sw_mult(fcc_engine *e, const double *x, double *y)
{
    /* y[m + j] = G_j x. */
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int j, k;
    double acc;
    for (j = 0; j < s->ms - e->m; j++) {
        acc = 0.0;
        for (k = P->sw_ptr[j]; k < P->sw_ptr[j + 1]; k++)
            acc += s->sw_val[k] * x[P->sw_idx[k]];
        y[e->m + j] = acc;
    }
}

void fcc_sp_sw_mult_t(fcc_engine *e, const double *z, const double *sc, double *y)
{
    /* y += G^T diag(sc) z over the rows (sc NULL: the identity). */
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int j, k, row;
    double zr;
    for (j = 0; j < s->ms - e->m; j++) {
        row = e->m + j;
        zr = sc == NULL ? z[row] : z[row] * sc[row];
        if (zr == 0.0)
            continue;
        for (k = P->sw_ptr[j]; k < P->sw_ptr[j + 1]; k++)
            y[P->sw_idx[k]] += s->sw_val[k] * zr;
    }
}

void fcc_sp_sw_residual(fcc_engine *e, const double *x, int pending, int penalised,
                        double *y, double *r2)
{
    /* The rows' share of the refinement's residual pass (fcc_al_refine.c,
     * residual_pass): r2 = b - G x, the deferred multiplier update, rho, and
     * y -= G^T (lambda - alpha r2) (penalised) or G^T lambda. */
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int j, k, row;
    double acc, z;
    for (j = 0; j < s->ms - e->m; j++) {
        row = e->m + j;
        if (s->alpha[row] == 0.0 && s->lam[row] == 0.0) {
            if (r2 != NULL)                    /* a free row: nothing to add */
                r2[row] = 0.0;
            continue;
        }
        acc = s->sw_b != NULL ? s->sw_b[j] : 0.0;
        for (k = P->sw_ptr[j]; k < P->sw_ptr[j + 1]; k++)
            acc -= s->sw_val[k] * x[P->sw_idx[k]];
        if (pending)
            s->lam[row] -= s->alpha[row] * acc;
        if (r2 != NULL)
            r2[row] = acc;
        s->rho += acc * s->alpha[row] * acc;
        z = s->lam[row];
        if (penalised)
            z -= s->alpha[row] * acc;
        for (k = P->sw_ptr[j]; k < P->sw_ptr[j + 1]; k++)
            y[P->sw_idx[k]] -= s->sw_val[k] * z;
    }
}

void fcc_sp_sw_first(fcc_engine *e, int warm, double *y)
{
    /* fcc_sp_sw_residual at x = 0 (fcc_sp_first_pass): y -= G^T (lambda - alpha b). */
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int j, k, row;
    double z;
    for (j = 0; j < s->ms - e->m; j++) {
        row = e->m + j;
        z = warm ? s->lam[row] : 0.0;
        if (s->sw_b != NULL)
            z -= s->alpha[row] * s->sw_b[j];
        if (z == 0.0)
            continue;
        for (k = P->sw_ptr[j]; k < P->sw_ptr[j + 1]; k++)
            y[P->sw_idx[k]] -= s->sw_val[k] * z;
    }
}
