/* Events: event functions, switchable joint rows, impacts (fcc_events.c,
 * fcc_event_actions.c). The kernels come from the model's generated event module
 * (fccgen_events.h). fcc_event_spec holds the constants (the table, each event's
 * direction, action, joint rows, restitution, the settings); fcc_events one run's
 * state (angle references, active rows, work, the log).
 *
 * The events run on both paths: the responses to the joint rows are solved with the
 * factorisation the engine holds (fcc_ev_response). Which active rows enter the solves
 * is decided on the dense path by an SVD of [B; G_active] (LAPACK's dgesvd), on the
 * sparse path by the pivots of the rows' Schur complement G Z (no LAPACK, no SVD;
 * fcc_event_actions.c says how).
 */
#ifndef FCC_EVENTS_H
#define FCC_EVENTS_H

#include "fcc_engine.h"
#include "fccgen_events.h"

enum {
    FCC_ACT_STOP = 0,
    FCC_ACT_LOG = 1,
    FCC_ACT_LOCK = 2,
    FCC_ACT_UNLOCK = 3,
    FCC_ACT_BOUNCE = 4,
    FCC_ACT_REST = 5,         /* a bounce too slow to go on: the limit holds (a lock) */
    FCC_ACT_RELEASE = 6       /* a resting contact whose force turned tensile lets go */
};

/* Columns of the event log: t, event, action, impulse, ke before, ke after,
 * constraint error, dof, speed before, note, sigma. */
#define FCC_LOG_COLS 11
enum {
    FCC_NOTE_REDUNDANT = 1,   /* a lock that adds no constraint on the motion */
    FCC_NOTE_UNCERTAIN = 2    /* the rank after the switch is in the uncertain band */
};

typedef struct fcc_event_spec {
    const fcc_event_table *tab;
    int n, ne, nr, np;
    int nang;                 /* angle quantities: p[3j:3j+3] their references */
    double tol;               /* location tolerance in time */
    double v_rest;            /* a bounce with |ds/dt| below this becomes a rest */
    int max_per_step;         /* more events than this in one step: Zeno, rest */
    long cap_log;             /* rows of the log */
    int *angle_row;           /* per parameter triple: its quantity row */
    int *direction;           /* per event: +1 rising, -1 falling, 0 either */
    int *action;
    int *row;                 /* per event: its joint's first quantity row (or -1) */
    int *row2;                /* ... second row (cylindrical) or -1 */
    double *restitution;
} fcc_event_spec;

