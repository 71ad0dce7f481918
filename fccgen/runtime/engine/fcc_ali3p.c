/* ALI3-P: the index-3 augmented Lagrangian formulation with mass-orthogonal
 * projections, integrated by the trapezoidal rule, the whole step loop (fcc_ali3p.h).
 *
 * References: E. Bayo, J. Garcia de Jalon, "Kinematic and Dynamic Simulation of
 * Multibody Systems", Springer 1994, ch. 4-5; J. Cuadrado, J. Cardenal, E. Bayo,
 * "Modeling and solution methods for efficient real-time simulation of multibody
 * dynamics", Multibody System Dynamics 1 (1997) 259-280.
 *
 * Equations: M q'' + B^T (alpha g + lambda) = Q with Q = f - h, the multipliers
 * lambda iterated so that g -> 0. The trapezoidal rule over a step h gives
 *     q' = (2/h) q - (2/h) q_n - q'_n,   q'' = (4/h^2) q - (4/h^2) q_n - (4/h) q'_n - q''_n,
 * so the dynamic equations premultiplied by h^2/4 are a system in q alone,
 *     F(q) = (h^2/4) [M q'' + B^T (alpha g + lambda) - Q] = 0,
 * solved by Newton with the tangent T = M + (h/2) C + (h^2/4) (B^T alpha B + K),
 * K = -df/dq and C = -df/dq' (the force Jacobian kernels; the derivatives of M, B and
 * h are left out, as in the references). After each Newton correction
 * lambda += alpha g. A step converges when the last correction max |dq| and the
 * constraint residual max_k |g_k| / ||B_k|| are both at most the tolerance (newton_tol
 * times the largest body length): with a small penalty the corrections can become
 * small while g still shrinks only by a constant factor per multiplier update. Steps
 * that end max_newton iterations with g within the tolerance and shrinking
 * corrections are accepted under conditions given at SLOW_FACTOR below (singular
 * positions). Then the speeds and accelerations are projected mass-orthogonally with
 * the same T:
 *     T q'  = W q'~  - (h^2/4) B^T alpha (0),
 *     T q'' = W q''~ - (h^2/4) B^T alpha ((dB/dt) q'),   W = T - (h^2/4) B^T alpha B,
 * i.e. q' = q'~ - T^-1 (h^2/4) B^T alpha B q'~, and likewise for q''.
 *
 * T is symmetrised, (T + T^T)/2, before its Cholesky factorisation: K and C of dampers
 * and follower torques are not symmetric; the iteration then is a quasi-Newton one
 * whose fixed point is unchanged. When a load's stiffness has negative directions
 * larger than the mass and penalty terms (a strongly compressed spring: K holds
 * -T/L (E - n n^T)), T is not positive definite and is factored by LU instead
 * (counted). M + (h^2/4) B^T alpha B is positive definite for a well posed model even
 * with redundant rows in B (M needs to be positive definite on the null space of B
 * only), so redundant constraints and singular positions pass.
 *
 * The penalty is one number per constraint row: alpha_k = penalty * m_ref / ||B_k||^2,
 * with m_ref the largest diagonal entry of M and B_k the row of B, both at the initial
 * state (set by the caller: fccgen/runtime/ali3p_setup.py and _ali3p.pyx say why the
 * default penalty is 1e9, when a larger one is needed and how the start raises it).
 * A step whose Newton iteration does not converge is taken again from its start with
 * every row's penalty FCC_ALI3P_PENALTY_RAISE times larger, at most max_raises times in
 * a run (the raised penalty is kept for the rest of the run; counted in raises). The
 * multiplier update shrinks g along a singular direction s of the row-scaled B by
 * about 1 / (1 + (h^2/4) penalty s^2): as a scissor structure deploys its smallest s
 * falls, and what the start's penalty made fast stalls. Models whose stiffest spring
 * outweighs the penalty get no raise (the caller sets max_raises 0): their stall comes
 * from the spring.
 */
#include <math.h>
#include <string.h>

#include "fcc_ali3p.h"

#define STEP_FLAGS (FCC_ASM_M | FCC_ASM_H | FCC_ASM_F | FCC_ASM_G | FCC_ASM_B \
                    | FCC_ASM_KQ | FCC_ASM_KV)

