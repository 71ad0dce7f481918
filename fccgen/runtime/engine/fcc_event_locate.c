/* Watching and locating events: the event functions' values, which of them crossed
 * zero in a step, and the Illinois iteration (modified regula falsi) that locates a
 * crossing within the location tolerance (at most 200 trials), with its trials placed
 * by a step's interpolant where the integrator has one to spare (fcc_interp). The
 * integrators (fcc_rk4.c, fcc_dopri5.c) drive these with their own states at the
 * trial times. */
#include <math.h>

#include <string.h>

#include "fcc_events.h"

void fcc_ev_mirror(fcc_events *ev)
{
    /* Copy the angle references into the element kernels' parameters (theta, cos,
     * sin of torsion springs and loads of joint angles; fcc_events_mirror). */
    int i;
    for (i = 0; i < ev->nm; i++)
        memcpy(ev->mdst + ev->mslot[i], ev->p + 3 * ev->mang[i], 3 * sizeof(double));
}

void fcc_ev_refresh(fcc_events *ev, const double *q)
{
    /* Move the angle references to the angles at q (turn counting), and their copies
     * in the element kernels; keep the largest move (a turn near half a turn between
     * two re-basings leaves the atan2's branch in doubt). */
    const fcc_event_spec *c = ev->spec;
    int j, row;
    double th;
    if (c->nr == 0)
        return;
    c->tab->quantity_values(q, NULL, 0.0, ev->p, ev->r);
    for (j = 0; j < c->nang; j++) {
        row = c->angle_row[j];
        th = ev->r[row];
        if (fabs(th - ev->p[3 * j]) > ev->max_turn) {
            ev->max_turn = fabs(th - ev->p[3 * j]);
            ev->max_turn_j = j;
        }
        ev->p[3 * j] = th;
        ev->p[3 * j + 1] = cos(th);
        ev->p[3 * j + 2] = sin(th);
    }
    fcc_ev_mirror(ev);
}

void fcc_ev_values(fcc_events *ev, const double *q, const double *v, double t,
                   double *out)
{
    ev->spec->tab->event_values(q, v, t, ev->p, out);
}

int fcc_ev_crosses(fcc_events *ev, int k, double a, double b)
{
    /* s_k goes from a to b across zero in the event's direction. */
    int up = a < 0.0 && 0.0 <= b, down = a > 0.0 && 0.0 >= b;
    if (k >= ev->spec->ne || ev->spec->direction[k] > 0)   /* release functions rise */
        return up;
    if (ev->spec->direction[k] < 0)
        return down;
    return up || down;
}

void fcc_ev_bracket(fcc_events *ev, int k, fcc_bracket *br, double b)
{
    /* Start the Illinois iteration on watched value k over [0, b], where it crosses
     * between ev->s0[k] (at 0) and ev->s1[k] (at b). A start just after an event
     * (fcc_ev_leaving's +-1e-300) counts as before the crossing: bisect first. */
    br->a = 0.0;
    br->b = b;
    br->fa = ev->s0[k];
    br->fb = ev->s1[k];
    br->side = 0;
    br->it = 0;
    if (fabs(br->fa) < 1e-200)
        br->fa = -br->fb;
}

int fcc_ev_bracket_open(fcc_events *ev, fcc_bracket *br, double scale)
{
    /* The bracket, times scale (its unit in seconds), is wider than the location
     * tolerance (and fewer than 200 trials were made: the cap). */
    return (br->b - br->a) * scale > ev->spec->tol && br->it < 200;
}

double fcc_ev_bracket_trial(fcc_bracket *br)
{
    /* The next trial point: the secant's zero, b - f_b (b - a) / (f_b - f_a), or the
     * midpoint where that is not inside (a, b). */
    double c;
    br->it++;
    c = br->fb != br->fa ? br->b - br->fb * (br->b - br->a) / (br->fb - br->fa)
                         : 0.5 * (br->a + br->b);
    if (!(br->a < c && c < br->b))
        c = 0.5 * (br->a + br->b);
    return c;
}

void fcc_ev_bracket_update(fcc_events *ev, int k, fcc_bracket *br, double c, double fc)
{
    /* Keep the half of the bracket that holds the crossing, given the value fc at the
     * trial c; the end kept twice in a row has its value halved (Illinois), so that
     * the secant does not stall on one side. */
    if (fcc_ev_crosses(ev, k, br->fa, fc)
            || (fc == 0.0 && fcc_ev_crosses(ev, k, br->fa, br->fb))) {
        br->b = c;
        br->fb = fc;
        if (br->side == -1)
            br->fa *= 0.5;
        br->side = -1;
    } else {
        br->a = c;
        br->fa = fc;
        if (br->side == 1)
            br->fb *= 0.5;
        br->side = 1;
    }
}

