/* Classical RK4 with projection, and RK4 on the Baumgarte-stabilised equations: the
 * whole per-step loop (fcc_rk4.h).
 *
 * After each step (if asked): Newton position projection onto g(q) = 0, then the
 * M-orthogonal velocity projection onto B v = 0; the factorisation of the velocity
 * projection is the one the next step's first stage needs (same M and B), so it is
 * reused. Events: after each step the watched values are compared with the step's
 * start; the first that crossed is located by re-integrating partial steps from the
 * saved start (Illinois, its trials placed by the step's Hermite interpolant), acted
 * on, and the rest of the step integrated again. With on_interpolant an event
 * function's crossing is located on the interpolant itself and the state there taken
 * from it: no partial step.
 */
#include <math.h>
#include <string.h>

#include "fcc_rk4.h"

static int stage(fcc_engine *e, fcc_rk4 *r, int k, const double *q, const double *v,
                 double *a, int reuse)
{
    int rc;
    e->err_stage = k;
    r->n_rhs++;
    if (r->baumgarte) {
        rc = fcc_baumgarte(e, q, v, a, r->alpha, r->beta);
    } else {
        rc = fcc_accelerations(e, q, v, a, reuse);
        if (rc == 0 && r->ev != NULL)         /* active lock rows (events) */
            rc = fcc_ev_constrain(e, r->ev, q, v, r->t0, a);
    }
    if (rc == 0 && r->sens != NULL)           /* the sensitivities' stage (fcc_sens.h) */
        rc = fcc_sens_rk4_stage(e, r->sens, k, q, v, a);
    if (rc == 0 && r->pw != NULL)             /* the stage's power (fcc_work.h) */
        r->p[k - 1] = fcc_stage_power(e, r->pw, q, v, a);
    return rc;
}

/* One classical RK4 step of (q' = v, v' = a(t, q, v)) of size h from t, in place;
 * leaves the time at t + h. */
static int step(fcc_engine *e, fcc_rk4 *r, double t, double h)
{
    int i, n = e->n;
    double h2 = 0.5 * h, h6 = h / 6.0, w0 = r->w;
    if (r->sens != NULL)
        fcc_sens_begin_step(r->sens, h);
    fcc_put_time(e->asmb, t);
    if (stage(e, r, 1, r->q, r->v, r->a1, e->factor_valid) < 0) return -1;
    for (i = 0; i < n; i++) {
        r->qs[i] = r->q[i] + h2 * r->v[i];
        r->v2[i] = r->v[i] + h2 * r->a1[i];
    }
    fcc_put_time(e->asmb, t + h2);
    if (stage(e, r, 2, r->qs, r->v2, r->a2, 0) < 0) return -1;
    for (i = 0; i < n; i++) {
        r->qs[i] = r->q[i] + h2 * r->v2[i];
        r->v3[i] = r->v[i] + h2 * r->a2[i];
    }
    if (stage(e, r, 3, r->qs, r->v3, r->a3, 0) < 0) return -1;
    for (i = 0; i < n; i++) {
        r->qs[i] = r->q[i] + h * r->v3[i];
        r->v4[i] = r->v[i] + h * r->a3[i];
    }
    fcc_put_time(e->asmb, t + h);
    if (stage(e, r, 4, r->qs, r->v4, r->a4, 0) < 0) return -1;
    for (i = 0; i < n; i++) {
        r->q[i] += h6 * (r->v[i] + 2.0 * r->v2[i] + 2.0 * r->v3[i] + r->v4[i]);
        r->v[i] += h6 * (r->a1[i] + 2.0 * r->a2[i] + 2.0 * r->a3[i] + r->a4[i]);
    }
    if (r->pw != NULL)                        /* the work, by the step's own weights */
        r->w = w0 + h6 * (r->p[0] + 2.0 * r->p[1] + 2.0 * r->p[2] + r->p[3]);
    return 0;
}

/* Check the new state, project it (if asked) and track max |g|. Follows a step, whose
 * last stage left M, B and their factorisation at q + h v3. */
