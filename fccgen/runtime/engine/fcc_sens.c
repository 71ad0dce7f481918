/* Forward sensitivities (fcc_sens.h): the tangent sweep over the elements, the
 * stages of RK4 on the sensitivities, the linearised projections. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fcc_sens.h"
#include "fcc_sens_sparse.h"

enum { SQ, SV, SQS, SV2, SV3, SV4, SA1, SA2, SA3, SA4, N_ROWS };

static double *row(const fcc_sens *s, int j, int which)
{
    return s->S + ((size_t)j * N_ROWS + (size_t)which) * (size_t)s->n;
}

static const fcc_dp_class *dp_class(const fcc_sens *s, int el)
{
    return &s->dp->classes[s->model->cls[el] - s->model->table->classes];
}

/* The element parameters some p_j moves (s->dP), element by element, and room for
 * their columns of J (fcc_sens.h: cptr, ccol, coff, WC). Returns 0, or -1 when out of
 * memory. */
static int moved_columns(fcc_sens *s)
{
    const fcc_model *md = s->model;
    int el, c, j, k, count = 0, n_el = md->n_el, np_all = md->n_p;
    for (k = 0; k < 2; k++) {          /* count, then fill */
        count = 0;
        for (el = 0; el < n_el; el++) {
            const fcc_dp_class *cl = dp_class(s, el);
            if (k == 1)
                s->cptr[el] = count;
            for (c = 0; c < md->pptr[el + 1] - md->pptr[el]; c++) {
                for (j = 0; j < s->np; j++)
                    if (s->dP[(size_t)j * np_all + md->pptr[el] + c] != 0.0)
                        break;
                if (j == s->np)
                    continue;
                if (k == 1) {
                    s->ccol[count] = c;
                    s->coff[count + 1] = s->coff[count] + (size_t)(cl->n_q + 3 * cl->n_g);
                }
                count++;
            }
        }
        if (k == 0) {
            s->cptr = calloc((size_t)n_el + 1, sizeof(int));
            s->ccol = calloc((size_t)count + 1, sizeof(int));
            s->coff = calloc((size_t)count + 1, sizeof(size_t));
            if (s->cptr == NULL || s->ccol == NULL || s->coff == NULL)
                return -1;
        }
    }
    s->cptr[n_el] = count;
    s->WC = calloc(s->coff[count] + 1, sizeof(double));
    return s->WC == NULL ? -1 : 0;
}

int fcc_sens_init(fcc_sens *s, const fcc_model *model, const fcc_dp_table *dp, int np,
                  const double *dP)
{
    int c, n = model->n_q, m = model->n_g, L = model->local_size, G = model->g_max;
    size_t total;
    memset(s, 0, sizeof(*s));
    if (dp == NULL || dp->abi_version != FCC_DP_ABI_VERSION || np < 1
        || dp->n_classes != model->table->n_classes)
        return FCC_ERR_ARGUMENT;
    for (c = 0; c < dp->n_classes; c++)
        if (strcmp(dp->classes[c].name, model->table->classes[c].name) != 0
            || dp->classes[c].tangent == NULL || dp->classes[c].prepare == NULL
            || dp->classes[c].apply == NULL || dp->classes[c].column == NULL
            || dp->classes[c].n_w < 0)
            return FCC_ERR_ARGUMENT;
    s->dp = dp;
    s->model = model;
    s->n = n;
    s->m = m;
    s->np = np;
    s->dP = dP;
    total = (size_t)np * N_ROWS * (size_t)n + 4 * (size_t)n + 5 * (size_t)(m + 1)
            + 5 * (size_t)L + (size_t)(G + 1) + 2 * (size_t)(L + 3 * G + 1)
            + 3 * (size_t)np * (size_t)(m + 1);
    s->S = calloc(total, sizeof(double));
    s->woff = calloc((size_t)model->n_el + 1, sizeof(size_t));
    if (s->S == NULL || s->woff == NULL) {
        fcc_sens_free(s);
        return FCC_ERR_MEMORY;
    }
    for (c = 0; c < model->n_el; c++)
        s->woff[c + 1] = s->woff[c]
            + (size_t)dp->classes[model->cls[c] - model->table->classes].n_w;
    s->W = calloc(s->woff[model->n_el] + 1, sizeof(double));
    if (s->W == NULL || moved_columns(s) != 0) {
        fcc_sens_free(s);
        return FCC_ERR_MEMORY;
    }
    s->r = s->S + (size_t)np * N_ROWS * (size_t)n;
    s->rhs = s->r + n;
    s->y = s->rhs + n;
    s->zero = s->y + n;
    s->lam = s->zero + n + m + 1;      /* zero: n + m + 1 zeros (a, lam, sq, sv) */
    s->b = s->lam + m + 1;
    s->gp = s->b + m + 1;
    s->phi = s->gp + m + 1;
    s->lq = s->phi + m + 1;
    s->lv = s->lq + L;
    s->la = s->lv + L;
    s->lsq = s->la + L;
    s->lsv = s->lsq + L;
    s->llam = s->lsv + L;
    s->lout = s->llam + G + 1;
    s->lcol = s->lout + L + 3 * G + 1;
    s->warm = s->lcol + L + 3 * G + 1;
    s->lam1 = s->warm + (size_t)np * (size_t)(m + 1);
    s->lam3 = s->lam1 + (size_t)np * (size_t)(m + 1);
    return FCC_OK;
}

