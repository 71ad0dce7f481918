# cython: language_level=3
"""The sparse path: accelerations and projections in time linear in the model's size.

SparseEngine is an Engine (same building blocks, same integrators) whose constrained
solve is the augmented-Lagrangian form of Garcia de Jalon and Bayo, used as iterative
refinement of the full saddle-point system

    M x + B^T lambda = Q,    B x = b.

With the SPD matrix A = M + B^T diag(alpha) B (M is singular for a body's 9 x 9 block
alone, but A is positive definite whenever M is on the null space of B: the mechanism is
well posed, whatever the rank of B: redundant rows need no rank decision), each
iteration takes the residuals r1 = Q - M x - B^T lambda, r2 = b - B x and corrects

    A dx = r1 + B^T alpha r2,   dlambda = alpha (B dx - r2),

which zeroes r1 and multiplies the constraint part of the error by about
1 / (1 + alpha sigma^2 / m) (sigma: a singular value of B, m a mass): with
alpha_k = RHO m_ref / ||B_k||^2 about three iterations reach rounding. It stops when
the estimated remaining change, |dx| rate / (1 - rate), is below AL_STOP |x|. The
multiplier update alpha (B dx - r2) equals -alpha r2 at the new x, so it is made in the
next iteration's residual pass, which forms r2, the update and r1 + B^T alpha r2 in one
sweep over the element blocks. Near a
singular position (sigma small) these steps slow down; the corrections are then
conjugate-gradient solves of the multipliers' Schur system B A^{-1} B^T, preconditioned
by diag(alpha), which take the few small singular values in a few extra steps.

M and B are kept as element blocks (the kernels' outputs, never a dense n x n or
m x n array); A is assembled from them through the scatter maps of
fccgen.runtime.sparsity, in the fill-reducing order chosen when the solver is loaded,
and factored by the LDL^T of _ldl.pyx over its fixed pattern. Per evaluation the work is
proportional to the number of nonzeros of the blocks and of L.

The velocity projection (Q = M v, b = 0) and each Newton step of the position
projection (Q = 0, b = -g) reuse the same solve. Solves whose constraint residual did not
converge (a singular position: b outside the range of B) are counted as the dense
path's dropped rows are.
"""
from libc.math cimport fabs, isfinite, sqrt
from libc.stdlib cimport calloc, free
from libc.string cimport memcpy, memset

import numpy as np

from ._assemble cimport ASM_B, ASM_C, ASM_F, ASM_G, ASM_H, ASM_M, Assembler
from ._engine cimport (ERR_LAPACK, ERR_NONFINITE_INPUT, ERR_NONFINITE_RESULT,
                       ERR_SINGULAR, ERR_DIVERGED, Engine, finite)
from ._ldl cimport ldl_numeric, ldl_solve, ldl_symbolic
from ._model_table cimport fcc_element_class

# alpha_k = RHO m_ref / s_k^2: the constraint error shrinks ~1/RHO per iteration, while
# A's condition number grows ~RHO (1e7: about 3 iterations, 1e-9 relative rounding in
# one solve, which the refinement removes; 1e6 took a third more solves on the A02
# chain). Not more: 1e8 gives unconverged solves on Bricard's loop, whose redundant
# rows are dependent only to rounding. Along such a row (singular value sigma tiny) a
# step moves x by about alpha sigma^2 / m of the way towards b's rounding noise over
# sigma; the few steps of a solve leave that negligible at 1e7 (as the dense path's
# dropped row), no longer at 1e8. Scaling alpha per row group cannot help: the row
# is one of a group of full-size rows. (Starting a solve from the previous stage's
# solution accumulates the same drift over the run: measured, it breaks Bricard.)
cdef double RHO = 1e7
# Augmented-Lagrangian steps stop when the estimated remaining change,
# |dx| rate / (1 - rate), is at most AL_STOP |x|; a step with rate above SLOW (or the
# AL_MAX-th) hands over to conjugate-gradient corrections, which stop when a step
# changes x by at most CG_STOP |x| (or after CG_MAX steps), the refinement when a
# correction is at most REFINE_STOP |x| (or after REFINE_MAX corrections: a solve
# that did not converge, counted).
cdef double AL_STOP = 1e-15
cdef int AL_MAX = 8
cdef double SLOW = 0.05
cdef double CG_STOP = 1e-13
cdef int CG_MAX = 40
cdef double REFINE_STOP = 1e-14
cdef int REFINE_MAX = 3
# Row scale floor within an element, as the dense path's (fccgen.rank.ROW_FLOOR).
cdef double ROW_FLOOR = 1e-4
# An LDL^T pivot D_k at or below this fraction of A_kk counts as zero.
cdef double PIVOT_TOL = 64 * 2.220446049250313e-16


