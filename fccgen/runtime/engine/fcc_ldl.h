/* A sparse LDL^T factorisation over a fixed pattern (fcc_ldl.c). Every array is the
 * caller's; nothing allocates. */
#ifndef FCC_LDL_H
#define FCC_LDL_H

/* Elimination tree (parent, -1 for a root) and column pointers Lp (n + 1) of L, from
 * the upper triangle of A's columns (Ap, Ai). Work: Lnz, flag (n each). */
void fcc_ldl_symbolic(int n, const int *Ap, const int *Ai, int *Lp, int *parent,
                      int *Lnz, int *flag);
/* The row patterns of L (after fcc_ldl_symbolic): Li, and for row k the columns
 * Rj[Rp[k]:Rp[k + 1]] in the order the up-looking solve visits them, with Rpos the
 * index of L_kj in Li/Lx. Work: Lnz, pattern, flag (n each). */
void fcc_ldl_rows(int n, const int *Ap, const int *Ai, const int *Lp, const int *parent,
                  int *Lnz, int *Li, int *Rp, int *Rj, int *Rpos, int *pattern,
                  int *flag);
/* L and the reciprocal pivots Dinv = 1 / D of A = L D L^T. Y (n) must be zero on
 * entry and is left zero. Returns 0, or k + 1 for the first pivot D_k not above
 * pivot_tol A_kk. */
int fcc_ldl_numeric(int n, const int *Ap, const int *Ai, const double *Ax,
                    const int *Lp, const int *Li, const int *Rp, const int *Rj,
                    const int *Rpos, double *Lx, double *Dinv, double *Y,
                    double pivot_tol);
/* x <- A^{-1} x with A = L D L^T (in the permuted numbering). */
void fcc_ldl_solve(int n, const int *Lp, const int *Li, const double *Lx,
                   const double *Dinv, double *x);

#endif