static int after_step(fcc_engine *e, fcc_rk4 *r)
{
    int rc, it = 0;
    double cerr;
    if (!(fcc_finite(r->q, e->n) && fcc_finite(r->v, e->n))) {
        e->err_where = FCC_AT_STEP;
        return fcc_fail(e, FCC_ERR_NONFINITE_INPUT, 0, !fcc_finite(r->q, e->n) ? 1 : 2);
    }
    if (fcc_diverged(e, r->q, r->q_bound) || fcc_diverged(e, r->v, r->v_bound)) {
        e->err_where = FCC_AT_STEP;
        return fcc_fail(e, FCC_ERR_DIVERGED, 0, e->err_bound == r->q_bound ? 1 : 2);
    }
    if (r->project) {
        e->err_where = FCC_AT_POSITIONS;
        rc = fcc_project_positions(e, r->q, &it, 1);   /* M, B, factor held: stage 4's */
        if (rc < 0)
            return -1;
        r->failures += rc;
        r->newton_total += it;
        if (it > r->newton_max)
            r->newton_max = it;
        cerr = fcc_max_abs_g(e->asmb);          /* g is left assembled at the final q */
        e->err_where = FCC_AT_VELOCITIES;
        if (fcc_project_velocities(e, r->q, r->v, e->b_fresh) < 0)
            return -1;
        if (r->sens != NULL && fcc_sens_project(e, r->sens, r->q, r->v) < 0)
            return -1;
        if (r->ev != NULL && fcc_ev_correct(e, r->ev, r->q, r->v) < 0)
            return -1;
    } else {
        fcc_assemble(e->asmb, r->q, NULL, FCC_ASM_G);
        cerr = fcc_max_abs_g(e->asmb);
    }
    if (!(cerr <= r->max_cerr))
        r->max_cerr = cerr;
    return 0;
}

void fcc_rk4_record(fcc_engine *e, fcc_rk4 *r, double t)
{
    double cerr;
    r->out.t[r->n_out] = t;
    cerr = fcc_write_record(e, &r->out, r->n_out, r->q, r->v);
    if (r->w_out != NULL)
        r->w_out[r->n_out] = r->w;
    if (r->sens != NULL)
        fcc_sens_record(r->sens, r->n_out);
    if (!(cerr <= r->max_cerr))
        r->max_cerr = cerr;
    r->n_out++;
}

/* The state at t0 + tau by one step of size tau from the saved step start (a
 * re-integrated partial step), into r->q, r->v. */
static int state_at(fcc_engine *e, fcc_rk4 *r, double t0, double tau)
{
    memcpy(r->q, r->saved, (size_t)e->n * sizeof(double));
    memcpy(r->v, r->saved + e->n, (size_t)e->n * sizeof(double));
    r->w = r->wsave;
    if (r->sens != NULL)                  /* the sensitivities at the step start */
        fcc_sens_restore(r->sens);
    e->factor_valid = 0;
    r->t0 = t0;
    return step(e, r, t0, tau);
}

/* Illinois (modified regula falsi, fcc_ev_bracket) on tau -> s_k(state(t0 + tau))
 * over [0, h], where s_k crosses between the saved start (ev->s0) and the step's end
 * (ev->s1): the bracket [a, b] always holds the crossing; stops when b - a <= tol.
 * With the step's interpolant ip (NULL: none) the trials of an event function go
 * beside its crossing on the interpolant, offset by the last trial's difference
 * (fcc_ev_guess, fcc_ev_guided_trial): two partial steps where Illinois takes five
 * to eight; at most 8 such, then Illinois. *tau: b, the earliest time found past the
 * crossing; r->trial_tau: the time of the state left in r->q, r->v. */
static int locate(fcc_engine *e, fcc_rk4 *r, int k, double t0, double h,
                  const fcc_interp *ip, double *tau)
{
    fcc_events *ev = r->ev;
    int ne = ev->spec->ne, guided = 0;
    fcc_bracket br;
    fcc_sens *sens = r->sens;             /* trials carry no sensitivities */
    double c, fc, g = 0.0;
    int rc, have = 0;
    fcc_ev_bracket(ev, k, &br, h);
    memcpy(ev->s_left, ev->s0, 2 * (size_t)ne * sizeof(double));
    if (ip != NULL && k < ne)
        have = fcc_ev_guess(ev, k, ip, &br, 0.0, &g);
    while (fcc_ev_bracket_open(ev, &br, 1.0)) {
        have = have && guided++ < 8;
        c = have ? fcc_ev_guided_trial(ev, &br, g, 1.0) : fcc_ev_bracket_trial(&br);
        r->sens = NULL;
        rc = state_at(e, r, t0, c);
        r->sens = sens;
        r->trial_tau = c;
        if (rc < 0)
            return -1;
        if (fcc_ev_watch(e, ev, r->q, r->v, t0 + c, ev->s1 + 2 * ne) < 0)  /* work */
            return -1;
        fc = ev->s1[2 * ne + k];
        fcc_ev_bracket_update(ev, k, &br, c, fc);
        if (br.a == c)                    /* every value at the bracket's left end */
            memcpy(ev->s_left, ev->s1 + 2 * ne, 2 * (size_t)ne * sizeof(double));
        if (have && fcc_ev_bracket_open(ev, &br, 1.0)) {   /* the offset at c */
            fc -= fcc_ev_interp_value(ev, k, ip, c);
            have = fcc_ev_guess(ev, k, ip, &br, fc, &g);
        }
    }
    *tau = br.b;
    return 0;
}