typedef struct fcc_events {
    const fcc_event_spec *spec;
    double *p;                /* angle references (theta, cos, sin), then constants */
    double *s0;               /* watched values (2 ne: the event functions, then the */
    double *s1;               /* release functions) at the step's start; at its end
                                 (or a trial time), then n numbers of work */
    double *sg;               /* event gradients (ne x n) */
    double *r, *rg, *rb;      /* quantity values, gradients (nr x n), bias */
    double *rgv;              /* the gradients' structural nonzeros (the table's
                                 n_gradient_nz, row by row; fcc_ev_gradients) */
    double *z;                /* nr x n: constrained responses to the active rows */
    double *gz;               /* nr x nr work */
    double *mu;
    double *held;             /* per quantity row: the value a lock holds (2 nr) */
    int *active;              /* per quantity row: the row is an active constraint */
    int *used;                /* ... and independent: it enters the solves (rank) */
    int n_used;
    int *rested;              /* per event: its bounce rests (release is watched) */
    int *tie;                 /* per watched value (2 ne): TIE_ marks of the step's
                                 crossings (fcc_ev_mark_crossed, fcc_ev_next_tie) */
    double *s_prev;           /* 2 ne: the watched values before the located instant */
    double *s_left;           /* 4 ne: the watched values at the left end of a location's
                                 bracket, then of the earliest location's (rk4) */
    double *rel_sign;         /* per event: the sign making its release function > 0
                                 when the resting contact's multiplier pulls */
    double *acc;              /* n: accelerations for the release functions */
    int m;                    /* the engine's constraint rows (0: rank work not set) */
    double *aug;              /* (m + nr) x n: the row-scaled [B; G_active] (rank) */
    double *svm, *sig, *svw;  /* its copy for dgesvd; singular values; work */
    int lsvw;
    int mz;                   /* the sparse engine's rows (0: no warm starts) */
    double *zlam;             /* nr x mz: each row's response's last multipliers */
    int *zlam_ok;             /* per quantity row: zlam holds converged ones */
    /* the sparse decision's responses kept at one q (decide_pivots): a tie of many
     * locks at one instant computes each row's response once, not once per lock */
    int *zslot;               /* per quantity row: its row of zc (-1: never locked) */
    double *zc;               /* (lockable rows) x n: the responses at zq */
    int *zc_ok;               /* per lockable row: zc holds its response at zq */
    int nzc;                  /* the lockable rows */
    double *zq;               /* n: the q of those responses */
    int zc_valid;             /* zq holds a q (0: nothing kept) */
    long n_switch_solves;     /* the run's responses solved for those decisions */
    double *tie_q;            /* n: the q of the last switch (sparse path) */
    long tie_factors;         /* the engine's factorisations and assemblies of the */
    long tie_assembled;       /* blocks at its end */
    int tie_valid;            /* tie_q holds it: a switch at the same q with no
                                 factorisation since reuses its factor (fcc_ev_apply) */
    int note;                 /* FCC_NOTE_ bits of the last switch */
    double note_sigma;        /* the smallest relative singular value in the band */
    int stop;                 /* a stop event happened */
    long n_log;
    double *log;              /* cap_log x FCC_LOG_COLS */
    double last[FCC_LOG_COLS]; /* the latest row, kept past cap_log too (n_log > 0) */
    /* the element kernels' copies of the angle references (torsion springs and loads
     * of joint angles count turns through them; fcc_events_mirror) */
    int nm;                   /* how many copies, */
    int *mslot;               /* ... where (the index of theta in mdst; cos, sin follow) */
    int *mang;                /* ... and of which angle (its parameter triple) */
    double *mdst;             /* the element parameters (an assembly's; not owned) */
    double *mkeep;            /* ... their values outside runs (3 nm) */
    double max_turn;          /* the largest re-basing |angle - theta_r| of the run */
    int max_turn_j;           /* ... its angle (parameter triple), -1: none yet */
    /* the used rows folded into the sparse factorisation (fcc_events_fold.c) */
    int fold;                 /* the run folds them (fcc_events_fold) */
    int fold_live;            /* ... and they go into the factor now (not in actions) */
    long n_fold_off;          /* runs that left the fold for the Schur complement: a
                                 row read a coordinate outside its pattern */
    int *fold_from;           /* per entry of the pattern's rows: its place in rgv,
                                 -1 where the row has no structural nonzero there */
    int fold_cap;             /* ... room for this many */
    int *fold_free;           /* n + n_gradient_nz: work, then per entry of rgv: its
                                 coordinate is not pinned (fcc_events_fold.c) */
    /* the choice between the fold and the Schur complement, made from the steps after
     * each switch (fcc_events_fold.c, "Which is cheaper") */
    int fold_able;            /* the rows can be folded in this run */
    int fold_trial;           /* choose after each switch (1, the default) or keep
                                 the fold (0) */
    int trial_phase;          /* 0: none under way; 1: steps folded; 2: steps with the
                                 Schur complement; -1: starts at the next step's end */
    int trial_steps;          /* steps counted in the phase, or since the choice */
    double trial_start;       /* the solves' cost at the phase's start */
    double trial_cost[2];     /* the folded, the Schur complement's steps' cost */
    double w_factor, w_iteration;  /* a factorisation's, a refinement step's cost */
    long n_trials;            /* trials decided in the run */
    long n_trials_folded;     /* ... that kept the fold */
} fcc_events;

/* Steps each way of a trial, and steps without a switch after which the choice is
 * measured again (fcc_events_fold.c, "Which is cheaper"). */
#define FCC_FOLD_TRIAL_STEPS 4
#define FCC_FOLD_RETRIAL_STEPS 1000

/* Illinois (modified regula falsi) on one watched value. */
typedef struct fcc_bracket {
    double a, b;              /* the bracket holding its crossing, b past it */
    double fa, fb;
    int side;                 /* the end kept last: -1 a, +1 b (0: none yet) */
    int it;
} fcc_bracket;

