# cython: language_level=3
"""A sparse LDL^T factorisation over a fixed pattern, in C without the GIL.

After T. A. Davis, "Algorithm 849: a concise sparse Cholesky factorization package"
(LDL): the matrix is given by the upper triangle of its (already permuted) columns,
Ap/Ai/Ax in compressed sparse columns. ldl_symbolic computes the elimination tree and
the column counts of L once; ldl_numeric is the up-looking factorisation: row k of L
is found by a sparse triangular solve L[:k, :k] y = A[:k, k] whose nonzero pattern is
the set of elimination-tree paths from the entries of A[:k, k] towards the root;
D_k = A_kk - sum_j L_kj^2 D_j. Every array is allocated by the caller: the per-step
work is allocation-free.
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


cdef int ldl_numeric(int n, const int *Ap, const int *Ai, const double *Ax,
                     const int *Lp, const int *parent, int *Lnz, int *Li, double *Lx,
                     double *D, double *Y, int *pattern, int *flag,
                     double pivot_tol) noexcept nogil:
    """L (unit lower, strict part in Lp/Li/Lx) and D of A = L D L^T. Returns 0, or
    k + 1 for the first pivot D_k not above pivot_tol A_kk (not positive definite)."""
    cdef int i, k, p, p2, length, top
    cdef double yi, l_ki, akk
    for k in range(n):
        Y[k] = 0.0
        top = n
        flag[k] = k
        Lnz[k] = 0
        akk = 0.0
        for p in range(Ap[k], Ap[k + 1]):
            i = Ai[p]
            if i > k:
                continue
            Y[i] += Ax[p]
            if i == k:
                akk += Ax[p]
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
        D[k] = Y[k]
        Y[k] = 0.0
        while top < n:
            i = pattern[top]
            top += 1
            yi = Y[i]
            Y[i] = 0.0
            p2 = Lp[i] + Lnz[i]
            for p in range(Lp[i], p2):
                Y[Li[p]] -= Lx[p] * yi
            l_ki = yi / D[i]
            D[k] -= l_ki * yi
            Li[p2] = k
            Lx[p2] = l_ki
            Lnz[i] += 1
        if not D[k] > pivot_tol * akk:
            return k + 1
    return 0


cdef void ldl_solve(int n, const int *Lp, const int *Li, const double *Lx,
                    const double *D, double *x) noexcept nogil:
    """x <- A^{-1} x with A = L D L^T (in the permuted numbering)."""
    cdef int j, p
    cdef double xj
    for j in range(n):
        xj = x[j]
        for p in range(Lp[j], Lp[j + 1]):
            x[Li[p]] -= Lx[p] * xj
    for j in range(n):
        x[j] /= D[j]
    for j in range(n - 1, -1, -1):
        xj = x[j]
        for p in range(Lp[j], Lp[j + 1]):
            xj -= Lx[p] * x[Li[p]]
        x[j] = xj
