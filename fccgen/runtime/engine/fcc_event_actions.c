/* What an event does: lock, unlock, bounce, rest, release, stop, log; and the
 * decision which active rows enter the solves.
 *
 * Impacts (M-orthogonal, consistent with B v = 0 and the active rows):
 * - lock (plastic): v+ = v- + Z mu, (G Z) mu = -G v-; the kinetic energy lost is
 *   (v- - v+)^T M (v- - v+) / 2.
 * - bounce (Newton, restitution e): along z = the response to ds/dq (with the active
 *   rows' responses projected out), v+ = v- + mu z, mu = -(1 + e) s'- / (ds/dq . z),
 *   so that s'+ = -e s'-. A bounce slower than v_rest, or the (max_per_step + 1)-th
 *   event of one step (Zeno), rests: its joint row is locked instead.
 * - release: a resting contact lets go when its row's multiplier turns tensile (the
 *   contact would have to pull): the release function of a resting bounce is that
 *   multiplier times the sign that makes it positive when it pulls, watched and
 *   located like an event function (fcc_ev_watch).
 *
 * Rank. The rows that enter the solves (ev->used) are decided at every switch by the
 * rule that decides B's rank at the start of a run (fccgen/rank.py): the SVD gap test
 * on the row-scaled [B; G_active], each active row kept when it raises the rank
 * (sigma_r > decide_tol sigma_1). A lock whose rows follow from B and the rows already
 * locked is held (its row error is reported) but adds no constraint: the degrees of
 * freedom after a switch are n - rank(B) - (the used rows).
 *
 * The sparse path decides without an SVD (and without LAPACK): each active row i, in
 * order, is used when the mobility it keeps once B and the rows used before it hold,
 * the pivot p_i = G_i z_i - y^T y of the rows' Schur complement G Z (z_i the response
 * to G_i under B, L y = G_U z_i with L the Cholesky factor of G_U Z_U over the rows U
 * used so far), is above PIVOT_TOL |G_i|^2 / m_ref (m_ref the largest diagonal entry of
 * M). That is the rows' own system, which the switch needs anyway: nr responses, each
 * one refinement with the factorisation held, instead of an SVD of the whole
 * (m + nr) x n Jacobian. The number p_i m_ref / |G_i|^2 is about the squared sine of
 * the angle between G_i and the rows before it, in M's metric (times a mass ratio at
 * most 1): exactly dependent rows leave rounding of the refinement (measured 3e-17:
 * the four-bar's rocker hinge locked after its crank), independent ones keep their
 * geometry (measured 1e-3 at the scissor boom's latch, 0.02 .. 26 on the four-bar and
 * the solar array): PIVOT_TOL sits seven decades from both. sqrt(p_i m_ref / |G_i|^2)
 * is logged as the row's sigma when it falls in the uncertain band.
 * The degrees of freedom: n - (B's rank decided at the run's start, or raised by the
 * rank watch) - (the used rows).
 */
#include <math.h>
#include <string.h>

#include "fcc_events.h"

/* ev->aug = [B; G] at q, each row divided as by fccgen.rank.row_scales: by its
 * length, B's rows by no less than row_floor times the longest row of their element
 * (consecutive rows with one row_group), G's rows each alone. */
