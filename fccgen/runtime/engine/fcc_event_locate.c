/* Watching and locating events: the event functions' values, which of them crossed
 * zero in a step, and the Illinois iteration (modified regula falsi) that locates a
 * crossing within the location tolerance (at most 200 trials). The integrators
 * (fcc_rk4.c, fcc_dopri5.c) drive these with their own states at the trial times. */
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