void fcc_sens_free(fcc_sens *s)
{
    free(s->S);
    free(s->E);
    free(s->W);
    free(s->woff);
    free(s->cptr);
    free(s->ccol);
    free(s->coff);
    free(s->WC);
    s->S = NULL;
    s->E = NULL;
    s->W = NULL;
    s->woff = NULL;
    s->cptr = NULL;
    s->ccol = NULL;
    s->coff = NULL;
    s->WC = NULL;
}

double *fcc_sens_sq(const fcc_sens *s, int j)
{
    return row(s, j, SQ);
}

double *fcc_sens_sv(const fcc_sens *s, int j)
{
    return row(s, j, SV);
}

void fcc_sens_start(fcc_sens *s, const double *S0)
{
    int j, n = s->n;
    for (j = 0; j < s->np; j++) {
        s->lam3[(size_t)j * (size_t)(s->m + 1) + s->m] = 0.0;   /* no stage 3 yet */
        memcpy(row(s, j, SQ), S0 + (size_t)j * 2 * n, (size_t)n * sizeof(double));
        memcpy(row(s, j, SV), S0 + (size_t)j * 2 * n + n, (size_t)n * sizeof(double));
    }
}

void fcc_sens_begin_step(fcc_sens *s, double h)
{
    s->h = h;
}

/* An element's row outputs of the tangent (lout after its nq coordinates): dR2
 * into b, -(dg/dp) into gp, -dPhi into phi. */
static void store_rows(fcc_sens *s, int row0, int nq, int ng)
{
    int i;
    for (i = 0; i < ng; i++) {
        s->b[row0 + i] = s->lout[nq + i];
        s->gp[row0 + i] = -s->lout[nq + ng + i];
        s->phi[row0 + i] = -s->lout[nq + 2 * ng + i];
    }
}

/* Gather element el's q, v, a (NULL: zeros) and lam (NULL: zeros) into lq, lv, la,
 * llam. */
static void gather(const fcc_sens *s, int el, const double *q, const double *v,
                   const double *a, const double *lam)
{
    const fcc_model *md = s->model;
    const fcc_dp_class *k = dp_class(s, el);
    const int *idx = md->qidx + md->qptr[el];
    int i, row0 = md->gptr[el];
    for (i = 0; i < k->n_q; i++) {
        s->lq[i] = q[idx[i]];
        s->lv[i] = v[idx[i]];
        s->la[i] = a != NULL ? a[idx[i]] : 0.0;
    }
    for (i = 0; i < k->n_g; i++)
        s->llam[i] = lam != NULL ? lam[row0 + i] : 0.0;
}

/* Prepare the tangents of the elements (with rows only: rows_only) at (q, v, a, lam)
 * into W, and the columns of the parameters some p_j moves into WC (a, lam NULL:
 * zeros). */
