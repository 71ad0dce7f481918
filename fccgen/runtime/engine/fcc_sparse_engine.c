/* The sparse path: accelerations and projections in time linear in the model's size.
 *
 * The engine's building blocks (fcc_engine.c) hand over to these when the engine takes
 * the sparse path; its solves are the augmented-Lagrangian refinement of
 * fcc_al_refine.c over the element blocks and the LDL^T of A = M + B^T diag(alpha) B
 * of fcc_sparse_blocks.c:
 *
 * - accelerations: M a + B^T lambda = f - h, B a = -c (Baumgarte:
 *   B a = -c - 2 alpha g' - beta^2 g, formed in baumgarte_targets);
 * - velocity projection: M w + B^T mu = M v, B w = b with b = -dg/dt of
 *   time-dependent constraints;
 * - each Newton step of the position projection (fcc_project_positions, with this
 *   path's assembly, residual and solve): M dq + B^T mu = 0, B dq = -g; after an
 *   integrator's step, first chord steps (below).
 *
 * Chord steps. After an RK4 step the blocks and the factorisation held are those of
 * its last stage, at q + h v3, about h^2 a / 2 from the new q (5e-6 m on the cart of
 * 20 links at dt 1e-3; DOPRI5's last stage is at the new q itself). A Newton step with
 * them, M4 dq + B4^T mu = 0, B4 dq = -g(q), is a chord step: a consistent system,
 * whose error is B4 - B(q), relative size d (about the distance over the model's
 * size). It is solved by one augmented-Lagrangian step from zero multipliers,
 * dq = A4^{-1} B4^T alpha (-g), off by about 1 / (1 + alpha sigma^2 / m) of itself
 * (1e-7 where the rows are well conditioned, more near a singular position, where it
 * shows in the residual as d does). The step leaves about d of the residual
 * (1e-6 .. 1e-5, measured after RK4 steps of 1e-3 s), and moves q along the
 * constraints, where no residual sees it, by about d times the step; its metric is M
 * at the stage's positions instead of the new ones, a change of the same order. It
 * saves the factorisation, the assembly of M and B and the refined solve of an exact
 * step: a sixth of the cart's RK4 step at n = 20. A chord step is kept when it leaves
 * at most CHORD_GAIN of the residual and that move, estimated as the fraction of the
 * residual left times the step's largest component, is at most CHORD_DRIFT of the
 * position tolerance; otherwise (a factorisation made far from q, a row that nearly
 * vanishes there, or a large step: the double pendulum at dt 0.05, where d is about
 * 1e-2 and the steps about 1e-7 m, moved 1.4e-8 m off the exact projections'
 * trajectory in 20 steps) it is undone and exact steps take over. The blocks must be
 * the factorisation's own: B at the new q with the stage's factor makes the penalised
 * system inconsistent by alpha |B| |B4 - B(q)|, and the step then moves q along the
 * constraints by about RHO d times its size (100 times on the cart). Models with rows
 * dependent only on the constraint manifold (fcc_al_refine.c, "Directions beyond the
 * decided rank") take exact steps only, whose solves fall back to the dense path's
 * treatment of those rows.
 *
 * The velocity projection's floor. The refinement's stop tests are relative to |x|
 * (fcc_al_refine.c); for the velocity projection they are relative to the larger of
 * |w| and the largest max |v_i| the run's velocity projections met, this one's input
 * included (reset at each run's rank decision, so a run never depends on an earlier
 * one). Every velocity of a run descends from those through RK updates, impulses and
 * projections, each of which rounds at the scale of its operands: the velocities carry
 * an absolute error of about eps times that peak whatever their size now, and so does
 * the projection's right-hand side M v. Where the projection's result is far below
 * the peak, a change relative to it alone is that rounding: a boom latched at 0 DOF
 * projects velocities of 1e-17 m/s (it deployed at 1 m/s) whose components along its
 * weak constraint directions converge at 0.02 per augmented-Lagrangian step, and met
 * the relative test after eight steps and a conjugate-gradient correction (a third
 * of the locked step), two with the floor. Where |w| is the run's scale, the floor
 * changes nothing. The acceleration and Newton solves keep their relative tests.
 *
 * A solve whose refinement did not converge (constraints so ill-conditioned that the
 * conjugate-gradient corrections run out of steps) is counted, and redone by the dense
 * path's solve (pivoted QR of B at the decided rank, fcc_dense.c) on M and B gathered
 * from the blocks, when the model has at most dense_fallback_max coordinates and the
 * engine has a LAPACK table; otherwise the unconverged solve is kept (and counted).
 */
#include <math.h>
#include <string.h>

#include "fcc_engine.h"

