/* Events in the engine: event functions, their location, and the switchable joint
 * rows the integrators add to every acceleration solve.
 *
 * The event kernels come from the model's generated event module (fccgen_events.h):
 * s_k(q, v, t), ds_k/dq, and the joint quantities r_j(q) (angles, slides) with their
 * Jacobian G and bias (dG/dt) v. Integrators (fcc_rk4.c, fcc_dopri5.c) locate sign
 * changes of s_k and call fcc_ev_apply (fcc_event_actions.c); they add the active rows
 * to every acceleration solve through fcc_ev_constrain and hold them after each step
 * through fcc_ev_correct.
 *
 * Switchable rows. A lock makes r_j(q) = r_j* a constraint without touching the
 * engine's own rows: with z_j = the engine's constrained response to the force G_j^T
 * (the solve x = argmin x^T M x / 2 - G_j x subject to B x = 0), the accelerations of
 * the augmented system are a + Z mu with (G Z) mu = -(G a + (dG/dt) v): the Schur
 * complement of the added rows, exact for any number of them. Switching is a flag per
 * row: nothing is regenerated or recompiled. On the sparse path, when the set-up put
 * the rows into the factorisation's pattern, a run folds them into the factor instead
 * (fcc_events_fold.c): no response per row.
 */
#include <math.h>
#include <string.h>

#include "fcc_events.h"

static void *zalloc(size_t n, size_t size)
{
    return FCC_CALLOC(n > 0 ? n : 1, size);
}

int fcc_event_spec_init(fcc_event_spec *c, const fcc_event_table *tab, int nang,
                        const int *angle_row, const int *direction, const int *action,
                        const int *row, const int *row2, const double *restitution,
                        double tol, double v_rest, int max_per_step, long cap_log)
{
    int k, ne = tab->n_events;
    memset(c, 0, sizeof(*c));
    c->tab = tab;
    c->n = tab->n_q;
    c->ne = ne;
    c->nr = tab->n_quantities;
    c->np = tab->n_p;
    c->nang = nang;
    c->tol = tol;
    c->v_rest = v_rest;
    c->max_per_step = max_per_step;
    c->cap_log = cap_log;
    c->angle_row = zalloc((size_t)nang + 1, sizeof(int));
    c->direction = zalloc((size_t)ne + 1, sizeof(int));
    c->action = zalloc((size_t)ne + 1, sizeof(int));
    c->row = zalloc((size_t)ne + 1, sizeof(int));
    c->row2 = zalloc((size_t)ne + 1, sizeof(int));
    c->restitution = zalloc((size_t)ne + 1, sizeof(double));
    if (!c->angle_row || !c->direction || !c->action || !c->row || !c->row2
            || !c->restitution) {
        fcc_event_spec_free(c);
        return FCC_ERR_MEMORY;
    }
    for (k = 0; k < nang; k++)
        c->angle_row[k] = angle_row[k];
    for (k = 0; k < ne; k++) {
        c->direction[k] = direction[k];
        c->action[k] = action[k];
        c->row[k] = row[k];
        c->row2[k] = row2[k];
        c->restitution[k] = restitution[k];
    }
    return FCC_OK;
}

void fcc_event_spec_free(fcc_event_spec *c)
{
    FCC_FREE(c->angle_row); FCC_FREE(c->direction); FCC_FREE(c->action);
    FCC_FREE(c->row); FCC_FREE(c->row2); FCC_FREE(c->restitution);
    memset(c, 0, sizeof(*c));
}

