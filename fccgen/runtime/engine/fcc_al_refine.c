/* The sparse path's constrained solve: iterative refinement of the saddle-point system
 *
 *     M x + B^T lambda = Q,    B x = b
 *
 * with the true residuals r1 = Q - M x - B^T lambda, r2 = b - B x, each correction an
 * augmented-Lagrangian step (Garcia de Jalon and Bayo) with the factor of
 * A = M + B^T diag(alpha) B (fcc_sparse_blocks.c):
 *
 *     A dx = r1 + B^T alpha r2,   dlambda = alpha (B dx - r2),
 *
 * which zeroes r1 and multiplies the constraint part of the error by about
 * 1 / (1 + alpha sigma^2 / m) (sigma: a singular value of B, m a mass): with
 * alpha_k = RHO m_ref / ||B_k||^2 about three iterations reach rounding. It stops when
 * the estimated remaining change, |dx| rate / (1 - rate), is below AL_STOP |x|. The
 * multiplier update alpha (B dx - r2) equals -alpha r2 at the new x, so it is made in
 * the next iteration's residual pass, which forms r2, the update and r1 + B^T alpha r2
 * in one sweep over the element blocks. Near a singular position (sigma small) these
 * steps slow down; the corrections are then conjugate-gradient solves of the
 * multipliers' Schur system B A^{-1} B^T, preconditioned by diag(alpha): its
 * eigenvalues are t / (1 + t), t = alpha sigma^2 / m, clustered at 1 but for the weak
 * directions, so a few weak directions cost a few extra steps (the scissor mast: 2-4),
 * many at once more (the A02 chain of 80 loops at its flat position: 180). Their
 * stopping test is on the residual, with a bound set from the first step's (see the
 * constants). Redundant rows need no rank decision.
 *
 * With switchable rows folded into the factor (fcc_sparse_fold.c) a step whose change
 * is itself at most AL_STOP of the floor also ends the steps: a structure that its
 * held rows lock to 0 DOF has accelerations and speeds of rounding size, and the rate
 * of two steps of noise says nothing (it read as slow, and boosted the factor at every
 * stage of the latched boom of 12 units: 4e-18 of the floor after a warm start).
 *
 * Augmented-Lagrangian steps stop when the estimated remaining change,
 * |dx| rate / (1 - rate), is at most AL_STOP |x| (|x| or the floor x_floor under it,
 * whichever is larger: the velocity projection's, fcc_sparse_engine.c; 0 for the
 * other solves); a step with rate above SLOW (or the
 * al_max-th) hands over to conjugate-gradient corrections. Their iterations stop when
 * the preconditioned residual r2^T diag(alpha) r2 of the constraints is at most
 * CG_TOL^2 times its value after the first augmented-Lagrangian step (a test on the
 * residual, not on the change: past the rounding floor the change can grow, along the
 * null space of B^T, which the redundant rows make large), or at the residual's own
 * rounding, sum_k alpha_k (eps ||B_k|| |x|)^2, whichever is larger, or after cg_max
 * steps. (That floor: a warm start's first residual, or a velocity projection's, is
 * near rounding already, and CG_TOL^2 of it lies below what any x gives; with the
 * raised alpha below, whose factor leaves some 1e-14 |x| of noise, such solves ran
 * all refine_max corrections, counted as not converged and were done again with
 * RHO's factor: on the scissor boom of 500 units, 69 conjugate-gradient steps, and
 * 12.4 ms per RK4 step against 3.69 ms with the floor: docs/performance.md.) The
 * refinement ends when a correction after the first starts below that bound (its
 * right-hand side is rounding: nothing left for the iterations) and, where the bound
 * is the residual's rounding, changes x by at most ROUNDING_ACCEPT |x|; or when a
 * correction changes x by at most REFINE_STOP |x| (the same floor). (The rounding
 * bound reads the rows' residual only; the change is the independent signal, how far
 * x still was off along the null space of B, which that residual does not see. Along
 * a weakly kept direction, the tilted body with sigma_r / sigma_1 =
 * 1e-3 of tests/test_small_model_path.py, corrections that started at rounding still
 * moved x by up to 1e-4 |x|; accepting them left its run 1.4e-4 off the dense path's,
 * with no warning. On the 1000-bar scissor boom the corrections that start at
 * rounding move x by 1e-14 .. 1e-9 |x|, 33 of 4,770 above 1e-10; on the tilted body
 * by 1e-13 .. 1e-10 |x|, and 60 of 10,000 above, from 1e-10 to 1e-4 |x|.) After
 * refine_max corrections it is a solve
 * that did not converge (counted, and redone by the dense solve when the model is
 * small enough: fcc_sparse_engine.c). The bound is relative to the first step's
 * residual, not to the first correction's: after al_max steps that converged slowly
 * the correction may start at rounding already (the scissor mast of 17 bays at
 * t = 0.2 s), and iterations below it only amplify the noise. CG_TOL 1e-8: measured
 * on the A02 chain of 80 loops at its flat position, 1e-9 reaches the same accuracy
 * and 1e-10 no longer converges.
 * FCC_CG_MAX 400: that chain takes 180 steps there (80 eigenvalues of
 * diag(alpha) B A^{-1} B^T spread between 1e-10 and 0.99: every loop's row nearly
 * dependent).
 *
 * A Newton step of the position projection stops at NEWTON_STOP instead
 * (fcc_sp_kkt_solve's newton): an error e |dq| in the step leaves about e times the
 * residual it removes, and moves q by e |dq| along the constraints, with |dq| about
 * the position tolerance (1e-11 of the model's size); the next residual check judges
 * the step. Where the rows are well conditioned the second step's estimate is about
 * 1e-14 |x|, so these solves take two steps instead of three.
 *
 * Directions beyond the decided rank (fcc_sparse_set_beyond_rank). Rows dependent only
 * on the constraint manifold (a linkage mobile by its geometry: Bricard's loop, the
 * scissor mast) are independent a little off it: at an RK stage, positions off by the
 * step's error, their singular value rises from 1e-15 to about that error, and so does
 * the right-hand side's component along them. Exactly dependent rows (A02's planar
 * rows) stay dependent. The dense path keeps rank pivots and drops the rest; resolving
 * such a direction instead divides the one small number by the other: stage
 * accelerations wrong by O(1) (measured 9.6 and 2e4 on Bricard's two encodings at
 * dt 1e-3) that pass every residual test. So for such models the conjugate-gradient
 * corrections stop at a search direction p whose preconditioned Rayleigh quotient
 * p^T S p / p^T diag(alpha)^-1 p, about t / (1 + t) with t = alpha sigma^2 / m, is
 * below that of a direction of FCC_BEYOND_FRACTION times the smallest scaled singular
 * value kept by the rank decision: far below every direction within the rank (the
 * scissor mast's weakest has t = 42), far above the stage's (sigma ~1e-6 at dt 1e-3,
 * 1e-4 at 1e-2, against 0.05 .. 0.2 kept on Bricard), and the solve counts as not
 * converged: the dense solve, which drops that direction, redoes it. Accepting the
 * stopped solve is not enough: the augmented-Lagrangian steps before it move x along
 * the direction too, by t / (1 + t) of the wrong amount each (Bricard's line encoding
 * kept 1e-2 J of energy error so).
 *
 * Near a singular position. Those conjugate-gradient steps are as many as the weak
 * directions with distinct t (the A02 chain of 40 loops near its flat position: up to
 * 59 in one solve, 176 in one RK4 step, 7 times the median step). So the first solve
 * of a factorisation that turns slow (from zero multipliers, or from warm ones)
 * factors A again with alpha raised FCC_AL_BOOST (1e5, fcc_sp_factor_boosted) and
 * starts again from zero; the rest of that factorisation's solves keep the raised
 * alpha. t grows 1e5 times, the weak directions' t / (1 + t) cluster at 1 and the
 * augmented-Lagrangian steps contract at 1e-4 .. 1e-2 again, the corrections (where
 * still needed) take a few steps. The chain stays near that position for a few steps,
 * so the next FCC_BOOST_HOLD factorisations (fcc_sp_factor) are made with the raised
 * alpha at once, and the count starts again at each raised solve whose steps still
 * contract slower than BOOST_STAY (1e-5: with RHO those would have been slow, t < 19);
 * a warm start there that turns slow goes on to the corrections instead of starting
 * again from zero. Without this, every solve of such a step first ran with RHO, turned
 * slow, started again from zero and factored again: 69 iterations and 11
 * factorisations in the chain's slowest step (4 times the median step), against 26
 * and 5 now, with 10 and 4 in the median step (benchmarks/step_time_spread.py). A's
 * condition grows 1e5 times as well (about 1e-4 relative rounding in one solve), which
 * the refinement's true residuals remove, as they remove RHO's: the runs agree with
 * the dense path's to 5e-12 there (4e-11 with a 1e4 boost started only after a slow
 * solve, 2e-12 with RHO: tests/test_sparse_singular_boost.py). With 1e4 held the
 * same way the raised solves still contract at up to 0.7 (49 iterations in the
 * slowest step); 1e6 takes no fewer than 1e5 (26), with 10 times the rounding.
 * Only the motion's own solves raise alpha (the accelerations, from lam_warm, and the
 * solves from zero: Newton, velocities, event responses); the sensitivities' solves,
 * which carry their own multipliers, keep the factor they find (a raise inside them
 * stopped the latch pendulum's sensitivity run with non-finite values at its latch:
 * tests/test_sensitivity_events.py). A run whose factorisations serve such solves
 * makes none with the raised alpha at once (own_lam_seen, from its first such solve):
 * held after that pendulum's latch, they stopped its sensitivity run the same way.
 * Models with rows beyond the decided rank (below) keep RHO: raising alpha moves x
 * along such a row by t / (1 + t) of a wrong amount (fcc_sparse_blocks.c, RHO). A
 * raised factor that fails its pivot test is replaced by RHO's again, and so is one
 * whose solve does not converge (then no raise is held: a driven four-bar, B square,
 * met that at its table's knots, and each held raise failed again,
 * tests/test_driver_tables.py).
 *
 * Warm start. Each augmented-Lagrangian step multiplies the multipliers' error by the
 * rate, about 1e-7 (RHO); from zero the first x is off by that rate times lambda, so a
 * solve takes three steps (two to reach rounding, one whose rate shows it has). The
 * accelerations of consecutive evaluations (RK stages, steps) differ by O(h), so
 * starting from the last converged ones leaves the first x off by the rate times that
 * change: two steps. Projections and Newton steps solve other systems and start from
 * zero. A warm start that meets a slow step (rate above SLOW) is dropped and the solve
 * starts again from zero, so the conjugate-gradient corrections near singular
 * positions run exactly as from a cold start.
 */
