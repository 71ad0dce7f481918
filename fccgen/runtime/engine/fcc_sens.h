/* Forward sensitivities of a run with respect to design parameters (fcc_sens.c).
 *
 * For each design parameter p_j (a with_parameters key), the state's derivative
 * s = (dq/dp_j, dv/dp_j) is carried through the integrator's own stages: at each stage
 * the accelerations' derivative s_a solves, with the stage's factorisation of (M, B),
 *
 *     M s_a + B^T s_lam = dR1,    B s_a = dR2
 *
 * where dR1, dR2 are the residuals' directional derivatives along (s_q, s_v, dP_j)
 * (the generated tangent kernels, fcc_dp.h; lam from the stage's solve, dP_j the
 * elements' parameters' derivative). Applying the step's own stage formulas to s
 * makes s the derivative of the discrete step itself. After the step's projections,
 * s is projected by their linearisations at the projected state (same factorisation):
 *
 *     s_q <- argmin |s_q' - s_q|_M  with  B s_q' = -(dg/dp) dP_j
 *     s_v <- argmin |s_v' - s_v|_M  with  B s_v' = -dPhi[s_q', dP_j],  Phi = B v + dg/dt
 *
 * Either path (the sparse path's solves and stage multipliers: fcc_sens_sparse.h;
 * its other multipliers by a solve: fcc_sens_sparse_multipliers). All work arrays
 * come from fcc_sens_init; every other call
 * returns 0 or -1 with the engine's error record filled.
 */
#ifndef FCC_SENS_H
#define FCC_SENS_H

#include "fcc_dp.h"
#include "fcc_engine.h"

struct fcc_events;

typedef struct fcc_sens {
    const fcc_dp_table *dp;        /* the model's tangent kernels (not owned) */
    const fcc_model *model;
    int n, m, np;                  /* coordinates, constraint rows, design parameters */
    const double *dP;              /* np x model->n_p: d(element parameters)/dp_j */
    double *out;                   /* records x np x 2n (the caller's; NULL: none) */
    double *S;                     /* per p_j, 10 n: sq sv sqs sv2 sv3 sv4 sa1..sa4 */
    double *lam, *r, *rhs, *b, *gp, *phi, *y, *zero;   /* work */
    double *lq, *lv, *la, *lsq, *lsv, *llam, *lout, *lcol;   /* an element's */
    double *W;                     /* the elements' prepared tangents (fcc_dp_prepare) */
    size_t *woff;                  /* n_el + 1: element el's at W + woff[el] */
    /* the moved parameter columns: the element parameters some p_j moves (dP != 0),
     * element el's at ccol[cptr[el]] .. ccol[cptr[el + 1] - 1] (a class's parameter
     * numbers), their columns of J (fcc_dp_column) prepared at WC + coff[k] */
    int *cptr, *ccol;
    size_t *coff;
    double *WC;
    double *warm;                  /* np x (m + 1): the sparse path's last multipliers of
                                      p_j's stage solve, [m]: 1 when they converged */
    double *lam1, *lam3;           /* np x (m + 1) each, RK4 on the sparse path: p_j's
                                      multipliers of the step's stage 1 and of the last
                                      stage 3 (t + h3 / 2), [m] as warm's */
    double h3;                     /* the step whose stage 3 lam3 holds */
    double h;                      /* the step being taken */
    /* events (fcc_sens_events.c; all NULL/0 without fcc_sens_events_init) */
    struct fcc_events *ev;         /* the run's events (not owned) */
    int nr, ne;                    /* their quantity rows, event functions */
    double *tout;                  /* cap x np: d(time)/dp_j per logged event (caller's) */
    long cap;
    double *E;                     /* the work below, one allocation */
    double *saved;                 /* np x 2n: s at the step start events restart from */
    double *dheld;                 /* np x nr: d(held value)/dp_j of each lock row */
    double *tau;                   /* np: d(event time)/dp_j of the event being acted on */
    double *emu, *target;          /* nr: rows' multipliers of a stage or impact; targets */
    double *dG, *G1, *G2;          /* nr x n: d(Jacobian of the rows) along s_q; work */
    double *rb1, *rb2;             /* 2 (nr + ne + 1), nr + ne + 1 numbers */
    double *vm, *am, *ap, *dv, *w, *x, *r0, *alpha;   /* n each (alpha: m + 1) */
    double *sg1, *sg2;             /* ne x n: event gradients along s_q (a bounce) */
    double *gk, *dgk, *wz, *vp;    /* n each: a bounce's gradient, its change, response,
                                      plastic speeds */
} fcc_sens;