int fcc_events_init(fcc_events *ev, const fcc_event_spec *c, const double *constants)
{
    size_t n = (size_t)c->n, ne = (size_t)c->ne, nr = (size_t)c->nr;
    int j;
    memset(ev, 0, sizeof(*ev));
    ev->spec = c;
    ev->fold_trial = 1;
    ev->p = FCC_CALLOC((size_t)c->np + 1, sizeof(double));
    ev->s0 = FCC_CALLOC(2 * ne + 1, sizeof(double));
    ev->s1 = FCC_CALLOC(4 * ne + n + 1, sizeof(double));
    ev->sg = FCC_CALLOC(ne * n + 1, sizeof(double));
    ev->r = FCC_CALLOC(nr + 1, sizeof(double));
    ev->rg = FCC_CALLOC(nr * n + 1, sizeof(double));
    ev->rb = FCC_CALLOC(nr + 1, sizeof(double));
    ev->rgv = FCC_CALLOC((size_t)c->tab->n_gradient_nz + 1, sizeof(double));
    ev->fold_free = FCC_CALLOC(n + (size_t)c->tab->n_gradient_nz + 1, sizeof(int));
    ev->z = FCC_CALLOC(nr * n + 1, sizeof(double));
    ev->gz = FCC_CALLOC(nr * nr + 1, sizeof(double));
    ev->mu = FCC_CALLOC(nr + 1, sizeof(double));
    ev->held = FCC_CALLOC(2 * nr + 1, sizeof(double));
    ev->active = FCC_CALLOC(nr + 1, sizeof(int));
    ev->used = FCC_CALLOC(nr + 1, sizeof(int));
    ev->rested = FCC_CALLOC(ne + 1, sizeof(int));
    ev->tie = FCC_CALLOC(2 * ne + 1, sizeof(int));
    ev->s_prev = FCC_CALLOC(2 * ne + 1, sizeof(double));
    ev->s_left = FCC_CALLOC(4 * ne + 1, sizeof(double));
    ev->rel_sign = FCC_CALLOC(ne + 1, sizeof(double));
    ev->acc = FCC_CALLOC(n + 1, sizeof(double));
    ev->log = FCC_CALLOC((size_t)c->cap_log * FCC_LOG_COLS + 1, sizeof(double));
    if (!ev->p || !ev->s0 || !ev->s1 || !ev->sg || !ev->r || !ev->rg || !ev->rb
            || !ev->z || !ev->gz || !ev->mu || !ev->held || !ev->active || !ev->used
            || !ev->rested || !ev->rel_sign || !ev->acc || !ev->log || !ev->tie
            || !ev->s_prev || !ev->s_left || !ev->rgv || !ev->fold_free) {
        fcc_events_free(ev);
        return FCC_ERR_MEMORY;
    }
    for (j = 0; j < c->nang; j++)             /* references 0: cos 1, sin 0 */
        ev->p[3 * j + 1] = 1.0;
    for (j = 0; j < c->np - 3 * c->nang; j++)
        ev->p[3 * c->nang + j] = constants[j];
    ev->max_turn_j = -1;
    return FCC_OK;
}

void fcc_events_free(fcc_events *ev)
{
    FCC_FREE(ev->p); FCC_FREE(ev->s0); FCC_FREE(ev->s1); FCC_FREE(ev->sg);
    FCC_FREE(ev->tie); FCC_FREE(ev->s_prev); FCC_FREE(ev->s_left);
    FCC_FREE(ev->r); FCC_FREE(ev->rg); FCC_FREE(ev->rb); FCC_FREE(ev->z);
    FCC_FREE(ev->gz); FCC_FREE(ev->mu); FCC_FREE(ev->held); FCC_FREE(ev->active);
    FCC_FREE(ev->used); FCC_FREE(ev->rested); FCC_FREE(ev->rel_sign); FCC_FREE(ev->acc);
    FCC_FREE(ev->log); FCC_FREE(ev->aug); FCC_FREE(ev->svm); FCC_FREE(ev->sig);
    FCC_FREE(ev->svw); FCC_FREE(ev->mslot); FCC_FREE(ev->mang); FCC_FREE(ev->mkeep);
    FCC_FREE(ev->zlam); FCC_FREE(ev->zlam_ok); FCC_FREE(ev->rgv);
    FCC_FREE(ev->zslot); FCC_FREE(ev->zc); FCC_FREE(ev->zc_ok); FCC_FREE(ev->zq);
    FCC_FREE(ev->tie_q);
    FCC_FREE(ev->fold_from); FCC_FREE(ev->fold_free);
    memset(ev, 0, sizeof(*ev));
}

