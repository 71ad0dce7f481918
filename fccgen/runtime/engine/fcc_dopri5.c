/* Dormand-Prince 5(4) with error control and dense output: the per-step loop
 * (fcc_dopri5.h).
 *
 * The method and its constants are those of Hairer, Norsett & Wanner, "Solving
 * Ordinary Differential Equations I" (2nd ed., 1993), section II.5 and the code
 * DOPRI5: FSAL stages, the error estimate of the embedded 4th-order solution measured
 * in the norm sqrt(mean((err_i / (atol + rtol max(|y0_i|, |y1_i|)))^2)) over
 * y = (q, v), the step factor 0.9 err^(-1/5) kept within [0.2, 10] (no growth right
 * after a rejection), and the 4th-order continuous extension for outputs at requested
 * times. Each rejection shrinks the step (to between FACMIN and 0.9 of it), until the
 * step underflows the rounding of t (FCC_RUN_UNDERFLOW): the bound on a step's work.
 *
 * With projection, every accepted step is followed by the Newton position projection
 * and the M-orthogonal velocity projection; the first stage of the next step is then
 * evaluated at the projected state (FSAL only holds without projection), reusing the
 * velocity projection's factorisation. Outputs interpolated from the dense output are
 * projected the same way.
 *
 * A caller that asks for its records one at a time (the exported API's step_to) sets
 * hold: a step that writes the last record asked for waits before its end's
 * projection, so that a record asked for next in the same step is written in the same
 * order, from the same state of the engine, as when all were asked for at the start.
 */
#include <math.h>
#include <string.h>

#include "fcc_dopri5.h"

/* Butcher tableau of DOPRI5 (Hairer, Norsett & Wanner, Table II.5.2). */
static const double C2 = 0.2, C3 = 0.3, C4 = 0.8, C5 = 8.0 / 9.0;
static const double A21 = 0.2;
static const double A31 = 3.0 / 40.0, A32 = 9.0 / 40.0;
static const double A41 = 44.0 / 45.0, A42 = -56.0 / 15.0, A43 = 32.0 / 9.0;
static const double A51 = 19372.0 / 6561.0, A52 = -25360.0 / 2187.0;
static const double A53 = 64448.0 / 6561.0, A54 = -212.0 / 729.0;
static const double A61 = 9017.0 / 3168.0, A62 = -355.0 / 33.0, A63 = 46732.0 / 5247.0;
static const double A64 = 49.0 / 176.0, A65 = -5103.0 / 18656.0;
static const double A71 = 35.0 / 384.0, A73 = 500.0 / 1113.0, A74 = 125.0 / 192.0;
static const double A75 = -2187.0 / 6784.0, A76 = 11.0 / 84.0;
/* error coefficients: 5th minus embedded 4th order weights */
static const double E1 = 71.0 / 57600.0, E3 = -71.0 / 16695.0, E4 = 71.0 / 1920.0;
static const double E5 = -17253.0 / 339200.0, E6 = 22.0 / 525.0, E7 = -1.0 / 40.0;
/* dense output (DOPRI5, CONTD5) */
static const double D1 = -12715105075.0 / 11282082432.0;
static const double D3 = 87487479700.0 / 32700410799.0;
static const double D4 = -10690763975.0 / 1880347072.0;
static const double D5 = 701980252875.0 / 199316789632.0;
static const double D6 = -1453857185.0 / 822651844.0;
static const double D7 = 69997945.0 / 29380423.0;
/* the same weights on K1..K7, for the sensitivities' stages (fcc_sens_dopri5.h) */
static const double EW[7] = {71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0,
                             -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0};
static const double DW[7] = {-12715105075.0 / 11282082432.0, 0.0,
                             87487479700.0 / 32700410799.0, -10690763975.0 / 1880347072.0,
                             701980252875.0 / 199316789632.0, -1453857185.0 / 822651844.0,
                             69997945.0 / 29380423.0};

static const double SAFETY = 0.9, FACMIN = 0.2, FACMAX = 10.0;
static const double UROUND = 2.220446049250313e-16;