#include <float.h>
#include <math.h>
#include <string.h>

#include "fcc_engine.h"

#define AL_STOP 1e-15
#define NEWTON_STOP 1e-8
#define SLOW 0.05
#define CG_TOL 1e-8
#define REFINE_STOP 1e-14
#define ROUNDING_ACCEPT 1e-10
#define BOOST_STAY 1e-5            /* "Near a singular position" */

/* One pass over the elements for the true residuals at x: r2 = b - B x (b NULL: zero;
 * stored when r2 is not NULL), then, when pending, the deferred multiplier update
 * lambda -= alpha r2 (the augmented-Lagrangian update lambda + alpha (B dx - r2_old)
 * written with the new residual), and y = base - M x - B^T (lambda - alpha r2) when
 * penalised (the right-hand side r1 + B^T alpha r2 of the next correction),
 * y = r1 = base - M x - B^T lambda otherwise; rho = r2^T diag(alpha) r2. Each
 * element's coordinates are gathered and scattered once; each of its coordinates'
 * share is summed in a register (M row, then the rows' terms in order). */
static void residual_pass(fcc_engine *e, const double *x, const double *b, int pending,
                          int penalised, double *y, double *r2)
{
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int el, a, c, r, nq, ng, row;
    const int *idx, *rows;
    const double *mb, *bb;
    double *xl = s->lq, *zl = s->lz;
    double acc, z;
    memcpy(y, s->base, (size_t)e->n * sizeof(double));
    s->rho = 0.0;
    for (el = 0; el < e->model->n_el; el++) {
        nq = P->snq[el];
        ng = P->sng[el];
        mb = P->mcptr[el + 1] > P->mcptr[el] ? s->Mc + P->mcptr[el] : NULL;
        if (mb == NULL && ng == 0)
            continue;
        idx = P->sidx + P->sptr[el];
        for (a = 0; a < nq; a++)
            xl[a] = x[idx[a]];
        bb = s->Bc + P->bcptr[el];
        rows = P->srow + P->sgptr[el];
        for (r = 0; r < ng; r++) {
            row = rows[r];
            acc = b != NULL ? b[row] : 0.0;
            for (a = 0; a < nq; a++)
                acc -= bb[r * nq + a] * xl[a];
            if (pending)
                s->lam[row] -= s->alpha[row] * acc;
            if (r2 != NULL)
                r2[row] = acc;
            s->rho += acc * s->alpha[row] * acc;
            z = s->lam[row];
            if (penalised)
                z -= s->alpha[row] * acc;
            zl[r] = z;
        }
        for (a = 0; a < nq; a++) {
            acc = 0.0;
            if (mb != NULL)
                for (c = 0; c < nq; c++)
                    acc += mb[a * nq + c] * xl[c];
            for (r = 0; r < ng; r++)
                acc += bb[r * nq + a] * zl[r];
            y[idx[a]] -= acc;
        }
    }
    if (s->ms > e->m)
        fcc_sp_sw_residual(e, x, pending, penalised, y, r2);
}