int fcc_events_rank_work(fcc_events *ev, const fcc_lapack *lapack, int m)
{
    int rows = m + ev->spec->nr, n = ev->spec->n, info = 0, one = 1, lwork = -1;
    double query = 0.0, dummy = 0.0;
    char N = 'N';
    FCC_FREE(ev->aug); FCC_FREE(ev->svm); FCC_FREE(ev->sig); FCC_FREE(ev->svw);
    ev->aug = ev->svm = ev->sig = ev->svw = NULL;
    ev->m = 0;
    if (lapack == NULL)
        return FCC_ERR_NO_LAPACK;
    if (rows > 0)
        lapack->dgesvd(&N, &N, &n, &rows, &dummy, &n, &dummy, &dummy, &one, &dummy,
                       &one, &query, &lwork, &info);
    ev->lsvw = (int)query > 5 * (n + rows) + 1 ? (int)query : 5 * (n + rows) + 1;
    ev->aug = FCC_CALLOC((size_t)rows * n + 1, sizeof(double));
    ev->svm = FCC_CALLOC((size_t)rows * n + 1, sizeof(double));
    ev->sig = FCC_CALLOC((size_t)(2 * rows + n + 1), sizeof(double));
    ev->svw = FCC_CALLOC((size_t)ev->lsvw, sizeof(double));
    if (!ev->aug || !ev->svm || !ev->sig || !ev->svw)
        return FCC_ERR_MEMORY;
    ev->m = m;
    return FCC_OK;
}

int fcc_events_sparse_work(fcc_events *ev, int m)
{
    const fcc_event_spec *c = ev->spec;
    int i, k, rows = 0, nr = c->nr;
    FCC_FREE(ev->zlam); FCC_FREE(ev->zlam_ok);
    FCC_FREE(ev->zslot); FCC_FREE(ev->zc); FCC_FREE(ev->zc_ok); FCC_FREE(ev->zq);
    FCC_FREE(ev->tie_q);
    ev->mz = 0;
    ev->tie_valid = 0;
    ev->nzc = 0;
    ev->zc_valid = 0;
    ev->zlam = FCC_CALLOC((size_t)nr * m + 1, sizeof(double));
    ev->zlam_ok = FCC_CALLOC((size_t)nr + 1, sizeof(int));
    ev->zslot = FCC_CALLOC((size_t)nr + 1, sizeof(int));
    if (!ev->zlam || !ev->zlam_ok || !ev->zslot)
        return FCC_ERR_MEMORY;
    for (i = 0; i < nr; i++)
        ev->zslot[i] = -1;
    for (k = 0; k < c->ne; k++) {             /* the rows a lock or a rest can hold */
        if (c->row[k] >= 0 && ev->zslot[c->row[k]] < 0)
            ev->zslot[c->row[k]] = rows++;
        if (c->row2[k] >= 0 && ev->zslot[c->row2[k]] < 0)
            ev->zslot[c->row2[k]] = rows++;
    }
    ev->zc = FCC_CALLOC((size_t)rows * c->n + 1, sizeof(double));
    ev->zc_ok = FCC_CALLOC((size_t)rows + 1, sizeof(int));
    ev->zq = FCC_CALLOC((size_t)c->n + 1, sizeof(double));
    ev->tie_q = FCC_CALLOC((size_t)c->n + 1, sizeof(double));
    if (!ev->zc || !ev->zc_ok || !ev->zq || !ev->tie_q)
        return FCC_ERR_MEMORY;
    ev->nzc = rows;
    ev->mz = m;
    return FCC_OK;
}

void fcc_events_reset(fcc_events *ev)
{
    const fcc_event_spec *c = ev->spec;
    int j;
    memset(ev->p, 0, 3 * (size_t)c->nang * sizeof(double));
    for (j = 0; j < c->nang; j++)
        ev->p[3 * j + 1] = 1.0;
    fcc_ev_mirror(ev);
    ev->max_turn = 0.0;
    ev->max_turn_j = -1;
    memset(ev->active, 0, (size_t)c->nr * sizeof(int));
    memset(ev->used, 0, (size_t)c->nr * sizeof(int));
    ev->n_used = 0;
    memset(ev->rested, 0, (size_t)c->ne * sizeof(int));
    if (ev->zlam_ok != NULL)
        memset(ev->zlam_ok, 0, (size_t)c->nr * sizeof(int));
    ev->zc_valid = 0;
    ev->tie_valid = 0;
    ev->n_switch_solves = 0;
    ev->n_trials = ev->n_trials_folded = 0;
    ev->n_log = 0;
    ev->stop = 0;
}

