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
/* max |x_i| > bound (n numbers); the value and bound go to the error record. */
int fcc_diverged(fcc_engine *e, const double *x, double bound);

#endif