void fcc_sp_first_pass(fcc_engine *e, const double *b, int warm, double *y)
{
    /* residual_pass at x = 0 (not pending, penalised), with lambda = 0 or (warm) the
     * multipliers the solve started from: y = base - B^T (lambda - alpha b), without
     * the products with M and B that vanish there; the same operations in the same
     * order as residual_pass on what is left (the same rounding). */
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int el, a, r, nq, ng, row;
    const int *idx, *rows;
    const double *bb;
    double *zl = s->lz;
    double acc, z;
    memcpy(y, s->base, (size_t)e->n * sizeof(double));
    if (s->ms > e->m)
        fcc_sp_sw_first(e, warm, y);
    if (b == NULL && !warm)
        return;
    for (el = 0; el < e->model->n_el; el++) {
        ng = P->sng[el];
        if (ng == 0)
            continue;
        nq = P->snq[el];
        idx = P->sidx + P->sptr[el];
        bb = s->Bc + P->bcptr[el];
        rows = P->srow + P->sgptr[el];
        for (r = 0; r < ng; r++) {
            row = rows[r];
            z = warm ? s->lam[row] : 0.0;
            if (b != NULL)
                z -= s->alpha[row] * b[row];
            zl[r] = z;
        }
        for (a = 0; a < nq; a++) {
            acc = 0.0;
            for (r = 0; r < ng; r++)
                acc += bb[r * nq + a] * zl[r];
            y[idx[a]] -= acc;
        }
    }
}

