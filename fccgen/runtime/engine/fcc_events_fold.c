/* The events' used rows folded into the sparse path's factorisation.
 *
 * When the sparse engine's pattern holds the model's switchable rows
 * (fcc_sparse_fold.c; the set-up puts them there), a run folds the used rows into
 * every factorisation: the rows' values go into the solve at each assembly of B
 * (fill_rows), their targets -(dG/dt) v into each acceleration solve, and the
 * refinement enforces them with the engine's own rows. The per-stage Schur complement
 * of fcc_events.c (one constrained solve per used row for its response z_j, then G Z)
 * is left out: fcc_ev_constrain has nothing to add, and reads the rows' multipliers
 * from the solve (mu_j = -lambda_{m+j}: the Schur form's a + Z mu puts G^T mu on the
 * right-hand side, the folded solve G^T lambda on the left). The step's velocity
 * projection holds G v = 0 with the rows folded; after it fcc_ev_correct holds the
 * positions, r_j(q) = held_j, with one folded solve instead of one response per row.
 *
 * Switches (fcc_ev_apply) run with the fold off (fold_live 0): their impacts and the
 * rank decision of the used rows (decide_pivots) need the engine's own constrained
 * responses, which a factor holding the rows does not give. Their velocity projection
 * assembles B afresh, so its factor is the engine's own; the next stage factors with
 * the new used rows folded.
 *
 * The pattern of each row is what its gradient read where the set-up sampled it
 * (fccgen.runtime.paths). Every fill checks it: a used row with a nonzero outside its
 * pattern (on a free coordinate) turns the fold off for the rest of the run (counted
 * in n_fold_off), and its stages take the Schur complement from there, which reads the
 * whole row.
 *
 * Which is cheaper depends on the model, not on its size: on the scissor boom of 12
 * units the fold's solves take half the refinement steps of the Schur complement's,
 * on the scissor mast with a latch per bay (one DOF, every latch but one redundant)
 * the folded row makes every solve slow and the Schur complement's solves, at 0 DOF,
 * converge in two steps. So a run measures both after each switch that leaves rows
 * used (fold_trial): FCC_FOLD_TRIAL_STEPS steps folded, then as many with the Schur
 * complement, each step's cost counted from the sparse engine's statistics, which do
 * not depend on the machine or its load (factorisations times a factorisation's
 * multiply-adds over the pattern of L, refinement steps times a solve's and a
 * product's), and keeps the cheaper until the next switch, or for
 * FCC_FOLD_RETRIAL_STEPS steps, after which it measures again (the motion may have
 * changed which is cheaper). The step after the switch itself is left out of both.
 * The same run always makes the same choices.
 */
#include <math.h>
#include <string.h>

#include "fcc_events.h"

/* Zero every row's values and norms (nothing folded). */
static void clear_rows(fcc_engine *e)
{
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int j;
    memset(s->sw_val, 0, (size_t)P->sw_ptr[P->n_sw] * sizeof(double));
    for (j = 0; j < P->n_sw; j++)
        s->rnorm[e->m + j] = 0.0;
}

/* fold_from and fold_free for P, made afresh whenever a run folds (the engine's pattern
 * may be another one, or changed, since the last run): each entry of the rows'
 * patterns found among its row's structural nonzeros (the event table's gradient_idx),
 * and which of those are on coordinates not pinned. 0, or -1 (memory). */
static int fold_maps(fcc_events *ev, const fcc_pattern *P)
{
    const fcc_event_table *tab = ev->spec->tab;
    int j, k, lo, hi, mid, col, nz = tab->n_gradient_nz, n_idx = P->sw_ptr[P->n_sw];
    int *pin = ev->fold_free;                 /* n flags first, then the nz flags */
    if (n_idx > ev->fold_cap) {
        FCC_FREE(ev->fold_from);
        ev->fold_cap = 0;
        ev->fold_from = FCC_CALLOC((size_t)n_idx + 1, sizeof(int));
        if (ev->fold_from == NULL)
            return -1;
        ev->fold_cap = n_idx;
    }
    memset(pin, 0, (size_t)ev->spec->n * sizeof(int));
    for (k = 0; k < P->n_pinned; k++)
        pin[P->pinned[k]] = 1;
    for (k = 0; k < nz; k++)
        pin[ev->spec->n + k] = !pin[tab->gradient_idx[k]];
    for (j = 0; j < P->n_sw; j++) {
        for (k = P->sw_ptr[j]; k < P->sw_ptr[j + 1]; k++) {
            col = P->sw_idx[k];
            lo = tab->gradient_ptr[j];
            hi = tab->gradient_ptr[j + 1];
            while (lo < hi) {                  /* the columns increase in a row */
                mid = lo + (hi - lo) / 2;
                if (tab->gradient_idx[mid] < col)
                    lo = mid + 1;
                else
                    hi = mid;
            }
            ev->fold_from[k] = lo < tab->gradient_ptr[j + 1]
                               && tab->gradient_idx[lo] == col ? lo : -1;
        }
    }
    return 0;
}