cdef void *_alloc(size_t n, size_t size) except NULL:
    cdef void *p = calloc(n if n > 0 else 1, size)
    if p == NULL:
        raise MemoryError("cannot allocate the sparse solve's work arrays")
    return p


def element_structure(Assembler asm):
    """(q_ptr, q_idx, couples) of the assembler's elements: couples[e] is True when
    element e has a mass matrix or constraint rows (it adds a block to A)."""
    cdef int e
    q_ptr = np.array([asm.qptr[e] for e in range(asm.n_el + 1)], dtype=np.intc)
    q_idx = np.array([asm.qidx[e] for e in range(asm.qptr[asm.n_el])], dtype=np.intc)
    couples = np.array([asm.cls[e].mass_matrix != NULL or asm.cls[e].n_g > 0
                        for e in range(asm.n_el)], dtype=bool)
    return q_ptr, q_idx, couples


cdef class SparseEngine(Engine):
    """An Engine whose solves use the sparse augmented-Lagrangian refinement (module
    docstring). Call :meth:`set_structure` (fccgen.runtime.sparsity) before use."""
    cdef bint ready
    cdef int nnz_a, nnz_l
    cdef int *mptr                # per element: start of its mass block (n_el + 1)
    cdef int *bptr                # per element: start of its Jacobian block
    cdef double *Mblk
    cdef double *Bblk
    cdef double *lq
    cdef double *ly               # local: an element's share of a product
    cdef double *alpha            # m: penalty per row
    cdef double *rnorm            # m: ||B_k||
    cdef int *perm                # new -> old
    cdef int *Ap
    cdef int *Ai
    cdef double *Ax
    cdef int *emap_ptr
    cdef int *emap
    cdef int *Lp
    cdef int *Li
    cdef double *Lx
    cdef double *D
    cdef int *parent
    cdef int *Lnz
    cdef int *flag
    cdef int *pattern
    cdef double *Y
    cdef double *w_n              # n-vectors: x-work, residual, correction, permuted
    cdef double *r1
    cdef double *dx
    cdef double *t
    cdef double *base
    cdef double *lam              # m-vectors
    cdef double *r2
    cdef double *bdx
    cdef double *res
    cdef double *mu
    cdef double *p
    cdef double *sp
    cdef double *u                # n
    cdef long n_factor, n_solves, n_iterations, n_unconverged
    cdef int most_iterations

    def __cinit__(self, Assembler asm, *args, **kwargs):
        cdef int e, nq, total_m = 0, total_b = 0, local = 1
        cdef const fcc_element_class *k
        self.mptr = <int *>_alloc(asm.n_el + 1, sizeof(int))
        self.bptr = <int *>_alloc(asm.n_el + 1, sizeof(int))
        for e in range(asm.n_el):
            k = asm.cls[e]
            nq = k.n_q
            local = max(local, nq)
            total_m += nq * nq if k.mass_matrix != NULL else 0
            total_b += k.n_g * nq
            self.mptr[e + 1] = total_m
            self.bptr[e + 1] = total_b
        self.Mblk = <double *>_alloc(total_m, sizeof(double))
        self.Bblk = <double *>_alloc(total_b, sizeof(double))
        self.lq = <double *>_alloc(local, sizeof(double))
        self.ly = <double *>_alloc(local, sizeof(double))
        cdef int n = asm.n_q, m = asm.n_g
        self.alpha = <double *>_alloc(m, sizeof(double))
        self.rnorm = <double *>_alloc(m, sizeof(double))
        self.lam = <double *>_alloc(m, sizeof(double))
        self.r2 = <double *>_alloc(m, sizeof(double))
        self.bdx = <double *>_alloc(m, sizeof(double))
        self.res = <double *>_alloc(m, sizeof(double))
        self.mu = <double *>_alloc(m, sizeof(double))
        self.p = <double *>_alloc(m, sizeof(double))
        self.sp = <double *>_alloc(m, sizeof(double))
        self.u = <double *>_alloc(n, sizeof(double))
        self.w_n = <double *>_alloc(n, sizeof(double))
        self.r1 = <double *>_alloc(n, sizeof(double))
        self.dx = <double *>_alloc(n, sizeof(double))
        self.t = <double *>_alloc(n, sizeof(double))
        self.base = <double *>_alloc(n, sizeof(double))

    def __dealloc__(self):
        free(self.mptr); free(self.bptr); free(self.Mblk); free(self.Bblk); free(self.lq)
        free(self.ly)
        free(self.alpha); free(self.rnorm); free(self.lam); free(self.r2); free(self.bdx)
        free(self.res); free(self.mu); free(self.p); free(self.sp); free(self.u)
        free(self.w_n); free(self.r1); free(self.dx); free(self.t); free(self.base)
        free(self.perm); free(self.Ap); free(self.Ai); free(self.Ax); free(self.emap_ptr)
        free(self.emap); free(self.Lp); free(self.Li); free(self.Lx); free(self.D)
        free(self.parent); free(self.Lnz); free(self.flag); free(self.pattern)
        free(self.Y)

    def set_structure(self, perm, Ap, Ai, emap_ptr, emap):
        """Take the pattern of A and the scatter maps (fccgen.runtime.sparsity.Structure)
        and do the symbolic factorisation."""
        if self.ready:
            raise RuntimeError("the structure is already set")
        cdef int[::1] pv = np.ascontiguousarray(perm, dtype=np.intc)
        cdef int[::1] apv = np.ascontiguousarray(Ap, dtype=np.intc)
        cdef int[::1] aiv = np.ascontiguousarray(Ai, dtype=np.intc)
        cdef int[::1] epv = np.ascontiguousarray(emap_ptr, dtype=np.intc)
        cdef int[::1] ev = np.ascontiguousarray(emap, dtype=np.intc)
        cdef int n = self.n, i
        if pv.shape[0] != n or apv.shape[0] != n + 1 or epv.shape[0] != self.asm.n_el + 1:
            raise ValueError("the structure does not match the engine's sizes")
        if sorted(np.asarray(pv).tolist()) != list(range(n)):
            raise ValueError("perm is not a permutation")
        self.nnz_a = apv[n]
        self.perm = <int *>_alloc(n, sizeof(int))
        self.Ap = <int *>_alloc(n + 1, sizeof(int))
        self.Ai = <int *>_alloc(self.nnz_a, sizeof(int))
        self.Ax = <double *>_alloc(self.nnz_a, sizeof(double))
        self.emap_ptr = <int *>_alloc(self.asm.n_el + 1, sizeof(int))
        self.emap = <int *>_alloc(ev.shape[0], sizeof(int))
        for i in range(n):
            self.perm[i] = pv[i]
        for i in range(n + 1):
            self.Ap[i] = apv[i]
        for i in range(self.nnz_a):
            self.Ai[i] = aiv[i]
        for i in range(self.asm.n_el + 1):
            self.emap_ptr[i] = epv[i]
        for i in range(ev.shape[0]):
            if not -1 <= ev[i] < self.nnz_a:
                raise ValueError("scatter map index out of range")
            self.emap[i] = ev[i]
        self.Lp = <int *>_alloc(n + 1, sizeof(int))
        self.parent = <int *>_alloc(n, sizeof(int))
        self.Lnz = <int *>_alloc(n, sizeof(int))
        self.flag = <int *>_alloc(n, sizeof(int))
        self.pattern = <int *>_alloc(n, sizeof(int))
        self.D = <double *>_alloc(n, sizeof(double))
        self.Y = <double *>_alloc(n, sizeof(double))
        ldl_symbolic(n, self.Ap, self.Ai, self.Lp, self.parent, self.Lnz, self.flag)
        self.nnz_l = self.Lp[n]
        self.Li = <int *>_alloc(self.nnz_l, sizeof(int))
        self.Lx = <double *>_alloc(self.nnz_l, sizeof(double))
        self.ready = True

    @property
    def nonzeros(self):
        """(nonzeros of upper(A), nonzeros of the strict lower part of L)."""
        return self.nnz_a, self.nnz_l

    def solve_statistics(self):
        """Factorisations and solves since the last rank decision, refinement iterations
        in all and at most in one solve, and solves that did not converge."""
        return dict(factorisations=self.n_factor, solves=self.n_solves,
                    iterations=self.n_iterations, max_iterations=self.most_iterations,
                    unconverged=self.n_unconverged)

    def decide_rank(self, q, rank):
        """Keep the decision for the reports (the solve itself needs no rank) and start
        the statistics anew."""
        Engine.decide_rank(self, q, rank)
        self.n_factor = self.n_solves = self.n_iterations = self.n_unconverged = 0
        self.most_iterations = 0

    def rank_statistics(self):
        """As Engine.rank_statistics; drops are solves whose constraint residual did
        not converge (a singular position)."""
        stats = Engine.rank_statistics(self)
        stats.update(factorisations=self.n_factor, drops=self.n_unconverged,
                     svd_checks=0, smallest_kept=1.0, largest_dropped=0.0)
        return stats

    # -- element blocks ------------------------------------------------------------
    cdef void assemble_mb(self, const double *q, int flags) noexcept nogil:
        """The mass (ASM_M) and Jacobian (ASM_B) blocks of every element at q."""
        cdef int e, i, nq
        cdef const fcc_element_class *k
        cdef const int *idx
        cdef const double *p
        for e in range(self.asm.n_el):
            k = self.asm.cls[e]
            nq = k.n_q
            idx = self.asm.qidx + self.asm.qptr[e]
            p = self.asm.params + self.asm.pptr[e]
            if not ((flags & ASM_M and k.mass_matrix != NULL)
                    or (flags & ASM_B and k.constraint_jacobian != NULL)):
                continue
            for i in range(nq):
                self.lq[i] = q[idx[i]]
            if flags & ASM_M and k.mass_matrix != NULL:
                k.mass_matrix(self.lq, p, self.Mblk + self.mptr[e])
            if flags & ASM_B and k.constraint_jacobian != NULL:
                k.constraint_jacobian(self.lq, p, self.Bblk + self.bptr[e])

    cdef void mult_m(self, const double *x, double *y, bint add) noexcept nogil:
        """y (+)= M x."""
        cdef int e, i, j, nq
        cdef const int *idx
        cdef const double *blk
        cdef double acc
        if not add:
            memset(y, 0, <size_t>self.n * sizeof(double))
        for e in range(self.asm.n_el):
            if self.mptr[e + 1] == self.mptr[e]:
                continue
            nq = self.asm.cls[e].n_q
            idx = self.asm.qidx + self.asm.qptr[e]
            blk = self.Mblk + self.mptr[e]
            for i in range(nq):
                acc = 0.0
                for j in range(nq):
                    acc += blk[i * nq + j] * x[idx[j]]
                y[idx[i]] += acc

    cdef void mult_b(self, const double *x, double *y) noexcept nogil:
        """y = B x (m rows)."""
        cdef int e, r, j, nq, row
        cdef const int *idx
        cdef const double *blk
        cdef double acc
        for e in range(self.asm.n_el):
            nq = self.asm.cls[e].n_q
            idx = self.asm.qidx + self.asm.qptr[e]
            blk = self.Bblk + self.bptr[e]
            row = self.asm.gptr[e]
            for r in range(self.asm.cls[e].n_g):
                acc = 0.0
                for j in range(nq):
                    acc += blk[r * nq + j] * x[idx[j]]
                y[row + r] = acc

    cdef void mult_bt(self, const double *z, const double *s, double *y) noexcept nogil:
        """y += B^T diag(s) z (s NULL: the identity)."""
        cdef int e, r, j, nq, row
        cdef const int *idx
        cdef const double *blk
        cdef double zr
        for e in range(self.asm.n_el):
            nq = self.asm.cls[e].n_q
            idx = self.asm.qidx + self.asm.qptr[e]
            blk = self.Bblk + self.bptr[e]
            row = self.asm.gptr[e]
            for r in range(self.asm.cls[e].n_g):
                zr = z[row + r] if s == NULL else z[row + r] * s[row + r]
                if zr == 0.0:
                    continue
                for j in range(nq):
                    y[idx[j]] += blk[r * nq + j] * zr

    cdef void residual_pass(self, const double *x, const double *b, bint pending,
                            bint penalised, double *y, double *r2) noexcept nogil:
        """One pass over the elements for the true residuals at x:
        r2 = b - B x (b NULL: zero; stored when r2 is not NULL), then, when pending,
        the deferred multiplier update lambda -= alpha r2 (the augmented-Lagrangian
        update lambda + alpha (B dx - r2_old) written with the new residual), and
        y = base - M x - B^T (lambda - alpha r2) when penalised (the right-hand side
        r1 + B^T alpha r2 of the next correction), y = r1 = base - M x - B^T lambda
        otherwise. Each element's coordinates are gathered and scattered once."""
        cdef int e, a, r, nq, ng, row
        cdef const int *idx
        cdef const double *mb
        cdef const double *bb
        cdef double *xl = self.lq
        cdef double *yl = self.ly
        cdef double acc, z
        memcpy(y, self.base, <size_t>self.n * sizeof(double))
        for e in range(self.asm.n_el):
            nq = self.asm.cls[e].n_q
            ng = self.asm.cls[e].n_g
            mb = self.Mblk + self.mptr[e] if self.mptr[e + 1] > self.mptr[e] else NULL
            if mb == NULL and ng == 0:
                continue
            idx = self.asm.qidx + self.asm.qptr[e]
            for a in range(nq):
                xl[a] = x[idx[a]]
                yl[a] = 0.0
            if mb != NULL:
                for a in range(nq):
                    acc = 0.0
                    for r in range(nq):
                        acc += mb[a * nq + r] * xl[r]
                    yl[a] = acc
            bb = self.Bblk + self.bptr[e]
            row = self.asm.gptr[e]
            for r in range(ng):
                acc = b[row + r] if b != NULL else 0.0
                for a in range(nq):
                    acc -= bb[r * nq + a] * xl[a]
                if pending:
                    self.lam[row + r] -= self.alpha[row + r] * acc
                if r2 != NULL:
                    r2[row + r] = acc
                z = self.lam[row + r]
                if penalised:
                    z -= self.alpha[row + r] * acc
                if z != 0.0:
                    for a in range(nq):
                        yl[a] += bb[r * nq + a] * z
            for a in range(nq):
                y[idx[a]] -= yl[a]

    cdef double row_norms(self) noexcept nogil:
        """rnorm_k = ||B_k||; alpha_k = RHO m_ref / s_k^2 with s_k = max(||B_k||,
        ROW_FLOOR * the largest row norm of its element), 0 for a zero row; m_ref = the
        largest diagonal entry of M. Returns m_ref."""
        cdef int e, r, j, nq, row, ng
        cdef double acc, largest, s, mref = 0.0
        cdef const double *blk
        for e in range(self.asm.n_el):
            if self.mptr[e + 1] == self.mptr[e]:
                continue
            nq = self.asm.cls[e].n_q
            blk = self.Mblk + self.mptr[e]
            for j in range(nq):
                if blk[j * nq + j] > mref:
                    mref = blk[j * nq + j]
        if not mref > 0.0:
            mref = 1.0
        for e in range(self.asm.n_el):
            nq = self.asm.cls[e].n_q
            ng = self.asm.cls[e].n_g
            blk = self.Bblk + self.bptr[e]
            row = self.asm.gptr[e]
            largest = 0.0
            for r in range(ng):
                acc = 0.0
                for j in range(nq):
                    acc += blk[r * nq + j] * blk[r * nq + j]
                self.rnorm[row + r] = sqrt(acc)
                if self.rnorm[row + r] > largest:
                    largest = self.rnorm[row + r]
            for r in range(ng):
                s = self.rnorm[row + r]
                if s < ROW_FLOOR * largest:
                    s = ROW_FLOOR * largest
                self.alpha[row + r] = RHO * mref / (s * s) if s > 0.0 else 0.0
        return mref

    cdef double scaled_residual_sparse(self) noexcept nogil:
        """max_k |g_k| / ||B_k|| (|g_k| for a zero row; NaN if a g_k is not), with the
        assembled g and the row norms of the Jacobian blocks."""
        cdef int k
        cdef double worst = 0.0, val
        self.row_norms()
        for k in range(self.m):
            val = fabs(self.asm.g[k])
            if self.rnorm[k] > 0.0:
                val /= self.rnorm[k]
            if not val <= worst:
                worst = val
                if val != val:
                    return val
        return worst

    # -- factorisation and solve ----------------------------------------------------
    cdef int factor(self, const double *q) noexcept nogil:
        """A = M + B^T diag(alpha) B from the blocks, and its LDL^T."""
        cdef int e, a, b, r, nq, ng, pos, info, bad
        cdef const int *em
        cdef const double *mb
        cdef const double *bb
        cdef const double *al
        cdef double val
        self.factor_valid = False
        if not self.ready:
            return self.fail(ERR_LAPACK, -1, 0)
        self.row_norms()
        memset(self.Ax, 0, <size_t>self.nnz_a * sizeof(double))
        for e in range(self.asm.n_el):
            if self.emap_ptr[e + 1] == self.emap_ptr[e]:
                continue
            nq = self.asm.cls[e].n_q
            ng = self.asm.cls[e].n_g
            em = self.emap + self.emap_ptr[e]
            mb = self.Mblk + self.mptr[e] if self.mptr[e + 1] > self.mptr[e] else NULL
            bb = self.Bblk + self.bptr[e]
            al = self.alpha + self.asm.gptr[e]
            for a in range(nq):
                for b in range(nq):
                    pos = em[a * nq + b]
                    if pos < 0:
                        continue
                    val = mb[a * nq + b] if mb != NULL else 0.0
                    for r in range(ng):
                        val += bb[r * nq + a] * al[r] * bb[r * nq + b]
                    self.Ax[pos] += val
        self.n_factor += 1
        info = ldl_numeric(self.n, self.Ap, self.Ai, self.Ax, self.Lp, self.parent,
                           self.Lnz, self.Li, self.Lx, self.D, self.Y, self.pattern,
                           self.flag, PIVOT_TOL)
        if info == 0:
            return 0
        bad = self.nonfinite_input(q, NULL, ASM_M | ASM_B)
        if bad:
            return self.fail(ERR_NONFINITE_INPUT, 0, bad)
        return self.fail(ERR_SINGULAR, info, 0)

    cdef void solve_a(self, double *x) noexcept nogil:
        """x <- A^{-1} x through the permutation."""
        cdef int i, n = self.n
        for i in range(n):
            self.t[i] = x[self.perm[i]]
        ldl_solve(n, self.Lp, self.Li, self.Lx, self.D, self.t)
        for i in range(n):
            x[self.perm[i]] = self.t[i]

    cdef int correction(self) noexcept nogil:
        """(dx, dlam) of M dx + B^T dlam = r1, B dx = r2: conjugate gradients on the
        multipliers' Schur system S mu = B x0 - r2, S = B A^{-1} B^T, preconditioned by
        diag(alpha), from x0 = A^{-1} (r1 + B^T alpha r2); dx = x0 - A^{-1} B^T mu and
        dlam = mu + alpha (B dx - r2) satisfy the first equation exactly whatever the
        iteration count. Returns the number of solves with A."""
        cdef int i, k = 0, n = self.n, m = self.m
        cdef double rz, rz_new, psp, step, du, ndx
        memcpy(self.dx, self.r1, <size_t>n * sizeof(double))
        self.mult_bt(self.r2, self.alpha, self.dx)
        self.solve_a(self.dx)
        self.mult_b(self.dx, self.res)
        rz = 0.0
        for i in range(m):
            self.res[i] -= self.r2[i]
            self.mu[i] = 0.0
            self.p[i] = self.alpha[i] * self.res[i]
            rz += self.res[i] * self.p[i]
        for k in range(1, CG_MAX + 1):
            if not rz > 0.0:
                break
            memset(self.u, 0, <size_t>n * sizeof(double))
            self.mult_bt(self.p, NULL, self.u)
            self.solve_a(self.u)
            self.mult_b(self.u, self.sp)
            psp = 0.0
            for i in range(m):
                psp += self.p[i] * self.sp[i]
            if not psp > 0.0:
                break
            step = rz / psp
            du = 0.0
            ndx = 0.0
            for i in range(n):
                self.dx[i] -= step * self.u[i]
                if fabs(step * self.u[i]) > du:
                    du = fabs(step * self.u[i])
                if fabs(self.dx[i]) > ndx:
                    ndx = fabs(self.dx[i])
            rz_new = 0.0
            for i in range(m):
                self.mu[i] += step * self.p[i]
                self.res[i] -= step * self.sp[i]
                rz_new += self.res[i] * self.alpha[i] * self.res[i]
            if not du > CG_STOP * ndx:
                break
            for i in range(m):
                self.p[i] = self.alpha[i] * self.res[i] + (rz_new / rz) * self.p[i]
            rz = rz_new
        for i in range(m):                  # res = B dx - r2
            self.bdx[i] = self.mu[i] + self.alpha[i] * self.res[i]
        return k + 1

    cdef void kkt_solve(self, const double *Q, const double *w, const double *b,
                        double *x) noexcept nogil:
        """x of M x + B^T lambda = Q + M w, B x = b (Q, w, b may be NULL: zero):
        iterative refinement with the true residuals r1 = Q + M w - M x - B^T lambda,
        r2 = b - B x. Each correction is one augmented-Lagrangian step (module
        docstring), its right-hand side and the previous step's multiplier update
        formed in one pass (:meth:`residual_pass`), while those converge fast; once a
        step shrinks the change by less than SLOW (a nearly singular B: near a
        singular position), the corrections are conjugate-gradient solves
        (:meth:`correction`)."""
        cdef int i, it, solves = 0, n = self.n, m = self.m, cg = 0
        cdef double nd, nx, prev = 0.0, rate
        cdef bint done = False, pending = False
        memset(self.base, 0, <size_t>n * sizeof(double))
        if Q != NULL:
            memcpy(self.base, Q, <size_t>n * sizeof(double))
        if w != NULL:
            self.mult_m(w, self.base, True)
        memset(x, 0, <size_t>n * sizeof(double))
        memset(self.lam, 0, <size_t>m * sizeof(double))
        self.n_solves += 1
        for it in range(AL_MAX + REFINE_MAX):
            if cg:
                self.residual_pass(x, b, pending, False, self.r1, self.r2)
                pending = False
                solves += self.correction()
                for i in range(m):
                    self.lam[i] += self.bdx[i]
                cg += 1
            else:
                self.residual_pass(x, b, pending, True, self.dx, NULL)
                self.solve_a(self.dx)
                pending = True
                solves += 1
            nd = 0.0
            nx = 0.0
            for i in range(n):
                x[i] += self.dx[i]
                if fabs(self.dx[i]) > nd:
                    nd = fabs(self.dx[i])
                if fabs(x[i]) > nx:
                    nx = fabs(x[i])
            if not nd > 0.0:                    # zero, or NaN (the caller checks x)
                done = True
                break
            if cg:
                if nd <= REFINE_STOP * nx:
                    done = True
                    break
                if cg >= REFINE_MAX:
                    break
            elif it > 0:
                rate = nd / prev
                if rate < 0.5 and nd * rate / (1.0 - rate) <= AL_STOP * nx:
                    done = True
                    break
                if rate > SLOW or it + 1 >= AL_MAX:
                    cg = 1
            prev = nd
        if not done:
            self.n_unconverged += 1
        self.n_iterations += solves
        if solves > self.most_iterations:
            self.most_iterations = solves

    # -- the Engine's building blocks ---------------------------------------------
    cdef int nonfinite_input(self, const double *q, const double *v, int flags) noexcept nogil:
        cdef int n = self.n, m = self.m
        if q != NULL and not finite(q, n): return 1
        if v != NULL and not finite(v, n): return 2
        if flags & ASM_M and not finite(self.Mblk, self.mptr[self.asm.n_el]): return 3
        if flags & ASM_H and not finite(self.asm.h, n): return 4
        if flags & ASM_F and not finite(self.asm.f, n): return 5
        if flags & ASM_B and not finite(self.Bblk, self.bptr[self.asm.n_el]): return 6
        if flags & ASM_C and not finite(self.asm.c, m): return 7
        if flags & ASM_G and not finite(self.asm.g, m): return 8
        return 0

    cdef int finish(self, const double *q, const double *v, const double *a,
                    int flags) noexcept nogil:
        """0, or the error of a non-finite result (blaming an input first)."""
        cdef int i
        if finite(a, self.n):
            return 0
        i = self.nonfinite_input(q, v, flags)
        return self.fail(ERR_NONFINITE_INPUT if i else ERR_NONFINITE_RESULT, 0, i)

    cdef int accelerations_at(self, const double *q, const double *v, double *a,
                              bint reuse) noexcept nogil:
        cdef int i, flags = ASM_H | ASM_F | ASM_C
        self.asm.assemble(q, v, flags)
        if not reuse:
            flags |= ASM_M | ASM_B
            self.assemble_mb(q, ASM_M | ASM_B)
            if self.factor(q) < 0:
                return -1
        for i in range(self.n):
            self.rhs[i] = self.asm.f[i] - self.asm.h[i]
        for i in range(self.m):
            self.nb[i] = -self.asm.c[i]
        self.kkt_solve(self.rhs, NULL, self.nb, a)
        return self.finish(q, v, a, flags)

    cdef int baumgarte_at(self, const double *q, const double *v, double *a,
                          double alpha, double beta) noexcept nogil:
        cdef int i, flags = ASM_M | ASM_B | ASM_H | ASM_F | ASM_C | ASM_G
        self.asm.assemble(q, v, ASM_H | ASM_F | ASM_C | ASM_G)
        self.assemble_mb(q, ASM_M | ASM_B)
        if self.factor(q) < 0:
            return -1
        for i in range(self.n):
            self.rhs[i] = self.asm.f[i] - self.asm.h[i]
        self.baumgarte_targets(v, alpha, beta, self.nb)
        self.kkt_solve(self.rhs, NULL, self.nb, a)
        return self.finish(q, v, a, flags)

    cdef void baumgarte_targets(self, const double *v, double alpha, double beta,
                                double *b) noexcept nogil:
        """b = -c - 2 alpha g' - beta^2 g, the right-hand side of B a = b in
        Baumgarte's stabilisation, with g' = B v (assembled c and g, blocks of B)."""
        cdef int i
        self.mult_b(v, b)
        for i in range(self.m):
            b[i] = -self.asm.c[i] - 2.0 * alpha * b[i] - beta * beta * self.asm.g[i]

    cdef int project_positions_at(self, double *q, int *iterations) noexcept nogil:
        cdef int i, it = 0
        cdef double res
        self.asm.assemble(q, NULL, ASM_G)
        self.assemble_mb(q, ASM_B)
        res = self.scaled_residual_sparse()
        while True:
            if not isfinite(res):
                iterations[0] = it
                return self.fail(ERR_NONFINITE_INPUT, 0,
                                 self.nonfinite_input(q, NULL, ASM_G | ASM_B) or 8)
            if res <= self.position_tol:
                break
            if it == 0 and res > self.diverge_residual:
                iterations[0] = it
                self.err_value = res
                self.err_bound = self.diverge_residual
                return self.fail(ERR_DIVERGED, 0, 3)
            if it >= self.max_newton:
                iterations[0] = it
                return 1
            if it == 0:
                self.assemble_mb(q, ASM_M)
            if self.factor(q) < 0:
                iterations[0] = it
                return -1
            for i in range(self.m):
                self.nb[i] = -self.asm.g[i]
            self.kkt_solve(NULL, NULL, self.nb, self.dq)
            for i in range(self.n):
                q[i] += self.dq[i]
            it += 1
            self.asm.assemble(q, NULL, ASM_G)
            self.assemble_mb(q, ASM_B)
            res = self.scaled_residual_sparse()
        iterations[0] = it
        return 0

    cdef int project_velocities_at(self, const double *q, double *v,
                                   bint have_B) noexcept nogil:
        self.assemble_mb(q, ASM_M if have_B else ASM_M | ASM_B)
        if self.factor(q) < 0:
            return -1
        self.velocity_targets(q, self.nb)
        self.kkt_solve(NULL, v, self.nb, self.vtmp)
        if self.finish(q, v, self.vtmp, ASM_M | ASM_B) < 0:
            return -1
        self.watch_kinetic_energy(v, self.vtmp)
        memcpy(v, self.vtmp, self.n * sizeof(double))
        self.factor_valid = True
        return 0

    cdef void velocity_targets(self, const double *q, double *b) noexcept nogil:
        """b of the velocity projection's B w = b: zero (the constraints do not
        depend on time)."""
        memset(b, 0, <size_t>self.m * sizeof(double))

    cdef void watch_kinetic_energy(self, const double *v, const double *w) noexcept nogil:
        """As Engine.watch_kinetic_energy, with M v from the blocks."""
        cdef int i, n = self.n
        cdef double before = 0.0, cut = 0.0
        self.mult_m(v, self.r1, False)
        for i in range(n):
            self.dx[i] = v[i] - w[i]
        self.mult_m(self.dx, self.t, False)
        for i in range(n):
            before += v[i] * self.r1[i]
            cut += self.dx[i] * self.t[i]
        if before > self.ke_peak:
            self.ke_peak = before
        if before > 1e-6 * self.ke_peak and before > 0.0 and cut / before > self.ke_cut_max:
            self.ke_cut_max = cut / before
            self.ke_cut_t = self.err_t

    cdef dict error_record(self):
        rec = Engine.error_record(self)
        rank = self.sol.rank_fixed
        rec.update(rank=rank, nullity=self.n - rank if rank >= 0 else self.n)
        return rec
