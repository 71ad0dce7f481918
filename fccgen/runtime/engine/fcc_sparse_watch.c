/* The sparse path's watch for changes of the degrees of freedom.
 *
 * The solves need no rank, but the reports do: the rank r decided at the start
 * (fccgen.rank) is kept, and raised, as on the dense path, when an SVD at a projected
 * state finds sigma_{r+1} > grow_tol sigma_1 (rows scaled as fccgen.rank.row_scales).
 * What starts that SVD is a bound, not a guess: for any n x k matrix N with
 * orthonormal columns, k = n - r,
 *
 *     sigma_{r+1}(B_s) <= ||B_s N||_2 <= ||B_s N||_F        (Courant-Fischer)
 *
 * and sigma_1 >= 1 (each element's largest scaled row has unit length), so no growth
 * past grow_tol goes unseen while ||B_s N||_F stays at or below it. N tracks the null
 * space of B: set from the SVD at the start (fcc_sparse_set_watch), then at every
 * velocity projection replaced by A^{-1} M N (orthonormalised) with the factor at
 * hand: a null-space direction is kept exactly (A x = M x when B x = 0), a component
 * along a row direction of singular value sigma shrinks by about
 * 1 / (1 + RHO sigma^2), so the motion of the constraint manifold between steps leaves
 * ||B_s N|| near 1e-10 while a new independent row (sigma_{r+1} leaving 0) shows in
 * full. One extra solve with A per tracked direction and projection. An SVD that does
 * not confirm growth, finding sigma_{r+1} = x sigma_1 (x <= grow_tol), moves the
 * trigger to the bound times grow_tol / x, kept within [2, 10]: the next SVD comes
 * when the bound has grown as much as sigma_{r+1} must to pass grow_tol (the bound
 * follows sigma_{r+1} within a constant on a mechanism leaving a singular position),
 * at least twice, so that SVDs stay rare near singular positions, and at most ten
 * times (the dense path's rule for its pivot).
 *
 * The SVD check needs LAPACK; without it the check finds nothing and the trigger
 * moves up. After a rank increase the watch starts again from the null space there
 * through the restart_watch callback (the Python build: a NumPy SVD); without one the
 * watch stops, the raised rank kept.
 */
#include <math.h>
#include <string.h>

#include "fcc_engine.h"

/* A tracked direction whose length falls below this in the orthonormalisation has
 * been taken by the constraints: check at once. */
#define COLLAPSE 1e-6

/* The factor between the bound of an SVD check that found sigma_{r+1} = x sigma_1
 * (below grow_tol) and the bound that starts the next one: grow_tol / x in [2, 10]. */
static double next_check_factor(double grow_tol, double x)
{
    if (!(x > 0.0) || grow_tol / x > 10.0)
        return 10.0;
    return grow_tol / x > 2.0 ? grow_tol / x : 2.0;
}

/* Modified Gram-Schmidt, twice, on the tracked columns; 0 when one of them shrinks
 * below COLLAPSE of its length (the constraints took that direction). */
static int orthonormalise(fcc_engine *e)
{
    fcc_sparse *s = &e->sp;
    int j, l, i, sweep, n = e->n;
    double d, before, after;
    double *a, *b;
    for (j = 0; j < s->n_track; j++) {
        a = s->track + j * n;
        before = 0.0;
        for (i = 0; i < n; i++)
            before += a[i] * a[i];
        for (sweep = 0; sweep < 2; sweep++) {
            for (l = 0; l < j; l++) {
                b = s->track + l * n;
                d = 0.0;
                for (i = 0; i < n; i++)
                    d += a[i] * b[i];
                for (i = 0; i < n; i++)
                    a[i] -= d * b[i];
            }
        }
        after = 0.0;
        for (i = 0; i < n; i++)
            after += a[i] * a[i];
        if (!(after > COLLAPSE * COLLAPSE * before))
            return 0;
        after = 1.0 / sqrt(after);
        for (i = 0; i < n; i++)
            a[i] *= after;
    }
    return 1;
}

/* rs_k = 1 / max(||B_k||, row_floor * the largest row of B_k's element), the row
 * scaling of fccgen.rank, from alpha_k = RHO m_ref / s_k^2 of the factor. */