static void scaled_rows(fcc_engine *e, fcc_events *ev, const double *q)
{
    const fcc_event_spec *c = ev->spec;
    int i, j, k, n = c->n, rows = ev->m + c->nr;
    double norm, largest;
    double *w = ev->sig + rows;                   /* rows numbers of work after sig */
    const int *group = e->model->row_group;
    fcc_assemble(e->asmb, q, NULL, FCC_ASM_B);
    fcc_ev_gradients(ev, q);
    memcpy(ev->aug, e->asmb->B, (size_t)ev->m * n * sizeof(double));
    memcpy(ev->aug + ev->m * n, ev->rg, (size_t)c->nr * n * sizeof(double));
    for (k = 0; k < rows; k++) {
        norm = 0.0;
        for (i = 0; i < n; i++)
            norm += ev->aug[k * n + i] * ev->aug[k * n + i];
        w[k] = sqrt(norm);
    }
    k = 0;
    while (k < ev->m) {
        j = k;
        largest = 0.0;
        while (j < ev->m && group[j] == group[k]) {
            largest = w[j] > largest ? w[j] : largest;
            j++;
        }
        for (i = k; i < j; i++)
            if (w[i] < e->set.row_floor * largest)
                w[i] = e->set.row_floor * largest;
        k = j;
    }
    for (k = 0; k < rows; k++) {
        norm = w[k] > 0.0 ? 1.0 / w[k] : 1.0;
        for (i = 0; i < n; i++)
            ev->aug[k * n + i] *= norm;
    }
}

/* The number of singular values of the first rows rows of ev->aug above
 * decide_tol sigma_1 (-1: LAPACK failed); the singular values are left in ev->sig. */
static int svd_count(fcc_engine *e, fcc_events *ev, int rows)
{
    int n = ev->spec->n, info = 0, one = 1, kmax = n < rows ? n : rows, rank = 0;
    double dummy = 0.0;
    char N = 'N';
    if (kmax == 0)
        return 0;
    memcpy(ev->svm, ev->aug, (size_t)rows * n * sizeof(double));
    e->lapack->dgesvd(&N, &N, &n, &rows, ev->svm, &n, ev->sig, &dummy, &one, &dummy,
                      &one, ev->svw, &ev->lsvw, &info);
    if (info != 0)
        return -1;
    if (!(ev->sig[0] > 0.0))
        return 0;
    while (rank < kmax && ev->sig[rank] > e->set.decide_tol * ev->sig[0])
        rank++;
    return rank;
}

/* Note a relative singular value that decided a row, if in the uncertain band. */
static void uncertain(fcc_engine *e, fcc_events *ev, double ratio)
{
    if (e->set.ambiguous_low <= ratio && ratio <= e->set.grow_tol) {
        if (!(ev->note & FCC_NOTE_UNCERTAIN) || ratio < ev->note_sigma)
            ev->note_sigma = ratio;
        ev->note |= FCC_NOTE_UNCERTAIN;
    }
}

/* A row's pivot ratio p m_ref / |G|^2 above this: it is used (the file's docstring);
 * in [PIVOT_LOW, PIVOT_HIGH]: the decision is noted as uncertain. */
#define PIVOT_TOL 1e-10
#define PIVOT_LOW 1e-12
#define PIVOT_HIGH 1e-8

/* Row i's response at q into z: the one kept from an earlier decision at the same q,
 * else solved and kept. A response depends on q alone (M, B at q; the factorisation
 * only decides how fast the refinement meets it, and the decisions run with the
 * folded rows out): a tie of many locks at one instant (a mast's latches) needs each
 * row's response once, not once per lock: on the 200-bay mast, 200 instead of about
 * 20,000 solves. */
static void response_at(fcc_engine *e, fcc_events *ev, int i, const double *q, double *z)
{
    size_t n = (size_t)ev->spec->n;
    int slot = ev->zslot != NULL && !ev->fold_live ? ev->zslot[i] : -1;
    if (slot >= 0) {
        if (!ev->zc_valid || memcmp(ev->zq, q, n * sizeof(double)) != 0) {
            memcpy(ev->zq, q, n * sizeof(double));
            memset(ev->zc_ok, 0, (size_t)ev->nzc * sizeof(int));
            ev->zc_valid = 1;
        }
        if (ev->zc_ok[slot]) {
            memcpy(z, ev->zc + (size_t)slot * n, n * sizeof(double));
            return;
        }
    }
    fcc_ev_row_response(e, ev, i, z);
    ev->n_switch_solves++;
    if (slot >= 0) {
        memcpy(ev->zc + (size_t)slot * n, z, n * sizeof(double));
        ev->zc_ok[slot] = 1;
    }
}