/* The interpolant of the step just taken from the saved start to t0 + h (r->q, r->v
 * at its end, r->a1 and r->a4 its first and last stages' accelerations), copied into
 * r->dense, or NULL when the run gave no room for it. */
static const fcc_interp *interpolant(fcc_engine *e, fcc_rk4 *r, double t0, double h,
                                     fcc_interp *ip)
{
    int n = e->n;
    double *d = r->dense;
    if (d == NULL)
        return NULL;
    memcpy(d, r->q, (size_t)n * sizeof(double));
    memcpy(d + n, r->v, (size_t)n * sizeof(double));
    memcpy(d + 2 * n, r->a1, (size_t)n * sizeof(double));
    memcpy(d + 3 * n, r->a4, (size_t)n * sizeof(double));
    ip->n = n;
    ip->t0 = t0;
    ip->h = h;
    ip->scale = 1.0;
    ip->q0 = r->saved;
    ip->v0 = r->saved + n;
    ip->q1 = d;
    ip->v1 = d + n;
    ip->a0 = d + 2 * n;
    ip->a1 = d + 3 * n;
    ip->q = d + 4 * n;
    ip->v = d + 5 * n;
    return ip;
}

/* The interpolant's end acceleration, evaluated at the step's end state (r->q, r->v
 * at t1, projected) in place of the last stage's approximation: the velocities'
 * cubic is then of the step's order, O(h^4), and the positions' quintic O(h^6) (with
 * RK4's last stage, O(h^2) off at the end, they are O(h^3) and O(h^4)). Its stage
 * power is the work's rate there. */
static int end_acceleration(fcc_engine *e, fcc_rk4 *r, double t1)
{
    fcc_put_time(e->asmb, t1);
    return stage(e, r, 4, r->q, r->v, r->dense + 3 * e->n, 0);
}

/* The state at t0 + tau on the step's interpolant ip into r->q, r->v (the located
 * time of an event found on it), and the work there by the cubic in the work and its
 * rates at the ends. The caller projects it (after_step). */
static void interpolated_state(fcc_engine *e, fcc_rk4 *r, const fcc_interp *ip,
                               double tau, const double *work)
{
    double h = ip->h, th = tau / h, t2 = th * th, t3 = t2 * th;
    fcc_ev_interp_state(ip, tau);
    memcpy(r->q, ip->q, (size_t)e->n * sizeof(double));
    memcpy(r->v, ip->v, (size_t)e->n * sizeof(double));
    if (r->pw != NULL)        /* work: W and its rate at the start, then at the end */
        r->w = (1.0 - 3.0 * t2 + 2.0 * t3) * work[0] + h * (th - 2.0 * t2 + t3) * work[1]
             + (3.0 * t2 - 2.0 * t3) * work[2] + h * (t3 - t2) * work[3];
    r->trial_tau = tau;
    e->factor_valid = 0;
}

/* r->q, r->v hold the state at the located time best, so it need not be integrated
 * again: the last trial was at best, no sensitivities run (trials carry none), and no
 * watch solved accelerations after it (a resting bounce's release function: that
 * solve leaves the factorisation the projection takes at another point). */
static int at_last_trial(fcc_rk4 *r, double best)
{
    fcc_events *ev = r->ev;
    int k;
    if (r->sens != NULL || r->trial_tau != best)
        return 0;
    for (k = 0; k < ev->spec->ne; k++)
        if (fcc_ev_rests(ev, k) && ev->rel_sign[k] != 0.0)
            return 0;
    return 1;
}