/* The conjugate gradients' bound from the first step's residual rho (residual_pass
 * just made): CG_TOL^2 rho, but not below the rounding of the residual itself,
 * sum_k alpha_k (eps ||B_k|| size)^2 (size: |x| or the floor under it), the value of
 * rho when each r2_k is off by one rounding of B_k x; *at_rounding is set when that
 * rounding is the bound. */
static double first_bound(const fcc_engine *e, double size, int *at_rounding)
{
    const fcc_sparse *s = &e->sp;
    int k;
    double floor = 0.0, bound = CG_TOL * CG_TOL * s->rho;
    for (k = 0; k < s->ms; k++)
        floor += s->alpha[k] * s->rnorm[k] * s->rnorm[k];
    floor *= DBL_EPSILON * size * DBL_EPSILON * size;
    *at_rounding = floor > bound;
    return bound > floor ? bound : floor;
}

/* (dx, dlam) of M dx + B^T dlam = r1, B dx = r2: conjugate gradients on the
 * multipliers' Schur system S mu = B x0 - r2, S = B A^{-1} B^T, preconditioned by
 * diag(alpha), from x0 = A^{-1} (r1 + B^T alpha r2); dx = x0 - A^{-1} B^T mu and
 * dlam = mu + alpha (B dx - r2) satisfy the first equation exactly whatever the
 * iteration count. The iterations stop when res^T alpha res is at most rz_stop (set to
 * CG_TOL^2 times its first value when not positive), or after cg_max. Returns the
 * number of solves with A; cg_steps holds the iterations taken (0: the residual
 * started below rz_stop). */