/* The sparse path's decision (the file's docstring): ev->used, ev->n_used, and the
 * responses of the used rows in ev->z (the factorisation must be the one at q). */
static int decide_pivots(fcc_engine *e, fcc_events *ev, const double *q)
{
    const fcc_event_spec *c = ev->spec;
    int i, j, b, k = 0, n = c->n, nr = c->nr;
    double *L = ev->gz, *y = ev->mu, *z;
    const double *g;
    double d, gg, p, acc, ratio, mref = e->sp.mref > 0.0 ? e->sp.mref : 1.0;
    fcc_ev_gradients(ev, q);
    ev->n_used = 0;
    for (i = 0; i < nr; i++) {
        ev->used[i] = 0;
        if (!ev->active[i])
            continue;
        g = ev->rg + i * n;
        z = ev->z + k * n;
        response_at(e, ev, i, q, z);
        d = 0.0;
        gg = 0.0;
        for (j = 0; j < n; j++) {
            d += g[j] * z[j];
            gg += g[j] * g[j];
        }
        if (!isfinite(d))
            return fcc_fail(e, FCC_ERR_NONFINITE_RESULT, 0, 0);
        p = d;
        for (b = 0; b < k; b++) {              /* G_i z_b = G_b z_i: M's inverse on */
            acc = 0.0;                          /* the constraints is symmetric */
            for (j = 0; j < n; j++)
                acc += g[j] * ev->z[b * n + j];
            for (j = 0; j < b; j++)
                acc -= L[b * nr + j] * y[j];
            y[b] = acc / L[b * nr + b];
            p -= y[b] * y[b];
        }
        ratio = gg > 0.0 ? p * mref / gg : 0.0;
        if (PIVOT_LOW <= ratio && ratio <= PIVOT_HIGH) {
            if (!(ev->note & FCC_NOTE_UNCERTAIN) || sqrt(ratio) < ev->note_sigma)
                ev->note_sigma = sqrt(ratio);
            ev->note |= FCC_NOTE_UNCERTAIN;
        }
        if (ratio > PIVOT_TOL) {
            for (b = 0; b < k; b++)
                L[k * nr + b] = y[b];
            L[k * nr + k] = sqrt(p);
            ev->used[i] = 1;
            ev->n_used++;
            k++;
        }
    }
    return 0;
}

int fcc_ev_decide(fcc_engine *e, fcc_events *ev, const double *q)
{
    /* Decide which active rows enter the solves (ev->used) at q, by the start's rank
     * rule on the row-scaled [B; G_active]: each active row, in order, is used when it
     * raises the rank by the SVD gap test. The singular value that decided a row (the
     * new last kept one, or the first dropped one) inside the uncertain band sets
     * FCC_NOTE_UNCERTAIN. Without the rank work (no engine at the reset) every active
     * row is used. The sparse path decides by the pivots of G Z instead
     * (decide_pivots). */
    const fcc_event_spec *c = ev->spec;
    int i, rows, rank, r, n = c->n;
    if (e->sparse)
        return decide_pivots(e, ev, q);
    ev->n_used = 0;
    if (ev->aug == NULL) {
        for (i = 0; i < c->nr; i++) {
            ev->used[i] = ev->active[i];
            ev->n_used += ev->used[i];
        }
        return 0;
    }
    scaled_rows(e, ev, q);
    rows = ev->m;
    rank = svd_count(e, ev, rows);
    if (rank < 0)
        return fcc_fail(e, FCC_ERR_SINGULAR, -3, 0);
    for (i = 0; i < c->nr; i++) {
        ev->used[i] = 0;
        if (!ev->active[i])
            continue;
        if (rows != ev->m + i)                 /* the candidate row after the kept ones */
            memcpy(ev->aug + rows * n, ev->aug + (ev->m + i) * n,
                   (size_t)n * sizeof(double));
        r = svd_count(e, ev, rows + 1);
        if (r < 0)
            return fcc_fail(e, FCC_ERR_SINGULAR, -3, 0);
        if (r > rank) {
            uncertain(e, ev, ev->sig[r - 1] / ev->sig[0]);
            ev->used[i] = 1;
            ev->n_used++;
            rows++;
            rank = r;
        } else if (rank < (n < rows + 1 ? n : rows + 1) && ev->sig[0] > 0.0) {
            uncertain(e, ev, ev->sig[rank] / ev->sig[0]);
        }
    }
    return 0;
}

