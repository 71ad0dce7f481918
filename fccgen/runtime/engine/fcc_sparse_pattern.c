/* The sparse path's constants (fcc_pattern, fcc_sparse.h): the solve's view of the
 * elements, the guards of the pattern, the pattern of A and the symbolic LDL^T.
 *
 * Which coordinates are pinned, which entries are guarded and the fill-reducing order
 * are decided by a set-up analysis outside the engine (the Python build's
 * fccgen.runtime.sparse_setup and sparsity); these functions take its results, work
 * out the offsets that follow from them, and do the symbolic factorisation once.
 */
#include <string.h>

#include "fcc_ldl.h"
#include "fcc_sparse.h"

static void *zalloc(size_t n, size_t size)
{
    return FCC_CALLOC(n > 0 ? n : 1, size);
}

/* A heap copy of n ints (at least one allocated), or NULL when out of memory. */
int *fcc_sp_copy_ints(const int *src, int n)
{
    int i, *p = zalloc((size_t)n, sizeof(int));
    if (p != NULL)
        for (i = 0; i < n; i++)
            p[i] = src[i];
    return p;
}

static double *copy_doubles(const double *src, int n)
{
    int i;
    double *p = zalloc((size_t)n, sizeof(double));
    if (p != NULL)
        for (i = 0; i < n; i++)
            p[i] = src[i];
    return p;
}

int fcc_pattern_init(fcc_pattern *P, const fcc_model *m)
{
    int e, i, nq, total_m = 0, total_b = 0;
    const fcc_element_class *k;
    memset(P, 0, sizeof(*P));
    P->model = m;
    P->n = m->n_q;
    P->m = m->n_g;
    P->mptr = zalloc((size_t)m->n_el + 1, sizeof(int));
    P->bptr = zalloc((size_t)m->n_el + 1, sizeof(int));
    P->snq = zalloc((size_t)m->n_el, sizeof(int));
    P->sng = zalloc((size_t)m->n_el, sizeof(int));
    P->sptr = zalloc((size_t)m->n_el + 1, sizeof(int));
    P->sgptr = zalloc((size_t)m->n_el + 1, sizeof(int));
    P->sidx = zalloc((size_t)m->qptr[m->n_el], sizeof(int));
    P->sloc = zalloc((size_t)m->qptr[m->n_el], sizeof(int));
    P->srow = zalloc((size_t)m->n_g, sizeof(int));
    P->srloc = zalloc((size_t)m->n_g, sizeof(int));
    P->efix = zalloc((size_t)m->n_el, sizeof(double));
    if (!P->mptr || !P->bptr || !P->snq || !P->sng || !P->sptr || !P->sgptr || !P->sidx
            || !P->sloc || !P->srow || !P->srloc || !P->efix) {
        fcc_pattern_free(P);
        return FCC_ERR_MEMORY;
    }
    for (e = 0; e < m->n_el; e++) {
        k = m->cls[e];
        nq = k->n_q;
        total_m += k->mass_matrix != NULL ? nq * nq : 0;
        total_b += k->n_g * nq;
        P->mptr[e + 1] = total_m;
        P->bptr[e + 1] = total_b;
    }
    for (e = 0; e <= m->n_el; e++) {
        P->sptr[e] = m->qptr[e];
        P->sgptr[e] = m->gptr[e];
    }
    for (e = 0; e < m->n_el; e++) {
        P->snq[e] = m->cls[e]->n_q;
        P->sng[e] = m->cls[e]->n_g;
        for (i = 0; i < m->cls[e]->n_q; i++) {
            P->sidx[m->qptr[e] + i] = m->qidx[m->qptr[e] + i];
            P->sloc[m->qptr[e] + i] = i;
        }
        for (i = 0; i < m->cls[e]->n_g; i++) {
            P->srow[m->gptr[e] + i] = m->gptr[e] + i;
            P->srloc[m->gptr[e] + i] = i;
        }
    }
    P->mcptr = P->mptr;
    P->bcptr = P->bptr;
    P->total_mc = total_m;
    P->total_bc = total_b;
    return FCC_OK;
}

static void free_structure(fcc_pattern *P)
{
    FCC_FREE(P->perm); FCC_FREE(P->Ap); FCC_FREE(P->Ai); FCC_FREE(P->ent_ptr);
    FCC_FREE(P->ent_a); FCC_FREE(P->ent_b); FCC_FREE(P->ent_pos); FCC_FREE(P->Lp);
    FCC_FREE(P->Li); FCC_FREE(P->Rp); FCC_FREE(P->Rj); FCC_FREE(P->Rpos);
    FCC_FREE(P->pin_diag);
    FCC_FREE(P->sw_ptr); FCC_FREE(P->sw_idx); FCC_FREE(P->sw_ent_ptr);
    FCC_FREE(P->sw_ent_a); FCC_FREE(P->sw_ent_b); FCC_FREE(P->sw_ent_pos);
    P->sw_ptr = P->sw_idx = P->sw_ent_ptr = P->sw_ent_a = P->sw_ent_b = NULL;
    P->sw_ent_pos = NULL;
    P->n_sw = 0;
    P->perm = P->Ap = P->Ai = P->ent_ptr = P->ent_a = P->ent_b = P->ent_pos = NULL;
    P->Lp = P->Li = P->Rp = P->Rj = P->Rpos = P->pin_diag = NULL;
    P->ready = 0;
}