/* A chord step is kept when it leaves at most CHORD_GAIN of the residual and moves q
 * along the constraints by at most CHORD_DRIFT of the position tolerance: far below
 * what the tolerance lets through, while an RK4 step at dt 1e-3 leaves a move of about
 * 1e-5 of 1e-11 m. */
#define CHORD_GAIN 1e-2
#define CHORD_DRIFT 1e-3

/* The dense solve of an unconverged refinement, if the model is small enough, the
 * engine has LAPACK and M, B factor there. */
static void dense_fallback(fcc_engine *e, const double *Q, const double *w,
                           const double *b, double *x)
{
    if (e->n > e->sp.dense_fallback_max || e->lapack == NULL || e->sp.sw_live)
        return;         /* (the dense solve has no switchable rows: kept, counted) */
    fcc_sp_gather_dense(e);
    if (fcc_dense_factor(&e->sol, e->asmb->M, e->asmb->B) == 0) {
        fcc_dense_apply(&e->sol, Q, w, b, x);
        e->sp.n_fallback++;
    }
}

void fcc_sp_solve_kkt(fcc_engine *e, const double *Q, const double *w, const double *b,
                      double *x, int warm, int newton)
{
    /* The refinement (warm: from the last accelerations' multipliers; newton: a Newton
     * step's); when it did not converge, the dense solve instead if the model is small
     * enough, the engine has LAPACK and M, B factor there. */
    if (fcc_sp_kkt_solve(e, Q, w, b, x, warm, newton))
        return;
    dense_fallback(e, Q, w, b, x);
}

int fcc_sp_solve_kkt_from(fcc_engine *e, const double *Q, double *x, double *lam_io,
                          int valid)
{
    /* x of M x + B^T lambda = Q, B x = 0 from the multipliers lam_io (when valid),
     * which receive the converged ones (fcc_sp_kkt_solve_from); the dense solve
     * instead as fcc_sp_solve_kkt. Returns whether lam_io holds converged ones. */
    if (fcc_sp_kkt_solve_from(e, Q, NULL, NULL, x, lam_io, valid, 0))
        return 1;
    dense_fallback(e, Q, NULL, NULL, x);
    return 0;
}

/* The accelerations' solve (rhs, nb) with the held switchable rows' targets
 * -(dG/dt) v (fcc_sparse_fold.c) when some are folded into the factor, and then the
 * floor max |f - h| / m_ref under |a| in the refinement's stop tests: a structure
 * locked to 0 DOF has accelerations of rounding size (its rows hold what the loads
 * would move), against which a relative test only meets noise and turns every solve
 * slow (the boosted factor again at each stage: the latched boom of 12 units, 2x its
 * free step); the loads' acceleration scale is what the rounding is relative to, as
 * the Schur complement's accelerations (the engine's own, then the rows' share) are. */
static void solve_with_targets(fcc_engine *e, const double *q, const double *v,
                               double *a)
{
    fcc_sparse *s = &e->sp;
    int i;
    double big = 0.0;
    if (s->sw_live && s->sw_fill != NULL) {
        s->sw_fill(s->sw_ctx, e, q, v);
        s->sw_b = s->sw_tgt;
        for (i = 0; i < e->n; i++)
            if (fabs(e->rhs[i]) > big)
                big = fabs(e->rhs[i]);
        s->x_floor = big / s->mref;
    }
    fcc_sp_solve_kkt(e, e->rhs, NULL, e->nb, a, 1, 0);
    s->sw_b = NULL;
    s->x_floor = 0.0;
}

int fcc_sp_accelerations(fcc_engine *e, const double *q, const double *v, double *a,
                         int reuse)
{
    int i, flags = FCC_ASM_H | FCC_ASM_F | FCC_ASM_C;
    fcc_assembly *as = e->asmb;
    if (reuse) {
        fcc_assemble(as, q, v, flags);
    } else {
        flags |= FCC_ASM_M | FCC_ASM_B;
        fcc_sp_assemble_blocks(e, q, v, flags);
        if (fcc_sp_factor(e, q) < 0)
            return -1;
    }
    for (i = 0; i < e->n; i++)
        e->rhs[i] = as->f[i] - as->h[i];
    for (i = 0; i < e->m; i++)
        e->nb[i] = -as->c[i];
    solve_with_targets(e, q, v, a);
    return fcc_check_result(e, q, v, a, flags);
}

/* b = -c - 2 alpha g' - beta^2 g, the right-hand side of B a = b in Baumgarte's
 * stabilisation, with g' = B v + dg/dt (assembled c, g and, for time-dependent
 * constraints, dg/dt; blocks of B). */
static void baumgarte_targets(fcc_engine *e, const double *v, double alpha, double beta,
                              double *b)
{
    int i;
    fcc_sp_mult_b(e, v, b);
    if (e->model->n_time)
        for (i = 0; i < e->m; i++)
            b[i] += e->asmb->gt[i];
    for (i = 0; i < e->m; i++)
        b[i] = -e->asmb->c[i] - 2.0 * alpha * b[i] - beta * beta * e->asmb->g[i];
}