/* Activate event k's joint rows at their present values; plastic impact. */
static int lock_rows(fcc_engine *e, fcc_events *ev, int k, double *q, double *v,
                     double *impulse)
{
    const fcc_event_spec *c = ev->spec;
    int m, i;
    double norm = 0.0;
    c->tab->quantity_values(q, NULL, 0.0, ev->p, ev->r);
    fcc_ev_set_rows(ev, k, 1);
    if (fcc_ev_decide(e, ev, q) < 0)
        return -1;
    if ((c->row[k] >= 0 && !ev->used[c->row[k]])
            || (c->row2[k] >= 0 && !ev->used[c->row2[k]]))
        ev->note |= FCC_NOTE_REDUNDANT;
    /* the sparse decision left the used rows' responses at q in ev->z */
    m = e->sparse ? ev->n_used : fcc_ev_responses(e, ev, q);
    if (fcc_ev_hold(e, ev, m, v, NULL, v) < 0)
        return -1;
    for (i = 0; i < m; i++)
        norm += ev->mu[i] * ev->mu[i];
    *impulse = sqrt(norm);
    return 0;
}

/* Newton's law s'+ = -e s'- along the constrained response to ds_k/dq. */
static int bounce(fcc_engine *e, fcc_events *ev, int k, double *q, double *v, double t,
                  double *impulse, double *speed)
{
    const fcc_event_spec *c = ev->spec;
    int j, m, n = c->n;
    double *g = ev->sg + k * n;
    double *w = ev->s1 + 2 * c->ne;               /* n numbers of work after s1 */
    double sd = 0.0, gz = 0.0, mu;
    c->tab->event_gradients(q, v, t, ev->p, ev->sg);
    for (j = 0; j < n; j++)
        sd += g[j] * v[j];
    *speed = sd;
    fcc_ev_response(e, g, w);
    m = fcc_ev_responses(e, ev, q);
    if (m > 0 && fcc_ev_hold(e, ev, m, w, NULL, w) < 0)
        return -1;
    for (j = 0; j < n; j++)
        gz += g[j] * w[j];
    if (!(gz > 0.0))
        return fcc_fail(e, FCC_ERR_SINGULAR, -2, 0);
    mu = -(1.0 + c->restitution[k]) * sd / gz;
    for (j = 0; j < n; j++)
        v[j] += mu * w[j];
    *impulse = mu;
    return 0;
}

/* ds_k/dt = ds_k/dq . v (event functions of q and t only). */
static double rate(fcc_events *ev, int k, const double *q, const double *v, double t)
{
    const fcc_event_spec *c = ev->spec;
    int j;
    double sd = 0.0;
    c->tab->event_gradients(q, v, t, ev->p, ev->sg);
    for (j = 0; j < c->n; j++)
        sd += ev->sg[k * c->n + j] * v[j];
    return sd;
}

