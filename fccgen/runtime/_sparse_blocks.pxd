# Element blocks of the sparse path and the LDL^T of A = M + B^T alpha B (see
# _sparse_blocks.pyx).
from ._engine cimport Engine


cdef void *alloc_zeroed(size_t n, size_t size) except NULL


cdef class SparseBlocks(Engine):
    cdef bint ready
    cdef int nnz_a, nnz_l
    cdef int *mptr                # per element: start of its mass block (n_el + 1)
    cdef int *bptr                # per element: start of its Jacobian block
    cdef double *Mblk
    cdef double *Bblk
    cdef double *lq               # local: an element's coordinates
    cdef double *alpha            # m: penalty per row
    cdef double *rnorm            # m: ||B_k|| of the Jacobian blocks held
    cdef double mref              # the largest diagonal entry of the mass blocks held
    cdef bint held                # an LDL^T of A is held (the last factor succeeded)
    cdef int *perm                # new -> old
    cdef int n_lead               # the leading columns of P A P^T that the LDL^T and its
                                  # solves cover; the rest are pinned: unit diagonals
    cdef int *Ap
    cdef int *Ai
    cdef double *Ax
    cdef int *ent_ptr             # per element: start of its entries of A (n_el + 1)
    cdef int *ent_a               # each entry's local row and column on the view
    cdef int *ent_b
    cdef int *ent_pos             # and its place in Ax
    cdef double *lb               # local: an element's rows times their penalties
    cdef int *Lp
    cdef int *Li
    cdef int *Rp                  # row patterns of L (_ldl.ldl_rows)
    cdef int *Rj
    cdef int *Rpos
    cdef double *Lx
    cdef double *Dinv             # n: the reciprocal pivots 1 / D_k of the LDL^T
    cdef int *parent
    cdef int *Lnz
    cdef int *flag
    cdef int *pattern
    cdef double *Y
    cdef double *t                # n: the permuted right-hand side of a solve
    cdef long n_factor
    cdef int *zero_m              # offsets into Mblk / Bblk of the entries that were zero at
    cdef int *zero_b              # the positions the pattern was taken at (planar_pattern)
    cdef double *zero_m_tol       # the size each may reach (GUARD_TOL of its block's largest)
    cdef double *zero_b_tol
    cdef int n_zero_m, n_zero_b
    cdef bint tripped             # one of them is not zero any more
    # The solve's view of the elements (set_pinned): each element's free local
    # coordinates and kept rows, and its blocks compacted to them (Mc, Bc). Without
    # pinned coordinates it is the full view, Mc and Bc the blocks themselves.
    cdef bint compact
    cdef int *snq                 # per element: its free local coordinates
    cdef int *sptr                # per element: start in sidx and sloc (n_el + 1)
    cdef int *sidx                # the global index of each free local coordinate
    cdef int *sloc                # its place in the element's local list
    cdef int *sng                 # per element: its kept rows
    cdef int *sgptr               # per element: start in srow and srloc (n_el + 1)
    cdef int *srow                # the global index of each kept row
    cdef int *srloc               # its local row
    cdef int *mcptr               # per element: start of its compact mass block
    cdef int *bcptr               # per element: start of its compact Jacobian block
    cdef double *Mc
    cdef double *Bc
    cdef double *efix             # per element: the largest norm of its fixed rows
    cdef int n_pinned
    cdef int *pinned              # the pinned coordinates
    cdef int *pin_diag            # where each one's diagonal sits in Ax
    cdef int n_fixed              # entries of the fixed rows' blocks
    cdef int *fixed_off           # offsets into Bblk
    cdef double *fixed_val        # their values where they were read
    cdef double *fixed_tol        # the change each may take (GUARD_TOL of its row)
    cdef int n_fixed_rows
    cdef int *fixed_rows          # the fixed rows (global)
    cdef double *fixed_g_tol      # |g_k| each may reach: position_tol ||B_k||

    cdef void assemble_mb(self, const double *q, int flags) noexcept nogil
    cdef void assemble_blocks(self, const double *q, const double *v,
                              int flags) noexcept nogil
    cdef void check_fixed_g(self) noexcept nogil
    cdef void mult_m(self, const double *x, double *y, bint add) noexcept nogil
    cdef void mult_m_full(self, const double *x, double *y, bint add) noexcept nogil
    cdef void mult_b(self, const double *x, double *y) noexcept nogil
    cdef void mult_bt(self, const double *z, const double *s, double *y) noexcept nogil
    cdef void gather_dense(self) noexcept nogil
    cdef void penalties(self) noexcept nogil
    cdef double scaled_residual_sparse(self) noexcept nogil
    cdef void solve_a(self, double *x) noexcept nogil
    cdef void solve_a_add(self, const double *y, double *x, double *step,
                          double *size) noexcept nogil
