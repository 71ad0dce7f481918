/* What the integrators share (fcc_rk4.c, fcc_dopri5.c, fcc_ali3p.c): where their
 * records go, and how a run pauses. */
#ifndef FCC_RUN_H
#define FCC_RUN_H

#include "fcc_engine.h"

/* Called after each step (a run's advance function returns FCC_RUN_PAUSE when it
 * returns nonzero): the Python build pauses about every 0.5 s of wall time for
 * signals and progress; NULL never pauses. */
typedef int (*fcc_pause_fn)(void *ctx);

/* The records of a run: caller-owned arrays with room for every record (t; q and v
 * n_q per record; body 6 n_bodies; energy (kinetic + potential); cerr max |g|). */
typedef struct fcc_records {
    double *t, *q, *v, *body, *energy, *cerr;
} fcc_records;

/* Write record j of the state (q, v) (all but its time): coordinates, speeds, body
 * outputs, energy and max |g|; returns that max |g|. */
double fcc_write_record(fcc_engine *e, const fcc_records *out, long j, const double *q,
                        const double *v);
/* The bounds past which a run has diverged (docs/reliability.md, "Runs that blow
 * up"): *q_bound, 1e6 times the size the state can reach by moving at its initial
 * speed, q_ref + |v0| t_end; *v_bound, 1e6 times the speed that crosses the model's
 * size in one step dt, |v0| + q_ref / dt (q_ref = max |q0|, or 1), or infinity for
 * adaptive methods (dt <= 0: no step to measure speeds by). An unstable explicit step
 * grows the state by a constant factor per step, so it passes these within tens of
 * steps, while no accurate run comes near them. (fccgen/runtime/guards.py holds the
 * same rule for the runs that step in Python.) */
void fcc_divergence_bounds(int n, const double *q0, const double *v0, double t_end,
                           double dt, double *q_bound, double *v_bound);
/* max |x_i| > bound (n numbers); the value and bound go to the error record. */
int fcc_diverged(fcc_engine *e, const double *x, double bound);

#endif
