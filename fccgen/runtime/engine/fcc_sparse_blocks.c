/* Element blocks of the sparse path and the LDL^T of the matrix built from them.
 *
 * The sparse path keeps M and B as the kernels' element blocks (a dense n x n or
 * m x n array only for the dense solve that redoes an unconverged one:
 * fcc_sp_gather_dense) with the products y = M x, y = B x, y += B^T diag(s) z over
 * them, and the matrix of the sparse solve
 *
 *     A = M + B^T diag(alpha) B,    alpha_k = RHO m_ref / s_k^2,
 *
 * (m_ref the largest diagonal entry of M, s_k = max(||B_k||, row_floor times the
 * largest row norm of B_k's element)), assembled through the scatter maps of the
 * pattern in its fill-reducing order and factored by the LDL^T of fcc_ldl.c. A is
 * positive definite whenever M is on the null space of B (the mechanism is well
 * posed), whatever the rank of B.
 *
 * RHO (FCC_RHO, 1e7): the constraint error shrinks ~1/RHO per iteration, while A's
 * condition number grows ~RHO (1e7: about 3 iterations, 1e-9 relative rounding in one
 * solve, which the refinement removes; 1e6 took a third more solves on the A02 chain).
 * Not more: 1e8 gives unconverged solves on Bricard's loop, whose redundant rows are
 * dependent only to rounding. Along such a row (singular value sigma tiny) a step
 * moves x by about alpha sigma^2 / m of the way towards b's rounding noise over sigma;
 * the few steps of a solve leave that negligible at 1e7 (as the dense path's dropped
 * row), no longer at 1e8. Scaling alpha per row group cannot help: the row is one of
 * a group of full-size rows. (Starting a solve from the previous stage's solution
 * accumulates the same drift over the run: measured, it breaks Bricard.) Solves that
 * slow down near a singular position, on models without such rows, are redone with
 * RHO FCC_AL_BOOST (fcc_sp_factor_boosted; fcc_al_refine.c says why).
 *
 * Guards. A block entry zero where the pattern of A was taken may grow to GUARD_TOL
 * (1e-12) of its block's largest entry before the pattern trips (the set-up,
 * fccgen/runtime/sparse_setup.py, gives each its bound): the factor of A then misses
 * entries of that relative size. The refinement's residuals use the full blocks, so
 * the solve still converges to the system's solution, except along directions it
 * leaves undetermined. A fixed row's entries and its g are guarded the same way.
 */
#include <math.h>
#include <string.h>

#include "fcc_engine.h"
#include "fcc_ldl.h"

/* An LDL^T pivot D_k at or below this fraction of A_kk counts as zero. */
#define PIVOT_TOL (64 * 2.220446049250313e-16)

void fcc_sp_assemble_mb(fcc_engine *e, const double *q, int flags)
{
    fcc_sp_assemble_blocks(e, q, NULL, flags);
}

