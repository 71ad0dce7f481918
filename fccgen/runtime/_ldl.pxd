# Sparse LDL^T over a fixed pattern (see _ldl.pyx).

cdef void ldl_symbolic(int n, const int *Ap, const int *Ai, int *Lp, int *parent,
                       int *Lnz, int *flag) noexcept nogil
cdef void ldl_rows(int n, const int *Ap, const int *Ai, const int *Lp, const int *parent,
                   int *Lnz, int *Li, int *Rp, int *Rj, int *Rpos, int *pattern,
                   int *flag) noexcept nogil
cdef int ldl_numeric(int n, const int *Ap, const int *Ai, const double *Ax,
                     const int *Lp, const int *Li, const int *Rp, const int *Rj,
                     const int *Rpos, double *Lx, double *Dinv, double *Y,
                     double pivot_tol) noexcept nogil
cdef void ldl_solve(int n, const int *Lp, const int *Li, const double *Lx,
                    const double *Dinv, double *x) noexcept nogil