/* Allocate for np parameters of the model (dP: np x model->n_p numbers, kept by
 * the caller). The element parameters that dP moves here are the ones whose columns
 * of the tangent are prepared for every run: a dP given later (s->dP before
 * fcc_sens_start) may move only those (the export gives every key's here). Returns FCC_OK, FCC_ERR_MEMORY, or FCC_ERR_ARGUMENT when dp does not
 * hold the model's classes in its order. */
int fcc_sens_init(fcc_sens *s, const fcc_model *model, const fcc_dp_table *dp, int np,
                  const double *dP);
void fcc_sens_free(fcc_sens *s);
/* The sensitivities at the start, S0: np x 2n ([dq0/dp_j; dv0/dp_j] per j). */
void fcc_sens_start(fcc_sens *s, const double *S0);
/* A step of size h begins (the stages' combinations use it). */
void fcc_sens_begin_step(fcc_sens *s, double h);
/* RK4 stage k (1..4) at (q, v) with its accelerations a, after fcc_accelerations (f,
 * h assembled at (q, v), M and B and their factorisation at q): s_a of every
 * parameter, then the next stage's sensitivities (after k = 4: the step's end). */
int fcc_sens_rk4_stage(fcc_engine *e, fcc_sens *s, int k, const double *q,
                       const double *v, const double *a);
/* Any method's stage at (q, v) with accelerations a (f, h, M, B and the factorisation
 * assembled there, locked rows constrained): begin once (the stage's multipliers, and
 * the elements' tangents prepared at (q, v, a, lam)), then s_a of parameter j along
 * the stage's (sq, sv) into sa, with the same q, v and a. */
void fcc_sens_stage_begin(fcc_engine *e, fcc_sens *s, const double *q, const double *v,
                          const double *a);
int fcc_sens_stage_acc(fcc_engine *e, fcc_sens *s, int j, const double *q,
                       const double *v, const double *a, const double *sq,
                       const double *sv, double *sa);
/* The linearised projections at the projected (q, v), after fcc_project_velocities
 * (its factorisation held). */
int fcc_sens_project(fcc_engine *e, fcc_sens *s, const double *q, const double *v);
/* Copy the state's sensitivities into record rec of out. */
void fcc_sens_record(const fcc_sens *s, long rec);

/* Shared with fcc_sens_events.c: the state's s_q of parameter j (s_v follows at +
 * FCC_SENS_SV_OFFSET n), and the tangent sweep of every element along (sq, sv, dP_j)
 * at (q, v, a, lam): dR1 into s->rhs, dR2 into s->b, -(dg/dp) dP_j into s->gp,
 * -dPhi into s->phi. */
double *fcc_sens_sq(const fcc_sens *s, int j);
double *fcc_sens_sv(const fcc_sens *s, int j);
void fcc_sens_sweep(fcc_engine *e, fcc_sens *s, const double *q, const double *v,
                    const double *a, const double *lam, const double *sq,
                    const double *sv, const double *dPj);

/* The sparse path's multipliers of a system the step's factorisation holds: lam (m)
 * of M x + B^T lam = Q, B x = b (b NULL: 0), by the refinement (x: n numbers of
 * work); warm: from the last accelerations' multipliers. (The dense path takes them
 * from its QR of B: fcc_dense_multipliers.) */
void fcc_sens_sparse_multipliers(fcc_engine *e, const double *Q, const double *b,
                                 double *x, double *lam, int warm);