/* k = (v, a(t, q, v)) at y = (q, v). */
static int f(fcc_engine *e, fcc_dopri5 *r, int stage, double t, const double *y,
             double *k, int reuse)
{
    int n = r->n2 / 2;
    fcc_put_time(e->asmb, t);
    e->err_stage = stage;
    r->n_rhs++;
    memcpy(k, y + n, (size_t)n * sizeof(double));
    if (fcc_accelerations(e, y, y + n, k + n, reuse) < 0)
        return -1;
    if (r->ev != NULL && fcc_ev_constrain(e, r->ev, y, y + n, r->t, k + n) < 0)
        return -1;                            /* active lock rows (events) */
    if (r->pw != NULL)                        /* the stage's power (fcc_work.h) */
        r->p[stage - 1] = fcc_stage_power(e, r->pw, y, y + n, k + n);
    return 0;
}

/* Stage `stage` of a step of size h (f), then the sensitivities' (w: the stage's
 * weights on the earlier stages, as for combine). */
static int fs(fcc_engine *e, fcc_dopri5 *r, int stage, double t, const double *y,
              double *k, int reuse, double h, const double *w)
{
    if (f(e, r, stage, t, y, k, reuse) < 0)
        return -1;
    if (r->sens.s != NULL)
        return fcc_sens_dp5_stage(e, &r->sens, stage, h, w, y, y + r->n2 / 2,
                                  k + r->n2 / 2);
    return 0;
}

/* out = y + h sum_{j < s} w[j] K_{j+1}. */
static void combine(fcc_dopri5 *r, double *out, double h, int s, const double *w)
{
    int i, j;
    double acc;
    for (i = 0; i < r->n2; i++) {
        acc = 0.0;
        for (j = 0; j < s; j++)
            if (w[j] != 0.0)
                acc += w[j] * r->k[j][i];
        out[i] = r->y[i] + h * acc;
    }
}

/* Stages 2..7 from K1 (already at y); leaves the 5th-order solution in y1. */
static int stages(fcc_engine *e, fcc_dopri5 *r, double h)
{
    double w[6];
    w[0] = A21;
    combine(r, r->yt, h, 1, w);
    if (fs(e, r, 2, r->t + C2 * h, r->yt, r->k[1], 0, h, w) < 0) return -1;
    w[0] = A31; w[1] = A32;
    combine(r, r->yt, h, 2, w);
    if (fs(e, r, 3, r->t + C3 * h, r->yt, r->k[2], 0, h, w) < 0) return -1;
    w[0] = A41; w[1] = A42; w[2] = A43;
    combine(r, r->yt, h, 3, w);
    if (fs(e, r, 4, r->t + C4 * h, r->yt, r->k[3], 0, h, w) < 0) return -1;
    w[0] = A51; w[1] = A52; w[2] = A53; w[3] = A54;
    combine(r, r->yt, h, 4, w);
    if (fs(e, r, 5, r->t + C5 * h, r->yt, r->k[4], 0, h, w) < 0) return -1;
    w[0] = A61; w[1] = A62; w[2] = A63; w[3] = A64; w[4] = A65;
    combine(r, r->yt, h, 5, w);
    if (fs(e, r, 6, r->t + h, r->yt, r->k[5], 0, h, w) < 0) return -1;
    w[0] = A71; w[1] = 0.0; w[2] = A73; w[3] = A74; w[4] = A75; w[5] = A76;
    combine(r, r->y1, h, 6, w);
    return fs(e, r, 7, r->t + h, r->y1, r->k[6], 0, h, w);
}

/* The scaled RMS norm of the local error estimate (NaN stays NaN: a rejection). */
static double error_norm(fcc_dopri5 *r, double h)
{
    int i;
    double d, sk, acc = 0.0;
    for (i = 0; i < r->n2; i++) {
        d = h * (E1 * r->k[0][i] + E3 * r->k[2][i] + E4 * r->k[3][i] + E5 * r->k[4][i]
                 + E6 * r->k[5][i] + E7 * r->k[6][i]);
        sk = r->atol + r->rtol * fmax(fabs(r->y[i]), fabs(r->y1[i]));
        acc += (d / sk) * (d / sk);
    }
    acc = sqrt(acc / r->n2);
    if (r->sens.s != NULL) {                  /* the sensitivities' (an option) */
        d = fcc_sens_dp5_error(&r->sens, h, EW, r->atol, r->rtol);
        if (!(d <= acc))
            acc = d;
    }
    return acc;
}