static int correction(fcc_engine *e, double *rz_stop)
{
    fcc_sparse *s = &e->sp;
    int i, n = e->n, m = s->ms, sw = s->ms > e->m;   /* the rows, switchable ones too */
    double rz, rz_new, psp, pap, step;
    s->beyond_hit = 0;
    memcpy(s->dx, s->r1, (size_t)n * sizeof(double));
    fcc_sp_mult_bt(e, s->r2, s->alpha, s->dx);
    if (sw)
        fcc_sp_sw_mult_t(e, s->r2, s->alpha, s->dx);
    fcc_sp_solve_a(e, s->dx);
    fcc_sp_mult_b(e, s->dx, s->res);
    if (sw)
        fcc_sp_sw_mult(e, s->dx, s->res);
    rz = 0.0;
    for (i = 0; i < m; i++) {
        s->res[i] -= s->r2[i];
        s->mu[i] = 0.0;
        s->cg_p[i] = s->alpha[i] * s->res[i];
        rz += s->res[i] * s->cg_p[i];
    }
    if (!(*rz_stop > 0.0))
        *rz_stop = CG_TOL * CG_TOL * rz;
    s->cg_steps = 0;
    while (s->cg_steps < s->cg_max && rz > *rz_stop) {
        memset(s->u, 0, (size_t)n * sizeof(double));
        fcc_sp_mult_bt(e, s->cg_p, NULL, s->u);
        if (sw)
            fcc_sp_sw_mult_t(e, s->cg_p, NULL, s->u);
        fcc_sp_solve_a(e, s->u);
        fcc_sp_mult_b(e, s->u, s->cg_sp);
        if (sw)
            fcc_sp_sw_mult(e, s->u, s->cg_sp);
        s->cg_steps++;
        psp = 0.0;
        for (i = 0; i < m; i++)
            psp += s->cg_p[i] * s->cg_sp[i];
        if (!(psp > 0.0))
            break;
        if (s->beyond_quotient > 0.0) {
            pap = 0.0;
            for (i = 0; i < m; i++)
                if (s->alpha[i] > 0.0)
                    pap += s->cg_p[i] * s->cg_p[i] / s->alpha[i];
            if (psp < s->beyond_quotient * pap) {
                s->cg_steps--;                 /* not taken: beyond the rank */
                s->n_beyond_rank++;
                s->beyond_hit = 1;
                break;
            }
        }
        step = rz / psp;
        for (i = 0; i < n; i++)
            s->dx[i] -= step * s->u[i];
        rz_new = 0.0;
        for (i = 0; i < m; i++) {
            s->mu[i] += step * s->cg_p[i];
            s->res[i] -= step * s->cg_sp[i];
            rz_new += s->res[i] * s->alpha[i] * s->res[i];
        }
        for (i = 0; i < m; i++)
            s->cg_p[i] = s->alpha[i] * s->res[i] + (rz_new / rz) * s->cg_p[i];
        rz = rz_new;
    }
    for (i = 0; i < m; i++)                 /* res = B dx - r2 */
        s->bdx[i] = s->mu[i] + s->alpha[i] * s->res[i];
    return s->cg_steps + 1;
}