int fcc_events_mirror(fcc_events *ev, fcc_assembly *a, int n, const int *slots,
                      const int *angles)
{
    int i;
    for (i = 0; i < n; i++)
        if (!(0 <= angles[i] && angles[i] < ev->spec->nang && 0 <= slots[i]
              && slots[i] + 3 <= a->model->n_p))
            return FCC_ERR_ARGUMENT;
    FCC_FREE(ev->mslot); FCC_FREE(ev->mang); FCC_FREE(ev->mkeep);
    ev->nm = 0;
    ev->mdst = NULL;
    ev->mslot = zalloc((size_t)n + 1, sizeof(int));
    ev->mang = zalloc((size_t)n + 1, sizeof(int));
    ev->mkeep = zalloc(3 * (size_t)n + 1, sizeof(double));
    if (!ev->mslot || !ev->mang || !ev->mkeep)
        return FCC_ERR_MEMORY;
    for (i = 0; i < n; i++) {
        ev->mslot[i] = slots[i];
        ev->mang[i] = angles[i];
        memcpy(ev->mkeep + 3 * i, a->params + slots[i], 3 * sizeof(double));
    }
    ev->nm = n;
    ev->mdst = a->params;
    return FCC_OK;
}

void fcc_events_restore(fcc_events *ev)
{
    int i;
    for (i = 0; i < ev->nm; i++)
        memcpy(ev->mdst + ev->mslot[i], ev->mkeep + 3 * i, 3 * sizeof(double));
}

/* b <- A^-1 b for a k x k A (row-major, destroyed), partial pivoting; -1 if singular
 * (a pivot below 1e-13 of the largest diagonal entry). */
static int solve_small(double *A, double *b, int k)
{
    int i, j, c, piv;
    double big = 0.0, f, tmp;
    for (i = 0; i < k; i++)
        if (fabs(A[i * k + i]) > big)
            big = fabs(A[i * k + i]);
    for (c = 0; c < k; c++) {
        piv = c;
        for (i = c + 1; i < k; i++)
            if (fabs(A[i * k + c]) > fabs(A[piv * k + c]))
                piv = i;
        if (!(fabs(A[piv * k + c]) > 1e-13 * big))
            return -1;
        if (piv != c) {
            for (j = 0; j < k; j++) {
                tmp = A[c * k + j]; A[c * k + j] = A[piv * k + j]; A[piv * k + j] = tmp;
            }
            tmp = b[c]; b[c] = b[piv]; b[piv] = tmp;
        }
        for (i = c + 1; i < k; i++) {
            f = A[i * k + c] / A[c * k + c];
            for (j = c; j < k; j++)
                A[i * k + j] -= f * A[c * k + j];
            b[i] -= f * b[c];
        }
    }
    for (c = k - 1; c >= 0; c--) {
        for (j = c + 1; j < k; j++)
            b[c] -= A[c * k + j] * b[j];
        b[c] /= A[c * k + c];
    }
    return 0;
}

void fcc_ev_gradients(fcc_events *ev, const double *q)
{
    const fcc_event_table *tab = ev->spec->tab;
    int j, k, n = ev->spec->n;
    double *row;
    tab->quantity_gradient_values(q, NULL, 0.0, ev->p, ev->rgv);
    for (j = 0; j < tab->n_quantities; j++) {
        row = ev->rg + (size_t)j * n;
        for (k = tab->gradient_ptr[j]; k < tab->gradient_ptr[j + 1]; k++)
            row[tab->gradient_idx[k]] = ev->rgv[k];
    }
}

void fcc_ev_response(fcc_engine *e, const double *g, double *z)
{
    /* z = argmin z^T M z / 2 - g z subject to B z = 0, with the factorisation the
     * engine holds: the dense path's null-space solve, or the sparse path's
     * augmented-Lagrangian refinement on its LDL^T (from zero multipliers: the
     * accelerations' warm start is left as it was). */
    if (e->sparse)
        fcc_sp_solve_kkt(e, g, NULL, NULL, z, 0, 0);
    else
        fcc_dense_apply(&e->sol, g, NULL, NULL, z);
}

