/* The engine: accelerations and projections (fcc_engine.h), one loop for both paths.
 *
 * The dense path's building blocks are here; where the sparse path differs (its
 * factorisation, solves, residual and the assembly of M and B as element blocks) the
 * building block hands over to fcc_sparse_*.c. Failures (a singular reduced mass
 * matrix, a non-finite quantity) set the error record and return -1, so nothing
 * continues on NaN.
 */
#include <math.h>
#include <string.h>

#include "fcc_engine.h"

int fcc_engine_init(fcc_engine *e, fcc_assembly *a, const fcc_lapack *lapack,
                    const fcc_settings *settings)
{
    int n = a->model->n_q, m = a->model->n_g, rc;
    memset(e, 0, sizeof(*e));
    e->asmb = a;
    e->model = a->model;
    e->lapack = lapack;
    e->set = *settings;
    e->n = n;
    e->m = m;
    e->diverge_residual = INFINITY;
    rc = fcc_dense_init(&e->sol, n, m, settings->rank_tol, settings->grow_tol,
                        settings->row_floor, lapack);
    if (rc != FCC_OK)
        return rc;
    e->sol.group = e->model->row_group;
    e->work = FCC_CALLOC((size_t)(4 * n + m + 1), sizeof(double));
    e->stages = FCC_CALLOC((size_t)(10 * n > 0 ? 10 * n : 1), sizeof(double));
    if (e->work == NULL || e->stages == NULL) {
        fcc_engine_free(e);
        return FCC_ERR_MEMORY;
    }
    e->rhs = e->work;
    e->nb = e->rhs + n;
    e->dq = e->nb + m;
    e->vtmp = e->dq + n;
    return FCC_OK;
}

void fcc_engine_free(fcc_engine *e)
{
    if (e->sparse)
        fcc_sparse_free(e);
    fcc_dense_free(&e->sol);
    FCC_FREE(e->work);
    FCC_FREE(e->stages);
    e->work = e->stages = NULL;
}

void fcc_engine_decide_rank(fcc_engine *e, int rank)
{
    e->sol.rank_fixed = rank;
    fcc_dense_reset_stats(&e->sol);
    e->n_rank_log = 0;
    e->ke_peak = 0.0;
    e->ke_cut_max = 0.0;
    e->ke_cut_t = 0.0;
    e->factor_valid = 0;
    if (e->sparse)
        fcc_sparse_reset_stats(e);
}

int fcc_fail(fcc_engine *e, int code, int info, int detail)
{
    e->err = code;
    e->err_info = info;
    e->err_detail = detail;
    return -1;
}

int fcc_nonfinite_input(fcc_engine *e, const double *q, const double *v, int flags)
{
    int n = e->n, m = e->m;
    const fcc_assembly *a = e->asmb;
    if (e->sparse)
        return fcc_sp_nonfinite_input(e, q, v, flags);
    if (q != NULL && !fcc_finite(q, n)) return 1;
    if (v != NULL && !fcc_finite(v, n)) return 2;
    if (flags & FCC_ASM_M && !fcc_finite(a->M, (long)n * n)) return 3;
    if (flags & FCC_ASM_H && !fcc_finite(a->h, n)) return 4;
    if (flags & FCC_ASM_F && !fcc_finite(a->f, n)) return 5;
    if (flags & FCC_ASM_B && !fcc_finite(a->B, (long)m * n)) return 6;
    if (flags & FCC_ASM_C && !fcc_finite(a->c, m)) return 7;
    if (flags & FCC_ASM_G && !fcc_finite(a->g, m)) return 8;
    return 0;
}

int fcc_factor(fcc_engine *e, const double *q)
{
    int old, bad, k, info;
    if (e->sparse)
        return fcc_sp_factor(e, q);
    old = e->sol.rank_fixed;
    info = fcc_dense_factor(&e->sol, e->asmb->M, e->asmb->B);
    e->factor_valid = 0;
    if (info == FCC_DENSE_NO_LAPACK)
        return fcc_fail(e, FCC_ERR_NO_LAPACK, 0, 0);
    if (e->sol.grew) {
        k = e->n_rank_log;
        if (k < FCC_RANK_LOG_SIZE) {
            e->rank_log[k][0] = e->err_t;      /* the integrators keep it current */
            e->rank_log[k][1] = old;
            e->rank_log[k][2] = e->sol.rank_fixed;
        }
        e->n_rank_log++;
    }
    if (info == 0)
        return 0;
    bad = fcc_nonfinite_input(e, q, NULL, FCC_ASM_M | FCC_ASM_B);
    if (bad)
        return fcc_fail(e, FCC_ERR_NONFINITE_INPUT, 0, bad);
    return fcc_fail(e, info > 0 ? FCC_ERR_SINGULAR : FCC_ERR_LAPACK, info, 0);
}

