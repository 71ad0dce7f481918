# cython: language_level=3
"""Element blocks of the sparse path and the LDL^T of the matrix built from them.

SparseBlocks (an Engine) keeps M and B as the kernels' element blocks (a dense n x n or
m x n array only for the dense solve that redoes an unconverged one: gather_dense)
with the products y = M x, y = B x, y += B^T diag(s) z over them,
and the matrix of the sparse solve

    A = M + B^T diag(alpha) B,    alpha_k = RHO m_ref / s_k^2,

(m_ref the largest diagonal entry of M, s_k = max(||B_k||, ROW_FLOOR times the largest
row norm of B_k's element)), assembled through the scatter maps of
fccgen.runtime.sparsity in the fill-reducing order chosen at load and factored by the
LDL^T of _ldl.pyx over its fixed pattern. A is positive definite whenever M is on the
null space of B (the mechanism is well posed), whatever the rank of B.
"""
from libc.math cimport fabs, sqrt
from libc.stdlib cimport calloc, free
from libc.string cimport memset

import numpy as np

from ._assemble cimport ASM_B, ASM_C, ASM_F, ASM_G, ASM_H, ASM_M, Assembler
from ._engine cimport (ERR_LAPACK, ERR_NONFINITE_INPUT, ERR_PATTERN, ERR_SINGULAR, Engine,
                       finite)
from ._ldl cimport ldl_numeric, ldl_rows, ldl_solve, ldl_symbolic
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
PENALTY = RHO                 # for the other modules
# Row scale floor within an element, as the dense path's (fccgen.rank.ROW_FLOOR).
cdef double ROW_FLOOR = 1e-4
# An LDL^T pivot D_k at or below this fraction of A_kk counts as zero.
cdef double PIVOT_TOL = 64 * 2.220446049250313e-16


cdef void *alloc_zeroed(size_t n, size_t size) except NULL:
    """calloc of at least one item, MemoryError when it fails."""
    cdef void *p = calloc(n if n > 0 else 1, size)
    if p == NULL:
        raise MemoryError("cannot allocate the sparse solve's work arrays")
    return p


# A block entry zero where the pattern of A was taken (SparseBlocks.planar_pattern)
# may grow to GUARD_TOL of its block's largest entry before the pattern trips: the
# factor of A then misses entries of that relative size. The refinement's residuals
# use the full blocks, so the solve still converges to the system's solution, except
# along directions it leaves undetermined: 1e-8 let Bricard's Newton projection from
# 1e-9 off the constraints land 1.8e-8 from the dense path's point (the redundant row
# there is independent to 1e-9). Rounding makes such entries nonzero too (a coordinate
# held at zero by a constraint gets 1e-17 from the solves), far below 1e-12.
cdef double GUARD_TOL = 1e-12


def element_structure(Assembler asm):
    """(q_ptr, q_idx, couples) of the assembler's elements: couples[e] is True when
    element e has a mass matrix or constraint rows (it adds a block to A)."""
    cdef int e
    q_ptr = np.array([asm.qptr[e] for e in range(asm.n_el + 1)], dtype=np.intc)
    q_idx = np.array([asm.qidx[e] for e in range(asm.qptr[asm.n_el])], dtype=np.intc)
    couples = np.array([asm.cls[e].mass_matrix != NULL or asm.cls[e].n_g > 0
                        for e in range(asm.n_el)], dtype=bool)
    return q_ptr, q_idx, couples


