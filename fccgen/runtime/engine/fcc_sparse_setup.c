/* One instance's work on the sparse path (fcc_sparse, fcc_sparse.h): allocated here,
 * once the pattern is known, and again when the set-up changes the pattern; the
 * solves never allocate. */
#include <math.h>
#include <string.h>

#include "fcc_engine.h"

static void *zalloc(size_t n, size_t size)
{
    return FCC_CALLOC(n > 0 ? n : 1, size);
}

/* Free what depends on the pattern (the compact blocks, A and its factor). */
static void free_resized(fcc_sparse *s)
{
    FCC_FREE(s->alpha); FCC_FREE(s->rnorm); FCC_FREE(s->lam); FCC_FREE(s->lam_warm);
    FCC_FREE(s->r2); FCC_FREE(s->bdx); FCC_FREE(s->res); FCC_FREE(s->mu);
    FCC_FREE(s->cg_p); FCC_FREE(s->cg_sp); FCC_FREE(s->sw_val); FCC_FREE(s->sw_tgt);
    s->alpha = s->rnorm = s->lam = s->lam_warm = s->r2 = s->bdx = s->res = NULL;
    s->mu = s->cg_p = s->cg_sp = s->sw_val = s->sw_tgt = NULL;
    if (s->Mc != s->Mblk)
        FCC_FREE(s->Mc);
    if (s->Bc != s->Bblk)
        FCC_FREE(s->Bc);
    s->Mc = s->Bc = NULL;
    FCC_FREE(s->Ax); FCC_FREE(s->lb); FCC_FREE(s->Lx); FCC_FREE(s->Dinv); FCC_FREE(s->Y);
    s->Ax = s->lb = s->Lx = s->Dinv = s->Y = NULL;
}

int fcc_sparse_init(fcc_engine *e, const fcc_pattern *P)
{
    fcc_sparse *s = &e->sp;
    const fcc_model *m = e->model;
    size_t n = (size_t)e->n, ng = (size_t)e->m;
    memset(s, 0, sizeof(*s));
    e->sparse = 1;
    s->pat = P;
    s->Mblk = zalloc((size_t)P->mptr[m->n_el], sizeof(double));
    s->Bblk = zalloc((size_t)P->bptr[m->n_el], sizeof(double));
    s->lq = zalloc((size_t)m->local_size, sizeof(double));
    s->tperm = zalloc(n, sizeof(double));
    s->u = zalloc(n, sizeof(double));
    s->w_n = zalloc(n, sizeof(double));
    s->r1 = zalloc(n, sizeof(double));
    s->dx = zalloc(n, sizeof(double));
    s->base = zalloc(n, sizeof(double));
    s->lz = zalloc((size_t)(m->g_max > 1 ? m->g_max : 1), sizeof(double));
    s->track = zalloc(n * FCC_TRACK_MAX, sizeof(double));
    s->bn = zalloc(ng * FCC_TRACK_MAX, sizeof(double));
    s->xw = zalloc(n, sizeof(double));
    s->rs = zalloc(ng, sizeof(double));
    s->mv = zalloc(n, sizeof(double));
    s->qsave = zalloc(n, sizeof(double));
    s->cg_max = FCC_CG_MAX;
    s->refine_max = FCC_REFINE_MAX;
    s->al_max = FCC_AL_MAX;
    s->boost = 1.0;
    s->dense_fallback_max = FCC_DENSE_FALLBACK_MAX;
    if (!s->Mblk || !s->Bblk || !s->lq || !s->tperm || !s->u || !s->w_n || !s->r1 || !s->dx
            || !s->base || !s->lz || !s->track || !s->bn || !s->xw || !s->rs || !s->mv
            || !s->qsave) {
        fcc_sparse_free(e);
        return FCC_ERR_MEMORY;
    }
    return fcc_sparse_resize(e);
}