static void fill_rows(void *ctx, fcc_engine *e, const double *q, const double *v)
{
    /* v NULL: the used rows' values on their patterns and their norms at q, zero for
     * the others; else their targets -(dG/dt) v at (q, v). The values come from the
     * gradients' structural nonzeros (fcc_ev_gradients), so a fill reads each row's
     * nonzeros, not n numbers per row; a used row whose nonzeros on free (not pinned)
     * coordinates are more than those on its pattern read outside it. */
    fcc_events *ev = ctx;
    const fcc_event_spec *c = ev->spec;
    const fcc_event_table *tab = c->tab;
    fcc_sparse *s = &e->sp;
    const fcc_pattern *P = s->pat;
    int j, k, f, inside, count;
    int live = ev->fold && ev->fold_live && ev->n_used > 0;
    double *val, norm, x;
    if (v != NULL) {
        if (live)
            tab->quantity_bias(q, v, e->asmb->t, ev->p, ev->rb);
        for (j = 0; j < c->nr; j++)
            s->sw_tgt[j] = live && ev->used[j] ? -ev->rb[j] : 0.0;
        return;
    }
    if (!live) {
        clear_rows(e);
        return;
    }
    tab->quantity_gradient_values(q, NULL, 0.0, ev->p, ev->rgv);
    for (j = 0; j < c->nr; j++) {
        val = s->sw_val + P->sw_ptr[j];
        if (!ev->used[j]) {
            for (k = P->sw_ptr[j]; k < P->sw_ptr[j + 1]; k++)
                val[k - P->sw_ptr[j]] = 0.0;
            s->rnorm[e->m + j] = 0.0;
            continue;
        }
        norm = 0.0;
        inside = 0;
        for (k = P->sw_ptr[j]; k < P->sw_ptr[j + 1]; k++) {
            f = ev->fold_from[k];
            x = f >= 0 ? ev->rgv[f] : 0.0;
            val[k - P->sw_ptr[j]] = x;
            norm += x * x;
            inside += x != 0.0;
        }
        count = 0;
        for (k = tab->gradient_ptr[j]; k < tab->gradient_ptr[j + 1]; k++)
            count += ev->rgv[k] != 0.0 && ev->fold_free[c->n + k];
        if (count != inside) {
            ev->fold = 0;                     /* outside its pattern: Schur from here */
            ev->fold_able = 0;
            ev->trial_phase = 0;
            ev->n_fold_off++;
            clear_rows(e);
            return;
        }
        s->rnorm[e->m + j] = sqrt(norm);
    }
}

/* The trial's weights: a factorisation's multiply-adds (sum over the columns of L of
 * their entries squared, the up-looking LDL^T's work, and the assembly of A) and a
 * refinement step's (one solve with L, D and L^T, and a product with A). */
static void trial_weights(fcc_events *ev, const fcc_pattern *P)
{
    double f = 0.0, c;
    int k;
    for (k = 0; k < P->n; k++) {
        c = (double)(P->Lp[k + 1] - P->Lp[k]);
        f += c * c;
    }
    ev->w_factor = f + (double)P->nnz_a;
    ev->w_iteration = 2.0 * (double)P->nnz_l + 2.0 * (double)P->nnz_a + (double)P->n;
}

int fcc_events_fold(fcc_events *ev, fcc_engine *e, int on)
{
    fcc_sparse *s = &e->sp;
    ev->fold = on && e->sparse && s->pat != NULL && ev->spec->nr > 0
               && s->pat->n_sw == ev->spec->nr && fold_maps(ev, s->pat) == 0;
    ev->fold_live = ev->fold;
    ev->fold_able = ev->fold;
    ev->trial_phase = 0;
    ev->trial_steps = 0;
    if (ev->fold) {
        trial_weights(ev, s->pat);
        s->sw_fill = fill_rows;
        s->sw_ctx = ev;
    } else if (e->sparse && s->sw_ctx == ev) {
        s->sw_fill = NULL;
        s->sw_ctx = NULL;
    }
    e->factor_valid = 0;                      /* the next factor with or without them */
    return ev->fold;
}