/* Coefficients of the continuous extension over the step y -> y1. */
static void dense(fcc_dopri5 *r, double h)
{
    int i;
    double dy, bspl;
    for (i = 0; i < r->n2; i++) {
        dy = r->y1[i] - r->y[i];
        bspl = h * r->k[0][i] - dy;
        r->rc[0][i] = r->y[i];
        r->rc[1][i] = dy;
        r->rc[2][i] = bspl;
        r->rc[3][i] = dy - h * r->k[6][i] - bspl;
        r->rc[4][i] = h * (D1 * r->k[0][i] + D3 * r->k[2][i] + D4 * r->k[3][i]
                           + D5 * r->k[4][i] + D6 * r->k[5][i] + D7 * r->k[6][i]);
    }
    if (r->sens.s != NULL)
        fcc_sens_dp5_dense(&r->sens, h, DW);
}

/* The work over the step by the fifth-order weights, and its continuous extension
 * (the one of dense(), with the stage powers for the stage derivatives). */
static void dense_work(fcc_dopri5 *r, double h)
{
    double dw = h * (A71 * r->p[0] + A73 * r->p[2] + A74 * r->p[3] + A75 * r->p[4]
                     + A76 * r->p[5]);
    r->rw[0] = r->w;
    r->rw[1] = dw;
    r->rw[2] = h * r->p[0] - dw;
    r->rw[3] = dw - h * r->p[6] - r->rw[2];
    r->rw[4] = h * (D1 * r->p[0] + D3 * r->p[2] + D4 * r->p[3] + D5 * r->p[4]
                    + D6 * r->p[5] + D7 * r->p[6]);
}

/* The work at the fraction th of the last step. */
static double work_at(const fcc_dopri5 *r, double th)
{
    double th1 = 1.0 - th;
    return r->rw[0] + th * (r->rw[1] + th1 * (r->rw[2] + th * (r->rw[3]
                                                               + th1 * r->rw[4])));
}

/* Position then velocity projection of y = (q, v), in place; reuse: M, B and the
 * factorisation held are the last stage's, at y (fcc_project_positions). */
static int project(fcc_engine *e, fcc_dopri5 *r, double *y, int reuse)
{
    int rc, it = 0, n = r->n2 / 2;
    e->err_where = FCC_AT_POSITIONS;
    rc = fcc_project_positions(e, y, &it, reuse);
    if (rc < 0)
        return -1;
    r->failures += rc;
    r->newton_total += it;
    e->err_where = FCC_AT_VELOCITIES;
    if (fcc_project_velocities(e, y, y + n, e->b_fresh) < 0)
        return -1;
    if (r->sens.s != NULL && fcc_sens_project(e, r->sens.s, y, y + n) < 0)
        return -1;                            /* the state's s (or an output's) */
    if (r->ev != NULL)
        return fcc_ev_correct(e, r->ev, y, y + n);
    return 0;
}

/* The continuous extension of the last step at its fraction th. */
static void dense_at(fcc_dopri5 *r, double th, double *out)
{
    int i;
    double th1 = 1.0 - th;
    for (i = 0; i < r->n2; i++)
        out[i] = r->rc[0][i] + th * (r->rc[1][i] + th1 * (
            r->rc[2][i] + th * (r->rc[3][i] + th1 * r->rc[4][i])));
}

/* Illinois (fcc_ev_bracket) on th -> s_k(dense output at th) over [0, 1] of the step
 * of size h from r->t0 (s_k crosses between ev->s0 and ev->s1); stops when the
 * bracket is below tol / h. *theta: the end of the bracket past the crossing. */