void fcc_sp_assemble_blocks(fcc_engine *e, const double *q, const double *v, int flags)
{
    /* The mass (FCC_ASM_M) and Jacobian (FCC_ASM_B) blocks of every element at q, and
     * their compact copies on the solve's view; the guards of the entries left out
     * and of the fixed rows; and in the same pass over the elements the assembly's h
     * (FCC_ASM_H), f (FCC_ASM_F) and c (FCC_ASM_C) at (q, v), as fcc_assemble. With
     * the blocks, while they are at hand: rnorm_k = ||B_k|| of the kept rows (the
     * whole row, pinned coordinates too) and mref, the largest diagonal entry of M on
     * the solve's view (1 if none is positive), for the penalties. */
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    const fcc_model *md = e->model;
    fcc_assembly *as = e->asmb;
    int el, i, a, b, r, nq, nf, ng;
    const fcc_element_class *k;
    const int *idx, *loc, *rl, *rows;
    double norm, mref = 0.0;
    const double *p, *src;
    double *dst;
    double *o = as->out, *lv = as->lv, *hv = as->h, *fv = as->f, *cv = as->c;
    int vec = flags & (FCC_ASM_H | FCC_ASM_F | FCC_ASM_C);
    s->n_assembled++;
    if (flags & FCC_ASM_H) memset(hv, 0, (size_t)e->n * sizeof(double));
    if (flags & FCC_ASM_F) memset(fv, 0, (size_t)e->n * sizeof(double));
    if (flags & FCC_ASM_C) memset(cv, 0, (size_t)e->m * sizeof(double));
    for (el = 0; el < md->n_el; el++) {
        k = md->cls[el];
        nq = k->n_q;
        idx = md->qidx + md->qptr[el];
        p = as->params + md->pptr[el];
        if (!((flags & FCC_ASM_M && k->mass_matrix != NULL)
              || (flags & FCC_ASM_B && k->constraint_jacobian != NULL) || vec))
            continue;
        for (i = 0; i < nq; i++)
            s->lq[i] = q[idx[i]];
        if (vec) {
            for (i = 0; i < nq; i++)
                lv[i] = v[idx[i]];
            fcc_element_vectors(k, s->lq, lv, p, idx, md->gptr[el], vec, o, hv, fv, cv);
        }
        nf = P->snq[el];
        loc = P->sloc + P->sptr[el];
        if (flags & FCC_ASM_M && k->mass_matrix != NULL) {
            k->mass_matrix(s->lq, p, s->Mblk + P->mptr[el]);
            if (P->compact) {
                src = s->Mblk + P->mptr[el];
                dst = s->Mc + P->mcptr[el];
                for (a = 0; a < nf; a++)
                    for (b = 0; b < nf; b++)
                        dst[a * nf + b] = src[loc[a] * nq + loc[b]];
            }
            dst = s->Mc + P->mcptr[el];
            for (a = 0; a < nf; a++)
                if (dst[a * nf + a] > mref)
                    mref = dst[a * nf + a];
        }
        if (flags & FCC_ASM_B && k->constraint_jacobian != NULL) {
            k->constraint_jacobian(s->lq, p, s->Bblk + P->bptr[el]);
            src = s->Bblk + P->bptr[el];
            rl = P->srloc + P->sgptr[el];
            rows = P->srow + P->sgptr[el];
            ng = P->sng[el];
            for (r = 0; r < ng; r++) {
                norm = 0.0;
                for (i = 0; i < nq; i++)
                    norm += src[rl[r] * nq + i] * src[rl[r] * nq + i];
                s->rnorm[rows[r]] = sqrt(norm);
            }
            if (P->compact) {
                dst = s->Bc + P->bcptr[el];
                for (r = 0; r < ng; r++)
                    for (a = 0; a < nf; a++)
                        dst[r * nf + a] = src[rl[r] * nq + loc[a]];
            }
        }
    }
    if (flags & FCC_ASM_M) {
        s->mref = mref > 0.0 ? mref : 1.0;
        for (i = 0; i < P->n_zero_m; i++)
            if (!(fabs(s->Mblk[P->zero_m[i]]) <= P->zero_m_tol[i]))
                s->tripped = 1;
    }
    if (flags & FCC_ASM_B) {
        fcc_sp_sw_fill(e, q);                 /* the switchable rows (fold.c) */
        for (i = 0; i < P->n_zero_b; i++)
            if (!(fabs(s->Bblk[P->zero_b[i]]) <= P->zero_b_tol[i]))
                s->tripped = 1;
        for (i = 0; i < P->n_fixed; i++)
            if (!(fabs(s->Bblk[P->fixed_off[i]] - P->fixed_val[i]) <= P->fixed_tol[i]))
                s->tripped = 1;
    }
}

void fcc_sp_check_fixed_g(fcc_engine *e)
{
    /* Trip the pattern when a fixed row no longer holds to the position tolerance
     * (assembled g): its pinned coordinates would need to move. */
    const fcc_pattern *P = e->sp.pat;
    int i;
    for (i = 0; i < P->n_fixed_rows; i++)
        if (!(fabs(e->asmb->g[P->fixed_rows[i]]) <= P->fixed_g_tol[i]))
            e->sp.tripped = 1;
}

/* y += M x over square element blocks: element e's block (at mptr[e], none when
 * mptr[e + 1] == mptr[e]) on the coordinates idx[ptr[e]:ptr[e + 1]]. */
static void mult_blocks(int n_el, const int *ptr, const int *idx, const int *mptr,
                        const double *blocks, const double *x, double *y)
{
    int el, i, j, nq;
    const int *ix;
    const double *blk;
    double acc;
    for (el = 0; el < n_el; el++) {
        if (mptr[el + 1] == mptr[el])
            continue;
        nq = ptr[el + 1] - ptr[el];
        ix = idx + ptr[el];
        blk = blocks + mptr[el];
        for (i = 0; i < nq; i++) {
            acc = 0.0;
            for (j = 0; j < nq; j++)
                acc += blk[i * nq + j] * x[ix[j]];
            y[ix[i]] += acc;
        }
    }
}