int fcc_ev_fold_constrain(fcc_engine *e, fcc_events *ev)
{
    /* The accelerations hold the used rows already when the factor had them folded:
     * their multipliers into ev->mu (in the used rows' order). */
    const fcc_event_spec *c = ev->spec;
    int j, k = 0;
    if (!(ev->fold && ev->fold_live && e->sp.sw_live))
        return 0;
    for (j = 0; j < c->nr; j++)
        if (ev->used[j])
            ev->mu[k++] = -e->sp.lam[e->m + j];
    return 1;
}

/* x <- the folded solve's x of M x + B^T lambda = 0, B x = 0, G x = sw_b. */
static void folded_solve(fcc_engine *e, double *x)
{
    e->sp.sw_b = e->sp.sw_tgt;
    fcc_sp_solve_kkt(e, NULL, NULL, NULL, x, 0, 0);
    e->sp.sw_b = NULL;
}

int fcc_ev_fold_correct(fcc_engine *e, fcc_events *ev, double *q)
{
    /* fcc_ev_correct with the factor at q holding the used rows (the step's velocity
     * projection): dq with G dq = held - r(q), M-orthogonal to the engine's rows.
     * The speeds need nothing more: that projection held G v = 0 with the rows at
     * this q already (the Schur form's second solve holds them with G at this q too,
     * after q moved); a solve for their rounding-size residual only met the weak
     * direction of the locked row (rate 0.28 per step on the boom of 12 units). */
    const fcc_event_spec *c = ev->spec;
    fcc_sparse *s = &e->sp;
    int i, j, n = c->n;
    double *dx = ev->acc;
    if (!(ev->fold && ev->fold_live && s->sw_live))
        return 0;
    c->tab->quantity_values(q, NULL, 0.0, ev->p, ev->r);
    for (j = 0; j < c->nr; j++)
        s->sw_tgt[j] = ev->used[j] ? ev->held[j] - ev->r[j] : 0.0;
    folded_solve(e, dx);
    for (i = 0; i < n; i++)
        q[i] += dx[i];
    if (!fcc_finite(q, n))
        return fcc_fail(e, FCC_ERR_NONFINITE_RESULT, 0, 0);
    e->factor_valid = 0;                      /* q moved: the next stage refactors */
    return 1;
}

/* -- Which is cheaper: the trial after each switch --------------------------------- */

static double solves_cost(const fcc_engine *e, const fcc_events *ev)
{
    return ev->w_factor * (double)e->sp.n_factor
           + ev->w_iteration * (double)e->sp.n_iterations;
}

void fcc_ev_trial_switch(fcc_events *ev)
{
    /* After a switch: rows used, a trial starts (folded) at the next step's end; none,
     * nothing to choose. fcc_ev_apply, the caller, has dropped the factor already:
     * the next stage factors with or without the rows. */
    if (!(ev->fold_able && ev->fold_trial))
        return;
    ev->fold = 1;
    ev->trial_phase = ev->n_used > 0 ? -1 : 0;
    ev->trial_steps = 0;
}

void fcc_ev_trial_step(fcc_engine *e, fcc_events *ev)
{
    /* At a step's end, after its correction (the factor at q is the step's own, with
     * or without the rows: a change of way takes effect from the next step on). */
    double now;
    int phase = ev->trial_phase;
    if (!(ev->fold_able && ev->fold_trial && ev->n_used > 0))
        return;
    if (phase == 0 && ++ev->trial_steps < FCC_FOLD_RETRIAL_STEPS)
        return;
    if (phase == 0)
        phase = -1;                           /* long since the choice: again */
    now = solves_cost(e, ev);
    if (phase < 0 || ++ev->trial_steps == FCC_FOLD_TRIAL_STEPS) {
        if (phase > 0)
            ev->trial_cost[phase - 1] = now - ev->trial_start;
        ev->trial_phase = phase < 0 ? 1 : phase == 1 ? 2 : 0;
        ev->trial_steps = 0;
        ev->trial_start = now;
        if (ev->trial_phase == 0) {
            ev->n_trials++;
            ev->fold = ev->trial_cost[0] <= ev->trial_cost[1];
            ev->n_trials_folded += ev->fold;
        } else {
            ev->fold = ev->trial_phase == 1;
        }
        if (!ev->fold)
            clear_rows(e);                    /* out of the next factorisation */
        e->factor_valid = 0;
    }
}