int fcc_check_result(fcc_engine *e, const double *q, const double *v, const double *a,
                  int flags)
{
    int i;
    if (fcc_finite(a, e->n))
        return 0;
    i = fcc_nonfinite_input(e, q, v, flags);
    return fcc_fail(e, i ? FCC_ERR_NONFINITE_INPUT : FCC_ERR_NONFINITE_RESULT, 0, i);
}

int fcc_accelerations(fcc_engine *e, const double *q, const double *v, double *a,
                      int reuse)
{
    int i, flags = FCC_ASM_H | FCC_ASM_F | FCC_ASM_C;
    fcc_assembly *as = e->asmb;
    if (e->sparse)
        return fcc_sp_accelerations(e, q, v, a, reuse);
    if (!reuse)
        flags |= FCC_ASM_M | FCC_ASM_B;
    fcc_assemble(as, q, v, flags);
    if (!reuse && fcc_factor(e, q) < 0)
        return -1;
    for (i = 0; i < e->n; i++)
        e->rhs[i] = as->f[i] - as->h[i];
    for (i = 0; i < e->m; i++)
        e->nb[i] = -as->c[i];
    fcc_dense_apply(&e->sol, e->rhs, NULL, e->nb, a);
    return fcc_check_result(e, q, v, a, flags);
}

int fcc_baumgarte(fcc_engine *e, const double *q, const double *v, double *a,
                  double alpha, double beta)
{
    int i, j, n = e->n;
    int flags = FCC_ASM_M | FCC_ASM_B | FCC_ASM_H | FCC_ASM_F | FCC_ASM_C | FCC_ASM_G;
    fcc_assembly *as = e->asmb;
    double bv;
    const double *row;
    if (e->sparse)
        return fcc_sp_baumgarte(e, q, v, a, alpha, beta);
    if (e->model->n_time)
        flags |= FCC_ASM_T;
    fcc_assemble(as, q, v, flags);
    if (fcc_factor(e, q) < 0)
        return -1;
    for (i = 0; i < n; i++)
        e->rhs[i] = as->f[i] - as->h[i];
    for (i = 0; i < e->m; i++) {
        row = as->B + i * n;
        bv = e->model->n_time ? as->gt[i] : 0.0;
        for (j = 0; j < n; j++)
            bv += row[j] * v[j];
        e->nb[i] = -as->c[i] - 2.0 * alpha * bv - beta * beta * as->g[i];
    }
    fcc_dense_apply(&e->sol, e->rhs, NULL, e->nb, a);
    return fcc_check_result(e, q, v, a, flags);
}

/* Assemble at q what the position projection asks for: g (FCC_ASM_G), B (FCC_ASM_B)
 * and M (FCC_ASM_M), where this engine's solves read them (the dense path: the
 * assembly's dense arrays; the sparse path keeps M and B as element blocks). */
static void assemble_constraints(fcc_engine *e, const double *q, int flags)
{
    if (e->sparse)
        fcc_sp_assemble_constraints(e, q, flags);
    else
        fcc_assemble(e->asmb, q, NULL, flags);
}

double fcc_constraint_residual(fcc_engine *e)
{
    if (e->sparse)
        return fcc_sp_scaled_residual(e);
    return fcc_scaled_residual(e->asmb);
}

void fcc_solve_constrained(fcc_engine *e, const double *Q, const double *w,
                           const double *b, double *x)
{
    if (e->sparse)
        fcc_sp_solve_kkt(e, Q, w, b, x, 0, 0);     /* from zero multipliers */
    else
        fcc_dense_apply(&e->sol, Q, w, b, x);
}

/* x of a Newton step, M x + B^T mu = 0, B x = b, with the factorisation at hand. Its
 * accuracy need only be far below the step's own (the next residual check judges the
 * step): the sparse path stops its refinement sooner. */
static void solve_newton(fcc_engine *e, const double *b, double *x)
{
    if (e->sparse)
        fcc_sp_solve_kkt(e, NULL, NULL, b, x, 0, 1);
    else
        fcc_dense_apply(&e->sol, NULL, NULL, b, x);
}