/* A step that ends max_newton iterations with the constraints met (max |g_k| / ||B_k||
 * <= tol) and its corrections still shrinking is accepted if the last correction is
 * at most SLOW_FACTOR * tol (counted in slow_steps): at a position where B loses rank
 * the multiplier iteration contracts only slowly (by 0.9-0.98 per iteration, whatever
 * the penalty) in the lost directions, while the constraints already hold. fccgen's
 * choice: on the N-four-bar (examples/a02_n_four_bar.yaml, h = 1e-3, penalty 1e12,
 * 20 s) 50 steps end their 30 iterations with corrections of 1e-10 to 2e-9 L; with
 * max_newton = 400 instead all but one converge, and B0 moves by at most 1.9e-6 m (the
 * run's error against the benchmark reference is 4.4e-4 m). */
#define SLOW_FACTOR 1e3

static int failed(fcc_ali3p *r, int code, int info, int detail)
{
    r->fail = code;
    r->fail_info = info;
    r->fail_detail = detail;
    return -1;
}

/* T = sym(M - (h/2) df/dq' - (h^2/4) df/dq) + (h^2/4) B^T alpha B, factored in place
 * (upper Cholesky factor, LAPACK column-major = our row-major transpose). */
static int tangent(fcc_engine *e, fcc_ali3p *r, double h)
{
    const fcc_assembly *as = e->asmb;
    int i, j, k, n = r->n, info = 0;
    double h2 = 0.5 * h, h4 = 0.25 * h * h, x, bk;
    char uplo = 'L';
    for (i = 0; i < n; i++) {
        for (j = i; j < n; j++) {
            x = 0.5 * (as->M[i * n + j] + as->M[j * n + i]
                       - h2 * (as->fv[i * n + j] + as->fv[j * n + i])
                       - h4 * (as->fq[i * n + j] + as->fq[j * n + i]));
            r->T[i * n + j] = x;
        }
    }
    for (k = 0; k < r->m; k++) {
        for (i = 0; i < n; i++) {
            bk = as->B[k * n + i];
            if (bk == 0.0)
                continue;
            bk *= h4 * r->alpha[k];
            for (j = i; j < n; j++)
                r->T[i * n + j] += bk * as->B[k * n + j];
        }
    }
    for (i = 0; i < n; i++)
        for (j = i; j < n; j++)
            r->T2[i * n + j] = r->T2[j * n + i] = r->T[i * n + j];
    /* row-major upper triangle = column-major lower triangle */
    r->lu = 0;
    e->lapack->dpotrf(&uplo, &n, r->T, &n, &info);
    if (info == 0)
        return 0;
    /* not positive definite: a load stiffness -df/dq with negative directions (a
     * compressed spring) larger than the mass and penalty terms; LU still solves */
    memcpy(r->T, r->T2, (size_t)n * n * sizeof(double));
    e->lapack->dgetrf(&n, &n, r->T, &n, r->ipiv, &info);
    if (info != 0)
        return failed(r, FCC_ALI3P_TANGENT, info, 0);
    r->lu = 1;
    r->lu_steps++;
    return 0;
}

/* x <- T^-1 x with the factored tangent. */
static void solve(fcc_engine *e, fcc_ali3p *r, double *x)
{
    int n = r->n, one = 1, info = 0;
    char uplo = 'L', trans = 'N';
    if (r->lu)
        e->lapack->dgetrs(&trans, &n, &one, r->T, &n, r->ipiv, x, &n, &info);
    else
        e->lapack->dpotrs(&uplo, &n, &one, r->T, &n, x, &n, &info);
}

/* out += scale B^T (alpha * y) (y: one number per constraint row). */
static void add_bt_alpha(fcc_engine *e, fcc_ali3p *r, const double *y, double scale,
                         double *out)
{
    int k, j, n = r->n;
    double c;
    for (k = 0; k < r->m; k++) {
        c = scale * r->alpha[k] * y[k];
        if (c == 0.0)
            continue;
        for (j = 0; j < n; j++)
            out[j] += c * e->asmb->B[k * n + j];
    }
}

/* Assemble and check that the state and what was assembled are finite. */
static int assemble(fcc_engine *e, fcc_ali3p *r, const double *q, const double *v,
                    int flags)
{
    int bad;
    r->n_asm++;
    fcc_assemble(e->asmb, q, v, flags);
    bad = fcc_nonfinite_input(e, q, v, flags);
    if (bad == 0 && flags & FCC_ASM_KQ && !fcc_finite(e->asmb->fq, (long)r->n * r->n))
        bad = 9;
    if (bad == 0 && flags & FCC_ASM_KV && !fcc_finite(e->asmb->fv, (long)r->n * r->n))
        bad = 10;
    if (bad)
        return failed(r, FCC_ALI3P_NONFINITE, 0, bad);
    return 0;
}

