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
                   + 3 * ((size_t)nr * n + 1) + 3 * room + 7 * (size_t)n + (size_t)m + 1
                   + 2 * ((size_t)ne * n + 1) + 4 * (size_t)n;
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
    s->sg1 = s->alpha + m + 1;
    s->sg2 = s->sg1 + (size_t)ne * n + 1;
    s->gk = s->sg2 + (size_t)ne * n + 1;
    s->dgk = s->gk + n;
    s->wz = s->dgk + n;
    s->vp = s->wz + n;
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

/* The release of resting bounce kk (event ne + kk) located at (q, v, t): its function
 * is rel_sign mu, mu the multiplier of kk's row in the accelerations (fcc_ev_watch),
 * so dte/dp_j = -(dmu_j) / (d(mu)/dt) with rel_sign cancelled. dmu_j is the row's
 * multiplier's derivative along (s_q, s_v, dP_j): the stage's linearised solve
 * (fcc_sens_rk4_stage) at (q, v) leaves it in ev->mu (fcc_sens_rows_acc's hold: its
 * coefficients on the rows' responses are dmu, fcc_sens.h); d(mu)/dt by central
 * differences of the watched function along the motion, (q, v, t) +- eps (v, a, 1)
 * (it holds the loads' explicit time; eps = 1e-5 s: O(eps^2) truncation, rounding of
 * the multiplier over eps about 1e-11 relative). Leaves s->tau, s->am (a-). */
static int release_time(fcc_engine *e, fcc_sens *s, int kk, const double *q,
                        const double *v, double t)
{
    fcc_events *ev = s->ev;
    const fcc_event_spec *c = ev->spec;
    int i, j, pos = 0, n = s->n, ne = s->ne, np_all = s->model->n_p;
    double eps = 1e-5 * (fabs(t) > 1.0 ? fabs(t) : 1.0), plus, rate, acc;
    double *qq = s->vp, *vv = s->wz;
    for (i = 0; i < c->row[kk]; i++)
        pos += ev->used[i];
    if (c->row[kk] < 0 || !ev->used[c->row[kk]])
        return fcc_fail(e, FCC_ERR_ARGUMENT, 0, 0);
    if (accelerations(e, s, q, v, t, s->am) < 0)
        return -1;
    for (i = 0; i < n; i++) {
        qq[i] = q[i] + eps * v[i];
        vv[i] = v[i] + eps * s->am[i];
    }
    if (fcc_ev_watch(e, ev, qq, vv, t + eps, s->rb1) < 0)
        return -1;
    plus = s->rb1[ne + kk];
    for (i = 0; i < n; i++) {
        qq[i] = q[i] - eps * v[i];
        vv[i] = v[i] - eps * s->am[i];
    }
    if (fcc_ev_watch(e, ev, qq, vv, t - eps, s->rb1) < 0)
        return -1;
    rate = (plus - s->rb1[ne + kk]) / (2.0 * eps) * ev->rel_sign[kk];   /* d(mu)/dt */
    e->factor_valid = 0;
    if (!(fabs(rate) > 0.0) || !isfinite(rate))
        return fcc_fail(e, FCC_ERR_NONFINITE_RESULT, 0, 0);
    if (accelerations(e, s, q, v, t, s->am) < 0)      /* again at (q, v, t) */
        return -1;
    fcc_sens_keep_mu(s);
    for (i = 0; i < n; i++) {                  /* B^T lam = f - h - M a + G^T mu */
        const double *Mi = e->asmb->M + (size_t)i * n;
        acc = e->asmb->f[i] - e->asmb->h[i];
        for (j = 0; j < n; j++)
            acc -= Mi[j] * s->am[j];
        s->r0[i] = acc;
    }
    fcc_sens_rows_force(s, s->r0);
    fcc_dense_multipliers(&e->sol, s->r0, s->alpha, s->w);
    for (j = 0; j < s->np; j++) {
        const double *sq = fcc_sens_sq(s, j), *sv = fcc_sens_sv(s, j);
        fcc_sens_sweep(e, s, q, v, s->am, s->alpha, sq, sv, s->dP + (size_t)j * np_all);
        fcc_sens_rows_rhs(s, q, sq);
        fcc_solve_constrained(e, s->rhs, NULL, s->b, s->dv);   /* (s->x: bias_dir's) */
        if (fcc_sens_rows_acc(e, s, q, v, s->am, sq, sv, s->dv) < 0)
            return -1;
        s->tau[j] = -ev->mu[pos] / rate;
    }
    e->factor_valid = 0;
    return 0;
}