void fcc_sp_mult_m(fcc_engine *e, const double *x, double *y, int add)
{
    /* y (+)= M x on the solve's view (pinned coordinates: neither read nor written). */
    const fcc_pattern *P = e->sp.pat;
    if (!add)
        memset(y, 0, (size_t)e->n * sizeof(double));
    mult_blocks(e->model->n_el, P->sptr, P->sidx, P->mcptr, e->sp.Mc, x, y);
}

void fcc_sp_mult_m_full(fcc_engine *e, const double *x, double *y, int add)
{
    /* y (+)= M x with the whole blocks (pinned coordinates too: M v of speeds that
     * are not yet zero there, for the velocity projection). */
    if (!add)
        memset(y, 0, (size_t)e->n * sizeof(double));
    mult_blocks(e->model->n_el, e->model->qptr, e->model->qidx, e->sp.pat->mptr,
                e->sp.Mblk, x, y);
}

void fcc_sp_mult_b(fcc_engine *e, const double *x, double *y)
{
    /* y = B x (m rows) on the solve's view: 0 in the fixed rows. */
    const fcc_pattern *P = e->sp.pat;
    int el, r, j, nq;
    const int *idx, *rows;
    const double *blk;
    double acc;
    if (P->compact)
        memset(y, 0, (size_t)e->m * sizeof(double));
    for (el = 0; el < e->model->n_el; el++) {
        nq = P->snq[el];
        idx = P->sidx + P->sptr[el];
        blk = e->sp.Bc + P->bcptr[el];
        rows = P->srow + P->sgptr[el];
        for (r = 0; r < P->sng[el]; r++) {
            acc = 0.0;
            for (j = 0; j < nq; j++)
                acc += blk[r * nq + j] * x[idx[j]];
            y[rows[r]] = acc;
        }
    }
}

void fcc_sp_mult_bt(fcc_engine *e, const double *z, const double *s, double *y)
{
    /* y += B^T diag(s) z (s NULL: the identity) on the solve's view. */
    const fcc_pattern *P = e->sp.pat;
    int el, r, j, nq;
    const int *idx, *rows;
    const double *blk;
    double zr;
    for (el = 0; el < e->model->n_el; el++) {
        nq = P->snq[el];
        idx = P->sidx + P->sptr[el];
        blk = e->sp.Bc + P->bcptr[el];
        rows = P->srow + P->sgptr[el];
        for (r = 0; r < P->sng[el]; r++) {
            zr = s == NULL ? z[rows[r]] : z[rows[r]] * s[rows[r]];
            if (zr == 0.0)
                continue;
            for (j = 0; j < nq; j++)
                y[idx[j]] += blk[r * nq + j] * zr;
        }
    }
}

void fcc_sp_gather_dense(fcc_engine *e)
{
    /* The assembly's dense M (n x n) and B (m x n, row-major) from the blocks. */
    const fcc_pattern *P = e->sp.pat;
    const fcc_model *md = e->model;
    int el, r, a, c, nq, row, n = e->n;
    const int *idx;
    const double *blk;
    double *Md = e->asmb->M, *Bd = e->asmb->B;
    memset(Md, 0, (size_t)n * n * sizeof(double));
    memset(Bd, 0, (size_t)e->m * n * sizeof(double));
    for (el = 0; el < md->n_el; el++) {
        nq = md->cls[el]->n_q;
        idx = md->qidx + md->qptr[el];
        if (P->mptr[el + 1] > P->mptr[el]) {
            blk = e->sp.Mblk + P->mptr[el];
            for (a = 0; a < nq; a++)
                for (c = 0; c < nq; c++)
                    Md[idx[a] * n + idx[c]] += blk[a * nq + c];
        }
        blk = e->sp.Bblk + P->bptr[el];
        row = md->gptr[el];
        for (r = 0; r < md->cls[el]->n_g; r++)
            for (a = 0; a < nq; a++)
                Bd[(row + r) * n + idx[a]] += blk[r * nq + a];
    }
}

/* alpha_k = RHO mref / s_k^2 with s_k = max(||B_k||, row_floor * the largest row norm
 * of B_k's element), 0 for a zero row (the norms and mref of the blocks held). Fixed
 * rows keep their constant norms and no penalty. */