/* Positions, speeds and accelerations at the end of the step (before the
 * projections), from the predictor q = q_n + h q'_n (the trapezoidal relations then
 * give q' = q'_n, q'' = -q''_n). The references' predictor adds h^2/2 q''_n; with
 * stiff loads (k h^2 / m >> 1) that lands far outside Newton's basin, while on the
 * examples the simpler one costs under one more iteration per step.
 *
 * Converged when the last correction max |dq| and the constraint residual
 * max_k |g_k| / ||B_k|| are both within the tolerance. When max_newton iterations end
 * with converged corrections but a residual above it, the step is accepted and
 * counted as a failure; when they end with the residual within it and corrections
 * shrinking, at most SLOW_FACTOR times it, the step is accepted and counted as slow;
 * otherwise the run stops. Leaves everything assembled at the final positions (and g
 * in the multipliers). */
static int newton(fcc_engine *e, fcc_ali3p *r, double h, int *iterations)
{
    const fcc_assembly *as = e->asmb;
    int i, j, it = 0, n = r->n;
    double h4 = 0.25 * h * h, dqmax = 0.0, dqlast = 0.0, x, res;
    for (i = 0; i < n; i++) {
        r->q[i] = r->q0[i] + h * r->v0[i];
        r->v[i] = r->v0[i];
        r->a[i] = -r->a0[i];
    }
    for (;;) {
        if (assemble(e, r, r->q, r->v, STEP_FLAGS) < 0)
            return -1;
        if (it > 0) {
            for (i = 0; i < r->m; i++)
                r->lam[i] += r->alpha[i] * as->g[i];
            if (dqmax <= r->tol || it >= r->max_newton) {
                res = fcc_scaled_residual(as);
                if (dqmax <= r->tol && res <= r->tol)
                    break;
                if (it >= r->max_newton && dqmax <= r->tol) {
                    r->failures++;
                    break;
                }
                if (it >= r->max_newton && res <= r->tol && dqmax < dqlast
                        && dqmax <= SLOW_FACTOR * r->tol) {
                    r->slow_steps++;
                    break;
                }
            }
        }
        if (it >= r->max_newton) {
            r->fail_dq = dqmax;
            return failed(r, FCC_ALI3P_NEWTON, it, 0);
        }
        /* -F = -(h^2/4) [M q'' + h - f + B^T (alpha g + lambda)] */
        for (i = 0; i < n; i++) {
            x = as->h[i] - as->f[i];
            for (j = 0; j < n; j++)
                x += as->M[i * n + j] * r->a[j];
            r->r[i] = -h4 * x;
        }
        for (i = 0; i < r->m; i++)
            r->w[i] = as->g[i] + r->lam[i] / r->alpha[i];
        add_bt_alpha(e, r, r->w, -h4, r->r);
        if (tangent(e, r, h) < 0)
            return -1;
        solve(e, r, r->r);
        dqlast = dqmax;
        dqmax = 0.0;
        for (i = 0; i < n; i++) {
            r->q[i] += r->r[i];
            r->v[i] += 2.0 / h * r->r[i];
            r->a[i] += 4.0 / (h * h) * r->r[i];
            if (!(fabs(r->r[i]) <= dqmax))
                dqmax = fabs(r->r[i]);
        }
        it++;
        if (!isfinite(dqmax))
            return failed(r, FCC_ALI3P_NONFINITE, 0, 1);
    }
    *iterations = it;
    return 0;
}

/* The speed and acceleration projections with the last factored tangent and B at the
 * converged positions (assembled by newton). */
static int project(fcc_engine *e, fcc_ali3p *r, double h)
{
    const fcc_assembly *as = e->asmb;
    int i, j, k, n = r->n;
    double h4 = 0.25 * h * h, x;
    for (k = 0; k < 2; k++) {
        if (k == 0 && e->model->n_time && assemble(e, r, r->q, r->v, FCC_ASM_T) < 0)
            return -1;
        if (k == 1 && assemble(e, r, r->q, r->v, FCC_ASM_C) < 0)
            return -1;
        for (i = 0; i < r->m; i++) {  /* B x + dg/dt for speeds, B x + bias for accelerations */
            x = k == 1 ? as->c[i] : (e->model->n_time ? as->gt[i] : 0.0);
            for (j = 0; j < n; j++)
                x += as->B[i * n + j] * (k == 1 ? r->a[j] : r->v[j]);
            r->w[i] = x;
        }
        for (i = 0; i < n; i++)
            r->r[i] = 0.0;
        add_bt_alpha(e, r, r->w, h4, r->r);
        solve(e, r, r->r);
        for (i = 0; i < n; i++) {
            if (k == 0)
                r->v[i] -= r->r[i];
            else
                r->a[i] -= r->r[i];
        }
    }
    if (!(fcc_finite(r->v, n) && fcc_finite(r->a, n)))
        return failed(r, FCC_ALI3P_NONFINITE, 0, 2);
    return 0;
}