/* Act on event k (-1 - k: rest it, the Zeno guard) at the located state, with the
 * sensitivities' jump when they run; fcc_ev_apply's return. */
static int act(fcc_engine *e, fcc_rk4 *r, int k, double t)
{
    int j = k < 0 ? -1 - k : k, rc;
    if (r->sens != NULL && fcc_sens_event_before(e, r->sens, j, r->q, r->v, t) < 0)
        return -1;
    rc = fcc_ev_apply(e, r->ev, k, r->q, r->v, t);
    if (rc < 0)
        return -1;
    if (r->sens != NULL && fcc_sens_event_after(e, r->sens, j, rc, r->q, r->v, t) < 0)
        return -1;
    return rc;
}

/* After a step from t0 of size h (state projected): find the first event that
 * crossed, locate it, act, and integrate the rest of the step again; repeat (at most
 * 4 max_per_step times). ev->s0 holds the event values at the step's start. */
static int events(fcc_engine *e, fcc_rk4 *r, double t0, double h)
{
    fcc_events *ev = r->ev;
    int ne = ev->spec->ne, max_per_step = ev->spec->max_per_step;
    int k, j, first, rc, count = 0, loops = 0, on_ip, found, from_ip;
    double tau, best, work[4] = {0.0, 0.0, 0.0, 0.0};
    fcc_interp interp;
    const fcc_interp *ip;
    for (;;) {
        if (fcc_ev_watch(e, ev, r->q, r->v, t0 + h, ev->s1) < 0)
            return -1;
        k = fcc_ev_crossed(ev, ev->s0, ev->s1);
        loops++;
        if (k < 0 || loops > 4 * max_per_step) {      /* none (more) in this step */
            fcc_ev_refresh(ev, r->q);
            return fcc_ev_watch(e, ev, r->q, r->v, t0 + h, ev->s0);
        }
        best = h;
        first = k;
        fcc_ev_mark_crossed(ev);
        ip = interpolant(e, r, t0, h, &interp);
        /* an event function crossed (k < ne: release functions take partial steps) */
        on_ip = ip != NULL && r->on_interpolant && r->sens == NULL && k < ne;
        if (on_ip) {
            work[0] = r->wsave;              /* before partial steps overwrite them */
            work[1] = r->p[0];
            work[2] = r->w;
            if (end_acceleration(e, r, t0 + h) < 0)
                return -1;
            work[3] = r->p[3];
        }
        r->trial_tau = -1.0;
        from_ip = 0;
        for (j = k; j < 2 * ne; j++) {           /* the earliest of those that crossed */
            if (j > k && !fcc_ev_watched(ev, j, ev->s0, ev->s1))   /* a held lock */
                continue;
            /* one that had not crossed by the left end of the earliest bracket
             * located crosses within it (a tie: acted at its instant, below) or
             * after it: no location needed (a mast's 200 latches crossing together
             * were located 200 times) */
            if (j > k && !from_ip && !fcc_ev_watched(ev, j, ev->s0, ev->s_left + 2 * ne))
                continue;
            found = on_ip && j < ne && fcc_ev_interp_locate(ev, j, ip, &tau);
            if (!found && locate(e, r, j, t0, h, ip, &tau) < 0)
                return -1;
            if (tau < best || j == k) {
                best = tau;
                first = j;
                from_ip = found;
                if (!found)
                    memcpy(ev->s_left + 2 * ne, ev->s_left,
                           2 * (size_t)ne * sizeof(double));
            }
        }
        if (from_ip)
            interpolated_state(e, r, ip, best, work);
        else if (!at_last_trial(r, best) && state_at(e, r, t0, best) < 0)
            return -1;
        if (after_step(e, r) < 0)
            return -1;
        e->err_t = t0 + best;
        fcc_ev_keep_start(ev, first);
        for (j = first; j >= 0; j = fcc_ev_next_tie(ev)) {
            count++;                         /* first, then the ties of its instant */
            rc = act(e, r, count <= max_per_step ? j : -1 - j, t0 + best);
            if (rc < 0)
                return -1;
            count -= rc;                     /* an impact that was none does not count */
            if (ev->stop) {
                r->stopped = 1;
                r->t_stop = t0 + best;
                return 0;
            }
            if (j == first) {
                fcc_ev_refresh(ev, r->q);
                if (fcc_ev_watch(e, ev, r->q, r->v, t0 + best, ev->s0) < 0)
                    return -1;
                ev->s0[first] = fcc_ev_leaving(ev, first, r->q, r->v, t0 + best);
            }
        }
        if (fcc_ev_settle(e, ev, r->q, r->v, t0 + best, first, 1) < 0)
            return -1;
        t0 = t0 + best;
        h = h - best;
        memcpy(r->saved, r->q, (size_t)e->n * sizeof(double));
        memcpy(r->saved + e->n, r->v, (size_t)e->n * sizeof(double));
        r->wsave = r->w;
        if (r->sens != NULL)
            fcc_sens_save(r->sens);
        if (h <= 0.0)
            return 0;
        r->t0 = t0;
        if (step(e, r, t0, h) < 0 || after_step(e, r) < 0)
            return -1;
    }
}