static void prepare(fcc_engine *e, fcc_sens *s, const double *q, const double *v,
                    const double *a, const double *lam, int rows_only)
{
    const fcc_model *md = s->model;
    const double *params = e->asmb->params;
    int el, c;
    const fcc_dp_class *k;
    for (el = 0; el < md->n_el; el++) {
        k = dp_class(s, el);
        if (rows_only && k->n_g == 0)
            continue;
        gather(s, el, q, v, a, lam);
        k->prepare(s->lq, s->lv, params + md->pptr[el], s->la, s->llam,
                   s->W + s->woff[el]);
        for (c = s->cptr[el]; c < s->cptr[el + 1]; c++)
            k->column(s->lq, s->lv, params + md->pptr[el], s->la, s->llam, s->ccol[c],
                      s->WC + s->coff[c]);
    }
}

/* lout (nout numbers) += d col. */
static void add_column(fcc_sens *s, int nout, double d, const double *col)
{
    int r;
    for (r = 0; r < nout; r++)
        s->lout[r] += d * col[r];
}

/* Add element el's parameters' part J_p dP_el to lout (nout numbers): from the
 * prepared columns (WC), which hold every element parameter some p_j moves. */
static void add_columns(fcc_sens *s, int el, int nout, const double *dPe)
{
    int c;
    for (c = s->cptr[el]; c < s->cptr[el + 1]; c++)
        if (dPe[s->ccol[c]] != 0.0)
            add_column(s, nout, dPe[s->ccol[c]], s->WC + s->coff[c]);
}

/* Element el's state part J_state [sq; sv] into lout, from its prepared entries w. */
static void apply_state(fcc_sens *s, int el, const double *w, const double *sq,
                        const double *sv)
{
    const fcc_model *md = s->model;
    const fcc_dp_class *k = dp_class(s, el);
    const int *idx = md->qidx + md->qptr[el];
    int i;
    for (i = 0; i < k->n_q; i++) {
        s->lsq[i] = sq[idx[i]];
        s->lsv[i] = sv[idx[i]];
    }
    k->apply(w, s->lsq, s->lsv, s->lout);
}

/* Element el's lout into rhs (its coordinates) and into b, gp, phi (its rows). */
static void scatter(fcc_sens *s, int el)
{
    const fcc_model *md = s->model;
    const fcc_dp_class *k = dp_class(s, el);
    const int *idx = md->qidx + md->qptr[el];
    int i;
    for (i = 0; i < k->n_q; i++)
        s->rhs[idx[i]] += s->lout[i];
    store_rows(s, md->gptr[el], k->n_q, k->n_g);
}

/* fcc_sens_sweep with the tangents prepared at the stage (fcc_sens_stage_begin):
 * along (sq, sv, dP_j), one apply per element and the moved columns (dPj: a row of
 * s->dP). */
static void prepared_sweep(fcc_sens *s, const double *sq, const double *sv,
                           const double *dPj)
{
    const fcc_model *md = s->model;
    int el;
    const fcc_dp_class *k;
    memset(s->rhs, 0, (size_t)s->n * sizeof(double));
    for (el = 0; el < md->n_el; el++) {
        k = dp_class(s, el);
        apply_state(s, el, s->W + s->woff[el], sq, sv);
        add_columns(s, el, k->n_q + 3 * k->n_g, dPj + md->pptr[el]);
        scatter(s, el);
    }
}

/* The tangent kernels of every element along (sq, sv, dP_j) at (q, v) with the
 * accelerations a and multipliers lam: dR1 into rhs, dR2 into b, (dg/dp) dP_j into
 * gp, dPhi into phi. Each element's tangent is prepared there (overwriting the
 * stage's prepared entries: the event sweeps call it between steps, and every stage
 * prepares its own) and applied, and its parameters' columns are evaluated where
 * dP_j moves them (any dP_j), as each class's one-shot tangent kernel does. */