/* Sensitivities through events (fcc_sens_events.c).
 *
 * An event located at te (s_k(q(te), te) = 0) inside a step: the engine integrates
 * a partial step of size tau from the step's start and projects; s is carried
 * through that partial step as through any step (at fixed tau), and
 *     dte/dp = -(ds_k/dq . s_q) / (ds_k/dq . v + ds_k/dt)
 * (the event functions do not depend on the design parameters). The state's total
 * derivative at te is s + f- dte/dp (f = (v, a)); the event's map x+ = J(x-) is
 * linearised at it, and the rest of the step starts from
 *     s+ = J_x (s- + f- dte/dp) + J_p - f+ dte/dp.
 * log: J = I, f+ = f- (s+ = s-); unlock: J = I, a+ without the rows; lock: the
 * plastic impact (M-orthogonal projection of v onto B v + g_t = 0 and G v = 0) and
 * the rows' held values r(q(te)) whose derivative G (s_q + v dte/dp) the linearised
 * projections and stages hold afterwards; stop: the run ends, and its last record
 * carries the total derivative s + f- dte/dp. While rows are locked, each stage and
 * projection of s adds them: G s_a = -d(G a + Gdot v)[s_q, s_v], G s_q = d(held),
 * G s_v = -dG[s_q] v (the rows' second derivatives by central differences of their
 * generated Jacobian and bias along s_q: O(eps^2), about 1e-10 relative).
 * bounce (restitution e_k, Newton's law along the response w to g = ds_k/dq): with
 * v_p = v- + mu_p w the plastic impact onto B, the used rows and g (mu_p = -g v- /
 * g w), v+ = (1 + e) v_p - e v-, so dv+ = (1 + e) dv_p - e dv-, dv_p the plastic
 * impact's linearisation with g as one more row (its change dg[s_q] by central
 * differences of the generated event gradients, as the rows'); q+ = q-. A bounce that
 * rests (too slow, or the Zeno guard) is a lock of its row: the lock's jump.
 * release (of a resting bounce): its function is the row's multiplier mu, so
 * dte/dp = -dmu / (dmu/dt), dmu the stage's linearised multiplier along the total
 * derivative (and dP), dmu/dt by central differences along the motion; then as an
 * unlock. */
/* Carry the sensitivities through ev's events; tout: cap x np (logged events).
 * Returns FCC_OK or FCC_ERR_MEMORY. */
int fcc_sens_events_init(fcc_sens *s, struct fcc_events *ev, double *tout, long cap);
/* Keep / put back s at a step start (the events' restarts). */
void fcc_sens_save(fcc_sens *s);
void fcc_sens_restore(fcc_sens *s);
/* Event k located at (q, v, t), projected, before fcc_ev_apply: dte/dp and the total
 * derivative (s becomes s + f- dte/dp). */
int fcc_sens_event_before(fcc_engine *e, fcc_sens *s, int k, const double *q,
                          const double *v, double t);
/* After fcc_ev_apply(k) returned rc at (q, v, t) (v: v+): the jump and s+. */
int fcc_sens_event_after(fcc_engine *e, fcc_sens *s, int k, int rc, const double *q,
                         const double *v, double t);
/* With locked rows (used), at a stage whose fcc_ev_constrain has just run: add the
 * rows' forces' derivative dG[sq]^T mu to s->rhs (s->emu: the stage's mu). */
void fcc_sens_rows_rhs(fcc_sens *s, const double *q, const double *sq);
/* ... then hold the rows on s_a after the solve: G s_a = -(dG a + d(Gdot v)). */
int fcc_sens_rows_acc(fcc_engine *e, fcc_sens *s, const double *q, const double *v,
                      const double *a, const double *sq, const double *sv, double *sa);
/* The rows' part of the linearised projections (after fcc_sens_project's B parts). */
int fcc_sens_rows_positions(fcc_engine *e, fcc_sens *s, int j, const double *q,
                            double *sq);
int fcc_sens_rows_speeds(fcc_engine *e, fcc_sens *s, const double *q, const double *v,
                         const double *sq, double *sv);
/* The number of used rows while sensitivities follow events (0: none). */
int fcc_sens_rows(const fcc_sens *s);
/* Keep the stage's rows' multipliers (ev->mu after fcc_ev_constrain) in s->emu; add
 * G^T emu to r (n numbers). */
void fcc_sens_keep_mu(fcc_sens *s);
void fcc_sens_rows_force(const fcc_sens *s, double *r);

#endif