static void scaled_rows(fcc_engine *e)
{
    fcc_sparse *s = &e->sp;
    int k;
    double largest = 0.0;
    for (k = 0; k < e->m; k++)
        if (s->alpha[k] > largest)
            largest = s->alpha[k];
    for (k = 0; k < e->m; k++)               /* alpha_k / largest = (s_min / s_k)^2 */
        s->rs[k] = largest > 0.0 ? sqrt(s->alpha[k] / largest) : 1.0;
    largest = 0.0;
    for (k = 0; k < e->m; k++)
        if (s->rnorm[k] * s->rs[k] > largest)
            largest = s->rnorm[k] * s->rs[k];
    for (k = 0; k < e->m; k++)
        s->rs[k] = largest > 0.0 ? s->rs[k] / largest : 1.0;
}

/* The dense path's confirmation: the SVD of the row-scaled B (fcc_dense_svd_rank, the
 * same scaling and grow_tol); more singular values above grow_tol sigma_1 than the
 * decided rank raise it, logged with the time like fcc_factor, and the watch starts
 * again from the null space there (also after a collapse); otherwise the trigger
 * moves up (next_check_factor). */
static void check_growth(fcc_engine *e, double bound, int collapsed)
{
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    const fcc_model *md = e->model;
    int el, r, a, nq, row, svd, old = e->sol.rank_fixed, n = e->n;
    const int *idx;
    const double *blk;
    s->n_svd++;
    memset(e->sol.A, 0, (size_t)e->m * n * sizeof(double));
    for (el = 0; el < md->n_el; el++) {    /* dense B (m x n, row-major) from the blocks */
        nq = md->cls[el]->n_q;
        idx = md->qidx + md->qptr[el];
        blk = s->Bblk + P->bptr[el];
        row = md->gptr[el];
        for (r = 0; r < md->cls[el]->n_g; r++)
            for (a = 0; a < nq; a++)
                e->sol.A[(row + r) * n + idx[a]] = blk[r * nq + a];
    }
    svd = fcc_dense_svd_rank(&e->sol, e->sol.A, e->set.grow_tol);
    if (svd > old) {
        if (e->n_rank_log < FCC_RANK_LOG_SIZE) {
            e->rank_log[e->n_rank_log][0] = e->err_t;
            e->rank_log[e->n_rank_log][1] = old;
            e->rank_log[e->n_rank_log][2] = svd;
        }
        e->n_rank_log++;
        e->sol.rank_fixed = svd;
    } else if (!collapsed) {
        s->grow_trigger = bound * next_check_factor(
            e->set.grow_tol,
            old < (n < e->m ? n : e->m) && e->sol.sigma[0] > 0.0
            ? e->sol.sigma[old] / e->sol.sigma[0] : 0.0);
        return;
    }
    if (s->restart_watch != NULL)        /* rare: once per change of the rank */
        s->restart_watch(s->restart_ctx, e);
    else
        s->n_track = 0;
}

void fcc_sp_watch_rank(fcc_engine *e)
{
    /* The watch at a projected state, with A factored there: N <- orth(A^{-1} M N),
     * then an SVD check when ||B_s N||_F passes the trigger. */
    fcc_sparse *s = &e->sp;
    int i, j, k = s->n_track, n = e->n;
    double bound = 0.0;
    double *col;
    int collapsed;
    if (k <= 0)
        return;
    /* With held rows folded into A (fcc_sparse_fold.c), A^{-1} M takes the null-space
     * directions those rows hold, which B's rank does not (the locked 24-bay mast:
     * ||B_s N|| 3e-4 after one update, and an SVD of B): N stays as it was while they
     * are held, its bound as valid (any orthonormal N of k columns), only no longer
     * following the motion. */
    for (j = 0; j < k && !s->sw_live; j++) {
        col = s->track + j * n;
        fcc_sp_mult_m(e, col, s->xw, 0);
        fcc_sp_solve_a(e, s->xw);
        memcpy(col, s->xw, (size_t)n * sizeof(double));
    }
    collapsed = !s->sw_live && !orthonormalise(e);
    if (collapsed) {
        bound = INFINITY;
    } else {
        scaled_rows(e);
        for (j = 0; j < k; j++) {
            fcc_sp_mult_b(e, s->track + j * n, s->bn + j * e->m);
            for (i = 0; i < e->m; i++) {
                s->bn[j * e->m + i] *= s->rs[i];
                bound += s->bn[j * e->m + i] * s->bn[j * e->m + i];
            }
        }
        bound = sqrt(bound);
    }
    if (bound > s->bound_max)
        s->bound_max = bound;
    if (bound > s->grow_trigger)
        check_growth(e, bound, collapsed);
}