void fcc_sens_sweep(fcc_engine *e, fcc_sens *s, const double *q, const double *v,
                    const double *a, const double *lam, const double *sq,
                    const double *sv, const double *dPj)
{
    const fcc_model *md = s->model;
    const double *params = e->asmb->params;
    int el, c, nout;
    const fcc_dp_class *k;
    double *w;
    memset(s->rhs, 0, (size_t)s->n * sizeof(double));
    for (el = 0; el < md->n_el; el++) {
        k = dp_class(s, el);
        nout = k->n_q + 3 * k->n_g;
        gather(s, el, q, v, a, lam);
        w = s->W + s->woff[el];
        k->prepare(s->lq, s->lv, params + md->pptr[el], s->la, s->llam, w);
        apply_state(s, el, w, sq, sv);
        for (c = 0; c < md->pptr[el + 1] - md->pptr[el]; c++) {
            if (dPj[md->pptr[el] + c] == 0.0)
                continue;
            k->column(s->lq, s->lv, params + md->pptr[el], s->la, s->llam, c, s->lcol);
            add_column(s, nout, dPj[md->pptr[el] + c], s->lcol);
        }
        scatter(s, el);
    }
}

/* The projections' sweep along (sq, 0, dP_j) with zero accelerations and multipliers:
 * (dg/dp) dP_j into gp, dPhi into phi, dR2 into b, for the elements with rows only
 * (rhs is not formed: the projections do not read it). The tangent is linear in its
 * direction, so an element whose sq and dP_j parts are all zero gives zeros: its rows
 * are set to 0 without calling it (a stiffness's or a mass's key moves one element's
 * parameters; the position sweep's sq is zero). The elements' tangents are prepared
 * at the projected (q, v) with zero accelerations and multipliers (fcc_sens_project). */
static void rows_sweep(fcc_sens *s, const double *sq, const double *dPj)
{
    const fcc_model *md = s->model;
    int el, i, nq, ng, row0, np_el, moved;
    const int *idx;
    const fcc_dp_class *k;
    for (el = 0; el < md->n_el; el++) {
        k = dp_class(s, el);
        ng = k->n_g;
        if (ng == 0)
            continue;
        nq = k->n_q;
        idx = md->qidx + md->qptr[el];
        row0 = md->gptr[el];
        np_el = md->pptr[el + 1] - md->pptr[el];
        moved = 0;
        for (i = 0; i < np_el && !moved; i++)
            moved = dPj[md->pptr[el] + i] != 0.0;
        for (i = 0; i < nq; i++) {
            s->lsq[i] = sq[idx[i]];
            moved = moved || s->lsq[i] != 0.0;
        }
        if (!moved) {
            for (i = 0; i < ng; i++)
                s->b[row0 + i] = s->gp[row0 + i] = s->phi[row0 + i] = 0.0;
            continue;
        }
        k->apply(s->W + s->woff[el], s->lsq, s->zero, s->lout);
        add_columns(s, el, nq + 3 * ng, dPj + md->pptr[el]);
        store_rows(s, row0, nq, ng);
    }
}

void fcc_sens_sparse_multipliers(fcc_engine *e, const double *Q, const double *b,
                                 double *x, double *lam, int warm)
{
    /* warm: from the last accelerations' multipliers (the stage's, when they
     * converged), else from zero; lam: the refinement's last multipliers (an
     * unconverged solve is counted as any) */
    memcpy(lam, e->sp.lam_warm, (size_t)e->m * sizeof(double));
    fcc_sp_kkt_solve_from(e, Q, NULL, b, x, lam, warm && e->sp.warm_valid, 0);
    memcpy(lam, e->sp.lam, (size_t)e->m * sizeof(double));
}

/* (M a)_i on the dense path (M assembled), 0 on the sparse path (whose multipliers
 * come from the blocks: fcc_sens_sparse_stage_lam). */
static double Mv(const fcc_engine *e, const double *a, int i)
{
    const double *Mi;
    double acc = 0.0;
    int j, n = e->n;
    if (e->sparse)
        return 0.0;
    Mi = e->asmb->M + (size_t)i * n;
    for (j = 0; j < n; j++)
        acc += Mi[j] * a[j];
    return acc;
}

/* lam of the stage's solve: B^T lam = f - h - M a (f, h assembled at the stage; M
 * too on the dense path, its blocks on the sparse path). */