double fcc_ev_leaving(fcc_events *ev, int k, const double *q, const double *v, double t)
{
    /* The value s_k counts as at a state just after an event on k: a bounce that
     * leaves its surface is on the side before the crossing (so that a return within
     * the same step is a new crossing), anything else where it is (a directed event
     * at its zero at least: below). After a release
     * (k = ne + j) the bounce j is put on the side before its crossing in ev->s0 (it
     * leaves its limit) and its release function is -1. */
    const fcc_event_spec *c = ev->spec;
    double sd, value;
    if (k >= c->ne) {
        if (c->direction[k - c->ne] != 0)
            ev->s0[k - c->ne] = c->direction[k - c->ne] < 0 ? 1e-300 : -1e-300;
        return -1.0;
    }
    fcc_ev_values(ev, q, v, t, ev->s1 + 2 * c->ne);
    if (c->action[k] == FCC_ACT_BOUNCE && c->direction[k] != 0) {
        sd = rate(ev, k, q, v, t);
        if (sd * c->direction[k] < 0.0)
            return c->direction[k] < 0 ? 1e-300 : -1e-300;
    }
    /* Located to event_tol past its crossing, s_k is O(rate x event_tol) there, and
     * the projections after the location move q by up to the position tolerance: that
     * can put s_k back before its crossing, and the rest of the step would find the
     * same crossing again (a log event on the sparse path, whose projections round
     * differently, did at dt 2e-3). A directed event that has just happened sits at
     * its zero, then; a new crossing needs s_k to go back before it first. */
    value = ev->s1[2 * c->ne + k];
    if (value * c->direction[k] < 0.0)
        return 0.0;
    return value;
}

/* Mark bounce k as resting on its row (locked, ev->z its used rows' responses) and
 * keep the sign that makes its release function positive when the row's multiplier
 * pulls: d sign(ds_k/dq . z_row), d the event's direction (or the sign of the approach
 * rate for either), since the row's multiplier mu moves s_k by (ds_k/dq . z_row) mu
 * and a contact pushes s_k back against d. */
static void rest_sign(fcc_events *ev, int k, const double *q, const double *v, double t,
                      double approach)
{
    const fcc_event_spec *c = ev->spec;
    int j, pos = 0, d = c->direction[k];
    double cz = 0.0;
    if (d == 0)
        d = approach < 0.0 ? -1 : 1;
    for (j = 0; j < c->row[k]; j++)
        pos += ev->used[j];
    ev->rested[k] = 1;
    ev->rel_sign[k] = 0.0;
    if (!ev->used[c->row[k]])
        return;                                /* held by other rows: never released */
    c->tab->event_gradients(q, v, t, ev->p, ev->sg);
    for (j = 0; j < c->n; j++)
        cz += ev->sg[k * c->n + j] * ev->z[pos * c->n + j];
    ev->rel_sign[k] = d * (cz > 0.0 ? 1.0 : -1.0);
}

static int apply(fcc_engine *e, fcc_events *ev, int k, double *q, double *v, double t,
                 int held);

int fcc_ev_apply(fcc_engine *e, fcc_events *ev, int k, double *q, double *v, double t)
{
    /* apply, with the folded rows out of the factor (fcc_events_fold.c: the impacts
     * and the rank decision need the engine's own responses); the next stage factors
     * with the rows folded again. On the sparse path a switch at the q of the last
     * one, with no factorisation since (the next of a tie of events at one instant:
     * an impact changes v, not q), starts from the factor that switch left, which is
     * the engine's own at q, instead of assembling and factoring the same matrix
     * again. */
    int rc, live = ev->fold_live;
    int held = e->sparse && ev->tie_valid && ev->tie_factors == e->sp.n_factor
               && ev->tie_assembled == e->sp.n_assembled
               && memcmp(ev->tie_q, q, (size_t)ev->spec->n * sizeof(double)) == 0;
    ev->fold_live = 0;
    rc = apply(e, ev, k, q, v, t, held);
    ev->fold_live = live;
    e->factor_valid = 0;
    ev->tie_valid = e->sparse && ev->tie_q != NULL && rc >= 0;
    if (ev->tie_valid) {
        memcpy(ev->tie_q, q, (size_t)ev->spec->n * sizeof(double));
        ev->tie_factors = e->sp.n_factor;
        ev->tie_assembled = e->sp.n_assembled;
    }
    if (rc == 0)
        fcc_ev_trial_switch(ev);              /* fold or Schur: measured afresh */
    return rc;
}