/* The refinement from x = 0 and the multipliers in lam (zero unless warm), the solves
 * with A added to *solves; the augmented-Lagrangian steps stop when the estimated
 * remaining change is at most stop |x|. Each correction is one augmented-Lagrangian
 * step, its right-hand side and the previous step's multiplier update formed in one
 * pass (residual_pass), while those converge fast; once a step shrinks the change by
 * less than SLOW (a nearly singular B: near a singular position), the corrections are
 * conjugate-gradient solves (correction). may_boost 1: a cold start with RHO that
 * meets that slow step returns -2 (the caller raises alpha); -1: a warm start with a
 * raised factor goes on to those corrections. Returns 1 when it converged, 0 when
 * not, -1 when a warm start met that slow step otherwise (not continued: the
 * conjugate-gradient bounds are set from a cold start's first residual). At most
 * al_max + refine_max passes; slow_rate receives the slowest rate of its
 * augmented-Lagrangian steps after the first two (1 once corrections ran). */
static int refine(fcc_engine *e, const double *b, double *x, int warm, int *solves,
                  double stop, int may_boost)
{
    fcc_sparse *s = &e->sp;
    int i, it, n = e->n, m = e->sp.ms, cg = 0, at_rounding = 0;
    double nd = 0.0, nx = 0.0, prev = 0.0, rate, rz_stop = -1.0, size;
    int pending = 0;
    memset(x, 0, (size_t)n * sizeof(double));
    s->slow_rate = 0.0;
    for (it = 0; it < s->al_max + s->refine_max; it++) {
        if (cg) {
            s->slow_rate = 1.0;
            residual_pass(e, x, b, pending, 0, s->r1, s->r2);
            pending = 0;
            *solves += correction(e, &rz_stop);
            if (s->beyond_hit)                 /* redone densely */
                return 0;
            for (i = 0; i < m; i++)
                s->lam[i] += s->bdx[i];
            nd = 0.0;
            nx = 0.0;
            for (i = 0; i < n; i++) {
                x[i] += s->dx[i];
                if (fabs(s->dx[i]) > nd)
                    nd = fabs(s->dx[i]);
                if (fabs(x[i]) > nx)
                    nx = fabs(x[i]);
            }
        } else {
            if (it == 0) {
                fcc_sp_first_pass(e, b, warm, s->dx);
            } else {
                residual_pass(e, x, b, pending, 1, s->dx, NULL);
                if (it == 1)
                    rz_stop = first_bound(e, nx > s->x_floor ? nx : s->x_floor,
                                          &at_rounding);
            }
            fcc_sp_solve_a_add(e, s->dx, x, &nd, &nx);
            pending = 1;
            *solves += 1;
        }
        if (!(nd > 0.0))                        /* zero, or NaN (the caller checks x) */
            return 1;
        size = nx > s->x_floor ? nx : s->x_floor;   /* |x|, or the floor under it */
        if (cg) {
            if (nd <= REFINE_STOP * size
                || (cg > 1 && s->cg_steps == 0
                    && (!at_rounding || nd <= ROUNDING_ACCEPT * size)))
                return 1;
            cg++;
            if (cg > s->refine_max)
                return 0;
        } else if (it > 0) {
            rate = nd / prev;
            if (it > 1 && rate > s->slow_rate)
                s->slow_rate = rate;
            if (rate < 0.5 && nd * rate / (1.0 - rate) <= stop * size)
                return 1;
            if (s->sw_live && s->x_floor > 0.0 && nd <= stop * size)
                return 1;                      /* rounding of the floor's scale */
            if (rate > SLOW)
                cg = 1;
        }
        if (!cg && it + 1 >= s->al_max)
            cg = 1;
        if (cg && warm && !(may_boost < 0 && s->boost != 1.0))
            return -1;
        if (cg && may_boost > 0)
            return -2;
        prev = nd;
    }
    return 0;
}