static int locate(fcc_engine *e, fcc_dopri5 *r, int k, double h, double *theta)
{
    fcc_events *ev = r->ev;
    int n = r->n2 / 2, ne = ev->spec->ne;
    fcc_bracket br;
    double c;
    fcc_ev_bracket(ev, k, &br, 1.0);
    while (fcc_ev_bracket_open(ev, &br, h)) {
        c = fcc_ev_bracket_trial(&br);
        dense_at(r, c, r->yt);
        if (fcc_ev_watch(e, ev, r->yt, r->yt + n, r->t0 + c * h, ev->s1 + 2 * ne) < 0)
            return -1;
        fcc_ev_bracket_update(ev, k, &br, c, ev->s1[2 * ne + k]);
    }
    *theta = br.b;
    return 0;
}

/* The earliest event that crosses in the step r->t0 -> t1 (-1: none; -2: a solve
 * failed), and where. */
static int first_event(fcc_engine *e, fcc_dopri5 *r, double h, double t1, double *theta)
{
    fcc_events *ev = r->ev;
    int n = r->n2 / 2, k, j, first;
    double th;
    if (fcc_ev_watch(e, ev, r->y1, r->y1 + n, t1, ev->s1) < 0)
        return -2;
    k = fcc_ev_crossed(ev, ev->s0, ev->s1);
    if (k < 0)
        return -1;
    *theta = 1.0;
    first = k;
    fcc_ev_mark_crossed(ev);
    for (j = k; j < 2 * ev->spec->ne; j++) {
        if (j > k && !fcc_ev_watched(ev, j, ev->s0, ev->s1))     /* a held lock */
            continue;
        if (locate(e, r, j, h, &th) < 0)
            return -2;
        if (th < *theta || j == k) {
            *theta = th;
            first = j;
        }
    }
    return first;
}

/* Act on event k at the (projected) state r->y, r->t, then on the events tied with
 * it (fcc_ev_next_tie); the next step's values. */
static int after_event(fcc_engine *e, fcc_dopri5 *r, int k)
{
    fcc_events *ev = r->ev;
    int n = r->n2 / 2, rc = 0, j, rc_j;
    if (k >= 0)
        fcc_ev_keep_start(ev, k);
    for (j = k; j >= 0; j = fcc_ev_next_tie(ev)) {
        e->err_t = r->t;
        if (r->sens.s != NULL
                && fcc_sens_event_before(e, r->sens.s, j, r->y, r->y + n, r->t) < 0)
            return -1;
        rc_j = fcc_ev_apply(e, ev, j, r->y, r->y + n, r->t);
        if (rc_j < 0)
            return -1;
        if (r->sens.s != NULL
                && fcc_sens_event_after(e, r->sens.s, j, rc_j, r->y, r->y + n, r->t) < 0)
            return -1;
        if (j == k)
            rc = rc_j;
        if (ev->stop) {
            r->stopped = 1;
            r->t_stop = r->t;
            if (r->n_out < r->n_req) {               /* the last record: the stop */
                r->out.t[r->n_out] = r->t;
                if (r->w_out != NULL)
                    r->w_out[r->n_out] = r->w;
                fcc_write_record(e, &r->out, r->n_out, r->y, r->y + n);
                if (r->sens.s != NULL)       /* the total derivative at the stop */
                    fcc_sens_record(r->sens.s, r->n_out);
                r->n_out++;
            }
            return 0;
        }
        if (j == k) {
            fcc_ev_refresh(ev, r->y);
            if (fcc_ev_watch(e, ev, r->y, r->y + n, r->t, ev->s0) < 0)
                return -1;
            if (rc == 0)
                ev->s0[k] = fcc_ev_leaving(ev, k, r->y, r->y + n, r->t);
        }
    }
    if (k >= 0)
        return fcc_ev_settle(e, ev, r->y, r->y + n, r->t, k, rc == 0);
    fcc_ev_refresh(ev, r->y);
    return fcc_ev_watch(e, ev, r->y, r->y + n, r->t, ev->s0) < 0 ? -1 : 0;
}