static void multipliers(fcc_engine *e, fcc_sens *s, const double *a)
{
    const fcc_assembly *as = e->asmb;
    int i, n = s->n;
    for (i = 0; i < n; i++)
        s->r[i] = as->f[i] - as->h[i] - Mv(e, a, i);
    if (fcc_sens_rows(s) > 0)                  /* + G^T mu of the locked rows */
        fcc_sens_rows_force(s, s->r);
    if (!e->sparse) {
        fcc_dense_multipliers(&e->sol, s->r, s->lam, s->y);
        return;
    }
    /* the sparse path, r = f - h (+ G^T mu): the acceleration solve's converged
     * multipliers corrected once, else the stage's system again, M x + B^T lam = r,
     * B x = -c, for its multipliers (x: the same a) */
    if (fcc_sens_sparse_stage_lam(e, s, a))
        return;
    for (i = 0; i < s->m; i++)
        s->gp[i] = -as->c[i];
    fcc_sens_sparse_multipliers(e, s->r, s->gp, s->y, s->lam, 1);
}

static int bad(fcc_engine *e, const double *x, int n)
{
    if (fcc_finite(x, n))
        return 0;
    return fcc_fail(e, FCC_ERR_NONFINITE_RESULT, 0, 0);
}

void fcc_sens_stage_begin(fcc_engine *e, fcc_sens *s, const double *q, const double *v,
                          const double *a)
{
    if (fcc_sens_rows(s) > 0)                  /* the stage's rows' multipliers */
        fcc_sens_keep_mu(s);
    multipliers(e, s, a);
    prepare(e, s, q, v, a, s->lam, 0);
}

int fcc_sens_stage_acc(fcc_engine *e, fcc_sens *s, int j, const double *q,
                       const double *v, const double *a, const double *sq,
                       const double *sv, double *sa)
{
    int rows = fcc_sens_rows(s);
    prepared_sweep(s, sq, sv, s->dP + (size_t)j * s->model->n_p);
    if (rows > 0)
        fcc_sens_rows_rhs(s, q, sq);
    if (fcc_sens_solve_from(e, s->rhs, s->b, sa,
                            s->warm + (size_t)j * (size_t)(s->m + 1)) < 0)
        return -1;
    if (rows > 0 && fcc_sens_rows_acc(e, s, q, v, a, sq, sv, sa) < 0)
        return -1;
    return bad(e, sa, s->n) ? -1 : 0;
}

/* RK4 on the sparse path: the start of parameter j's stage k solve (s->warm, which
 * fcc_sens_solve_from starts from; by default the previous stage's multipliers).
 * Stages 1 and 3 follow a stage at their own time (the last step's stage 4, stage 2)
 * and start from its multipliers; stages 2 and 4 are half a step later than the stage
 * before, and the multipliers' change over it took about 5 solves with A to refine
 * away on the 7-unit scissor boom, against 2 for stages 1 and 3. Their start is the
 * line through two earlier stages' converged multipliers, at the stage's time: stage 2
 * (t + h/2) from stage 1 (t) and the last step's stage 3 (t - h/2, when that step had
 * the same h), stage 4 (t + h) from stages 1 and 3 (t + h/2): an error of second order
 * in h instead of first. It is only a start: the refinement runs to its own tolerance
 * from it (a warm start that converges slowly is restarted from zero there). */
static void rk4_warm(fcc_sens *s, int j, int k)
{
    int i, m = s->m;
    size_t off = (size_t)j * (size_t)(m + 1);
    double *w = s->warm + off, *l1 = s->lam1 + off, *l3 = s->lam3 + off;
    if (k == 2 && w[m] != 0.0 && l3[m] != 0.0 && s->h3 == s->h) {
        for (i = 0; i < m; i++)           /* w: stage 1's */
            w[i] = 2.0 * w[i] - l3[i];
    } else if (k == 4 && l1[m] != 0.0 && w[m] != 0.0) {
        for (i = 0; i < m; i++)           /* w: stage 3's */
            w[i] = 2.0 * w[i] - l1[i];
    }
}

/* After parameter j's stage k (1 or 3): keep its multipliers (with their flag). */
static void rk4_keep(fcc_sens *s, int j, int k)
{
    size_t off = (size_t)j * (size_t)(s->m + 1);
    memcpy((k == 1 ? s->lam1 : s->lam3) + off, s->warm + off,
           (size_t)(s->m + 1) * sizeof(double));
}

