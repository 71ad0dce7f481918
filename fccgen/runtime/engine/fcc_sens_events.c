/* Sensitivities through events (fcc_sens.h): the event times' derivatives, the jumps
 * of s at a located event (saltation), and the locked rows in the stages and
 * projections of s. Both paths (fcc_sens.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fcc_events.h"
#include "fcc_sens.h"

/* The rows' second derivatives are central differences of their generated Jacobian
 * and bias along a direction moved by this fraction of the coordinates' size. */
#define DIR_STEP 1e-5

int fcc_sens_events_init(fcc_sens *s, fcc_events *ev, double *tout, long cap)
{
    int n = s->n, np = s->np, nr = ev->spec->nr, ne = ev->spec->ne, m = s->m;
    size_t room = (size_t)nr + ne + 1;
    size_t total = (size_t)np * (2 * (size_t)n + (size_t)nr + 1) + 2 * ((size_t)nr + 1)
                   + 3 * ((size_t)nr * n + 1) + 3 * room + 7 * (size_t)n + (size_t)m + 1;
    free(s->E);
    s->E = calloc(total, sizeof(double));
    if (s->E == NULL)
        return FCC_ERR_MEMORY;
    s->ev = ev;
    s->nr = nr;
    s->ne = ne;
    s->tout = tout;
    s->cap = cap;
    s->saved = s->E;
    s->dheld = s->saved + (size_t)np * 2 * n;
    s->tau = s->dheld + (size_t)np * nr;
    s->emu = s->tau + np;
    s->target = s->emu + nr + 1;
    s->dG = s->target + nr + 1;
    s->G1 = s->dG + (size_t)nr * n + 1;
    s->G2 = s->G1 + (size_t)nr * n + 1;
    s->rb1 = s->G2 + (size_t)nr * n + 1;       /* 2 room: values, then a bias's change */
    s->rb2 = s->rb1 + 2 * room;
    s->vm = s->rb2 + room;
    s->am = s->vm + n;
    s->ap = s->am + n;
    s->dv = s->ap + n;
    s->w = s->dv + n;
    s->x = s->w + n;
    s->r0 = s->x + n;
    s->alpha = s->r0 + n;
    return FCC_OK;
}

int fcc_sens_rows(const fcc_sens *s)
{
    return s->ev != NULL ? s->ev->n_used : 0;
}

void fcc_sens_save(fcc_sens *s)
{
    int j, n = s->n;
    if (s->ev == NULL)
        return;
    for (j = 0; j < s->np; j++) {
        memcpy(s->saved + (size_t)j * 2 * n, fcc_sens_sq(s, j), (size_t)n * sizeof(double));
        memcpy(s->saved + (size_t)j * 2 * n + n, fcc_sens_sv(s, j),
               (size_t)n * sizeof(double));
    }
}

void fcc_sens_restore(fcc_sens *s)
{
    int j, n = s->n;
    if (s->ev == NULL)
        return;
    for (j = 0; j < s->np; j++) {
        memcpy(fcc_sens_sq(s, j), s->saved + (size_t)j * 2 * n, (size_t)n * sizeof(double));
        memcpy(fcc_sens_sv(s, j), s->saved + (size_t)j * 2 * n + n,
               (size_t)n * sizeof(double));
    }
}

static double inf_norm(const double *x, int n)
{
    int i;
    double big = 0.0;
    for (i = 0; i < n; i++)
        if (fabs(x[i]) > big)
            big = fabs(x[i]);
    return big;
}

/* The step of the central differences along (dq, dv) at (q, v): DIR_STEP of the
 * coordinates' (speeds') size over the direction's; 0 for a zero direction. */
static double dir_step(const double *q, const double *v, const double *dq,
                       const double *dv, int n)
{
    double lq = inf_norm(q, n), nq = inf_norm(dq, n), lv, nv, ratio;
    lq = lq > 1e-3 ? lq : 1e-3;
    ratio = nq / lq;
    if (dv != NULL) {
        lv = inf_norm(v, n);
        lv = lv > 1e-3 * lq ? lv : 1e-3 * lq;
        nv = inf_norm(dv, n);
        if (nv / lv > ratio)
            ratio = nv / lv;
    }
    return ratio > 0.0 ? DIR_STEP / ratio : 0.0;
}