void fcc_ev_row_response(fcc_engine *e, fcc_events *ev, int j, double *z)
{
    /* fcc_ev_response to quantity row j's gradient (ev->rg). The sparse path starts
     * from the multipliers of that row's last response (each row's moves by O(h)
     * between stages, as the accelerations' do: two refinement steps instead of
     * three, fcc_al_refine.c "Warm start"), when fcc_events_sparse_work made room. */
    const double *g = ev->rg + j * ev->spec->n;
    if (e->sparse && ev->mz == e->m && ev->zlam != NULL)
        ev->zlam_ok[j] = fcc_sp_solve_kkt_from(e, g, z, ev->zlam + (size_t)j * e->m,
                                               ev->zlam_ok[j]);
    else
        fcc_ev_response(e, g, z);
}

int fcc_ev_responses(fcc_engine *e, fcc_events *ev, const double *q)
{
    /* Jacobian rows of the quantities at q, and z_j (rows of ev->z, used rows in
     * order) with the engine's factorisation at q; the number of used rows. */
    const fcc_event_spec *c = ev->spec;
    int j, m = 0;
    fcc_ev_gradients(ev, q);
    for (j = 0; j < c->nr; j++) {
        if (ev->used[j]) {
            fcc_ev_row_response(e, ev, j, ev->z + m * c->n);
            m++;
        }
    }
    return m;
}

int fcc_ev_multipliers(fcc_engine *e, fcc_events *ev, int m)
{
    /* mu <- (G Z)^-1 mu over the m active rows (G Z from ev->rg, ev->z). */
    const fcc_event_spec *c = ev->spec;
    int a = 0, b, i, j, n = c->n;
    double acc;
    for (i = 0; i < c->nr; i++) {
        if (!ev->used[i])
            continue;
        for (b = 0; b < m; b++) {
            acc = 0.0;
            for (j = 0; j < n; j++)
                acc += ev->rg[i * n + j] * ev->z[b * n + j];
            ev->gz[a * m + b] = acc;
        }
        a++;
    }
    if (solve_small(ev->gz, ev->mu, m) < 0)
        return fcc_fail(e, FCC_ERR_SINGULAR, -1, 0);
    return 0;
}

/* x += Z mu. */
static void add_responses(fcc_events *ev, int m, double *x)
{
    int b, j, n = ev->spec->n;
    for (b = 0; b < m; b++)
        for (j = 0; j < n; j++)
            x[j] += ev->z[b * n + j] * ev->mu[b];
}

int fcc_ev_hold(fcc_engine *e, fcc_events *ev, int m, const double *x,
                const double *target, double *y)
{
    /* y += Z mu with (G Z) mu = target - G x for the active rows (target NULL: 0). */
    const fcc_event_spec *c = ev->spec;
    int a = 0, i, j, n = c->n;
    double acc;
    for (i = 0; i < c->nr; i++) {
        if (ev->used[i]) {
            acc = 0.0;
            for (j = 0; j < n; j++)
                acc += ev->rg[i * n + j] * x[j];
            ev->mu[a] = (target != NULL ? target[a] : 0.0) - acc;
            a++;
        }
    }
    if (fcc_ev_multipliers(e, ev, m) < 0)
        return -1;
    add_responses(ev, m, y);
    return 0;
}

int fcc_ev_constrain(fcc_engine *e, fcc_events *ev, const double *q, const double *v,
                     double t, double *a)
{
    /* a <- the accelerations with the active rows added (the engine's factorisation
     * must be the one at q, as fcc_accelerations leaves it). */
    const fcc_event_spec *c = ev->spec;
    int m, i, k = 0;
    if (ev->n_used == 0 || fcc_ev_fold_constrain(e, ev))
        return 0;                             /* folded: the solve held them */
    m = fcc_ev_responses(e, ev, q);
    c->tab->quantity_bias(q, v, t, ev->p, ev->rb);
    for (i = 0; i < c->nr; i++) {
        if (ev->used[i]) {
            ev->held[c->nr + k] = -ev->rb[i];          /* target G a = -(dG/dt) v */
            k++;
        }
    }
    return fcc_ev_hold(e, ev, m, a, ev->held + c->nr, a);
}

