# cython: language_level=3
"""A sparse LDL^T factorisation over a fixed pattern, in C without the GIL.

After T. A. Davis, "Algorithm 849: a concise sparse Cholesky factorization package"
(LDL): the matrix is given by the upper triangle of its (already permuted) columns,
Ap/Ai/Ax in compressed sparse columns. The factorisation is up-looking: row k of L is
found by a sparse triangular solve L[:k, :k] y = A[:k, k], whose nonzero pattern is the
set of elimination-tree paths from the entries of A[:k, k] towards the root, and
D_k = A_kk - sum_j L_kj^2 D_j.

The pattern is the same at every factorisation, so all of the symbolic work is done
once (ldl_symbolic, ldl_rows): the elimination tree, the column pointers Lp and row
indices Li of L, and for every row k the columns j of its entries in the order of the
triangular solve (Rp/Rj) with the place of L_kj in Lx (Rpos). ldl_numeric then only
does arithmetic, in the same order as Davis' ldl_numeric, but keeping the reciprocal
pivots 1 / D_k: each L_kj is a product where Davis divides (one rounding apart), and
the solves multiply too. Every array is allocated by the caller: the per-step work is
allocation-free.
"""


cdef void ldl_symbolic(int n, const int *Ap, const int *Ai, int *Lp, int *parent,
                       int *Lnz, int *flag) noexcept nogil:
    """Elimination tree (parent, -1 for a root) and column pointers Lp (n + 1) of L."""
    cdef int i, k, p
    for k in range(n):
        parent[k] = -1
        flag[k] = k
        Lnz[k] = 0
        for p in range(Ap[k], Ap[k + 1]):
            i = Ai[p]
            if i < k:
                while flag[i] != k:
                    if parent[i] == -1:
                        parent[i] = k
                    Lnz[i] += 1
                    flag[i] = k
                    i = parent[i]
    Lp[0] = 0
    for k in range(n):
        Lp[k + 1] = Lp[k] + Lnz[k]


cdef void ldl_rows(int n, const int *Ap, const int *Ai, const int *Lp, const int *parent,
                   int *Lnz, int *Li, int *Rp, int *Rj, int *Rpos, int *pattern,
                   int *flag) noexcept nogil:
    """The row patterns of L (after ldl_symbolic): Li, and for row k the columns
    Rj[Rp[k]:Rp[k + 1]] in the order the up-looking solve visits them (the reversed
    elimination-tree paths, as in Davis' ldl_numeric) with Rpos the index of L_kj in
    Li/Lx. Work: Lnz, pattern, flag (n each)."""
    cdef int i, k, p, length, top, t = 0
    for k in range(n):
        Lnz[k] = 0
    Rp[0] = 0
    for k in range(n):
        top = n
        flag[k] = k
        for p in range(Ap[k], Ap[k + 1]):
            i = Ai[p]
            if i > k:
                continue
            length = 0
            while flag[i] != k:
                pattern[length] = i
                length += 1
                flag[i] = k
                i = parent[i]
            while length > 0:
                top -= 1
                length -= 1
                pattern[top] = pattern[length]
        while top < n:
            i = pattern[top]
            top += 1
            Rj[t] = i
            Rpos[t] = Lp[i] + Lnz[i]
            Li[Rpos[t]] = k
            Lnz[i] += 1
            t += 1
        Rp[k + 1] = t


cdef int ldl_numeric(int n, const int *Ap, const int *Ai, const double *Ax,
                     const int *Lp, const int *Li, const int *Rp, const int *Rj,
                     const int *Rpos, double *Lx, double *Dinv, double *Y,
                     double pivot_tol) noexcept nogil:
    """L (unit lower, strict part in Lp/Li/Lx) and the reciprocal pivots Dinv = 1 / D
    of A = L D L^T over the pattern of ldl_rows: one division per pivot, where
    L_ki = y_i / D_i would take one per entry of L and each solve one per row. Y (n)
    must be zero on entry and is left zero. Returns 0, or k + 1 for the first pivot
    D_k not above pivot_tol A_kk (not positive definite)."""
    cdef int i, k, p, p2, t
    cdef double yi, l_ki, akk, dk
    for k in range(n):
        for p in range(Ap[k], Ap[k + 1]):
            i = Ai[p]
            if i <= k:
                Y[i] += Ax[p]
        akk = Y[k]
        dk = akk
        Y[k] = 0.0
        for t in range(Rp[k], Rp[k + 1]):
            i = Rj[t]
            yi = Y[i]
            Y[i] = 0.0
            p2 = Rpos[t]
            for p in range(Lp[i], p2):
                Y[Li[p]] -= Lx[p] * yi
            l_ki = yi * Dinv[i]
            dk -= l_ki * yi
            Lx[p2] = l_ki
        if not dk > pivot_tol * akk:            # (Y is zero: row k is done)
            return k + 1
        Dinv[k] = 1.0 / dk
    return 0


cdef void ldl_solve(int n, const int *Lp, const int *Li, const double *Lx,
                    const double *Dinv, double *x) noexcept nogil:
    """x <- A^{-1} x with A = L D L^T (in the permuted numbering): L y = x, then
    L^T x = D^{-1} y, the scaling done in the backward sweep."""
    cdef int j, p
    cdef double xj
    for j in range(n):
        xj = x[j]
        for p in range(Lp[j], Lp[j + 1]):
            x[Li[p]] -= Lx[p] * xj
    for j in range(n - 1, -1, -1):
        xj = x[j] * Dinv[j]
        for p in range(Lp[j], Lp[j + 1]):
            xj -= Lx[p] * x[Li[p]]
        x[j] = xj