/* Write the requested output r->n_out from the dense output of the last step. */
static int record(fcc_engine *e, fcc_dopri5 *r)
{
    long j = r->n_out, n = r->n2 / 2;
    double cerr;
    if (r->w_out != NULL)
        r->w_out[j] = j > 0 && r->pw != NULL ? work_at(r, (r->out.t[j] - r->t0) / r->h)
                                             : r->w;
    if (j > 0) {
        dense_at(r, (r->out.t[j] - r->t0) / r->h, r->yt);
        if (r->sens.s != NULL)             /* s there, projected with the output */
            fcc_sens_dp5_output(&r->sens, (r->out.t[j] - r->t0) / r->h);
        if (r->project) {
            fcc_put_time(e->asmb, r->out.t[j]);
            if (project(e, r, r->yt, 0) < 0)
                return -1;
            e->factor_valid = 0;           /* the factorisation is not the one at r->y */
        }
    } else {
        memcpy(r->yt, r->y, (size_t)r->n2 * sizeof(double));
    }
    if (r->sens.s != NULL) {
        fcc_sens_record(r->sens.s, j);
        if (j > 0)
            fcc_sens_dp5_restore(&r->sens);
    }
    cerr = fcc_write_record(e, &r->out, j, r->yt, r->yt + n);
    if (!(cerr <= r->max_cerr))
        r->max_cerr = cerr;
    r->n_out++;
    return 0;
}

/* The records of the accepted step in (t0, t] (before its event's time, with an
 * event: a record at an event's time shows the state after it, as RK4's do; the next
 * step, starting there, writes it, or flush() at the end of the run). Returns 1 when
 * the step holds after writing the last requested record (hold), 0 when its end
 * follows, -1 on an error. */
static int step_records(fcc_engine *e, fcc_dopri5 *r)
{
    long before = r->n_out;
    int k = r->step_event;
    while (r->n_out < r->n_req && (k >= 0 ? r->out.t[r->n_out] < r->t
                                          : r->out.t[r->n_out] <= r->t * (1 + 4 * UROUND)))
        if (record(e, r) < 0)
            return -1;
    if (r->n_out > before)
        r->step_recorded = 1;
    r->held = r->hold && r->n_out > before && r->n_out == r->n_req;
    return r->held;
}

/* Take the accepted step y -> y1: its continuous extension, its event, then its
 * records (step_records; 1: held there). */
static int accept(fcc_engine *e, fcc_dopri5 *r, double h)
{
    int k = -1;
    double th = 1.0, t1;
    dense(r, h);
    if (r->pw != NULL)
        dense_work(r, h);
    r->t0 = r->t;
    t1 = r->t_end - (r->t + h) > 4 * UROUND * r->t_end ? r->t + h : r->t_end;
    if (r->ev != NULL) {
        k = first_event(e, r, h, t1, &th);
        if (k == -2)
            return -1;
        if (k >= 0) {                          /* the step ends at the event */
            t1 = r->t0 + th * h;
            dense_at(r, th, r->y1);
        }
    }
    r->t = t1;
    r->accepted++;
    r->step_event = k;
    r->step_th = th;
    r->step_recorded = 0;
    return step_records(e, r);
}

/* The accepted step's end, after its records: the state there (or at its event),
 * projection, the event acted on and the next K1. */
static int finish_step(fcc_engine *e, fcc_dopri5 *r)
{
    int n = r->n2 / 2, k = r->step_event;
    double th = r->step_th;
    r->held = 0;
    memcpy(r->y, r->y1, (size_t)r->n2 * sizeof(double));
    if (r->sens.s != NULL)                    /* s at the step's end (or the event) */
        fcc_sens_dp5_take(&r->sens, th);
    if (r->pw != NULL)
        r->w = work_at(r, th);                /* th: 1, or the event's fraction */
    e->err_t = r->t;
    if (!fcc_finite(r->y, r->n2)) {
        e->err_where = FCC_AT_STEP;
        return fcc_fail(e, FCC_ERR_NONFINITE_INPUT, 0, !fcc_finite(r->y, n) ? 1 : 2);
    }
    if (fcc_diverged(e, r->y, r->q_bound) || fcc_diverged(e, r->y + n, r->v_bound)) {
        e->err_where = FCC_AT_STEP;
        return fcc_fail(e, FCC_ERR_DIVERGED, 0, e->err_bound == r->q_bound ? 1 : 2);
    }
    if (r->project) {
        fcc_put_time(e->asmb, r->t);
        /* stage 7's M, B and factorisation are at y1, unless a record projected since
         * (or an event function moved y1: with events, a set with some) */
        if (project(e, r, r->y, !r->step_recorded
                    && (r->ev == NULL || r->ev->spec->ne == 0)) < 0)
            return -1;
        if (r->ev != NULL) {
            if (after_event(e, r, k) < 0)
                return -1;
            if (r->stopped)
                return 0;
        }
        e->err_where = FCC_AT_STAGE;
        return fs(e, r, 1, r->t, r->y, r->k[0], e->factor_valid, 0.0, NULL);
    }
    memcpy(r->k[0], r->k[6], (size_t)r->n2 * sizeof(double));        /* FSAL */
    r->p[0] = r->p[6];
    if (r->ev != NULL)                        /* angle references only (no projection) */
        fcc_ev_refresh(r->ev, r->y);
    fcc_assemble(e->asmb, r->y, NULL, FCC_ASM_G);
    if (!(fcc_max_abs_g(e->asmb) <= r->max_cerr))
        r->max_cerr = fcc_max_abs_g(e->asmb);
    return 0;
}

