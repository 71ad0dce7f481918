/* Classical RK4 with projection, and RK4 on the Baumgarte-stabilised equations
 * (fcc_rk4.c): the whole per-step loop, events included. */
#ifndef FCC_RK4_H
#define FCC_RK4_H

#include "fcc_events.h"
#include "fcc_sens.h"
#include "fcc_work.h"
#include "fcc_run.h"

typedef struct fcc_rk4 {
    /* settings (the caller's) */
    int project;              /* position then velocity projection after each step */
    int baumgarte;            /* stages use fcc_baumgarte (alpha, beta), no projection */
    double alpha, beta;
    long n_steps;             /* steps of dt, the last one shortened to end at t_end */
    long every;               /* record every this many steps (and t_end) */
    double dt, t_end;
    fcc_records out;          /* room for 1 + n_steps / every (+ 1) records */
    fcc_events *ev;           /* events (NULL: none) */
    double *saved;            /* 2 n: the step start an event is located from */
    double *dense;            /* 6 n: the step's interpolant that places the location's
                                 trials (NULL: Illinois alone, twice the partial
                                 steps) */
    int on_interpolant;       /* with dense: an event function's crossing is located on
                                 the step's interpolant, its end acceleration evaluated
                                 at the step's end, and the state there is the
                                 interpolant's (as dopri5's dense output): one
                                 evaluation more per event step instead of the partial
                                 steps (none with sens: they take the partial steps) */
    fcc_pause_fn pause;
    void *pause_ctx;
    /* state and statistics */
    long k;                   /* steps done */
    long n_out;               /* records written */
    long n_rhs;               /* acceleration evaluations */
    long newton_total;        /* Newton iterations of all projections */
    int newton_max;           /* most Newton iterations in one projection */
    long failures;            /* position projections that did not converge */
    double max_cerr;          /* largest max |g| of a recorded or stepped state */
    double q_bound, v_bound;  /* max |q| and max |v| past these: the run diverged */
    double *q, *v, *qs, *v2, *v3, *v4, *a1, *a2, *a3, *a4;   /* in the engine */
    double t0;                /* time at the start of the step (stage times) */
    double trial_tau;         /* the partial step whose state r->q, r->v hold (events) */
    int stopped;              /* a stop event ended the run at t_stop */
    double t_stop;
    /* the work of the forces without potential (settings: pw NULL, none; w_out, W at
     * each record, with pw) */
    fcc_power *pw;
    double *w_out;
    double w, wsave;          /* W done so far; at the saved step start (events) */
    double p[4];              /* the stages' powers */
    fcc_sens *sens;           /* forward sensitivities (NULL: none; needs project;
                                 started by the caller) */
} fcc_rk4;

/* Start a run from (q0, v0) with the settings in r (the rest of r is set here): the
 * state in the engine's stage arrays, the divergence bounds from the initial state
 * (fcc_divergence_bounds), the events reset by the caller (fcc_events_reset) and
 * watched here. The settings are project, baumgarte, alpha, beta, n_steps, every, dt,
 * t_end, out, ev, saved, dense, pause, pause_ctx, pw and w_out (zero the struct first:
 * NULL pointers are "none"). Events without event functions (ne = 0) only re-base the
 * angle references after every step (springs count turns); with event functions they
 * need project. Returns 0 or -1 (the engine's error record). */
int fcc_rk4_start(fcc_rk4 *r, fcc_engine *e, const double *q0, const double *v0);
/* Write record r->n_out at time t. */
void fcc_rk4_record(fcc_engine *e, fcc_rk4 *r, double t);
/* Steps until the end (FCC_RUN_DONE), an error (FCC_RUN_ERROR) or a pause
 * (FCC_RUN_PAUSE). */
int fcc_rk4_advance(fcc_engine *e, fcc_rk4 *r);
/* The run's end (also after an error): the engine free for other calls. */
void fcc_run_finish(fcc_engine *e);

#endif