int fcc_sens_rk4_stage(fcc_engine *e, fcc_sens *s, int k, const double *q,
                       const double *v, const double *a)
{
    static const int stage_q[4] = {SQ, SQS, SQS, SQS}, stage_v[4] = {SV, SV2, SV3, SV4};
    int i, j, n = s->n;
    double h = s->h, h2 = 0.5 * h, h6 = h / 6.0;
    double *sq, *sv, *sqs, *sa;
    fcc_sens_stage_begin(e, s, q, v, a);
    for (j = 0; j < s->np; j++) {
        sa = row(s, j, SA1 + k - 1);
        if (e->sparse && (k == 2 || k == 4))
            rk4_warm(s, j, k);
        if (fcc_sens_stage_acc(e, s, j, q, v, a, row(s, j, stage_q[k - 1]),
                               row(s, j, stage_v[k - 1]), sa) < 0)
            return -1;
        if (e->sparse && (k == 1 || k == 3))
            rk4_keep(s, j, k);
        sq = row(s, j, SQ);
        sv = row(s, j, SV);
        sqs = row(s, j, SQS);
        if (k == 1 || k == 2) {          /* stage k + 1 at t + h/2 */
            const double *svk = row(s, j, k == 1 ? SV : SV2);
            double *svn = row(s, j, k == 1 ? SV2 : SV3);
            for (i = 0; i < n; i++) {
                sqs[i] = sq[i] + h2 * svk[i];
                svn[i] = sv[i] + h2 * sa[i];
            }
        } else if (k == 3) {             /* stage 4 at t + h */
            const double *sv3 = row(s, j, SV3);
            double *sv4 = row(s, j, SV4);
            for (i = 0; i < n; i++) {
                sqs[i] = sq[i] + h * sv3[i];
                sv4[i] = sv[i] + h * sa[i];
            }
        } else {                         /* the step's end */
            const double *sv2 = row(s, j, SV2), *sv3 = row(s, j, SV3), *sv4 = row(s, j, SV4);
            const double *a1 = row(s, j, SA1), *a2 = row(s, j, SA2), *a3 = row(s, j, SA3);
            for (i = 0; i < n; i++) {
                sq[i] += h6 * (sv[i] + 2.0 * sv2[i] + 2.0 * sv3[i] + sv4[i]);
                sv[i] += h6 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + sa[i]);
            }
        }
    }
    if (k == 3)
        s->h3 = h;
    return 0;
}

int fcc_sens_project(fcc_engine *e, fcc_sens *s, const double *q, const double *v)
{
    int j, n = s->n, np_all = s->model->n_p;
    double *sq, *sv;
    prepare(e, s, q, v, NULL, NULL, 1);
    for (j = 0; j < s->np; j++) {
        sq = row(s, j, SQ);
        sv = row(s, j, SV);
        /* positions: gp = -(dg/dp) dP_j does not depend on the direction's q part */
        rows_sweep(s, s->zero, s->dP + (size_t)j * np_all);
        if (fcc_sens_solve(e, NULL, sq, s->gp, s->y) < 0)
            return -1;
        memcpy(sq, s->y, (size_t)n * sizeof(double));
        if (fcc_sens_rows(s) > 0 && fcc_sens_rows_positions(e, s, j, q, sq) < 0)
            return -1;
        /* speeds: phi = -dPhi[s_q, dP_j] with the projected s_q */
        rows_sweep(s, sq, s->dP + (size_t)j * np_all);
        if (fcc_sens_solve(e, NULL, sv, s->phi, s->y) < 0)
            return -1;
        memcpy(sv, s->y, (size_t)n * sizeof(double));
        if (fcc_sens_rows(s) > 0 && fcc_sens_rows_speeds(e, s, q, v, sq, sv) < 0)
            return -1;
        if (bad(e, sq, n) || bad(e, sv, n))
            return -1;
    }
    return 0;
}

void fcc_sens_record(const fcc_sens *s, long rec)
{
    int j, n = s->n;
    double *o;
    if (s->out == NULL)
        return;
    for (j = 0; j < s->np; j++) {
        o = s->out + ((size_t)rec * s->np + j) * 2 * (size_t)n;
        memcpy(o, row(s, j, SQ), (size_t)n * sizeof(double));
        memcpy(o + n, row(s, j, SV), (size_t)n * sizeof(double));
    }
}