int fcc_sp_kkt_solve(fcc_engine *e, const double *Q, const double *w, const double *b,
                     double *x, int warm, int newton)
{
    /* x of M x + B^T lambda = Q + M w, B x = b (Q, w, b may be NULL: zero): iterative
     * refinement with the true residuals. warm (the accelerations): lambda starts
     * from the last converged acceleration solve's multipliers, else from zero; a warm
     * start that meets a slow step starts again from zero. newton: a Newton step's
     * solve, whose augmented-Lagrangian steps stop at NEWTON_STOP. Returns whether
     * the refinement converged. */
    fcc_sparse *s = &e->sp;
    int status = fcc_sp_kkt_solve_from(e, Q, w, b, x, warm ? s->lam_warm : NULL,
                                       warm && s->warm_valid, newton);
    if (warm)
        s->warm_valid = status;
    return status;
}

int fcc_sp_kkt_solve_from(fcc_engine *e, const double *Q, const double *w,
                          const double *b, double *x, double *lam_io, int valid,
                          int newton)
{
    /* fcc_sp_kkt_solve with its own warm start: lambda starts from lam_io (m numbers)
     * when valid, and lam_io receives the multipliers of a converged solve (lam_io
     * NULL: from zero, nothing kept). Returns whether the refinement converged. */
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int i, status, solves = 0, n = e->n, m = e->m, ms = s->ms;
    int motion = s->beyond_quotient == 0.0 && (lam_io == NULL || lam_io == s->lam_warm);
    if (lam_io != NULL && lam_io != s->lam_warm)
        s->own_lam_seen = 1;              /* no held raise from here on in this run */
    if (Q != NULL)
        memcpy(s->base, Q, (size_t)n * sizeof(double));
    else
        memset(s->base, 0, (size_t)n * sizeof(double));
    if (w != NULL)                        /* M w whole: w may move pinned coordinates */
        fcc_sp_mult_m_full(e, w, s->base, 1);
    for (i = 0; i < P->n_pinned; i++)     /* pinned coordinates: x stays 0 there */
        s->base[P->pinned[i]] = 0.0;
    s->n_solves++;
    status = -1;
    if (lam_io != NULL && valid) {
        /* lam_warm holds the switchable rows' multipliers too; a caller's m only */
        memcpy(s->lam, lam_io, (size_t)(lam_io == s->lam_warm ? ms : m) * sizeof(double));
        if (lam_io != s->lam_warm && ms > m)
            memset(s->lam + m, 0, (size_t)(ms - m) * sizeof(double));
        status = refine(e, b, x, 1, &solves, AL_STOP, motion ? -1 : 0);
        if (status == -1 && motion && s->boost == 1.0)
            status = -2;                  /* slow with RHO: the boost at once */
    }
    if (status == -1) {
        memset(s->lam, 0, (size_t)ms * sizeof(double));
        status = refine(e, b, x, 0, &solves, newton ? NEWTON_STOP : AL_STOP,
                        motion && s->boost == 1.0);
    }
    if (status == -2) {                   /* slow with RHO: again with the boost */
        memset(s->lam, 0, (size_t)ms * sizeof(double));
        fcc_sp_factor_boosted(e);
        status = refine(e, b, x, 0, &solves, newton ? NEWTON_STOP : AL_STOP, 0);
        s->slow_rate = 1.0;
    }
    if (status != 1 && motion && s->boost != 1.0) {
        /* the raised factor's solve did not converge (the raised A too ill-conditioned
         * for the refinement: a driven four-bar, whose B is square, at its table's
         * knots): RHO's factor again, from zero, and no held raise */
        s->slow_rate = 0.0;
        if (fcc_sp_factor_unboosted(e) == 0) {
            memset(s->lam, 0, (size_t)ms * sizeof(double));
            status = refine(e, b, x, 0, &solves, newton ? NEWTON_STOP : AL_STOP, 0);
        }
    }
    if (status == 1 && motion && s->boost != 1.0 && s->slow_rate > BOOST_STAY
            && !s->own_lam_seen)
        s->boost_hold = FCC_BOOST_HOLD;   /* still near: the next factors boosted */
    if (lam_io != NULL && status == 1)
        memcpy(lam_io, s->lam, (size_t)(lam_io == s->lam_warm ? ms : m) * sizeof(double));
    if (status != 1)
        s->n_unconverged++;
    s->n_iterations += solves;
    if (solves > s->most_iterations)
        s->most_iterations = solves;
    return status == 1;
}