static void penalties(fcc_engine *e)
{
    const fcc_pattern *P = e->sp.pat;
    fcc_sparse *s = &e->sp;
    int el, r, ng, row;
    double largest, sk, row_floor = e->set.row_floor;
    const int *rows;
    for (el = 0; el < e->model->n_el; el++) {
        ng = P->sng[el];
        rows = P->srow + P->sgptr[el];
        largest = P->efix[el];
        for (r = 0; r < ng; r++)
            if (s->rnorm[rows[r]] > largest)
                largest = s->rnorm[rows[r]];
        for (r = 0; r < ng; r++) {
            row = rows[r];
            sk = s->rnorm[row];
            if (sk < row_floor * largest)
                sk = row_floor * largest;
            s->alpha[row] = sk > 0.0 ? FCC_RHO * s->boost * s->mref / (sk * sk) : 0.0;
        }
    }
    fcc_sp_sw_penalties(e);
}

double fcc_sp_scaled_residual(fcc_engine *e)
{
    /* max_k |g_k| / ||B_k|| (|g_k| for a zero row; NaN if a g_k is not), with the
     * assembled g and the row norms of the Jacobian blocks. */
    int k;
    double worst = 0.0, val;
    for (k = 0; k < e->m; k++) {
        val = fabs(e->asmb->g[k]);
        if (e->sp.rnorm[k] > 0.0)
            val /= e->sp.rnorm[k];
        if (!(val <= worst)) {
            worst = val;
            if (val != val)
                return val;
        }
    }
    return worst;
}

static int factor(fcc_engine *e, const double *q);

static int factor_raised(fcc_engine *e, const double *q)
{
    /* A with alpha raised FCC_AL_BOOST (fcc_al_refine.c, "Near a singular position"):
     * 0 when factored; -1 when that factor fails its pivots, with the engine's error
     * as before (the caller factors with RHO). */
    int err = e->err, info = e->err_info, detail = e->err_detail;
    e->sp.boost = FCC_AL_BOOST;
    if (factor(e, q) == 0) {
        e->sp.n_boosted++;
        return 0;
    }
    e->err = err;
    e->err_info = info;
    e->err_detail = detail;
    return -1;
}

int fcc_sp_factor(fcc_engine *e, const double *q)
{
    /* A = M + B^T diag(alpha) B from the blocks (alpha with RHO), and its LDL^T; with
     * alpha raised FCC_AL_BOOST instead while boost_hold counts, RHO's when that
     * factor fails. */
    fcc_sparse *s = &e->sp;
    if (s->boost_hold > 0 && s->beyond_quotient == 0.0 && !s->own_lam_seen) {
        s->boost_hold--;
        if (factor_raised(e, q) == 0)
            return 0;
        s->boost_hold = 0;
    }
    s->boost = 1.0;
    return factor(e, q);
}

int fcc_sp_factor_boosted(fcc_engine *e)
{
    /* A again from the blocks held, alpha raised FCC_AL_BOOST. 0 when factored; -1
     * when that factor fails (the blocks factored with RHO again). */
    if (factor_raised(e, NULL) == 0)
        return 0;
    fcc_sp_factor_unboosted(e);
    return -1;
}

int fcc_sp_factor_unboosted(fcc_engine *e)
{
    /* A again from the blocks held, alpha with RHO, and no raise held (a raised
     * factor that failed, or whose solve did not converge). 0 when factored. */
    e->sp.boost = 1.0;
    e->sp.boost_hold = 0;
    return factor(e, NULL);
}