/* s->dG = d(G)/dq along dq (all nr rows; zero for a zero direction). */
static void jacobian_dir(fcc_sens *s, const double *q, const double *dq)
{
    const fcc_event_table *tab = s->ev->spec->tab;
    int i, n = s->n, nr = s->nr;
    double eps = dir_step(q, NULL, dq, NULL, n);
    if (eps == 0.0) {
        memset(s->dG, 0, (size_t)nr * n * sizeof(double));
        return;
    }
    for (i = 0; i < n; i++)
        s->w[i] = q[i] + eps * dq[i];
    tab->quantity_gradients(s->w, NULL, 0.0, s->ev->p, s->G1);
    for (i = 0; i < n; i++)
        s->w[i] = q[i] - eps * dq[i];
    tab->quantity_gradients(s->w, NULL, 0.0, s->ev->p, s->G2);
    for (i = 0; i < nr * n; i++)
        s->dG[i] = (s->G1[i] - s->G2[i]) / (2.0 * eps);
}

/* out[nr] = d(Gdot v)[dq, dv] at (q, v): the bias is quadratic in v, its central
 * difference along dv exact but for rounding. */
static void bias_dir(fcc_sens *s, const double *q, const double *v, const double *dq,
                     const double *dv, double *out)
{
    const fcc_event_table *tab = s->ev->spec->tab;
    int i, n = s->n, nr = s->nr;
    double eps = dir_step(q, v, dq, dv, n);
    double *qq = s->w, *vv = s->x;
    if (eps == 0.0) {
        memset(out, 0, (size_t)nr * sizeof(double));
        return;
    }
    for (i = 0; i < n; i++) {
        qq[i] = q[i] + eps * dq[i];
        vv[i] = v[i] + eps * dv[i];
    }
    tab->quantity_bias(qq, vv, 0.0, s->ev->p, s->rb1);
    for (i = 0; i < n; i++) {
        qq[i] = q[i] - eps * dq[i];
        vv[i] = v[i] - eps * dv[i];
    }
    tab->quantity_bias(qq, vv, 0.0, s->ev->p, s->rb2);
    for (i = 0; i < nr; i++)
        out[i] = (s->rb1[i] - s->rb2[i]) / (2.0 * eps);
}

void fcc_sens_keep_mu(fcc_sens *s)
{
    memcpy(s->emu, s->ev->mu, (size_t)s->ev->n_used * sizeof(double));
}

/* r += sum over used rows of G_i^T mu_a (G rows in mat, nr x n). */
static void add_rows_t(const fcc_sens *s, const double *mat, const double *mu, double *r)
{
    const fcc_events *ev = s->ev;
    int i, a = 0, j, n = s->n;
    for (i = 0; i < s->nr; i++) {
        if (!ev->used[i])
            continue;
        for (j = 0; j < n; j++)
            r[j] += mat[i * n + j] * mu[a];
        a++;
    }
}

/* target_a = -(mat_i . x) - (extra ? extra_i : 0) over the used rows. */
static void rows_target(fcc_sens *s, const double *mat, const double *x,
                        const double *extra)
{
    const fcc_events *ev = s->ev;
    int i, a = 0, j, n = s->n;
    double acc;
    for (i = 0; i < s->nr; i++) {
        if (!ev->used[i])
            continue;
        acc = 0.0;
        for (j = 0; j < n; j++)
            acc += mat[i * n + j] * x[j];
        s->target[a++] = -acc - (extra != NULL ? extra[i] : 0.0);
    }
}

void fcc_sens_rows_force(const fcc_sens *s, double *r)
{
    add_rows_t(s, s->ev->rg, s->emu, r);
}

void fcc_sens_rows_rhs(fcc_sens *s, const double *q, const double *sq)
{
    jacobian_dir(s, q, sq);
    add_rows_t(s, s->dG, s->emu, s->rhs);
}

int fcc_sens_rows_acc(fcc_engine *e, fcc_sens *s, const double *q, const double *v,
                      const double *a, const double *sq, const double *sv, double *sa)
{
    /* s->dG along sq from fcc_sens_rows_rhs; ev->rg, ev->z at q (fcc_ev_constrain) */
    double *db = s->rb1 + s->nr + s->ne + 1;   /* rb1's second half */
    bias_dir(s, q, v, sq, sv, db);
    rows_target(s, s->dG, a, db);
    return fcc_ev_hold(e, s->ev, s->ev->n_used, sa, s->target, sa);
}