int fcc_ev_correct(fcc_engine *e, fcc_events *ev, double *q, double *v)
{
    /* After a step's projections (factorisation at q): one Newton correction of the
     * active rows' positions, r_j(q) = held_j, then their speeds, G v = 0. */
    const fcc_event_spec *c = ev->spec;
    int m, i, k = 0;
    if (ev->n_used == 0)
        return 0;
    i = fcc_ev_fold_correct(e, ev, q);      /* folded: one solve (fold.c) */
    if (i < 0)
        return -1;
    if (i == 0) {                           /* the Schur complement's responses */
        m = fcc_ev_responses(e, ev, q);
        c->tab->quantity_values(q, NULL, 0.0, ev->p, ev->r);
        for (i = 0; i < c->nr; i++) {
            if (ev->used[i]) {
                ev->mu[k] = ev->held[i] - ev->r[i];
                k++;
            }
        }
        if (fcc_ev_multipliers(e, ev, m) < 0)
            return -1;
        add_responses(ev, m, q);
        if (fcc_ev_hold(e, ev, m, v, NULL, v) < 0)
            return -1;
        e->factor_valid = 0;               /* q moved: the next stage refactors */
    }
    fcc_ev_trial_step(e, ev);
    return 0;
}

double fcc_ev_kinetic(fcc_engine *e, const double *q, const double *v)
{
    fcc_assemble(e->asmb, q, v, FCC_ASM_E);
    return e->asmb->energy[0];
}

double fcc_ev_row_error(fcc_events *ev, const double *q)
{
    const fcc_event_spec *c = ev->spec;
    int i;
    double big = 0.0;
    c->tab->quantity_values(q, NULL, 0.0, ev->p, ev->r);
    for (i = 0; i < c->nr; i++)
        if (ev->active[i] && fabs(ev->r[i] - ev->held[i]) > big)
            big = fabs(ev->r[i] - ev->held[i]);
    return big;
}

void fcc_ev_set_rows(fcc_events *ev, int k, int flag)
{
    /* Switch event k's joint rows on (held at their present values, ev->r) or off; no
     * bounce on those rows rests any more (a rest sets its flag after). */
    const fcc_event_spec *c = ev->spec;
    int j;
    if (c->row[k] >= 0) {
        ev->active[c->row[k]] = flag;
        ev->held[c->row[k]] = ev->r[c->row[k]];
        for (j = 0; j < c->ne; j++)
            if (c->row[j] == c->row[k])
                ev->rested[j] = 0;
    }
    if (c->row2[k] >= 0) {
        ev->active[c->row2[k]] = flag;
        ev->held[c->row2[k]] = ev->r[c->row2[k]];
    }
}

int fcc_ev_watch(fcc_engine *e, fcc_events *ev, const double *q, const double *v,
                 double t, double *out)
{
    /* out[:ne] = s_k(q, v, t); out[ne + k] = the release function of bounce k while it
     * rests: rel_sign_k mu, mu the multiplier of its row in the accelerations at
     * (q, v, t) with the active rows (positive: the contact pulls), else -1. The
     * accelerations are solved only while something rests (the factorisation is left
     * at q, not valid for the integrator). */
    const fcc_event_spec *c = ev->spec;
    int k, j, pos, any_rest = 0;
    fcc_ev_values(ev, q, v, t, out);
    for (k = 0; k < c->ne; k++) {
        out[c->ne + k] = -1.0;
        if (fcc_ev_rests(ev, k) && ev->rel_sign[k] != 0.0)
            any_rest = 1;
    }
    if (!any_rest)
        return 0;
    fcc_put_time(e->asmb, t);
    if (fcc_accelerations(e, q, v, ev->acc, 0) < 0)
        return -1;
    if (fcc_ev_constrain(e, ev, q, v, t, ev->acc) < 0)
        return -1;
    e->factor_valid = 0;
    for (k = 0; k < c->ne; k++) {
        if (fcc_ev_rests(ev, k) && ev->rel_sign[k] != 0.0) {
            pos = 0;
            for (j = 0; j < c->row[k]; j++)
                pos += ev->used[j];
            out[c->ne + k] = ev->rel_sign[k] * ev->mu[pos];
        }
    }
    return 0;
}