void fcc_pattern_free(fcc_pattern *P)
{
    free_structure(P);
    if (P->compact) {
        FCC_FREE(P->mcptr);
        FCC_FREE(P->bcptr);
    }
    FCC_FREE(P->mptr); FCC_FREE(P->bptr); FCC_FREE(P->snq); FCC_FREE(P->sng);
    FCC_FREE(P->sptr); FCC_FREE(P->sgptr); FCC_FREE(P->sidx); FCC_FREE(P->sloc);
    FCC_FREE(P->srow); FCC_FREE(P->srloc); FCC_FREE(P->efix); FCC_FREE(P->pinned);
    FCC_FREE(P->fixed_off); FCC_FREE(P->fixed_val); FCC_FREE(P->fixed_tol);
    FCC_FREE(P->fixed_rows); FCC_FREE(P->fixed_norm); FCC_FREE(P->fixed_g_tol);
    FCC_FREE(P->zero_m); FCC_FREE(P->zero_b); FCC_FREE(P->zero_m_tol);
    FCC_FREE(P->zero_b_tol);
    memset(P, 0, sizeof(*P));
}

int fcc_pattern_set_view(fcc_pattern *P, const int *snq, const int *sloc,
                         const int *sng, const int *srloc, const double *efix,
                         int n_pinned, const int *pinned, int n_fixed_rows,
                         const int *fixed_rows, const double *fixed_norm,
                         const double *fixed_g_tol, int n_fixed, const int *fixed_off,
                         const double *fixed_val, const double *fixed_tol)
{
    const fcc_model *m = P->model;
    int e, a, r, nf, ng, at = 0, rt = 0, total_m = 0, total_b = 0;
    int *mcptr = zalloc((size_t)m->n_el + 1, sizeof(int));
    int *bcptr = zalloc((size_t)m->n_el + 1, sizeof(int));
    if (mcptr == NULL || bcptr == NULL) {
        FCC_FREE(mcptr);
        FCC_FREE(bcptr);
        return FCC_ERR_MEMORY;
    }
    for (e = 0; e < m->n_el; e++) {
        nf = snq[e];
        ng = sng[e];
        for (a = 0; a < nf; a++) {
            P->sloc[at + a] = sloc[at + a];
            P->sidx[at + a] = m->qidx[m->qptr[e] + sloc[at + a]];
        }
        P->snq[e] = nf;
        P->sptr[e + 1] = P->sptr[e] + nf;
        at += nf;
        for (r = 0; r < ng; r++) {
            P->srloc[rt + r] = srloc[rt + r];
            P->srow[rt + r] = m->gptr[e] + srloc[rt + r];
        }
        P->sng[e] = ng;
        P->sgptr[e + 1] = P->sgptr[e] + ng;
        rt += ng;
        total_m += m->cls[e]->mass_matrix != NULL ? nf * nf : 0;
        total_b += ng * nf;
        mcptr[e + 1] = total_m;
        bcptr[e + 1] = total_b;
        P->efix[e] = efix[e];
    }
    if (P->compact) {
        FCC_FREE(P->mcptr);
        FCC_FREE(P->bcptr);
    }
    P->compact = 1;
    P->mcptr = mcptr;
    P->bcptr = bcptr;
    P->total_mc = total_m;
    P->total_bc = total_b;
    P->n_pinned = n_pinned;
    P->pinned = fcc_sp_copy_ints(pinned, n_pinned);
    P->n_fixed_rows = n_fixed_rows;
    P->fixed_rows = fcc_sp_copy_ints(fixed_rows, n_fixed_rows);
    P->fixed_norm = copy_doubles(fixed_norm, n_fixed_rows);
    P->fixed_g_tol = copy_doubles(fixed_g_tol, n_fixed_rows);
    P->n_fixed = n_fixed;
    P->fixed_off = fcc_sp_copy_ints(fixed_off, n_fixed);
    P->fixed_val = copy_doubles(fixed_val, n_fixed);
    P->fixed_tol = copy_doubles(fixed_tol, n_fixed);
    if (!P->pinned || !P->fixed_rows || !P->fixed_norm || !P->fixed_g_tol
            || !P->fixed_off || !P->fixed_val || !P->fixed_tol)
        return FCC_ERR_MEMORY;
    return FCC_OK;
}

