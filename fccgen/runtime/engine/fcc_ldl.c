/* A sparse LDL^T factorisation over a fixed pattern (fcc_ldl.h).
 *
 * After T. A. Davis, "Algorithm 849: a concise sparse Cholesky factorization package"
 * (LDL): the matrix is given by the upper triangle of its (already permuted) columns,
 * Ap/Ai/Ax in compressed sparse columns. The factorisation is up-looking: row k of L
 * is found by a sparse triangular solve L[:k, :k] y = A[:k, k], whose nonzero pattern
 * is the set of elimination-tree paths from the entries of A[:k, k] towards the root,
 * and D_k = A_kk - sum_j L_kj^2 D_j.
 *
 * The pattern is the same at every factorisation, so all of the symbolic work is done
 * once (fcc_ldl_symbolic, fcc_ldl_rows): the elimination tree, the column pointers Lp
 * and row indices Li of L, and for every row k the columns j of its entries in the
 * order of the triangular solve (Rp/Rj) with the place of L_kj in Lx (Rpos).
 * fcc_ldl_numeric then only does arithmetic, in the same order as Davis' ldl_numeric,
 * but keeping the reciprocal pivots 1 / D_k: each L_kj is a product where Davis
 * divides (one rounding apart), and the solves multiply too. Every array is the
 * caller's: the per-step work is allocation-free.
 */
#include "fcc_ldl.h"

void fcc_ldl_symbolic(int n, const int *Ap, const int *Ai, int *Lp, int *parent,
                      int *Lnz, int *flag)
{
    int i, k, p;
    for (k = 0; k < n; k++) {
        parent[k] = -1;
        flag[k] = k;
        Lnz[k] = 0;
        for (p = Ap[k]; p < Ap[k + 1]; p++) {
            i = Ai[p];
            if (i < k) {
                while (flag[i] != k) {
                    if (parent[i] == -1)
                        parent[i] = k;
                    Lnz[i]++;
                    flag[i] = k;
                    i = parent[i];
                }
            }
        }
    }
    Lp[0] = 0;
    for (k = 0; k < n; k++)
        Lp[k + 1] = Lp[k] + Lnz[k];
}

void fcc_ldl_rows(int n, const int *Ap, const int *Ai, const int *Lp, const int *parent,
                  int *Lnz, int *Li, int *Rp, int *Rj, int *Rpos, int *pattern,
                  int *flag)
{
    int i, k, p, length, top, t = 0;
    for (k = 0; k < n; k++)
        Lnz[k] = 0;
    Rp[0] = 0;
    for (k = 0; k < n; k++) {
        top = n;
        flag[k] = k;
        for (p = Ap[k]; p < Ap[k + 1]; p++) {
            i = Ai[p];
            if (i > k)
                continue;
            length = 0;
            while (flag[i] != k) {
                pattern[length] = i;
                length++;
                flag[i] = k;
                i = parent[i];
            }
            while (length > 0) {
                top--;
                length--;
                pattern[top] = pattern[length];
            }
        }
        while (top < n) {
            i = pattern[top];
            top++;
            Rj[t] = i;
            Rpos[t] = Lp[i] + Lnz[i];
            Li[Rpos[t]] = k;
            Lnz[i]++;
            t++;
        }
        Rp[k + 1] = t;
    }
}

int fcc_ldl_numeric(int n, const int *Ap, const int *Ai, const double *Ax,
                    const int *Lp, const int *Li, const int *Rp, const int *Rj,
                    const int *Rpos, double *Lx, double *Dinv, double *Y,
                    double pivot_tol)
{
    int i, k, p, p2, t;
    double yi, l_ki, akk, dk;
    for (k = 0; k < n; k++) {
        for (p = Ap[k]; p < Ap[k + 1]; p++) {
            i = Ai[p];
            if (i <= k)
                Y[i] += Ax[p];
        }
        akk = Y[k];
        dk = akk;
        Y[k] = 0.0;
        for (t = Rp[k]; t < Rp[k + 1]; t++) {
            i = Rj[t];
            yi = Y[i];
            Y[i] = 0.0;
            p2 = Rpos[t];
            for (p = Lp[i]; p < p2; p++)
                Y[Li[p]] -= Lx[p] * yi;
            l_ki = yi * Dinv[i];
            dk -= l_ki * yi;
            Lx[p2] = l_ki;
        }
        if (!(dk > pivot_tol * akk))           /* (Y is zero: row k is done) */
            return k + 1;
        Dinv[k] = 1.0 / dk;
    }
    return 0;
}

void fcc_ldl_solve(int n, const int *Lp, const int *Li, const double *Lx,
                   const double *Dinv, double *x)
{
    int j, p;
    double xj;
    for (j = 0; j < n; j++) {
        xj = x[j];
        for (p = Lp[j]; p < Lp[j + 1]; p++)
            x[Li[p]] -= Lx[p] * xj;
    }
    for (j = n - 1; j >= 0; j--) {
        xj = x[j] * Dinv[j];
        for (p = Lp[j]; p < Lp[j + 1]; p++)
            xj -= Lx[p] * x[Li[p]];
        x[j] = xj;
    }
}