int fcc_sens_rows_positions(fcc_engine *e, fcc_sens *s, int j, const double *q,
                            double *sq)
{
    fcc_events *ev = s->ev;
    int i, a = 0;
    if (j == 0)                                /* the rows' responses at q, once */
        fcc_ev_responses(e, ev, q);
    for (i = 0; i < s->nr; i++)
        if (ev->used[i])
            s->target[a++] = s->dheld[(size_t)j * s->nr + i];
    return fcc_ev_hold(e, ev, ev->n_used, sq, s->target, sq);
}

int fcc_sens_rows_speeds(fcc_engine *e, fcc_sens *s, const double *q, const double *v,
                         const double *sq, double *sv)
{
    jacobian_dir(s, q, sq);
    rows_target(s, s->dG, v, NULL);
    return fcc_ev_hold(e, s->ev, s->ev->n_used, sv, s->target, sv);
}

/* a = the accelerations at (q, v, t) with the rows used now (factorisation left at
 * q, ev->rg and ev->z at q, ev->mu their multipliers). */
static int accelerations(fcc_engine *e, fcc_sens *s, const double *q, const double *v,
                         double t, double *a)
{
    fcc_put_time(e->asmb, t);
    if (fcc_accelerations(e, q, v, a, 0) < 0)
        return -1;
    return fcc_ev_constrain(e, s->ev, q, v, t, a);
}

int fcc_sens_event_before(fcc_engine *e, fcc_sens *s, int k, const double *q,
                          const double *v, double t)
{
    const fcc_event_table *tab = s->ev->spec->tab;
    int i, j, n = s->n, ne = s->ne;
    double rate = 0.0, dt = 1e-6 * (fabs(t) > 1.0 ? fabs(t) : 1.0), st, acc;
    double *g, *sq, *sv;
    if (k >= ne)                               /* a release: not carried (refused) */
        return fcc_fail(e, FCC_ERR_ARGUMENT, 0, 0);
    tab->event_gradients(q, v, t, s->ev->p, s->ev->sg);
    g = s->ev->sg + (size_t)k * n;
    tab->event_values(q, v, t + dt, s->ev->p, s->rb1);    /* ds_k/dt: time events */
    tab->event_values(q, v, t - dt, s->ev->p, s->rb2);
    st = (s->rb1[k] - s->rb2[k]) / (2.0 * dt);
    for (i = 0; i < n; i++)
        rate += g[i] * v[i];
    rate += st;
    if (accelerations(e, s, q, v, t, s->am) < 0)
        return -1;
    e->factor_valid = 0;
    if (!(fabs(rate) > 0.0) || !isfinite(rate))  /* a grazing crossing: dte/dp infinite */
        return fcc_fail(e, FCC_ERR_NONFINITE_RESULT, 0, 0);
    memcpy(s->vm, v, (size_t)n * sizeof(double));
    for (j = 0; j < s->np; j++) {
        sq = fcc_sens_sq(s, j);
        sv = fcc_sens_sv(s, j);
        acc = 0.0;
        for (i = 0; i < n; i++)
            acc += g[i] * sq[i];
        s->tau[j] = -acc / rate;
        for (i = 0; i < n; i++) {
            sq[i] += v[i] * s->tau[j];
            sv[i] += s->am[i] * s->tau[j];
        }
    }
    return 0;
}

/* The plastic impact's linearisation for parameter j at q (fcc_sens.h): along the
 * total derivative (dq, dv-) in (sq, sv), with v+ = v, the jump s->dv = v+ - v-, the
 * multipliers s->alpha (B) and s->emu (the rows, mu = -beta) of
 * M (v+ - v-) + B^T alpha + G^T beta = 0; dv+ into sv, and the held values'
 * derivatives of event k's rows, G dq. */