int fcc_sens_event_before(fcc_engine *e, fcc_sens *s, int k, const double *q,
                          const double *v, double t)
{
    const fcc_event_table *tab = s->ev->spec->tab;
    int i, j, n = s->n, ne = s->ne;
    double rate = 0.0, dt = 1e-6 * (fabs(t) > 1.0 ? fabs(t) : 1.0), st, acc;
    double *g, *sq, *sv;
    if (k >= ne) {                             /* a release */
        if (release_time(e, s, k - ne, q, v, t) < 0)
            return -1;
        memcpy(s->vm, v, (size_t)n * sizeof(double));
        for (j = 0; j < s->np; j++) {
            sq = fcc_sens_sq(s, j);
            sv = fcc_sens_sv(s, j);
            for (i = 0; i < n; i++) {
                sq[i] += v[i] * s->tau[j];
                sv[i] += s->am[i] * s->tau[j];
            }
        }
        return 0;
    }
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

/* s->dgk = d(ds_k/dq)[dq] at (q, t): central differences of the generated event
 * gradients along dq (as the rows', jacobian_dir; zero for a zero direction). */
static void event_gradient_dir(fcc_sens *s, int k, const double *q, const double *v,
                               double t, const double *dq)
{
    const fcc_event_table *tab = s->ev->spec->tab;
    int i, n = s->n;
    double eps = dir_step(q, NULL, dq, NULL, n);
    if (eps == 0.0) {
        memset(s->dgk, 0, (size_t)n * sizeof(double));
        return;
    }
    for (i = 0; i < n; i++)
        s->w[i] = q[i] + eps * dq[i];
    tab->event_gradients(s->w, v, t, s->ev->p, s->sg1);
    for (i = 0; i < n; i++)
        s->w[i] = q[i] - eps * dq[i];
    tab->event_gradients(s->w, v, t, s->ev->p, s->sg2);
    for (i = 0; i < n; i++)
        s->dgk[i] = (s->sg1[(size_t)k * n + i] - s->sg2[(size_t)k * n + i]) / (2.0 * eps);
}

/* The bounce's plastic part at q (factorisation and the used rows' responses at q,
 * v-: s->vm): g = ds_k/dq (s->gk), its response w held by the used rows (s->wz, and
 * their coefficients mu_w), mu_p = -g v- / g w, the plastic jump s->dv = mu_p w,
 * v_p = v- + s->dv (s->vp), the rows' impact multipliers mu_p mu_w (s->emu: the
 * balance's G^T beta with beta = -mu_p mu_w) and B's, s->alpha, of
 * M dv + B^T alpha + G^T beta - mu_p g = 0. Returns mu_p, or NAN (the engine's error
 * record filled) when g w is not positive. */
static double bounce_plastic(fcc_engine *e, fcc_sens *s, int k, const double *q,
                             const double *v, double t)
{
    fcc_events *ev = s->ev;
    int i, l, n = s->n, m;
    double gw = 0.0, gv = 0.0, mup, acc;
    ev->spec->tab->event_gradients(q, v, t, ev->p, ev->sg);
    memcpy(s->gk, ev->sg + (size_t)k * n, (size_t)n * sizeof(double));
    fcc_ev_response(e, s->gk, s->wz);
    m = fcc_ev_responses(e, ev, q);
    if (m > 0 && fcc_ev_hold(e, ev, m, s->wz, NULL, s->wz) < 0)
        return NAN;
    for (i = 0; i < n; i++) {
        gw += s->gk[i] * s->wz[i];
        gv += s->gk[i] * s->vm[i];
    }
    if (!(gw > 0.0)) {
        fcc_fail(e, FCC_ERR_SINGULAR, -2, 0);
        return NAN;
    }
    mup = -gv / gw;
    for (i = 0; i < m; i++)
        s->emu[i] = mup * ev->mu[i];
    for (i = 0; i < n; i++) {
        s->dv[i] = mup * s->wz[i];
        s->vp[i] = s->vm[i] + s->dv[i];
    }
    for (i = 0; i < n; i++) {                  /* B^T alpha = mu_p g - M dv + G^T emu */
        const double *Mi = e->asmb->M + (size_t)i * n;
        acc = mup * s->gk[i];
        for (l = 0; l < n; l++)
            acc -= Mi[l] * s->dv[l];
        s->r0[i] = acc;
    }
    if (m > 0)
        add_rows_t(s, ev->rg, s->emu, s->r0);
    fcc_dense_multipliers(&e->sol, s->r0, s->alpha, s->w);
    return mup;
}

/* The bounce's linearisation for parameter j (fcc_sens.h), after bounce_plastic:
 * dv_p solves M dv_p + B^T . + G^T . + g . = M dv- - dM dv - dB^T alpha - dG^T beta
 * + mu_p dg with B dv_p = -dPhi[sq, dP] at v_p, G dv_p = -dG[sq] v_p and
 * g dv_p = -dg[sq] v_p (the row g last, along its held response w); then
 * dv+ = (1 + e) dv_p - e dv- into sv. */
static int bounce_jump(fcc_engine *e, fcc_sens *s, int k, int j, const double *q,
                       const double *v, double t, double mup)
{
    fcc_events *ev = s->ev;
    int i, n = s->n, np_all = s->model->n_p;
    double *sq = fcc_sens_sq(s, j), *sv = fcc_sens_sv(s, j);
    const double *dPj = s->dP + (size_t)j * np_all;
    double rest = ev->spec->restitution[k], gw = 0.0, gx = 0.0, dgv = 0.0, delta;
    fcc_sens_sweep(e, s, q, s->vp, s->zero, s->zero, sq, s->zero, dPj);
    memcpy(s->r0, s->rhs, (size_t)n * sizeof(double));
    fcc_sens_sweep(e, s, q, s->vp, s->dv, s->alpha, sq, s->zero, dPj);
    event_gradient_dir(s, k, q, v, t, sq);
    for (i = 0; i < n; i++)
        s->rhs[i] += mup * s->dgk[i] - s->r0[i];
    if (ev->n_used > 0) {
        jacobian_dir(s, q, sq);
        add_rows_t(s, s->dG, s->emu, s->rhs);
    }
    fcc_solve_constrained(e, s->rhs, sv, s->phi, s->x);
    if (ev->n_used > 0) {
        rows_target(s, s->dG, s->vp, NULL);
        if (fcc_ev_hold(e, ev, ev->n_used, s->x, s->target, s->x) < 0)
            return -1;
    }
    for (i = 0; i < n; i++) {
        gw += s->gk[i] * s->wz[i];
        gx += s->gk[i] * s->x[i];
        dgv += s->dgk[i] * s->vp[i];
    }
    delta = (-dgv - gx) / gw;
    for (i = 0; i < n; i++)
        sv[i] = (1.0 + rest) * (s->x[i] + delta * s->wz[i]) - rest * sv[i];
    return 0;
}

int fcc_sens_event_after(fcc_engine *e, fcc_sens *s, int k, int rc, const double *q,
                         const double *v, double t)
{
    fcc_events *ev = s->ev;
    const fcc_event_spec *c = ev->spec;
    int i, j, n = s->n, act = k < c->ne ? c->action[k] : FCC_ACT_UNLOCK;  /* release */
    double *sq, *sv, *plus = s->am;
    long row = ev->n_log - 1;
    if (rc == 0 && row >= 0 && row < s->cap && s->tout != NULL)
        for (j = 0; j < s->np; j++)
            s->tout[(size_t)row * s->np + j] = s->tau[j];
    if (rc == 0 && act == FCC_ACT_STOP)
        return 0;                              /* the last record: the total derivative */
    if (rc == 0 && act == FCC_ACT_BOUNCE && memcmp(v, s->vm, (size_t)n * sizeof(double)) == 0)
        act = FCC_ACT_LOG;                     /* the Zeno guard without a row: no jump */
    else if (rc == 0 && act == FCC_ACT_BOUNCE && ev->rested[k])
        act = FCC_ACT_LOCK;                    /* it rests: its row is locked */
    if (rc == 0 && act == FCC_ACT_BOUNCE) {
        double mup;
        if (accelerations(e, s, q, v, t, s->ap) < 0)
            return -1;
        mup = bounce_plastic(e, s, k, q, v, t);
        if (isnan(mup))
            return -1;
        for (j = 0; j < s->np; j++)
            if (bounce_jump(e, s, k, j, q, v, t, mup) < 0)
                return -1;
        plus = s->ap;
    } else if (rc == 0 && act == FCC_ACT_LOCK) {
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
        return fcc_fail(e, FCC_ERR_ARGUMENT, 0, 0);   /* no other action */
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