/* Records left at the end of the run (an event at t_end): the state there. */
static void flush(fcc_engine *e, fcc_dopri5 *r)
{
    int n = r->n2 / 2;
    double cerr;
    while (r->n_out < r->n_req) {
        if (r->w_out != NULL)
            r->w_out[r->n_out] = r->w;
        cerr = fcc_write_record(e, &r->out, r->n_out, r->y, r->y + n);
        if (r->sens.s != NULL)
            fcc_sens_record(r->sens.s, r->n_out);
        if (!(cerr <= r->max_cerr))
            r->max_cerr = cerr;
        r->n_out++;
    }
}

/* An accepted step after its records (rc: accept's or step_records'): held there
 * (a pause), or its end. Returns 1 with *status what the advance returns (an error,
 * the pause, a stop event's end), 0 to step on. */
static int close_step(fcc_engine *e, fcc_dopri5 *r, int rc, int *status)
{
    if (rc != 0) {
        *status = rc < 0 ? FCC_RUN_ERROR : FCC_RUN_PAUSE;
        return 1;
    }
    if (finish_step(e, r) < 0) {
        *status = FCC_RUN_ERROR;
        return 1;
    }
    if (r->stopped) {
        *status = FCC_RUN_DONE;
        return 1;
    }
    r->h = r->h_next;
    r->last_rejected = 0;
    return 0;
}

int fcc_dopri5_advance(fcc_engine *e, fcc_dopri5 *r)
{
    double h, err, fac;
    int status;
    /* a step held after its records: more of them, or its end */
    if (r->held && close_step(e, r, step_records(e, r), &status))
        return status;
    while (r->t < r->t_end) {
        h = fmin(r->h, r->t_end - r->t);
        if (0.1 * h <= fabs(r->t) * UROUND || h <= 0.0) {
            e->err_t = r->t;
            e->err_h = h;
            return FCC_RUN_UNDERFLOW;
        }
        e->err_where = FCC_AT_STAGE;
        e->err_t = r->t;
        e->err_h = h;
        if (stages(e, r, h) < 0)
            return FCC_RUN_ERROR;
        err = error_norm(r, h);
        if (err <= 1.0) {
            fac = err == 0.0 ? FACMAX : fmin(FACMAX, fmax(FACMIN, SAFETY * pow(err, -0.2)));
            if (r->last_rejected && fac > 1.0)
                fac = 1.0;
            r->h = h;
            r->h_next = h * fac;
            if (close_step(e, r, accept(e, r, h), &status))
                return status;
        } else {
            /* NaN fails "err <= 1" too and shrinks the step by FACMIN */
            fac = !(err == err) ? FACMIN : fmax(FACMIN, SAFETY * pow(err, -0.2));
            r->h = h * fac;
            r->rejected++;
            r->last_rejected = 1;
        }
        if (r->t < r->t_end && r->pause != NULL && r->pause(r->pause_ctx))
            return FCC_RUN_PAUSE;
    }
    flush(e, r);
    return FCC_RUN_DONE;
}