static int lock_jump(fcc_engine *e, fcc_sens *s, int k, int j, const double *q,
                     const double *v)
{
    fcc_events *ev = s->ev;
    int i, c, n = s->n, np_all = s->model->n_p;
    double *sq = fcc_sens_sq(s, j), *sv = fcc_sens_sv(s, j), acc;
    const double *dPj = s->dP + (size_t)j * np_all;
    /* dR1 of the impact's balance: -dM dv_jump - dB^T alpha (two sweeps: the
     * tangent is linear in (a, lam)) - dG^T beta, beta = -mu */
    fcc_sens_sweep(e, s, q, v, s->zero, s->zero, sq, s->zero, dPj);
    memcpy(s->r0, s->rhs, (size_t)n * sizeof(double));
    fcc_sens_sweep(e, s, q, v, s->dv, s->alpha, sq, s->zero, dPj);
    for (i = 0; i < n; i++)
        s->rhs[i] -= s->r0[i];
    jacobian_dir(s, q, sq);
    add_rows_t(s, s->dG, s->emu, s->rhs);
    /* B dv+ = -dPhi[sq, dP] at v+ (s->phi), then the rows: G dv+ = -dG[sq] v+ */
    fcc_solve_constrained(e, s->rhs, sv, s->phi, s->x);
    rows_target(s, s->dG, v, NULL);
    if (fcc_ev_hold(e, ev, ev->n_used, s->x, s->target, s->x) < 0)
        return -1;
    memcpy(sv, s->x, (size_t)n * sizeof(double));
    for (c = 0; c < s->nr; c++) {              /* held = r(q(te)): d = G (sq + v tau) */
        if (c != ev->spec->row[k] && c != ev->spec->row2[k])
            continue;
        acc = 0.0;
        for (i = 0; i < n; i++)
            acc += ev->rg[c * n + i] * sq[i];
        s->dheld[(size_t)j * s->nr + c] = acc;
    }
    return 0;
}

int fcc_sens_event_after(fcc_engine *e, fcc_sens *s, int k, int rc, const double *q,
                         const double *v, double t)
{
    fcc_events *ev = s->ev;
    const fcc_event_spec *c = ev->spec;
    int i, j, n = s->n, act = c->action[k];
    double *sq, *sv, *plus = s->am;
    long row = ev->n_log - 1;
    if (rc == 0 && row >= 0 && row < s->cap && s->tout != NULL)
        for (j = 0; j < s->np; j++)
            s->tout[(size_t)row * s->np + j] = s->tau[j];
    if (rc == 0 && act == FCC_ACT_STOP)
        return 0;                              /* the last record: the total derivative */
    if (rc == 0 && act == FCC_ACT_LOCK) {
        /* the impact's multipliers (lock_rows: v+ = v- + Z mu, beta = -mu) before the
         * accelerations overwrite them; M dv_jump + B^T alpha = G^T mu */
        memcpy(s->emu, ev->mu, (size_t)ev->n_used * sizeof(double));
        if (accelerations(e, s, q, v, t, s->ap) < 0)
            return -1;
        for (i = 0; i < n; i++)
            s->dv[i] = v[i] - s->vm[i];
        for (i = 0; i < n; i++) {
            double m = 0.0;
            int l;
            for (l = 0; !e->sparse && l < n; l++)   /* sparse: x = dv_jump below */
                m += e->asmb->M[(size_t)i * n + l] * s->dv[l];
            s->r0[i] = -m;
        }
        add_rows_t(s, ev->rg, s->emu, s->r0);
        if (e->sparse)                         /* M x + B^T alpha = G^T mu, B x = 0 */
            fcc_sens_sparse_multipliers(e, s->r0, NULL, s->w, s->alpha, 0);
        else
            fcc_dense_multipliers(&e->sol, s->r0, s->alpha, s->w);
        for (j = 0; j < s->np; j++)
            if (lock_jump(e, s, k, j, q, v) < 0)
                return -1;
        plus = s->ap;
    } else if (rc == 0 && act == FCC_ACT_UNLOCK) {
        if (accelerations(e, s, q, v, t, s->ap) < 0)
            return -1;
        plus = s->ap;
    } else if (rc == 0 && act != FCC_ACT_LOG) {
        return fcc_fail(e, FCC_ERR_ARGUMENT, 0, 0);   /* bounces: refused before */
    }
    e->factor_valid = 0;
    for (j = 0; j < s->np; j++) {              /* s+ = J s_total - f+ tau */
        sq = fcc_sens_sq(s, j);
        sv = fcc_sens_sv(s, j);
        for (i = 0; i < n; i++) {
            sq[i] -= v[i] * s->tau[j];
            sv[i] -= plus[i] * s->tau[j];
        }
        if (!(fcc_finite(sq, n) && fcc_finite(sv, n)))
            return fcc_fail(e, FCC_ERR_NONFINITE_RESULT, 0, 0);
    }
    return 0;
}