cdef class SparseBlocks(Engine):
    """The element blocks, the products with them and the factorisation of A (module
    docstring). Call :meth:`set_structure` (fccgen.runtime.sparsity) before use."""

    def __cinit__(self, Assembler asm, *args, **kwargs):
        cdef int e, nq, total_m = 0, total_b = 0, local = 1
        cdef const fcc_element_class *k
        self.mptr = <int *>alloc_zeroed(asm.n_el + 1, sizeof(int))
        self.bptr = <int *>alloc_zeroed(asm.n_el + 1, sizeof(int))
        for e in range(asm.n_el):
            k = asm.cls[e]
            nq = k.n_q
            local = max(local, nq)
            total_m += nq * nq if k.mass_matrix != NULL else 0
            total_b += k.n_g * nq
            self.mptr[e + 1] = total_m
            self.bptr[e + 1] = total_b
        self.Mblk = <double *>alloc_zeroed(total_m, sizeof(double))
        self.Bblk = <double *>alloc_zeroed(total_b, sizeof(double))
        self.lq = <double *>alloc_zeroed(local, sizeof(double))
        self.ly = <double *>alloc_zeroed(local, sizeof(double))
        self.alpha = <double *>alloc_zeroed(asm.n_g, sizeof(double))
        self.rnorm = <double *>alloc_zeroed(asm.n_g, sizeof(double))
        self.t = <double *>alloc_zeroed(asm.n_q, sizeof(double))

    def __dealloc__(self):
        free(self.mptr); free(self.bptr); free(self.Mblk); free(self.Bblk); free(self.lq)
        free(self.ly); free(self.alpha); free(self.rnorm); free(self.t)
        free(self.zero_m); free(self.zero_b); free(self.zero_m_tol); free(self.zero_b_tol)
        free(self.perm); free(self.Ap); free(self.Ai); free(self.Ax); free(self.emap_ptr)
        free(self.emap); free(self.Lp); free(self.Li); free(self.Lx); free(self.D)
        free(self.parent); free(self.Lnz); free(self.flag); free(self.pattern)
        free(self.Y); free(self.Rp); free(self.Rj); free(self.Rpos)

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
        self.perm = <int *>alloc_zeroed(n, sizeof(int))
        self.Ap = <int *>alloc_zeroed(n + 1, sizeof(int))
        self.Ai = <int *>alloc_zeroed(self.nnz_a, sizeof(int))
        self.Ax = <double *>alloc_zeroed(self.nnz_a, sizeof(double))
        self.emap_ptr = <int *>alloc_zeroed(self.asm.n_el + 1, sizeof(int))
        self.emap = <int *>alloc_zeroed(ev.shape[0], sizeof(int))
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
        self.Lp = <int *>alloc_zeroed(n + 1, sizeof(int))
        self.parent = <int *>alloc_zeroed(n, sizeof(int))
        self.Lnz = <int *>alloc_zeroed(n, sizeof(int))
        self.flag = <int *>alloc_zeroed(n, sizeof(int))
        self.pattern = <int *>alloc_zeroed(n, sizeof(int))
        self.D = <double *>alloc_zeroed(n, sizeof(double))
        self.Y = <double *>alloc_zeroed(n, sizeof(double))
        ldl_symbolic(n, self.Ap, self.Ai, self.Lp, self.parent, self.Lnz, self.flag)
        self.nnz_l = self.Lp[n]
        self.Li = <int *>alloc_zeroed(self.nnz_l, sizeof(int))
        self.Lx = <double *>alloc_zeroed(self.nnz_l, sizeof(double))
        self.Rp = <int *>alloc_zeroed(n + 1, sizeof(int))
        self.Rj = <int *>alloc_zeroed(self.nnz_l, sizeof(int))
        self.Rpos = <int *>alloc_zeroed(self.nnz_l, sizeof(int))
        ldl_rows(n, self.Ap, self.Ai, self.Lp, self.parent, self.Lnz, self.Li, self.Rp,
                 self.Rj, self.Rpos, self.pattern, self.flag)
        self.ready = True

    def planar_pattern(self, samples):
        """Take the pattern of A from the element blocks at the coordinate vectors in
        samples (before set_structure): the entries (a, b) of each element's block of A
        nonzero at any of them (M_ab != 0 or B_ra B_rb != 0 for some row r, a NaN
        counting as nonzero), and keep the offsets of the block entries of M and B zero
        at all of them, which every later assembly checks: a nonzero one trips the
        pattern (the factorisation then fails with ERR_PATTERN and the solver redoes
        the call on the full pattern, paths.make_engine). A model written in a plane
        keeps its out-of-plane entries exactly zero while it moves in it, so the fill
        of L is about halved there. Returns (mask_ptr, mask) for
        fccgen.runtime.sparsity.structure."""
        cdef int e, a, b, r, nq, ng, k
        cdef const double *mb
        cdef const double *bb
        cdef double[:, ::1] qs = np.ascontiguousarray(np.atleast_2d(samples), dtype=float)
        if self.ready:
            raise RuntimeError("the structure is already set")
        if qs.shape[1] != self.n:
            raise ValueError(f"samples have {qs.shape[1]} coordinates, the model {self.n}")
        _, _, couples = element_structure(self.asm)
        sizes = np.array([self.asm.cls[e].n_q ** 2 for e in range(self.asm.n_el)],
                         dtype=np.intp)
        ptr = np.concatenate([[0], np.cumsum(sizes * couples)]).astype(np.intp)
        mask = np.zeros(ptr[self.asm.n_el], dtype=bool)
        cdef unsigned char[::1] mk = mask.view(np.uint8)
        zero_m = np.ones(self.mptr[self.asm.n_el], dtype=bool)
        zero_b = np.ones(self.bptr[self.asm.n_el], dtype=bool)
        cdef unsigned char[::1] zm = zero_m.view(np.uint8)
        cdef unsigned char[::1] zb = zero_b.view(np.uint8)
        scale_m = np.zeros(self.asm.n_el)          # largest |entry| of each block
        scale_b = np.zeros(self.asm.n_el)
        cdef double[::1] sm = scale_m, sb = scale_b
        for k in range(qs.shape[0]):
            self.assemble_mb(&qs[k, 0], ASM_M | ASM_B)
            for e in range(self.asm.n_el):
                if ptr[e + 1] == ptr[e]:
                    continue
                nq = self.asm.cls[e].n_q
                ng = self.asm.cls[e].n_g
                if self.mptr[e + 1] > self.mptr[e]:
                    mb = self.Mblk + self.mptr[e]
                    for a in range(nq * nq):
                        if mb[a] != 0.0:
                            mk[ptr[e] + a] = 1
                            zm[self.mptr[e] + a] = 0
                            if fabs(mb[a]) > sm[e]:
                                sm[e] = fabs(mb[a])
                bb = self.Bblk + self.bptr[e]
                for r in range(ng):
                    for a in range(nq):
                        if bb[r * nq + a] == 0.0:
                            continue
                        zb[self.bptr[e] + r * nq + a] = 0
                        if fabs(bb[r * nq + a]) > sb[e]:
                            sb[e] = fabs(bb[r * nq + a])
                        for b in range(nq):
                            if bb[r * nq + b] != 0.0:
                                mk[ptr[e] + a * nq + b] = 1
        offs_m = np.flatnonzero(zero_m)
        offs_b = np.flatnonzero(zero_b)
        # each offset's tolerance: GUARD_TOL times the largest entry of its block
        m_len = [self.mptr[e + 1] - self.mptr[e] for e in range(self.asm.n_el)]
        b_len = [self.bptr[e + 1] - self.bptr[e] for e in range(self.asm.n_el)]
        tol_m = GUARD_TOL * np.repeat(scale_m, m_len)[offs_m]
        tol_b = GUARD_TOL * np.repeat(scale_b, b_len)[offs_b]
        free(self.zero_m); free(self.zero_b); free(self.zero_m_tol); free(self.zero_b_tol)
        self.zero_m = <int *>alloc_zeroed(offs_m.size, sizeof(int))
        self.zero_b = <int *>alloc_zeroed(offs_b.size, sizeof(int))
        self.zero_m_tol = <double *>alloc_zeroed(offs_m.size, sizeof(double))
        self.zero_b_tol = <double *>alloc_zeroed(offs_b.size, sizeof(double))
        for a in range(offs_m.size):
            self.zero_m[a] = offs_m[a]
            self.zero_m_tol[a] = tol_m[a]
        for a in range(offs_b.size):
            self.zero_b[a] = offs_b[a]
            self.zero_b_tol[a] = tol_b[a]
        self.n_zero_m, self.n_zero_b = offs_m.size, offs_b.size
        self.tripped = False
        return ptr, mask

    @property
    def pattern_tripped(self):
        """Whether an assembly found a block entry nonzero that was zero where the
        pattern was taken (planar_pattern)."""
        return bool(self.tripped)

    @property
    def nonzeros(self):
        """(nonzeros of upper(A), nonzeros of the strict lower part of L)."""
        return self.nnz_a, self.nnz_l

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
        if flags & ASM_M:
            for i in range(self.n_zero_m):
                if not fabs(self.Mblk[self.zero_m[i]]) <= self.zero_m_tol[i]:
                    self.tripped = True
        if flags & ASM_B:
            for i in range(self.n_zero_b):
                if not fabs(self.Bblk[self.zero_b[i]]) <= self.zero_b_tol[i]:
                    self.tripped = True

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

    cdef void gather_dense(self) noexcept nogil:
        """The assembler's dense M (n x n) and B (m x n, row-major) from the blocks."""
        cdef int e, r, a, c, nq, row, n = self.n
        cdef const int *idx
        cdef const double *blk
        cdef double *Md = self.asm.M
        cdef double *Bd = self.asm.B
        memset(Md, 0, <size_t>n * n * sizeof(double))
        memset(Bd, 0, <size_t>self.m * n * sizeof(double))
        for e in range(self.asm.n_el):
            nq = self.asm.cls[e].n_q
            idx = self.asm.qidx + self.asm.qptr[e]
            if self.mptr[e + 1] > self.mptr[e]:
                blk = self.Mblk + self.mptr[e]
                for a in range(nq):
                    for c in range(nq):
                        Md[idx[a] * n + idx[c]] += blk[a * nq + c]
            blk = self.Bblk + self.bptr[e]
            row = self.asm.gptr[e]
            for r in range(self.asm.cls[e].n_g):
                for a in range(nq):
                    Bd[(row + r) * n + idx[a]] += blk[r * nq + a]

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
        if self.tripped:
            return self.fail(ERR_PATTERN, 0, 0)
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
        info = ldl_numeric(self.n, self.Ap, self.Ai, self.Ax, self.Lp, self.Li, self.Rp,
                           self.Rj, self.Rpos, self.Lx, self.D, self.Y, PIVOT_TOL)
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

    # -- the Engine's building block that reads the blocks ----------------------------
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