static int apply(fcc_engine *e, fcc_events *ev, int k, double *q, double *v, double t,
                 int held)
{
    /* Act on event k at the located state (q, v, t), in place, and log it. A bounce
     * with |s'| < v_rest, or k < 0 (the Zeno guard: -1 - k is the event), rests;
     * k >= ne releases the resting bounce k - ne. Every switch decides the used rows
     * anew (fcc_ev_decide). Returns 1 (nothing done) for a bounce that does not
     * approach its surface. */
    const fcc_event_spec *c = ev->spec;
    int act, rest = k < 0;
    double ke0, impulse = 0.0, speed = 0.0, cerr, approach = 0.0, re;
    double *rec;
    if (rest)
        k = -1 - k;
    ev->note = 0;
    ev->note_sigma = 0.0;
    if (k >= c->ne) {
        k -= c->ne;
        act = FCC_ACT_RELEASE;
    } else {
        act = c->action[k];
    }
    /* factorisation at q, B v = 0; held (the next switch of a tie): the factor the
     * last switch left at this q, and the v its impact left, which B v = 0 holds
     * already (the impact adds responses z with B z = 0) */
    if (!held && fcc_project_velocities(e, q, v, 0) < 0)
        return -1;
    ke0 = fcc_ev_kinetic(e, q, v);
    if (act == FCC_ACT_STOP) {
        ev->stop = 1;
    } else if (act == FCC_ACT_LOCK) {
        if (lock_rows(e, ev, k, q, v, &impulse) < 0)
            return -1;
    } else if (act == FCC_ACT_UNLOCK || act == FCC_ACT_RELEASE) {
        fcc_ev_set_rows(ev, k, 0);
        if (fcc_ev_decide(e, ev, q) < 0)
            return -1;
    } else if (act == FCC_ACT_BOUNCE) {
        approach = rate(ev, k, q, v, t);
        if (!rest && c->direction[k] != 0 && approach * c->direction[k] <= 0)
            return 1;                                   /* not approaching: no impact */
        if (!rest) {
            if (bounce(e, ev, k, q, v, t, &impulse, &speed) < 0)
                return -1;
            rest = fabs(speed) < c->v_rest;
            if (rest)                                   /* undo: it rests instead */
                c->tab->event_gradients(q, v, t, ev->p, ev->sg);
        }
        if (rest && c->row[k] >= 0) {
            act = FCC_ACT_REST;
            if (fcc_project_velocities(e, q, v, 0) < 0)
                return -1;
            if (lock_rows(e, ev, k, q, v, &impulse) < 0)
                return -1;
            rest_sign(ev, k, q, v, t, approach);
        }
    }
    e->factor_valid = 0;
    fcc_assemble(e->asmb, q, NULL, FCC_ASM_G);
    cerr = fcc_max_abs_g(e->asmb);
    if (c->nr) {
        re = fcc_ev_row_error(ev, q);
        if (re > cerr)
            cerr = re;
    }
    rec = ev->last;
    rec[0] = t;
    rec[1] = k;
    rec[2] = act;
    rec[3] = impulse;
    rec[4] = ke0;
    rec[5] = fcc_ev_kinetic(e, q, v);
    rec[6] = cerr;
    rec[7] = (e->sparse ? e->n - e->sol.rank_fixed : e->sol.nr) - ev->n_used;
    rec[8] = speed;
    rec[9] = ev->note;
    rec[10] = ev->note_sigma;
    if (ev->n_log < c->cap_log)
        memcpy(ev->log + ev->n_log * FCC_LOG_COLS, rec, sizeof ev->last);
    ev->n_log++;
    return 0;
}