int fcc_sparse_resize(fcc_engine *e)
{
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int i;
    size_t ms = (size_t)e->m + (size_t)P->n_sw;
    free_resized(s);
    /* the solve's rows: the engine's, then the switchable rows (fcc_sparse_fold.c) */
    s->ms = (int)ms;
    s->sw_live = 0;
    s->sw_b = NULL;
    s->warm_valid = 0;
    s->alpha = zalloc(ms, sizeof(double));
    s->rnorm = zalloc(ms, sizeof(double));
    s->lam = zalloc(ms, sizeof(double));
    s->lam_warm = zalloc(ms, sizeof(double));
    s->r2 = zalloc(ms, sizeof(double));
    s->bdx = zalloc(ms, sizeof(double));
    s->res = zalloc(ms, sizeof(double));
    s->mu = zalloc(ms, sizeof(double));
    s->cg_p = zalloc(ms, sizeof(double));
    s->cg_sp = zalloc(ms, sizeof(double));
    s->sw_val = zalloc(P->n_sw > 0 ? (size_t)P->sw_ptr[P->n_sw] : 0, sizeof(double));
    s->sw_tgt = zalloc((size_t)P->n_sw, sizeof(double));
    s->Mc = P->compact ? zalloc((size_t)P->total_mc, sizeof(double)) : s->Mblk;
    s->Bc = P->compact ? zalloc((size_t)P->total_bc, sizeof(double)) : s->Bblk;
    if (s->Mc == NULL || s->Bc == NULL || !s->alpha || !s->rnorm || !s->lam
            || !s->lam_warm || !s->r2 || !s->bdx || !s->res || !s->mu || !s->cg_p
            || !s->cg_sp || !s->sw_val || !s->sw_tgt)
        return FCC_ERR_MEMORY;
    for (i = 0; i < P->n_fixed_rows; i++) {   /* constant norms and no penalty */
        s->rnorm[P->fixed_rows[i]] = P->fixed_norm[i];
        s->alpha[P->fixed_rows[i]] = 0.0;
    }
    if (!P->ready)
        return FCC_OK;
    s->Ax = zalloc((size_t)P->nnz_a, sizeof(double));
    s->lb = zalloc((size_t)P->lb_size, sizeof(double));
    s->Lx = zalloc((size_t)P->nnz_l, sizeof(double));
    s->Dinv = zalloc((size_t)e->n, sizeof(double));
    s->Y = zalloc((size_t)e->n, sizeof(double));
    if (!s->Ax || !s->lb || !s->Lx || !s->Dinv || !s->Y)
        return FCC_ERR_MEMORY;
    return FCC_OK;
}

void fcc_sparse_free(fcc_engine *e)
{
    fcc_sparse *s = &e->sp;
    free_resized(s);
    FCC_FREE(s->Mblk); FCC_FREE(s->Bblk); FCC_FREE(s->lq);
    FCC_FREE(s->tperm); FCC_FREE(s->u); FCC_FREE(s->w_n);
    FCC_FREE(s->r1); FCC_FREE(s->dx); FCC_FREE(s->base); FCC_FREE(s->lz);
    FCC_FREE(s->track); FCC_FREE(s->bn); FCC_FREE(s->xw); FCC_FREE(s->rs);
    FCC_FREE(s->mv); FCC_FREE(s->qsave);
    memset(s, 0, sizeof(*s));
    e->sparse = 0;
}

void fcc_sparse_reset_stats(fcc_engine *e)
{
    fcc_sparse *s = &e->sp;
    s->n_factor = s->n_solves = s->n_iterations = s->n_unconverged = 0;
    s->n_beyond_rank = 0;
    s->n_boosted = 0;
    s->boost_hold = 0;
    s->own_lam_seen = 0;
    s->v_peak = 0.0;
    s->n_fallback = 0;
    s->n_chord = s->n_chord_undone = 0;
    e->sol.n_drop = 0;
    s->most_iterations = 0;
    s->n_svd = 0;
    s->bound_max = 0.0;
    s->n_track = 0;
}

void fcc_sparse_set_beyond_rank(fcc_engine *e, double kept_sigma)
{
    double t = FCC_RHO * pow(FCC_BEYOND_FRACTION * kept_sigma, 2.0);
    e->sp.beyond_quotient = kept_sigma > 0.0 ? t / (1.0 + t) : 0.0;
}

void fcc_sparse_set_watch(fcc_engine *e, int k, const double *basis, double trigger)
{
    fcc_sparse *s = &e->sp;
    if (k > FCC_TRACK_MAX)
        k = 0;
    if (k > 0)
        memcpy(s->track, basis, (size_t)k * e->n * sizeof(double));
    s->n_track = k;
    s->grow_trigger = trigger;
}