/* A step's Hermite interpolant from t0 to t0 + h (fcc_event_locate.c): positions
 * quintic in (q, v, a) at both ends, velocities cubic in (v, a); a1 may be an
 * approximation (RK4's last stage). Trials are placed by it (fcc_ev_guess,
 * fcc_ev_guided_trial); the located time is always the real integration's. */
typedef struct fcc_interp {
    int n;
    double t0, h;
    double scale;             /* the bracket's unit in seconds */
    const double *q0, *v0, *a0, *q1, *v1, *a1;
    double *q, *v;            /* work: the interpolated state */
} fcc_interp;

/* The spec of a table's events: per event direction, action, rows, restitution; the
 * angle quantities' rows; copied. */
int fcc_event_spec_init(fcc_event_spec *c, const fcc_event_table *tab, int nang,
                        const int *angle_row, const int *direction, const int *action,
                        const int *row, const int *row2, const double *restitution,
                        double tol, double v_rest, int max_per_step, long cap_log);
void fcc_event_spec_free(fcc_event_spec *c);
/* One run's state; constants: the event module's parameters after the angle
 * references (np - 3 nang numbers). */
int fcc_events_init(fcc_events *ev, const fcc_event_spec *c, const double *constants);
void fcc_events_free(fcc_events *ev);
/* The rank work for an engine with m rows (needs the engine's LAPACK table). */
int fcc_events_rank_work(fcc_events *ev, const fcc_lapack *lapack, int m);
/* The warm starts of the sparse path's responses for an engine with m rows
 * (set-up; without it the responses start from zero multipliers). */
int fcc_events_sparse_work(fcc_events *ev, int m);
/* Start a run: angle references 0 (and their copies), no rows active or resting, an
 * empty log, no turn yet. */
void fcc_events_reset(fcc_events *ev);
/* Copy the angle references into the assembly a's element parameters at every
 * re-basing (fcc_ev_refresh) and reset: the reference of angle angles[i] (its index
 * among the angle quantities) to a->params[slots[i] .. slots[i] + 3) (theta, cos,
 * sin). Their present values are kept for fcc_events_restore. Set-up: allocates.
 * Returns FCC_OK, FCC_ERR_ARGUMENT (an index out of range) or FCC_ERR_MEMORY. */
int fcc_events_mirror(fcc_events *ev, fcc_assembly *a, int n, const int *slots,
                      const int *angles);
/* Put back the element parameters' values kept by fcc_events_mirror (outside runs a
 * torsion spring's reference is its free angle). */
void fcc_events_restore(fcc_events *ev);

void fcc_ev_bracket(fcc_events *ev, int k, fcc_bracket *br, double b);
int fcc_ev_bracket_open(fcc_events *ev, fcc_bracket *br, double scale);
double fcc_ev_bracket_trial(fcc_bracket *br);
void fcc_ev_bracket_update(fcc_events *ev, int k, fcc_bracket *br, double c, double fc);
/* The interpolant's state at t0 + tau into ip->q, ip->v; event function k (< ne) on it;
 * its crossing of s_k + d inside br (1 and *g, or 0: none there); the real trial beside
 * the guess g that closes br soonest (or the Illinois trial). */
void fcc_ev_interp_state(const fcc_interp *ip, double tau);
double fcc_ev_interp_value(fcc_events *ev, int k, const fcc_interp *ip, double tau);
int fcc_ev_guess(fcc_events *ev, int k, const fcc_interp *ip, const fcc_bracket *br,
                 double d, double *g);
double fcc_ev_guided_trial(fcc_events *ev, fcc_bracket *br, double g, double scale);
/* The crossing of event function k (k < ne) on the interpolant over [0, ip->h],
 * closed to the location tolerance by the Illinois iteration on event kernels alone
 * (at most 200): *tau, the end of the bracket past the crossing. 0: it does not cross
 * on the interpolant (the caller takes the real trials). */
int fcc_ev_interp_locate(fcc_events *ev, int k, const fcc_interp *ip, double *tau);
void fcc_ev_refresh(fcc_events *ev, const double *q);
/* The angle references' copies into the element parameters (after a change of p). */
void fcc_ev_mirror(fcc_events *ev);
void fcc_ev_values(fcc_events *ev, const double *q, const double *v, double t,
                   double *out);