void fcc_ali3p_record(fcc_engine *e, fcc_ali3p *r, double t)
{
    double cerr;
    r->n_asm++;
    r->out.t[r->n_out] = t;
    cerr = fcc_write_record(e, &r->out, r->n_out, r->q, r->v);
    if (!(cerr <= r->max_cerr))
        r->max_cerr = cerr;
    r->n_out++;
}

/* Back to the start of the step (q, q', q'', multipliers) with every row's penalty
 * FCC_ALI3P_PENALTY_RAISE times larger; the failed step's iterations are counted. */
static void raise_penalty(fcc_ali3p *r)
{
    int i, n = r->n;
    memcpy(r->q, r->q0, (size_t)n * sizeof(double));
    memcpy(r->v, r->v0, (size_t)n * sizeof(double));
    memcpy(r->a, r->a0, (size_t)n * sizeof(double));
    memcpy(r->lam, r->lam0, (size_t)r->m * sizeof(double));
    for (i = 0; i < r->m; i++)
        r->alpha[i] *= FCC_ALI3P_PENALTY_RAISE;
    r->newton_total += r->max_newton;
    r->raises++;
    r->fail = r->fail_info = r->fail_detail = 0;
}

int fcc_ali3p_advance(fcc_engine *e, fcc_ali3p *r)
{
    double t, h;
    int it = 0, n = r->n;
    if (e->lapack == NULL)
        return failed(r, FCC_ALI3P_NO_LAPACK, 0, 0);
    while (r->k < r->n_steps) {
        t = r->k * r->dt;
        h = r->k < r->n_steps - 1 ? r->dt : r->t_end - t;
        r->fail_t = t;
        r->fail_h = h;
        memcpy(r->q0, r->q, (size_t)n * sizeof(double));
        memcpy(r->v0, r->v, (size_t)n * sizeof(double));
        memcpy(r->a0, r->a, (size_t)n * sizeof(double));
        memcpy(r->lam0, r->lam, (size_t)r->m * sizeof(double));
        fcc_put_time(e->asmb, t + h);
        if (newton(e, r, h, &it) < 0 || project(e, r, h) < 0) {
            if (r->fail != FCC_ALI3P_NEWTON || r->raises >= r->max_raises)
                return FCC_RUN_ERROR;
            raise_penalty(r);               /* and take the step again from its start */
            continue;
        }
        r->newton_total += it;
        if (it > r->newton_max)
            r->newton_max = it;
        r->k++;
        t = r->k < r->n_steps ? r->k * r->dt : r->t_end;
        if (r->k % r->every == 0 || r->k == r->n_steps)
            fcc_ali3p_record(e, r, t);
        if (r->k < r->n_steps && r->pause != NULL && r->pause(r->pause_ctx))
            return FCC_RUN_PAUSE;
    }
    return FCC_RUN_DONE;
}

void fcc_ali3p_start(fcc_ali3p *r, fcc_engine *e)
{
    int n = e->n, m = e->m;
    double *p = r->state;
    r->n = n;
    r->m = m;
    r->k = r->n_out = r->n_asm = r->newton_total = r->failures = r->slow_steps = 0;
    r->newton_max = r->fail = r->fail_info = r->fail_detail = 0;
    r->max_cerr = r->fail_dq = 0.0;
    r->fail_t = r->fail_h = 0.0;
    r->q = p;
    r->v = p + n;
    r->a = p + 2 * n;
    r->q0 = p + 3 * n;
    r->v0 = p + 4 * n;
    r->a0 = p + 5 * n;
    r->lam = p + 6 * n;
    r->alpha = p + 6 * n + m;
    r->T = p + 6 * n + 2 * m;
    r->T2 = r->T + (long)n * n;
    r->r = r->T2 + (long)n * n;
    r->w = r->r + n;
    r->lam0 = r->w + m;
    r->raises = 0;
    r->lu = 0;
    r->lu_steps = 0;
    e->running = 1;
}