static int factor(fcc_engine *e, const double *q)
{
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int el, a, b, r, nq, ng, info, bad, t;
    const int *rows;
    const double *mb, *bb;
    double val;
    e->factor_valid = 0;
    s->held = 0;
    if (!P->ready)
        return fcc_fail(e, FCC_ERR_LAPACK, -1, 0);
    if (s->tripped)
        return fcc_fail(e, FCC_ERR_PATTERN, 0, 0);
    penalties(e);
    memset(s->Ax, 0, (size_t)P->nnz_a * sizeof(double));
    for (el = 0; el < e->model->n_el; el++) {
        if (P->ent_ptr[el + 1] == P->ent_ptr[el])
            continue;
        nq = P->snq[el];
        ng = P->sng[el];
        mb = P->mcptr[el + 1] > P->mcptr[el] ? s->Mc + P->mcptr[el] : NULL;
        bb = s->Bc + P->bcptr[el];
        rows = P->srow + P->sgptr[el];
        for (r = 0; r < ng; r++)              /* the rows scaled by their penalties */
            for (a = 0; a < nq; a++)
                s->lb[r * nq + a] = bb[r * nq + a] * s->alpha[rows[r]];
        for (t = P->ent_ptr[el]; t < P->ent_ptr[el + 1]; t++) {
            a = P->ent_a[t];
            b = P->ent_b[t];
            val = mb != NULL ? mb[a * nq + b] : 0.0;
            for (r = 0; r < ng; r++)
                val += s->lb[r * nq + a] * bb[r * nq + b];
            s->Ax[P->ent_pos[t]] += val;
        }
    }
    fcc_sp_sw_factor(e);                    /* the held switchable rows */
    for (a = 0; a < P->n_pinned; a++)       /* pinned: a unit diagonal, nothing else */
        s->Ax[P->pin_diag[a]] = 1.0;
    s->n_factor++;
    info = fcc_ldl_numeric(P->n_lead, P->Ap, P->Ai, s->Ax, P->Lp, P->Li, P->Rp, P->Rj,
                           P->Rpos, s->Lx, s->Dinv, s->Y, PIVOT_TOL);
    if (info == 0) {
        s->held = 1;
        return 0;
    }
    bad = fcc_nonfinite_input(e, q, NULL, FCC_ASM_M | FCC_ASM_B);
    if (bad)
        return fcc_fail(e, FCC_ERR_NONFINITE_INPUT, 0, bad);
    return fcc_fail(e, FCC_ERR_SINGULAR, info, 0);
}

void fcc_sp_solve_a(fcc_engine *e, double *x)
{
    /* x <- A^{-1} x through the permutation (pinned coordinates past n_lead: x as it
     * is, A's unit diagonal there). */
    const fcc_pattern *P = e->sp.pat;
    double *t = e->sp.tperm;
    int i, n = P->n_lead;
    for (i = 0; i < n; i++)
        t[i] = x[P->perm[i]];
    fcc_ldl_solve(n, P->Lp, P->Li, e->sp.Lx, e->sp.Dinv, t);
    for (i = 0; i < n; i++)
        x[P->perm[i]] = t[i];
}

void fcc_sp_solve_a_add(fcc_engine *e, const double *y, double *x, double *step,
                        double *size)
{
    /* x += A^{-1} y, with step = max |A^{-1} y| and size = max |x| after it, in the
     * pass that scatters the solve. y must be zero on the pinned coordinates past
     * n_lead (A^{-1} y is then zero there too): they are not visited, so x keeps its
     * values there, and size counts them only if they are zero (as in the
     * refinement, whose x stays zero on them). */
    const fcc_pattern *P = e->sp.pat;
    double *t = e->sp.tperm;
    int i, j, n = P->n_lead;
    double d, xj, nd = 0.0, nx = 0.0;
    for (i = 0; i < n; i++)
        t[i] = y[P->perm[i]];
    fcc_ldl_solve(n, P->Lp, P->Li, e->sp.Lx, e->sp.Dinv, t);
    for (i = 0; i < n; i++) {
        j = P->perm[i];
        d = t[i];
        xj = x[j] + d;
        x[j] = xj;
        if (fabs(d) > nd)
            nd = fabs(d);
        if (fabs(xj) > nx)
            nx = fabs(xj);
    }
    *step = nd;
    *size = nx;
}

int fcc_sp_nonfinite_input(fcc_engine *e, const double *q, const double *v, int flags)
{
    const fcc_pattern *P = e->sp.pat;
    int n = e->n, m = e->m, n_el = e->model->n_el;
    if (q != NULL && !fcc_finite(q, n)) return 1;
    if (v != NULL && !fcc_finite(v, n)) return 2;
    if (flags & FCC_ASM_M && !fcc_finite(e->sp.Mblk, P->mptr[n_el])) return 3;
    if (flags & FCC_ASM_H && !fcc_finite(e->asmb->h, n)) return 4;
    if (flags & FCC_ASM_F && !fcc_finite(e->asmb->f, n)) return 5;
    if (flags & FCC_ASM_B && !fcc_finite(e->sp.Bblk, P->bptr[n_el])) return 6;
    if (flags & FCC_ASM_C && !fcc_finite(e->asmb->c, m)) return 7;
    if (flags & FCC_ASM_G && !fcc_finite(e->asmb->g, m)) return 8;
    return 0;
}