int fcc_sp_baumgarte(fcc_engine *e, const double *q, const double *v, double *a,
                     double alpha, double beta)
{
    int i, flags = FCC_ASM_M | FCC_ASM_B | FCC_ASM_H | FCC_ASM_F | FCC_ASM_C | FCC_ASM_G;
    fcc_assembly *as = e->asmb;
    fcc_assemble(as, q, v, FCC_ASM_H | FCC_ASM_F | FCC_ASM_C | FCC_ASM_G
                 | (e->model->n_time ? FCC_ASM_T : 0));
    fcc_sp_assemble_mb(e, q, FCC_ASM_M | FCC_ASM_B);
    if (fcc_sp_factor(e, q) < 0)
        return -1;
    for (i = 0; i < e->n; i++)
        e->rhs[i] = as->f[i] - as->h[i];
    baumgarte_targets(e, v, alpha, beta, e->nb);
    solve_with_targets(e, q, v, a);
    return fcc_check_result(e, q, v, a, flags);
}

void fcc_sp_assemble_constraints(fcc_engine *e, const double *q, int flags)
{
    /* g into the assembly (the fixed rows checked), M and B as element blocks. */
    if (flags & FCC_ASM_G) {
        fcc_assemble(e->asmb, q, NULL, FCC_ASM_G);
        fcc_sp_check_fixed_g(e);
    }
    if (flags & (FCC_ASM_M | FCC_ASM_B))
        fcc_sp_assemble_mb(e, q, flags & (FCC_ASM_M | FCC_ASM_B));
}

int fcc_sp_chord_ready(fcc_engine *e)
{
    /* A factorisation is held, its blocks with it, and no row is dependent only on
     * the constraint manifold (the file's docstring, "Chord steps"). */
    return e->sp.held && !e->sp.tripped && e->sp.beyond_quotient == 0.0;
}

int fcc_sp_chord_step(fcc_engine *e, double *q, double *res)
{
    /* A Newton step with the blocks and factorisation held (one augmented-Lagrangian
     * step), kept (1: q moved, g assembled there, *res its residual) when it leaves at
     * most CHORD_GAIN of the residual and its estimated move along the constraints,
     * (residual left / residual before) max |dq|, is at most CHORD_DRIFT of the
     * position tolerance; else undone (0: q and g as they were). */
    fcc_sparse *s = &e->sp;
    int i, n = e->n;
    double trial, step, size;
    for (i = 0; i < e->m; i++)
        e->nb[i] = -e->asmb->g[i];
    memset(s->base, 0, (size_t)n * sizeof(double));
    fcc_sp_first_pass(e, e->nb, 0, e->dq);     /* B^T alpha (-g): zero where pinned */
    memcpy(s->qsave, q, (size_t)n * sizeof(double));
    fcc_sp_solve_a_add(e, e->dq, q, &step, &size);
    fcc_sp_assemble_constraints(e, q, FCC_ASM_G);
    trial = fcc_sp_scaled_residual(e);
    if (trial <= CHORD_GAIN * *res
            && trial * step <= CHORD_DRIFT * e->set.position_tol * *res) {
        *res = trial;
        s->n_chord++;
        return 1;
    }
    memcpy(q, s->qsave, (size_t)n * sizeof(double));
    fcc_sp_assemble_constraints(e, q, FCC_ASM_G);
    s->n_chord_undone++;
    return 0;
}

/* b of the velocity projection's B w = b: -dg/dt at the time set last (zero when no
 * constraint depends on time). */
static void velocity_targets(fcc_engine *e, const double *q, double *b)
{
    int i;
    if (!e->model->n_time) {
        memset(b, 0, (size_t)e->m * sizeof(double));
        return;
    }
    fcc_assemble(e->asmb, q, NULL, FCC_ASM_T);
    for (i = 0; i < e->m; i++)
        b[i] = -e->asmb->gt[i];
}

/* v is zero on every pinned coordinate (as after a projection): then the products
 * with M on the solve's view give M v on the free coordinates, all that the velocity
 * projection's solve and energy watch read (w is zero there too). */
static int pinned_still(fcc_engine *e, const double *v)
{
    const fcc_pattern *P = e->sp.pat;
    int i;
    for (i = 0; i < P->n_pinned; i++)
        if (v[P->pinned[i]] != 0.0)
            return 0;
    return 1;
}

/* The energy watch (fcc_engine.c) with M v from the velocity projection (mv). The
 * energy removed is (v - w)^T M (v - w) = (v - w)^T M v - w^T B^T mu, and B w = 0 when
 * no constraint depends on time: then one product, M v, gives both numbers
 * (w^T M (v - w) is rounding, about 1e-16 |w| |M (v - w)|); with time-dependent
 * constraints, a second product with v - w. */