int fcc_rk4_advance(fcc_engine *e, fcc_rk4 *r)
{
    double t, h;
    while (r->k < r->n_steps) {
        t = r->k * r->dt;
        h = r->k < r->n_steps - 1 ? r->dt : r->t_end - t;
        e->err_where = FCC_AT_STAGE;
        e->err_t = t;
        e->err_h = h;
        if (r->ev != NULL) {
            memcpy(r->saved, r->q, (size_t)e->n * sizeof(double));
            memcpy(r->saved + e->n, r->v, (size_t)e->n * sizeof(double));
            r->wsave = r->w;
            if (r->sens != NULL)
                fcc_sens_save(r->sens);
        }
        r->t0 = t;
        if (step(e, r, t, h) < 0)
            return FCC_RUN_ERROR;
        r->k++;
        t = r->k < r->n_steps ? r->k * r->dt : r->t_end;
        e->err_t = t;
        if (after_step(e, r) < 0)
            return FCC_RUN_ERROR;
        if (r->ev != NULL) {
            if (events(e, r, t - h, h) < 0)
                return FCC_RUN_ERROR;
            if (r->stopped) {
                fcc_rk4_record(e, r, r->t_stop);
                return FCC_RUN_DONE;
            }
        }
        if (r->k % r->every == 0 || r->k == r->n_steps)
            fcc_rk4_record(e, r, t);
        if (r->k < r->n_steps && r->pause != NULL && r->pause(r->pause_ctx))
            return FCC_RUN_PAUSE;
    }
    return FCC_RUN_DONE;
}

int fcc_rk4_start(fcc_rk4 *r, fcc_engine *e, const double *q0, const double *v0)
{
    int i, n = e->n;
    double big = 0.0;
    r->q = e->stages;
    r->v = e->stages + n;
    r->qs = e->stages + 2 * n;
    r->v2 = e->stages + 3 * n;
    r->v3 = e->stages + 4 * n;
    r->v4 = e->stages + 5 * n;
    r->a1 = e->stages + 6 * n;
    r->a2 = e->stages + 7 * n;
    r->a3 = e->stages + 8 * n;
    r->a4 = e->stages + 9 * n;
    memcpy(r->q, q0, (size_t)n * sizeof(double));
    memcpy(r->v, v0, (size_t)n * sizeof(double));
    r->k = r->n_out = r->n_rhs = r->failures = r->newton_total = 0;
    r->newton_max = 0;
    r->max_cerr = 0.0;
    r->t0 = 0.0;
    r->stopped = 0;
    r->t_stop = r->t_end;
    r->w = r->wsave = 0.0;
    r->p[0] = r->p[1] = r->p[2] = r->p[3] = 0.0;
    fcc_divergence_bounds(n, q0, v0, r->t_end, r->dt, &r->q_bound, &r->v_bound);
    e->factor_valid = 0;
    e->err = FCC_OK;
    fcc_put_time(e->asmb, 0.0);
    /* A step that leaves the constraints by 1% of the model's size (an accurate one
     * leaves them by its local error, orders below) has diverged. */
    for (i = 0; i < n; i++)
        if (fabs(q0[i]) > big)
            big = fabs(q0[i]);
    e->diverge_residual = 1e-2 * (big > 1e-300 ? big : 1e-300);
    e->running = 1;
    if (r->ev != NULL)
        return fcc_ev_watch(e, r->ev, r->q, r->v, 0.0, r->ev->s0);
    return 0;
}

void fcc_run_finish(fcc_engine *e)
{
    e->running = 0;
    e->diverge_residual = INFINITY;
}