/* Trials placed by a step's interpolant (fcc_interp). A re-integrated partial step
 * costs a whole step's acceleration evaluations; the interpolant costs event kernels
 * only. It says where the crossing is to about its own error (the step's local error,
 * orders below the location tolerance on a resolved step), so the real trials go just
 * before and just past that guess and the bracket closes in two of them instead of
 * the Illinois iteration's five to eight. The answer is still the real integration's
 * bracket, closed to the tolerance: the interpolant only chooses where to look, and
 * where it cannot (no crossing on it, or a guess outside the bracket, or too many
 * guided trials) the Illinois trial is taken. */

void fcc_ev_interp_state(const fcc_interp *ip, double tau)
{
    /* Positions: quintic Hermite in (q, v, a) at both ends; velocities: cubic Hermite
     * in (v, a). th = tau / h in [0, 1]. */
    int i;
    double h = ip->h, th = tau / h, t2 = th * th, t3 = t2 * th, t4 = t3 * th,
           t5 = t4 * th;
    double p0 = 1.0 - 10.0 * t3 + 15.0 * t4 - 6.0 * t5,
           p1 = h * (th - 6.0 * t3 + 8.0 * t4 - 3.0 * t5),
           p2 = 0.5 * h * h * (t2 - 3.0 * t3 + 3.0 * t4 - t5),
           p3 = 10.0 * t3 - 15.0 * t4 + 6.0 * t5,
           p4 = h * (-4.0 * t3 + 7.0 * t4 - 3.0 * t5),
           p5 = 0.5 * h * h * (t3 - 2.0 * t4 + t5);
    double c0 = 1.0 - 3.0 * t2 + 2.0 * t3, c1 = h * (th - 2.0 * t2 + t3),
           c2 = 3.0 * t2 - 2.0 * t3, c3 = h * (t3 - t2);
    for (i = 0; i < ip->n; i++) {
        ip->q[i] = p0 * ip->q0[i] + p1 * ip->v0[i] + p2 * ip->a0[i]
                 + p3 * ip->q1[i] + p4 * ip->v1[i] + p5 * ip->a1[i];
        ip->v[i] = c0 * ip->v0[i] + c1 * ip->a0[i] + c2 * ip->v1[i] + c3 * ip->a1[i];
    }
}

double fcc_ev_interp_value(fcc_events *ev, int k, const fcc_interp *ip, double tau)
{
    /* Event function k (k < ne) on the interpolant at t0 + tau. */
    double *out = ev->s1 + 2 * ev->spec->ne;          /* work */
    fcc_ev_interp_state(ip, tau);
    fcc_ev_values(ev, ip->q, ip->v, ip->t0 + tau, out);
    return out[k];
}

int fcc_ev_guess(fcc_events *ev, int k, const fcc_interp *ip, const fcc_bracket *br,
                 double d, double *g)
{
    /* The crossing of s_k + d on the interpolant inside the real bracket br (d: the
     * interpolant's offset from the real integration at the last trial), by the same
     * Illinois iteration to a thousandth of the guided trials' offset (at most 60
     * kernel evaluations). A start just after an event counts as before the crossing,
     * as in fcc_ev_bracket (the function leaves its zero there). 0: s_k + d does not
     * cross there (no guess). */
    fcc_bracket in;
    double c, eps = 0.25 * ev->spec->tol / ip->scale;
    in.a = br->a;
    in.b = br->b;
    in.fb = fcc_ev_interp_value(ev, k, ip, in.b) + d;
    if (in.a == 0.0 && fabs(ev->s0[k]) < 1e-200)
        in.fa = -in.fb;
    else
        in.fa = fcc_ev_interp_value(ev, k, ip, in.a) + d;
    in.side = 0;
    in.it = 0;
    if (!fcc_ev_crosses(ev, k, in.fa, in.fb))
        return 0;
    while (in.b - in.a > 1e-3 * eps && in.it < 60) {
        c = fcc_ev_bracket_trial(&in);
        fcc_ev_bracket_update(ev, k, &in, c, fcc_ev_interp_value(ev, k, ip, c) + d);
    }
    *g = 0.5 * (in.a + in.b);
    return 1;
}

int fcc_ev_interp_locate(fcc_events *ev, int k, const fcc_interp *ip, double *tau)
{
    fcc_bracket in;
    double c;
    in.a = 0.0;
    in.b = ip->h;
    in.fb = fcc_ev_interp_value(ev, k, ip, in.b);
    in.fa = fabs(ev->s0[k]) < 1e-200 ? -in.fb : fcc_ev_interp_value(ev, k, ip, 0.0);
    in.side = 0;
    in.it = 0;
    if (!fcc_ev_crosses(ev, k, in.fa, in.fb))
        return 0;
    while (fcc_ev_bracket_open(ev, &in, ip->scale)) {
        c = fcc_ev_bracket_trial(&in);
        fcc_ev_bracket_update(ev, k, &in, c, fcc_ev_interp_value(ev, k, ip, c));
    }
    *tau = in.b;
    return 1;
}