int fcc_pattern_set_guards(fcc_pattern *P, int n_zero_m, const int *zero_m,
                           const double *zero_m_tol, int n_zero_b, const int *zero_b,
                           const double *zero_b_tol)
{
    FCC_FREE(P->zero_m); FCC_FREE(P->zero_b); FCC_FREE(P->zero_m_tol);
    FCC_FREE(P->zero_b_tol);
    P->zero_m = fcc_sp_copy_ints(zero_m, n_zero_m);
    P->zero_m_tol = copy_doubles(zero_m_tol, n_zero_m);
    P->zero_b = fcc_sp_copy_ints(zero_b, n_zero_b);
    P->zero_b_tol = copy_doubles(zero_b_tol, n_zero_b);
    P->n_zero_m = n_zero_m;
    P->n_zero_b = n_zero_b;
    if (!P->zero_m || !P->zero_m_tol || !P->zero_b || !P->zero_b_tol)
        return FCC_ERR_MEMORY;
    return FCC_OK;
}

int fcc_pattern_set_structure(fcc_pattern *P, const int *perm, const int *Ap,
                              const int *Ai, const int *ent_ptr, const int *ent_a,
                              const int *ent_b, const int *ent_pos)
{
    const fcc_model *m = P->model;
    int n = P->n, e, i, k, n_ent = ent_ptr[m->n_el], rc = FCC_OK;
    int *parent, *Lnz, *flag, *pattern, *pinv, *is_pinned;
    free_structure(P);
    P->nnz_a = Ap[n];
    P->perm = fcc_sp_copy_ints(perm, n);
    P->Ap = fcc_sp_copy_ints(Ap, n + 1);
    P->Ai = fcc_sp_copy_ints(Ai, P->nnz_a);
    P->ent_ptr = fcc_sp_copy_ints(ent_ptr, m->n_el + 1);
    P->ent_a = fcc_sp_copy_ints(ent_a, n_ent);
    P->ent_b = fcc_sp_copy_ints(ent_b, n_ent);
    P->ent_pos = fcc_sp_copy_ints(ent_pos, n_ent);
    P->Lp = zalloc((size_t)n + 1, sizeof(int));
    P->pin_diag = zalloc((size_t)P->n_pinned, sizeof(int));
    parent = zalloc((size_t)n, sizeof(int));
    Lnz = zalloc((size_t)n, sizeof(int));
    flag = zalloc((size_t)n, sizeof(int));
    pattern = zalloc((size_t)n, sizeof(int));
    pinv = zalloc((size_t)n, sizeof(int));
    is_pinned = zalloc((size_t)n, sizeof(int));
    if (!P->perm || !P->Ap || !P->Ai || !P->ent_ptr || !P->ent_a || !P->ent_b
            || !P->ent_pos || !P->Lp || !P->pin_diag || !parent || !Lnz || !flag
            || !pattern || !pinv || !is_pinned) {
        rc = FCC_ERR_MEMORY;
        goto done;
    }
    P->lb_size = 1;
    for (e = 0; e < m->n_el; e++)
        if (P->snq[e] * P->sng[e] > P->lb_size)
            P->lb_size = P->snq[e] * P->sng[e];
    fcc_ldl_symbolic(n, P->Ap, P->Ai, P->Lp, parent, Lnz, flag);
    P->nnz_l = P->Lp[n];
    P->Li = zalloc((size_t)P->nnz_l, sizeof(int));
    P->Rp = zalloc((size_t)n + 1, sizeof(int));
    P->Rj = zalloc((size_t)P->nnz_l, sizeof(int));
    P->Rpos = zalloc((size_t)P->nnz_l, sizeof(int));
    if (!P->Li || !P->Rp || !P->Rj || !P->Rpos) {
        rc = FCC_ERR_MEMORY;
        goto done;
    }
    fcc_ldl_rows(n, P->Ap, P->Ai, P->Lp, parent, Lnz, P->Li, P->Rp, P->Rj, P->Rpos,
                 pattern, flag);
    for (i = 0; i < n; i++)
        pinv[P->perm[i]] = i;
    for (i = 0; i < P->n_pinned; i++) {
        k = pinv[P->pinned[i]];              /* the diagonal closes its column */
        P->pin_diag[i] = P->Ap[k + 1] - 1;
        if (P->Ai[P->pin_diag[i]] != k) {
            rc = FCC_ERR_ARGUMENT;
            goto done;
        }
        is_pinned[k] = 1;
    }
    /* Trailing pinned columns (sparsity.isolated_last puts them there) are unit
     * diagonals with nothing in their rows: L is the identity there and a solve leaves
     * x as it is, so the factorisation and the solves stop before them. */
    P->n_lead = n;
    while (P->n_lead > 0 && is_pinned[P->n_lead - 1]
           && P->Ap[P->n_lead] - P->Ap[P->n_lead - 1] == 1
           && P->Lp[P->n_lead] == P->Lp[P->n_lead - 1])
        P->n_lead--;
    P->ready = 1;
done:
    FCC_FREE(parent); FCC_FREE(Lnz); FCC_FREE(flag); FCC_FREE(pattern); FCC_FREE(pinv);
    FCC_FREE(is_pinned);
    if (rc != FCC_OK)
        free_structure(P);
    return rc;
}
