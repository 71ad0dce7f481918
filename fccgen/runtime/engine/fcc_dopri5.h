/* Dormand-Prince 5(4) with error control and dense output (fcc_dopri5.c): the
 * per-step loop, projections and events included. */
#ifndef FCC_DOPRI5_H
#define FCC_DOPRI5_H

#include "fcc_events.h"
#include "fcc_sens_dopri5.h"
#include "fcc_work.h"
#include "fcc_run.h"

#define FCC_DOPRI5_WORK 15      /* work arrays of 2 n numbers each */

typedef struct fcc_dopri5 {
    /* settings (the caller's) */
    int project;              /* projections after each accepted step and record */
    double rtol, atol;
    double t_end;
    double h0;                /* the first step (0: Hairer's automatic choice) */
    long n_req;               /* records requested: at out.t[0 .. n_req) (0 first) */
    fcc_records out;          /* out.t holds the requested times (a stop: its time) */
    fcc_events *ev;           /* events (NULL: none) */
    double *work;             /* FCC_DOPRI5_WORK x 2 n numbers */
    fcc_pause_fn pause;
    void *pause_ctx;
    int hold;                 /* a step that writes the last requested record holds
                                 there (FCC_RUN_PAUSE) before its end's projection and
                                 events: the caller may request more records, at times
                                 in the step (written by the next advance) or past it
                                 (the step ends, the run goes on); records requested
                                 one at a time then equal those requested at once */
    /* state and statistics */
    int n2;                   /* 2 n: length of y = (q, v) */
    double t, h;
    int last_rejected;
    long accepted, rejected, n_rhs, newton_total, failures;
    double max_cerr;
    long n_out;               /* records written */
    double *y, *y1, *yt;      /* state at t; trial state at t + h; stage argument */
    double *k[7];             /* stages K1..K7 (each 2 n: velocity then acceleration) */
    double *rc[5];            /* dense output coefficients of the last accepted step */
    double t0;                /* start of the last accepted step */
    int held;                 /* the last accepted step is held after its records */
    int step_event;           /* its event (-1: none), ... */
    double step_th;           /* ... where in the step (1: none) ... */
    int step_recorded;        /* ... whether it wrote records, ... */
    double h_next;            /* ... and the next step's size */
    int stopped;              /* a stop event ended the run at t_stop */
    double t_stop;
    /* the work of the forces without potential (settings: pw NULL, none; w_out, W at
     * each record, with pw) */
    fcc_power *pw;
    double *w_out;
    double w;                 /* W done up to t */
    double p[7];              /* the stages' powers */
    double rw[5];             /* W's continuous extension over the last step */
    double q_bound, v_bound;  /* max |q|, max |v| past these: diverged (v: infinity) */
    /* forward sensitivities (settings: sens.s NULL, none; needs project and the dense
     * path; sens.s started by the caller, its work set up here) */
    fcc_sens_dp5 sens;
} fcc_dopri5;

/* Start a run from (q0, v0) with the settings in r: the first record, the first
 * stage and (h0 = 0) the starting step, the divergence bounds (fcc_divergence_bounds
 * without a speed bound). The settings are project, rtol, atol, t_end, h0, n_req,
 * out, ev, work, pause, pause_ctx, hold, pw, w_out and sens (zero the struct first: NULL pointers
 * are "none"). The events are reset by the caller (fcc_events_reset); events without
 * event functions (ne = 0) only re-base the angle references after every step, with
 * event functions they need project. A record at an event's time shows the state
 * after the event. Returns 0 or FCC_RUN_ERROR (the engine's error record). */
int fcc_dopri5_start(fcc_dopri5 *r, fcc_engine *e, const double *q0, const double *v0);
/* Steps until the end (FCC_RUN_DONE), an error (FCC_RUN_ERROR, FCC_RUN_UNDERFLOW:
 * e->err_t, err_h say where) or a pause (FCC_RUN_PAUSE: pause, or a step held after
 * its records with hold). */
int fcc_dopri5_advance(fcc_engine *e, fcc_dopri5 *r);

#endif