double fcc_ev_guided_trial(fcc_events *ev, fcc_bracket *br, double g, double scale)
{
    /* The next real trial beside the guess g: a quarter of the tolerance past it when
     * that closes the bracket against its start a, a quarter before it when that closes
     * it against its end b, else a quarter before it (the next guess, corrected by that
     * trial, then goes past it and closes). The Illinois trial where that is not inside
     * the bracket. */
    double tol = ev->spec->tol / scale, eps = 0.25 * tol, c;
    if (g + eps - br->a <= tol)
        c = g + eps;
    else
        c = g - eps;
    if (!(br->a < c && c < br->b))
        return fcc_ev_bracket_trial(br);
    br->it++;
    return c;
}

/* A lock, or a bounce that came to rest, whose rows hold (its function hovers at
 * zero: no new event). */
static int locked(fcc_events *ev, int k)
{
    const fcc_event_spec *c = ev->spec;
    return ((c->action[k] == FCC_ACT_LOCK || c->action[k] == FCC_ACT_BOUNCE)
            && c->row[k] >= 0 && ev->active[c->row[k]]);
}

int fcc_ev_rests(fcc_events *ev, int k)
{
    /* Event k is a bounce resting on its row (its release is watched). */
    return ev->rested[k] && ev->spec->row[k] >= 0 && ev->active[ev->spec->row[k]];
}

int fcc_ev_watched(fcc_events *ev, int k, const double *a, const double *b)
{
    /* Watched value k (event function k < ne, or release function of resting bounce
     * k - ne) crosses from a to b and counts: a lock or rest whose rows hold hovers
     * at zero by the position tolerance, and its crossings are that noise, not
     * events. */
    int ne = ev->spec->ne;
    if (k < ne)
        return fcc_ev_crosses(ev, k, a[k], b[k]) && !locked(ev, k);
    return fcc_ev_rests(ev, k - ne) && fcc_ev_crosses(ev, k, a[k], b[k]);
}

int fcc_ev_crossed(fcc_events *ev, const double *a, const double *b)
{
    /* The first watched value that crosses from a to b and counts (fcc_ev_watched),
     * or -1: an event function k < ne, or the release function ne + k of a resting
     * bounce k. */
    int k;
    for (k = 0; k < 2 * ev->spec->ne; k++)
        if (fcc_ev_watched(ev, k, a, b))
            return k;
    return -1;
}

/* Ties. The integrators locate the earliest crossing of a step, act on it, and read
 * every watched value again at its instant to go on from there. Another event that
 * crossed by that instant as well (two latches of a symmetric structure, balls
 * dropped from one height: an exact tie, or one within the location tolerance) is
 * then already past its zero in the values read, so it would never be seen to cross:
 * a limit passed through, a latch never locked, without a word. These functions let
 * the integrator act on each of them at the same instant instead. */
enum { TIE_NONE, TIE_CROSSED, TIE_ACTED };

void fcc_ev_mark_crossed(fcc_events *ev)
{
    int k;
    for (k = 0; k < 2 * ev->spec->ne; k++)
        ev->tie[k] = fcc_ev_watched(ev, k, ev->s0, ev->s1) ? TIE_CROSSED : TIE_NONE;
}

void fcc_ev_keep_start(fcc_events *ev, int first)
{
    memcpy(ev->s_prev, ev->s0, (size_t)(2 * ev->spec->ne) * sizeof(double));
    ev->tie[first] = TIE_NONE;                  /* the integrator's own */
}

int fcc_ev_next_tie(fcc_events *ev)
{
    int k;
    for (k = 0; k < 2 * ev->spec->ne; k++)
        if (ev->tie[k] == TIE_CROSSED && fcc_ev_watched(ev, k, ev->s_prev, ev->s0)) {
            ev->tie[k] = TIE_ACTED;
            return k;
        }
    return -1;
}

int fcc_ev_settle(fcc_engine *e, fcc_events *ev, const double *q, const double *v,
                  double t, int first, int first_leaves)
{
    int k, acted = 0;
    for (k = 0; k < 2 * ev->spec->ne; k++)
        acted |= ev->tie[k] == TIE_ACTED;
    if (!acted)
        return 0;
    fcc_ev_refresh(ev, q);
    if (fcc_ev_watch(e, ev, q, v, t, ev->s0) < 0)
        return -1;
    if (first_leaves)
        ev->s0[first] = fcc_ev_leaving(ev, first, q, v, t);
    for (k = 0; k < 2 * ev->spec->ne; k++)
        if (ev->tie[k] == TIE_ACTED) {
            ev->s0[k] = fcc_ev_leaving(ev, k, q, v, t);
            ev->tie[k] = TIE_NONE;
        }
    return 0;
}