int fcc_project_positions(fcc_engine *e, double *q, int *iterations, int reuse)
{
    /* Newton on g(q) = 0, in place: dq = argmin dq^T M dq / 2 subject to B dq = -g,
     * with g and B at every iterate and the metric M at the starting point. Leaves g
     * assembled at the final q, and B when b_fresh. reuse: M, B and the factorisation
     * held are an integrator's last stage's, near q; an engine that can (the sparse
     * path, fcc_sp_chord_ready) first takes chord steps with them, and the first one
     * that does not converge as it should is undone: exact steps from there. */
    int i, it = 0, bad;
    double res;
    int exact = 0;
    reuse = reuse && e->sparse && fcc_sp_chord_ready(e);
    e->b_fresh = !reuse;
    assemble_constraints(e, q, reuse ? FCC_ASM_G : FCC_ASM_G | FCC_ASM_B);
    res = fcc_constraint_residual(e);
    for (;;) {
        if (!isfinite(res)) {
            *iterations = it;
            bad = fcc_nonfinite_input(e, q, NULL, FCC_ASM_G | FCC_ASM_B);
            return fcc_fail(e, FCC_ERR_NONFINITE_INPUT, 0, bad ? bad : 8);
        }
        if (res <= e->set.position_tol)
            break;
        if (it == 0 && res > e->diverge_residual) {
            *iterations = it;
            e->err_value = res;
            e->err_bound = e->diverge_residual;
            return fcc_fail(e, FCC_ERR_DIVERGED, 0, 3);
        }
        if (it >= e->set.max_newton) {
            *iterations = it;
            return 1;
        }
        if (reuse) {
            i = fcc_sp_chord_step(e, q, &res);
            if (i < 0) {
                *iterations = it;
                return -1;
            }
            if (i == 1) {
                it++;
                continue;
            }
            reuse = 0;
        }
        if (!exact) {                     /* the metric: M at the first exact step */
            assemble_constraints(e, q, e->b_fresh ? FCC_ASM_M : FCC_ASM_M | FCC_ASM_B);
            e->b_fresh = exact = 1;
        }
        if (fcc_factor(e, q) < 0) {
            *iterations = it;
            return -1;
        }
        for (i = 0; i < e->m; i++)
            e->nb[i] = -e->asmb->g[i];
        solve_newton(e, e->nb, e->dq);
        for (i = 0; i < e->n; i++)
            q[i] += e->dq[i];
        it++;
        assemble_constraints(e, q, FCC_ASM_G | FCC_ASM_B);
        res = fcc_constraint_residual(e);
    }
    *iterations = it;
    return 0;
}

void fcc_note_energy_cut(fcc_engine *e, double before, double cut)
{
    if (before > e->ke_peak)
        e->ke_peak = before;
    if (before > 1e-6 * e->ke_peak && before > 0.0 && cut / before > e->ke_cut_max) {
        e->ke_cut_max = cut / before;
        e->ke_cut_t = e->err_t;
    }
}

/* Track the fraction of the kinetic energy v^T M v / 2 that the projection v -> w
 * removes, (v - w)^T M (v - w) / 2 (M-orthogonal: the energy lost). Accurate steps
 * lose O(local error^2); a finite fraction means the constraints forbid a motion the
 * integrator made (a wrong rank, a locked mechanism). Fractions are counted once the
 * energy is above 1e-6 of its peak. */
static void watch_kinetic_energy(fcc_engine *e, const double *v, const double *w)
{
    int i, j, n = e->n;
    double before = 0.0, cut = 0.0, mv, md;
    const double *row;
    for (i = 0; i < n; i++) {
        row = e->asmb->M + i * n;
        mv = 0.0;
        md = 0.0;
        for (j = 0; j < n; j++) {
            mv += row[j] * v[j];
            md += row[j] * (v[j] - w[j]);
        }
        before += v[i] * mv;
        cut += (v[i] - w[i]) * md;
    }
    fcc_note_energy_cut(e, before, cut);
}

int fcc_project_velocities(fcc_engine *e, const double *q, double *v, int have_B)
{
    /* v <- the M-orthogonal projection of v onto B v = -dg/dt (0 unless the model
     * has drivers), in place. Leaves the factorisation of (M, B) at q. */
    int i;
    int flags = have_B ? FCC_ASM_M : FCC_ASM_M | FCC_ASM_B;
    fcc_assembly *as = e->asmb;
    if (e->sparse)
        return fcc_sp_project_velocities(e, q, v, have_B);
    if (e->model->n_time)
        flags |= FCC_ASM_T;
    fcc_assemble(as, q, NULL, flags);
    e->sol.check_growth = 1;              /* q has just been projected (or is given) */
    i = fcc_factor(e, q);
    e->sol.check_growth = 0;
    if (i < 0)
        return -1;
    if (e->model->n_time)
        for (i = 0; i < e->m; i++)
            e->nb[i] = -as->gt[i];
    fcc_dense_apply(&e->sol, NULL, v, e->model->n_time ? e->nb : NULL, e->vtmp);
    if (!fcc_finite(e->vtmp, e->n)) {
        i = fcc_nonfinite_input(e, q, v, FCC_ASM_M | FCC_ASM_B);
        return fcc_fail(e, i ? FCC_ERR_NONFINITE_INPUT : FCC_ERR_NONFINITE_RESULT, 0, i);
    }
    watch_kinetic_energy(e, v, e->vtmp);
    memcpy(v, e->vtmp, (size_t)e->n * sizeof(double));
    e->factor_valid = 1;
    return 0;
}