static void watch_kinetic_energy(fcc_engine *e, const double *v, const double *w)
{
    fcc_sparse *s = &e->sp;
    int i, n = e->n;
    double before = 0.0, cut = 0.0;
    for (i = 0; i < n; i++) {
        s->dx[i] = v[i] - w[i];
        before += v[i] * s->mv[i];
    }
    if (e->model->n_time) {
        fcc_sp_mult_m_full(e, s->dx, s->tperm, 0);
        for (i = 0; i < n; i++)
            cut += s->dx[i] * s->tperm[i];
    } else {
        for (i = 0; i < n; i++)
            cut += s->dx[i] * s->mv[i];
    }
    fcc_note_energy_cut(e, before, cut);
}

/* The velocity projection's floor under |w| in the refinement's stop tests
 * (fcc_al_refine.c): the largest max |v_i| the run's velocity projections met, this
 * one's input included (file docstring, "The velocity projection's floor"). */
static double velocity_floor(fcc_engine *e, const double *v)
{
    int i;
    for (i = 0; i < e->n; i++)
        if (fabs(v[i]) > e->sp.v_peak)
            e->sp.v_peak = fabs(v[i]);
    return e->sp.v_peak;
}

int fcc_sp_project_velocities(fcc_engine *e, const double *q, double *v, int have_B)
{
    fcc_sparse *s = &e->sp;
    fcc_sp_assemble_mb(e, q, have_B ? FCC_ASM_M : FCC_ASM_M | FCC_ASM_B);
    if (fcc_sp_factor(e, q) < 0)
        return -1;
    velocity_targets(e, q, e->nb);
    if (pinned_still(e, v))                    /* M v on the view is enough */
        fcc_sp_mult_m(e, v, s->mv, 0);
    else                                       /* M v whole: v moves pinned coordinates */
        fcc_sp_mult_m_full(e, v, s->mv, 0);
    s->x_floor = velocity_floor(e, v);
    fcc_sp_solve_kkt(e, s->mv, NULL, e->nb, e->vtmp, 0, 0);
    s->x_floor = 0.0;
    if (fcc_check_result(e, q, v, e->vtmp, FCC_ASM_M | FCC_ASM_B) < 0)
        return -1;
    watch_kinetic_energy(e, v, e->vtmp);
    memcpy(v, e->vtmp, (size_t)e->n * sizeof(double));
    e->factor_valid = 1;
    fcc_sp_watch_rank(e);
    return 0;
}

/* The multipliers of the acceleration solve just made, corrected once. That solve's
 * lambda is accurate to about RHO eps of itself only (its last augmented-Lagrangian
 * update multiplies the rounding of B x - b by alpha), which the sensitivities'
 * stages would carry into s_a through dB[s_q]^T lambda (4e-10 of them on the double
 * pendulum) and which a driver force is. One correction removes it: r1 = r - M a -
 * B^T lambda is formed directly (rounding of f, not alpha times rounding of B x),
 * about -B^T dlam with dlam the error, and one augmented-Lagrangian step of
 * M dx + B^T dlam = r1, B dx = 0 from zero, dx = A^{-1} r1, dlam = alpha B dx,
 * recovers dlam but for 1 / (1 + t) of it (t = alpha sigma^2 / m: 1e-7 where the rows
 * are well conditioned, 1/43 along the scissor mast's weakest direction): lambda then
 * accurate to RHO eps times that. A refinement to rounding would chase r1's own
 * rounding (its right-hand side is rounding-sized: 4.5 solves with A per stage on the
 * scissor boom, against one). r: f - h (+ G^T mu of held rows) at the solve's state,
 * a: its accelerations, lam: its converged multipliers (sp.lam_warm, or a copy),
 * corrected in place; y (n) and b (m) are work. Returns whether lam is finite. */
int fcc_sp_correct_multipliers(fcc_engine *e, const double *r, const double *a,
                               double *lam, double *y, double *b)
{
    int i, n = e->n;
    const fcc_pattern *P = e->sp.pat;
    fcc_sp_mult_m_full(e, a, y, 0);
    fcc_sp_mult_bt(e, lam, NULL, y);
    for (i = 0; i < n; i++)
        y[i] = r[i] - y[i];
    for (i = 0; i < P->n_pinned; i++)     /* pinned coordinates: dx stays 0 there */
        y[P->pinned[i]] = 0.0;
    fcc_sp_solve_a(e, y);
    fcc_sp_mult_b(e, y, b);
    for (i = 0; i < e->m; i++)
        lam[i] += e->sp.alpha[i] * b[i];
    return fcc_finite(lam, e->m);
}