/* Hairer's starting step (HINIT): h0 from |y|/|f|, refined by one more stage. */
static double initial_step(fcc_engine *e, fcc_dopri5 *r)
{
    int i;
    double sk, d0 = 0.0, d1 = 0.0, d2 = 0.0, h0, h1;
    for (i = 0; i < r->n2; i++) {
        sk = r->atol + r->rtol * fabs(r->y[i]);
        d0 += pow(r->y[i] / sk, 2.0);
        d1 += pow(r->k[0][i] / sk, 2.0);
    }
    d0 = sqrt(d0 / r->n2);
    d1 = sqrt(d1 / r->n2);
    h0 = d0 < 1e-5 || d1 < 1e-5 ? 1e-6 : 0.01 * d0 / d1;
    h0 = fmin(h0, r->t_end);
    for (i = 0; i < r->n2; i++)
        r->yt[i] = r->y[i] + h0 * r->k[0][i];
    if (f(e, r, 2, h0, r->yt, r->k[1], 0) < 0)
        return -1.0;
    for (i = 0; i < r->n2; i++) {
        sk = r->atol + r->rtol * fabs(r->y[i]);
        d2 += pow((r->k[1][i] - r->k[0][i]) / sk, 2.0);
    }
    d2 = sqrt(d2 / r->n2) / h0;
    if (fmax(d1, d2) <= 1e-15)
        h1 = fmax(1e-6, h0 * 1e-3);
    else
        h1 = pow(0.01 / fmax(d1, d2), 0.2);
    return fmin(100.0 * h0, fmin(h1, r->t_end));
}

int fcc_dopri5_start(fcc_dopri5 *r, fcc_engine *e, const double *q0, const double *v0)
{
    int i, n = e->n, status;
    double big = 0.0;
    r->n2 = 2 * n;
    r->t = 0.0;
    r->h = r->h0;
    r->last_rejected = 0;
    r->held = r->step_recorded = 0;
    r->step_event = -1;
    r->step_th = 1.0;
    r->accepted = r->rejected = r->n_rhs = r->newton_total = r->failures = 0;
    r->max_cerr = 0.0;
    r->n_out = 0;
    r->y = r->work;
    r->y1 = r->work + r->n2;
    r->yt = r->work + 2 * r->n2;
    for (i = 0; i < 7; i++)
        r->k[i] = r->work + (3 + i) * r->n2;
    for (i = 0; i < 5; i++)
        r->rc[i] = r->work + (10 + i) * r->n2;
    memcpy(r->y, q0, (size_t)n * sizeof(double));
    memcpy(r->y + n, v0, (size_t)n * sizeof(double));
    e->factor_valid = 0;
    e->err = FCC_OK;
    r->stopped = 0;
    r->t_stop = r->t_end;
    r->t0 = 0.0;
    r->w = 0.0;
    for (i = 0; i < 7; i++)
        r->p[i] = 0.0;
    for (i = 0; i < 5; i++)
        r->rw[i] = 0.0;
    fcc_divergence_bounds(n, q0, v0, r->t_end, 0.0, &r->q_bound, &r->v_bound);
    if (r->project) {
        /* a step that leaves the constraints by 1% of the model's size diverged */
        for (i = 0; i < n; i++)
            if (fabs(q0[i]) > big)
                big = fabs(q0[i]);
        e->diverge_residual = 1e-2 * (big > 1e-300 ? big : 1e-300);
    }
    if (r->ev != NULL)
        fcc_ev_watch(e, r->ev, r->y, r->y + n, 0.0, r->ev->s0);
    if (r->sens.s != NULL)
        fcc_sens_dp5_start(&r->sens);
    e->running = 1;
    record(e, r);                           /* the first record: y as given */
    e->err_where = FCC_AT_STAGE;
    e->err_t = 0.0;
    e->err_h = r->h0;
    status = fs(e, r, 1, 0.0, r->y, r->k[0], 0, 0.0, NULL);
    if (status == 0 && r->h == 0.0) {
        r->h = initial_step(e, r);
        status = r->h < 0 ? -1 : 0;
    }
    return status < 0 ? FCC_RUN_ERROR : 0;
}