int fcc_ev_watch(fcc_engine *e, fcc_events *ev, const double *q, const double *v,
                 double t, double *out);
int fcc_ev_crossed(fcc_events *ev, const double *a, const double *b);
/* Watched value k crosses from a[k] to b[k] and counts: not a held lock or rest
 * (whose function hovers at zero by the position tolerance). */
int fcc_ev_watched(fcc_events *ev, int k, const double *a, const double *b);
/* Ties: events that cross at (or within the location tolerance of) the same instant.
 * fcc_ev_mark_crossed marks every watched value that crosses from s0 to s1 (after
 * fcc_ev_crossed found one); fcc_ev_keep_start keeps s0 before the located instant's
 * values replace it and unmarks first, the event the integrator acts on itself; after
 * it acted and s0 was read at its instant, fcc_ev_next_tie returns another marked
 * value that had crossed by then (from the kept values to s0), marked as acted, or -1; fcc_ev_settle reads s0 again after the
 * ties acted and puts each acted one (and first, when first_leaves) where
 * fcc_ev_leaving says. */
void fcc_ev_mark_crossed(fcc_events *ev);
void fcc_ev_keep_start(fcc_events *ev, int first);
int fcc_ev_next_tie(fcc_events *ev);
int fcc_ev_settle(fcc_engine *e, fcc_events *ev, const double *q, const double *v,
                  double t, int first, int first_leaves);
int fcc_ev_crosses(fcc_events *ev, int k, double a, double b);
int fcc_ev_constrain(fcc_engine *e, fcc_events *ev, const double *q, const double *v,
                     double t, double *a);
int fcc_ev_correct(fcc_engine *e, fcc_events *ev, double *q, double *v);
int fcc_ev_apply(fcc_engine *e, fcc_events *ev, int k, double *q, double *v, double t);
/* Fold the used rows into the sparse engine's factorisation for the runs from here
 * (on: if e is sparse and its pattern holds the nr switchable rows; off: the Schur
 * complement). Returns whether they are folded. (fcc_events_fold.c) */
int fcc_events_fold(fcc_events *ev, fcc_engine *e, int on);
/* The folded rows' shares of fcc_ev_constrain and fcc_ev_correct (1: done folded; 0:
 * not folded now, the Schur complement instead; -1: failed). */
int fcc_ev_fold_constrain(fcc_engine *e, fcc_events *ev);
int fcc_ev_fold_correct(fcc_engine *e, fcc_events *ev, double *q);
/* The trial's bookkeeping: after a switch (fcc_ev_apply) and at each step's end
 * (fcc_ev_correct, after its correction). */
void fcc_ev_trial_switch(fcc_events *ev);
void fcc_ev_trial_step(fcc_engine *e, fcc_events *ev);
double fcc_ev_leaving(fcc_events *ev, int k, const double *q, const double *v,
                      double t);

/* Shared by fcc_events.c and fcc_event_actions.c. */
/* The quantities' Jacobian at q: its structural nonzeros into ev->rgv, and scattered
 * into the dense rows ev->rg (whose other entries are zero from the start and never
 * written): (rows x their nonzeros) numbers instead of the dense kernel's nr x n. */
void fcc_ev_gradients(fcc_events *ev, const double *q);
void fcc_ev_response(fcc_engine *e, const double *g, double *z);
void fcc_ev_row_response(fcc_engine *e, fcc_events *ev, int j, double *z);
int fcc_ev_responses(fcc_engine *e, fcc_events *ev, const double *q);
int fcc_ev_multipliers(fcc_engine *e, fcc_events *ev, int m);
int fcc_ev_hold(fcc_engine *e, fcc_events *ev, int m, const double *x,
                const double *target, double *y);
void fcc_ev_set_rows(fcc_events *ev, int k, int flag);
int fcc_ev_rests(fcc_events *ev, int k);
double fcc_ev_kinetic(fcc_engine *e, const double *q, const double *v);
double fcc_ev_row_error(fcc_events *ev, const double *q);
int fcc_ev_decide(fcc_engine *e, fcc_events *ev, const double *q);

#endif
