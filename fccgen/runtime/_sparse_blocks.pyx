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

from ._cengine cimport fcc_assemble, fcc_put_time, fcc_max_abs_g, fcc_scaled_residual
from ._assemble cimport ASM_B, ASM_C, ASM_F, ASM_G, ASM_H, ASM_M, Assembler
from ._cengine cimport fcc_element_vectors as element_vectors
from ._engine cimport (ERR_LAPACK, ERR_NONFINITE_INPUT, ERR_PATTERN, ERR_SINGULAR, Engine,
                       finite)
from ._cengine cimport (fcc_ldl_numeric as ldl_numeric, fcc_ldl_rows as ldl_rows,
                        fcc_ldl_solve as ldl_solve, fcc_ldl_symbolic as ldl_symbolic)
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


cdef int *int_array(values) except NULL:
    """A new C array (alloc_zeroed) holding the integers in values."""
    cdef Py_ssize_t i, n = len(values)
    cdef int *p = <int *>alloc_zeroed(n, sizeof(int))
    for i in range(n):
        p[i] = values[i]
    return p


cdef double *double_array(values) except NULL:
    """A new C array (alloc_zeroed) holding the numbers in values."""
    cdef Py_ssize_t i, n = len(values)
    cdef double *p = <double *>alloc_zeroed(n, sizeof(double))
    for i in range(n):
        p[i] = values[i]
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


# A row pins its last free coordinate only when that entry is at least PIN_PIVOT of
# the row's norm: the pinned coordinate then follows from the row without
# amplifying rounding (rows of the constraints that pin in practice, planes and
# "perpendicular to a fixed vector", have entries of one size).
PIN_PIVOT = 1e-3


def _pin(taken, norms):
    """The coordinates pinned by the rows taken (SparseBlocks.set_pinned): {row:
    {coordinate: entry}}; a row with one coordinate not yet pinned pins it, repeatedly
    (a queue over the rows' counts of coordinates not yet pinned)."""
    rows_of = {}
    left = {}
    for row, coef in taken.items():
        left[row] = len(coef)
        for j in coef:
            rows_of.setdefault(j, []).append(row)
    queue = sorted(row for row, k in left.items() if k == 1)
    pinned = set()
    while queue:
        row = queue.pop()
        if left[row] != 1:
            continue
        j = next(j for j in taken[row] if j not in pinned)
        if abs(taken[row][j]) < PIN_PIVOT * norms[row]:
            continue
        pinned.add(j)
        for other in rows_of[j]:
            left[other] -= 1
            if left[other] == 1:
                queue.append(other)
    return pinned


def view_masks(masks, locals_, couples):
    """The masks of planar_pattern (mask_ptr, mask: each coupling element's full
    n_q x n_q block) narrowed to the solve's view (set_pinned): locals_ = (sizes,
    s_ptr, s_loc) of SparseBlocks.solve_locals, couples of solve_elements."""
    ptr, mask = masks
    sizes, s_ptr, s_loc = locals_
    parts = []
    for e in range(len(sizes)):
        if couples[e]:
            loc = s_loc[s_ptr[e]:s_ptr[e + 1]]
            full = np.asarray(mask[ptr[e]:ptr[e + 1]]).reshape(sizes[e], sizes[e])
            parts.append(full[np.ix_(loc, loc)].ravel())
        else:
            parts.append(np.zeros(0, dtype=bool))
    view_ptr = np.concatenate([[0], np.cumsum([p.size for p in parts])]).astype(np.intp)
    return view_ptr, (np.concatenate(parts) if parts else np.zeros(0, dtype=bool))


def element_structure(Assembler asm):
    """(q_ptr, q_idx, couples) of the assembler's elements: couples[e] is True when
    element e has a mass matrix or constraint rows (it adds a block to A)."""
    cdef int e
    q_ptr = np.array([asm.model.qptr[e] for e in range(asm.n_el + 1)], dtype=np.intc)
    q_idx = np.array([asm.model.qidx[e] for e in range(asm.model.qptr[asm.n_el])], dtype=np.intc)
    couples = np.array([asm.model.cls[e].mass_matrix != NULL or asm.model.cls[e].n_g > 0
                        for e in range(asm.n_el)], dtype=bool)
    return q_ptr, q_idx, couples


cdef void mult_blocks(int n_el, const int *ptr, const int *idx, const int *mptr,
                      const double *blocks, const double *x, double *y) noexcept nogil:
    """y += M x over square element blocks: element e's block (at mptr[e], none when
    mptr[e + 1] == mptr[e]) on the coordinates idx[ptr[e]:ptr[e + 1]]."""
    cdef int e, i, j, nq
    cdef const int *ix
    cdef const double *blk
    cdef double acc
    for e in range(n_el):
        if mptr[e + 1] == mptr[e]:
            continue
        nq = ptr[e + 1] - ptr[e]
        ix = idx + ptr[e]
        blk = blocks + mptr[e]
        for i in range(nq):
            acc = 0.0
            for j in range(nq):
                acc += blk[i * nq + j] * x[ix[j]]
            y[ix[i]] += acc


cdef class SparseBlocks(Engine):
    """The element blocks, the products with them and the factorisation of A (module
    docstring). Call :meth:`set_structure` (fccgen.runtime.sparsity) before use."""

    def __cinit__(self, Assembler asm, *args, **kwargs):
        cdef int e, nq, i, total_m = 0, total_b = 0, local = 1
        cdef const fcc_element_class *k
        self.mptr = <int *>alloc_zeroed(asm.n_el + 1, sizeof(int))
        self.bptr = <int *>alloc_zeroed(asm.n_el + 1, sizeof(int))
        for e in range(asm.n_el):
            k = asm.model.cls[e]
            nq = k.n_q
            local = max(local, nq)
            total_m += nq * nq if k.mass_matrix != NULL else 0
            total_b += k.n_g * nq
            self.mptr[e + 1] = total_m
            self.bptr[e + 1] = total_b
        self.Mblk = <double *>alloc_zeroed(total_m, sizeof(double))
        self.Bblk = <double *>alloc_zeroed(total_b, sizeof(double))
        self.lq = <double *>alloc_zeroed(local, sizeof(double))
        self.alpha = <double *>alloc_zeroed(asm.n_g, sizeof(double))
        self.rnorm = <double *>alloc_zeroed(asm.n_g, sizeof(double))
        self.t = <double *>alloc_zeroed(asm.n_q, sizeof(double))
        # the full view (set_pinned narrows it)
        self.snq = <int *>alloc_zeroed(asm.n_el, sizeof(int))
        self.sng = <int *>alloc_zeroed(asm.n_el, sizeof(int))
        self.sptr = <int *>alloc_zeroed(asm.n_el + 1, sizeof(int))
        self.sgptr = <int *>alloc_zeroed(asm.n_el + 1, sizeof(int))
        self.sidx = <int *>alloc_zeroed(asm.model.qptr[asm.n_el], sizeof(int))
        self.sloc = <int *>alloc_zeroed(asm.model.qptr[asm.n_el], sizeof(int))
        self.srow = <int *>alloc_zeroed(asm.n_g, sizeof(int))
        self.srloc = <int *>alloc_zeroed(asm.n_g, sizeof(int))
        self.efix = <double *>alloc_zeroed(asm.n_el, sizeof(double))
        for e in range(asm.n_el + 1):
            self.sptr[e] = asm.model.qptr[e]
            self.sgptr[e] = asm.model.gptr[e]
        for e in range(asm.n_el):
            self.snq[e] = asm.model.cls[e].n_q
            self.sng[e] = asm.model.cls[e].n_g
            for i in range(asm.model.cls[e].n_q):
                self.sidx[asm.model.qptr[e] + i] = asm.model.qidx[asm.model.qptr[e] + i]
                self.sloc[asm.model.qptr[e] + i] = i
            for i in range(asm.model.cls[e].n_g):
                self.srow[asm.model.gptr[e] + i] = asm.model.gptr[e] + i
                self.srloc[asm.model.gptr[e] + i] = i
        self.mcptr = self.mptr
        self.bcptr = self.bptr
        self.Mc = self.Mblk
        self.Bc = self.Bblk

    def __dealloc__(self):
        if self.compact:
            free(self.mcptr); free(self.bcptr); free(self.Mc); free(self.Bc)
        free(self.snq); free(self.sng); free(self.sptr); free(self.sgptr); free(self.sidx)
        free(self.sloc); free(self.srow); free(self.srloc); free(self.efix)
        free(self.pinned); free(self.pin_diag); free(self.fixed_off); free(self.fixed_val)
        free(self.fixed_tol); free(self.fixed_rows); free(self.fixed_g_tol)
        free(self.mptr); free(self.bptr); free(self.Mblk); free(self.Bblk); free(self.lq)
        free(self.alpha); free(self.rnorm); free(self.t)
        free(self.zero_m); free(self.zero_b); free(self.zero_m_tol); free(self.zero_b_tol)
        free(self.perm); free(self.Ap); free(self.Ai); free(self.Ax); free(self.ent_ptr)
        free(self.ent_a); free(self.ent_b); free(self.ent_pos); free(self.lb)
        free(self.Lp); free(self.Li); free(self.Lx); free(self.Dinv)
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
        cdef int n = self.n, i, k, e, nq
        if pv.shape[0] != n or apv.shape[0] != n + 1 or epv.shape[0] != self.asm.n_el + 1:
            raise ValueError("the structure does not match the engine's sizes")
        if sorted(np.asarray(pv).tolist()) != list(range(n)):
            raise ValueError("perm is not a permutation")
        self.nnz_a = apv[n]
        self.perm = <int *>alloc_zeroed(n, sizeof(int))
        self.Ap = <int *>alloc_zeroed(n + 1, sizeof(int))
        self.Ai = <int *>alloc_zeroed(self.nnz_a, sizeof(int))
        self.Ax = <double *>alloc_zeroed(self.nnz_a, sizeof(double))
        for i in range(n):
            self.perm[i] = pv[i]
        for i in range(n + 1):
            self.Ap[i] = apv[i]
        for i in range(self.nnz_a):
            self.Ai[i] = aiv[i]
        for i in range(ev.shape[0]):
            if not -1 <= ev[i] < self.nnz_a:
                raise ValueError("scatter map index out of range")
        # each element's entries of A as a list (local a, b; place in Ax), without
        # the pairs the map leaves out (the lower triangle, entries zero in the plane)
        ent_a, ent_b, ent_pos, ent_ptr, largest = [], [], [], [0], 1
        for e in range(self.asm.n_el):
            nq = self.snq[e]
            if epv[e + 1] > epv[e] and epv[e + 1] - epv[e] != nq * nq:
                raise ValueError("the scatter map does not match the solve's view")
            for i in range(epv[e], epv[e + 1]):
                if ev[i] >= 0:
                    ent_a.append((i - epv[e]) // nq)
                    ent_b.append((i - epv[e]) % nq)
                    ent_pos.append(ev[i])
            ent_ptr.append(len(ent_pos))
            largest = max(largest, nq * self.sng[e])
        self.ent_ptr = int_array(ent_ptr)
        self.ent_a = int_array(ent_a)
        self.ent_b = int_array(ent_b)
        self.ent_pos = int_array(ent_pos)
        self.lb = <double *>alloc_zeroed(largest, sizeof(double))
        self.Lp = <int *>alloc_zeroed(n + 1, sizeof(int))
        self.parent = <int *>alloc_zeroed(n, sizeof(int))
        self.Lnz = <int *>alloc_zeroed(n, sizeof(int))
        self.flag = <int *>alloc_zeroed(n, sizeof(int))
        self.pattern = <int *>alloc_zeroed(n, sizeof(int))
        self.Dinv = <double *>alloc_zeroed(n, sizeof(double))
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
        free(self.pin_diag)
        self.pin_diag = <int *>alloc_zeroed(self.n_pinned, sizeof(int))
        pinv = np.empty(n, dtype=np.intc)
        pinv[np.asarray(pv)] = np.arange(n, dtype=np.intc)
        is_pinned = np.zeros(n, dtype=bool)
        for i in range(self.n_pinned):
            k = pinv[self.pinned[i]]          # the diagonal closes its column
            self.pin_diag[i] = self.Ap[k + 1] - 1
            if self.Ai[self.pin_diag[i]] != k:
                raise ValueError("the pattern of A lacks a pinned coordinate's diagonal")
            is_pinned[k] = True
        # Trailing pinned columns (sparsity.isolated_last puts them there) are unit
        # diagonals with nothing in their rows: L is the identity there and a solve
        # leaves x as it is, so the factorisation and the solves stop before them.
        self.n_lead = n
        while (self.n_lead > 0 and is_pinned[self.n_lead - 1]
               and self.Ap[self.n_lead] - self.Ap[self.n_lead - 1] == 1
               and self.Lp[self.n_lead] == self.Lp[self.n_lead - 1]):
            self.n_lead -= 1
        self.ready = True

    def set_pinned(self, samples):
        """Leave out of the solve the coordinates that linear constraints with constant
        rows hold still, and those rows (before planar_pattern and set_structure). A
        row is taken when its Jacobian entries are the same at every coordinate vector
        in samples (paths.pattern_samples: every coordinate that sits off zero or moves
        is moved there, so a row that depends on one changes), its element does not
        depend on the time, and it holds at samples[0] to the position tolerance
        (|g_k| <= position_tol ||B_k||). Among those rows, one whose entries are zero
        but for one coordinate not yet pinned (and that entry at least PIN_PIVOT of
        the row's norm) pins it; pinning repeats until no row pins another (a point
        on the plane z = 0 pins its z, then a body's "perpendicular to z" row pins the
        next point's z, and so on down a planar chain). The taken rows whose every
        entry is on pinned coordinates are *fixed*: they hold B_R x = 0 with x = 0 on
        the pinned coordinates (their right-hand sides vanish: constant rows of a
        constraint that holds), so the accelerations, speed changes and Newton steps
        of the pinned coordinates are zero, and the solve works on the other
        coordinates and rows alone, with every block compacted to them. The same
        answer as the full solve, while the fixed rows keep their entries (checked at
        every assembly against GUARD_TOL of the row's largest) and hold (checked with
        g at each position projection): otherwise the pattern trips and the solver
        redoes the call on the full pattern, as for planar_pattern. Returns the number
        of pinned coordinates (0: the full view is kept)."""
        cdef int e, a, r, nq, ng, k, row, at, nf
        cdef const fcc_element_class *c
        cdef double[:, ::1] qs = np.ascontiguousarray(np.atleast_2d(samples), dtype=float)
        if self.ready or self.compact:
            raise RuntimeError("the structure is already set")
        if qs.shape[1] != self.n:
            raise ValueError(f"samples have {qs.shape[1]} coordinates, the model {self.n}")
        n_el = self.asm.n_el
        nb = self.bptr[n_el]
        if nb == 0:
            return 0
        blocks = []
        for k in range(qs.shape[0]):
            self.assemble_mb(&qs[k, 0], ASM_B)
            blocks.append(np.array(<double[:nb]>self.Bblk))
        g0 = self.asm.quantity(ASM_G, np.asarray(qs[0]))
        taken = {}                            # row -> {coordinate: entry}
        where = {}                            # row -> (element, local row)
        norms = {}
        for e in range(n_el):
            c = self.asm.model.cls[e]
            if c.constraint_jacobian == NULL or c.constraint_rate != NULL:
                continue
            nq, ng = c.n_q, c.n_g
            idx = [self.asm.model.qidx[self.asm.model.qptr[e] + a] for a in range(nq)]
            for r in range(ng):
                at = self.bptr[e] + r * nq
                entries = blocks[0][at:at + nq]
                if any(not np.array_equal(entries, b[at:at + nq]) for b in blocks[1:]):
                    continue
                norm = float(np.sqrt(np.dot(entries, entries)))
                row = self.asm.model.gptr[e] + r
                if not (norm > 0.0 and abs(g0[row]) <= self.position_tol * norm):
                    continue
                coef = {}
                for a in range(nq):
                    coef[idx[a]] = coef.get(idx[a], 0.0) + float(entries[a])
                taken[row] = {j: x for j, x in coef.items() if x != 0.0}
                where[row] = (e, r)
                norms[row] = norm
        pinned = _pin(taken, norms)
        if not pinned:
            return 0
        fixed = sorted(row for row, coef in taken.items() if set(coef) <= pinned)
        fixed_set = set(fixed)
        # the view: free local coordinates and kept rows of every element
        cdef int total_m = 0, total_b = 0
        self.mcptr = <int *>alloc_zeroed(n_el + 1, sizeof(int))
        self.bcptr = <int *>alloc_zeroed(n_el + 1, sizeof(int))
        self.compact = True
        for e in range(n_el):
            c = self.asm.model.cls[e]
            nq, ng = c.n_q, c.n_g
            nf = 0
            for a in range(nq):
                if self.asm.model.qidx[self.asm.model.qptr[e] + a] not in pinned:
                    self.sidx[self.sptr[e] + nf] = self.asm.model.qidx[self.asm.model.qptr[e] + a]
                    self.sloc[self.sptr[e] + nf] = a
                    nf += 1
            self.snq[e] = nf
            self.sptr[e + 1] = self.sptr[e] + nf
            k = 0
            for r in range(ng):
                if self.asm.model.gptr[e] + r not in fixed_set:
                    self.srow[self.sgptr[e] + k] = self.asm.model.gptr[e] + r
                    self.srloc[self.sgptr[e] + k] = r
                    k += 1
            self.sng[e] = k
            self.sgptr[e + 1] = self.sgptr[e] + k
            total_m += nf * nf if c.mass_matrix != NULL else 0
            total_b += k * nf
            self.mcptr[e + 1] = total_m
            self.bcptr[e + 1] = total_b
        self.Mc = <double *>alloc_zeroed(total_m, sizeof(double))
        self.Bc = <double *>alloc_zeroed(total_b, sizeof(double))
        # the fixed rows: constant norms, no penalty, and their guards
        self.n_pinned = len(pinned)
        self.pinned = int_array(sorted(pinned))
        self.n_fixed_rows = len(fixed)
        self.fixed_rows = int_array(fixed)
        self.fixed_g_tol = double_array([self.position_tol * norms[row] for row in fixed])
        offsets, values, tols = [], [], []
        for row in fixed:
            e, r = where[row]
            nq = self.asm.model.cls[e].n_q
            at = self.bptr[e] + r * nq
            entries = blocks[0][at:at + nq]
            self.rnorm[row] = norms[row]
            self.alpha[row] = 0.0
            if norms[row] > self.efix[e]:
                self.efix[e] = norms[row]
            offsets += range(at, at + nq)
            values += entries.tolist()
            tols += [GUARD_TOL * float(np.max(np.abs(entries)))] * nq
        self.n_fixed = len(offsets)
        self.fixed_off = int_array(offsets)
        self.fixed_val = double_array(values)
        self.fixed_tol = double_array(tols)
        return self.n_pinned

    def solve_elements(self):
        """(q_ptr, q_idx, couples) of the solve's view (set_pinned): each element's
        free coordinates, and whether it adds a block to A (a mass matrix or kept
        rows on them); the assembler's elements when nothing is pinned."""
        cdef int e
        n_el = self.asm.n_el
        q_ptr = np.array([self.sptr[e] for e in range(n_el + 1)], dtype=np.intc)
        q_idx = np.array([self.sidx[e] for e in range(self.sptr[n_el])], dtype=np.intc)
        couples = np.array([self.snq[e] > 0 and (self.mcptr[e + 1] > self.mcptr[e]
                                                 or self.sng[e] > 0)
                            for e in range(n_el)], dtype=bool)
        return q_ptr, q_idx, couples

    def view_entries(self):
        """(in_m, in_b): for each entry of the mass and Jacobian blocks, whether the
        solve's view (set_pinned) reads it (its coordinates free, its row kept)."""
        cdef int e, a, b, r, nq
        pinned = np.zeros(self.n, dtype=bool)
        pinned[self.pinned_coordinates[0]] = True
        fixed = np.zeros(self.m, dtype=bool)
        fixed[self.pinned_coordinates[1]] = True
        in_m = np.zeros(self.mptr[self.asm.n_el], dtype=bool)
        in_b = np.zeros(self.bptr[self.asm.n_el], dtype=bool)
        for e in range(self.asm.n_el):
            nq = self.asm.model.cls[e].n_q
            free = ~pinned[[self.asm.model.qidx[self.asm.model.qptr[e] + a] for a in range(nq)]]
            if self.mptr[e + 1] > self.mptr[e]:
                in_m[self.mptr[e]:self.mptr[e + 1]] = np.outer(free, free).ravel()
            rows = ~fixed[self.asm.model.gptr[e]:self.asm.model.gptr[e + 1]]
            if self.bptr[e + 1] > self.bptr[e]:
                in_b[self.bptr[e]:self.bptr[e + 1]] = np.outer(rows, free).ravel()
        return in_m, in_b

    def solve_locals(self):
        """(sizes, s_ptr, s_loc): each element's number of local coordinates, and
        where each free one of the solve's view (set_pinned) sits in that list."""
        cdef int e
        n_el = self.asm.n_el
        return (np.array([self.asm.model.cls[e].n_q for e in range(n_el)], dtype=np.intp),
                np.array([self.sptr[e] for e in range(n_el + 1)], dtype=np.intp),
                np.array([self.sloc[e] for e in range(self.sptr[n_el])], dtype=np.intp))

    @property
    def pinned_coordinates(self):
        """The coordinates the solve leaves out (set_pinned), and the fixed rows."""
        cdef int i
        return (np.array([self.pinned[i] for i in range(self.n_pinned)], dtype=np.intp),
                np.array([self.fixed_rows[i] for i in range(self.n_fixed_rows)],
                         dtype=np.intp))

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
        sizes = np.array([self.asm.model.cls[e].n_q ** 2 for e in range(self.asm.n_el)],
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
                nq = self.asm.model.cls[e].n_q
                ng = self.asm.model.cls[e].n_g
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
        if self.compact:
            # entries on a pinned coordinate or in a fixed row need no guard: the
            # solve never reads them (x is 0 there; fixed rows have their own guard)
            free_m, free_b = self.view_entries()
            zero_m &= free_m
            zero_b &= free_b
        offs_m = np.flatnonzero(zero_m)
        offs_b = np.flatnonzero(zero_b)
        # each offset's tolerance: GUARD_TOL times the largest entry of its block
        m_len = [self.mptr[e + 1] - self.mptr[e] for e in range(self.asm.n_el)]
        b_len = [self.bptr[e + 1] - self.bptr[e] for e in range(self.asm.n_el)]
        tol_m = GUARD_TOL * np.repeat(scale_m, m_len)[offs_m]
        tol_b = GUARD_TOL * np.repeat(scale_b, b_len)[offs_b]
        free(self.zero_m); free(self.zero_b); free(self.zero_m_tol); free(self.zero_b_tol)
        self.zero_m = int_array(offs_m)
        self.zero_m_tol = double_array(tol_m)
        self.zero_b = int_array(offs_b)
        self.zero_b_tol = double_array(tol_b)
        self.n_zero_m, self.n_zero_b = offs_m.size, offs_b.size
        self.tripped = False
        if not self.compact:
            return ptr, mask
        return view_masks((ptr, mask), self.solve_locals(), self.solve_elements()[2])

    @property
    def pattern_tripped(self):
        """Whether an assembly found a block entry nonzero that was zero where the
        pattern was taken (planar_pattern)."""
        return bool(self.tripped)

    @property
    def nonzeros(self):
        """(nonzeros of upper(A), nonzeros of the strict lower part of L)."""
        return self.nnz_a, self.nnz_l

    @property
    def factored_columns(self):
        """The columns the LDL^T and its solves cover (set_structure: all but the
        trailing pinned ones)."""
        return self.n_lead

    # -- element blocks ------------------------------------------------------------
    cdef void assemble_mb(self, const double *q, int flags) noexcept nogil:
        """The mass (ASM_M) and Jacobian (ASM_B) blocks of every element at q, and
        their compact copies on the solve's view (set_pinned); the guards of the
        entries left out (planar_pattern) and of the fixed rows."""
        self.assemble_blocks(q, NULL, flags)

    cdef void assemble_blocks(self, const double *q, const double *v,
                              int flags) noexcept nogil:
        """assemble_mb, and in the same pass over the elements the assembler's h
        (ASM_H), f (ASM_F) and c (ASM_C) at (q, v), as Assembler.assemble. With the
        blocks, while they are at hand: rnorm_k = ||B_k|| of the kept rows (the
        whole row, pinned coordinates too) and mref, the largest diagonal entry of M
        on the solve's view (1 if none is positive), for the penalties."""
        cdef int e, i, a, b, r, nq, nf, ng
        cdef const fcc_element_class *k
        cdef const int *idx
        cdef const int *loc
        cdef const int *rl
        cdef const int *rows
        cdef double norm, mref = 0.0
        cdef const double *p
        cdef const double *src
        cdef double *dst
        cdef double *o = self.asm.a.out
        cdef double *lv = self.asm.a.lv
        cdef double *hv = self.asm.a.h
        cdef double *fv = self.asm.a.f
        cdef double *cv = self.asm.a.c
        cdef int vec = flags & (ASM_H | ASM_F | ASM_C)
        if flags & ASM_H: memset(hv, 0, <size_t>self.n * sizeof(double))
        if flags & ASM_F: memset(fv, 0, <size_t>self.n * sizeof(double))
        if flags & ASM_C: memset(cv, 0, <size_t>self.m * sizeof(double))
        for e in range(self.asm.n_el):
            k = self.asm.model.cls[e]
            nq = k.n_q
            idx = self.asm.model.qidx + self.asm.model.qptr[e]
            p = self.asm.a.params + self.asm.model.pptr[e]
            if not ((flags & ASM_M and k.mass_matrix != NULL)
                    or (flags & ASM_B and k.constraint_jacobian != NULL) or vec):
                continue
            for i in range(nq):
                self.lq[i] = q[idx[i]]
            if vec:
                for i in range(nq):
                    lv[i] = v[idx[i]]
                element_vectors(k, self.lq, lv, p, idx, self.asm.model.gptr[e], vec, o, hv,
                                fv, cv)
            nf = self.snq[e]
            loc = self.sloc + self.sptr[e]
            if flags & ASM_M and k.mass_matrix != NULL:
                k.mass_matrix(self.lq, p, self.Mblk + self.mptr[e])
                if self.compact:
                    src = self.Mblk + self.mptr[e]
                    dst = self.Mc + self.mcptr[e]
                    for a in range(nf):
                        for b in range(nf):
                            dst[a * nf + b] = src[loc[a] * nq + loc[b]]
                dst = self.Mc + self.mcptr[e]
                for a in range(nf):
                    if dst[a * nf + a] > mref:
                        mref = dst[a * nf + a]
            if flags & ASM_B and k.constraint_jacobian != NULL:
                k.constraint_jacobian(self.lq, p, self.Bblk + self.bptr[e])
                src = self.Bblk + self.bptr[e]
                rl = self.srloc + self.sgptr[e]
                rows = self.srow + self.sgptr[e]
                ng = self.sng[e]
                for r in range(ng):
                    norm = 0.0
                    for i in range(nq):
                        norm += src[rl[r] * nq + i] * src[rl[r] * nq + i]
                    self.rnorm[rows[r]] = sqrt(norm)
                if self.compact:
                    dst = self.Bc + self.bcptr[e]
                    for r in range(ng):
                        for a in range(nf):
                            dst[r * nf + a] = src[rl[r] * nq + loc[a]]
        if flags & ASM_M:
            self.mref = mref if mref > 0.0 else 1.0
            for i in range(self.n_zero_m):
                if not fabs(self.Mblk[self.zero_m[i]]) <= self.zero_m_tol[i]:
                    self.tripped = True
        if flags & ASM_B:
            for i in range(self.n_zero_b):
                if not fabs(self.Bblk[self.zero_b[i]]) <= self.zero_b_tol[i]:
                    self.tripped = True
            for i in range(self.n_fixed):
                if not fabs(self.Bblk[self.fixed_off[i]] - self.fixed_val[i]) \
                        <= self.fixed_tol[i]:
                    self.tripped = True

    cdef void check_fixed_g(self) noexcept nogil:
        """Trip the pattern when a fixed row (set_pinned) no longer holds to the
        position tolerance (assembled g): its pinned coordinates would need to move."""
        cdef int i
        for i in range(self.n_fixed_rows):
            if not fabs(self.asm.a.g[self.fixed_rows[i]]) <= self.fixed_g_tol[i]:
                self.tripped = True

    cdef void mult_m(self, const double *x, double *y, bint add) noexcept nogil:
        """y (+)= M x on the solve's view (pinned coordinates: neither read nor
        written)."""
        if not add:
            memset(y, 0, <size_t>self.n * sizeof(double))
        mult_blocks(self.asm.n_el, self.sptr, self.sidx, self.mcptr, self.Mc, x, y)

    cdef void mult_m_full(self, const double *x, double *y, bint add) noexcept nogil:
        """y (+)= M x with the whole blocks (pinned coordinates too: M v of speeds
        that are not yet zero there, for the velocity projection)."""
        if not add:
            memset(y, 0, <size_t>self.n * sizeof(double))
        mult_blocks(self.asm.n_el, self.asm.model.qptr, self.asm.model.qidx, self.mptr, self.Mblk,
                    x, y)

    cdef void mult_b(self, const double *x, double *y) noexcept nogil:
        """y = B x (m rows) on the solve's view: 0 in the fixed rows."""
        cdef int e, r, j, nq
        cdef const int *idx
        cdef const int *rows
        cdef const double *blk
        cdef double acc
        if self.compact:
            memset(y, 0, <size_t>self.m * sizeof(double))
        for e in range(self.asm.n_el):
            nq = self.snq[e]
            idx = self.sidx + self.sptr[e]
            blk = self.Bc + self.bcptr[e]
            rows = self.srow + self.sgptr[e]
            for r in range(self.sng[e]):
                acc = 0.0
                for j in range(nq):
                    acc += blk[r * nq + j] * x[idx[j]]
                y[rows[r]] = acc

    cdef void mult_bt(self, const double *z, const double *s, double *y) noexcept nogil:
        """y += B^T diag(s) z (s NULL: the identity) on the solve's view."""
        cdef int e, r, j, nq
        cdef const int *idx
        cdef const int *rows
        cdef const double *blk
        cdef double zr
        for e in range(self.asm.n_el):
            nq = self.snq[e]
            idx = self.sidx + self.sptr[e]
            blk = self.Bc + self.bcptr[e]
            rows = self.srow + self.sgptr[e]
            for r in range(self.sng[e]):
                zr = z[rows[r]] if s == NULL else z[rows[r]] * s[rows[r]]
                if zr == 0.0:
                    continue
                for j in range(nq):
                    y[idx[j]] += blk[r * nq + j] * zr

    cdef void gather_dense(self) noexcept nogil:
        """The assembler's dense M (n x n) and B (m x n, row-major) from the blocks."""
        cdef int e, r, a, c, nq, row, n = self.n
        cdef const int *idx
        cdef const double *blk
        cdef double *Md = self.asm.a.M
        cdef double *Bd = self.asm.a.B
        memset(Md, 0, <size_t>n * n * sizeof(double))
        memset(Bd, 0, <size_t>self.m * n * sizeof(double))
        for e in range(self.asm.n_el):
            nq = self.asm.model.cls[e].n_q
            idx = self.asm.model.qidx + self.asm.model.qptr[e]
            if self.mptr[e + 1] > self.mptr[e]:
                blk = self.Mblk + self.mptr[e]
                for a in range(nq):
                    for c in range(nq):
                        Md[idx[a] * n + idx[c]] += blk[a * nq + c]
            blk = self.Bblk + self.bptr[e]
            row = self.asm.model.gptr[e]
            for r in range(self.asm.model.cls[e].n_g):
                for a in range(nq):
                    Bd[(row + r) * n + idx[a]] += blk[r * nq + a]

    cdef void penalties(self) noexcept nogil:
        """alpha_k = RHO mref / s_k^2 with s_k = max(||B_k||, ROW_FLOOR * the largest
        row norm of B_k's element), 0 for a zero row (the norms and mref of the
        blocks held: assemble_blocks). Fixed rows (set_pinned) keep their constant
        norms and no penalty."""
        cdef int e, r, ng, row
        cdef double largest, s
        cdef const int *rows
        for e in range(self.asm.n_el):
            ng = self.sng[e]
            rows = self.srow + self.sgptr[e]
            largest = self.efix[e]
            for r in range(ng):
                if self.rnorm[rows[r]] > largest:
                    largest = self.rnorm[rows[r]]
            for r in range(ng):
                row = rows[r]
                s = self.rnorm[row]
                if s < ROW_FLOOR * largest:
                    s = ROW_FLOOR * largest
                self.alpha[row] = RHO * self.mref / (s * s) if s > 0.0 else 0.0

    cdef double scaled_residual_sparse(self) noexcept nogil:
        """max_k |g_k| / ||B_k|| (|g_k| for a zero row; NaN if a g_k is not), with the
        assembled g and the row norms of the Jacobian blocks."""
        cdef int k
        cdef double worst = 0.0, val
        for k in range(self.m):
            val = fabs(self.asm.a.g[k])
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
        cdef int e, a, b, r, nq, ng, info, bad
        cdef int t
        cdef const int *rows
        cdef const double *mb
        cdef const double *bb
        cdef double val
        self.factor_valid = False
        self.held = False
        if not self.ready:
            return self.fail(ERR_LAPACK, -1, 0)
        if self.tripped:
            return self.fail(ERR_PATTERN, 0, 0)
        self.penalties()
        memset(self.Ax, 0, <size_t>self.nnz_a * sizeof(double))
        for e in range(self.asm.n_el):
            if self.ent_ptr[e + 1] == self.ent_ptr[e]:
                continue
            nq = self.snq[e]
            ng = self.sng[e]
            mb = self.Mc + self.mcptr[e] if self.mcptr[e + 1] > self.mcptr[e] else NULL
            bb = self.Bc + self.bcptr[e]
            rows = self.srow + self.sgptr[e]
            for r in range(ng):                 # the rows scaled by their penalties
                for a in range(nq):
                    self.lb[r * nq + a] = bb[r * nq + a] * self.alpha[rows[r]]
            for t in range(self.ent_ptr[e], self.ent_ptr[e + 1]):
                a = self.ent_a[t]
                b = self.ent_b[t]
                val = mb[a * nq + b] if mb != NULL else 0.0
                for r in range(ng):
                    val += self.lb[r * nq + a] * bb[r * nq + b]
                self.Ax[self.ent_pos[t]] += val
        for a in range(self.n_pinned):      # pinned: a unit diagonal, nothing else
            self.Ax[self.pin_diag[a]] = 1.0
        self.n_factor += 1
        info = ldl_numeric(self.n_lead, self.Ap, self.Ai, self.Ax, self.Lp, self.Li,
                           self.Rp, self.Rj, self.Rpos, self.Lx, self.Dinv, self.Y,
                           PIVOT_TOL)
        if info == 0:
            self.held = True
            return 0
        bad = self.nonfinite_input(q, NULL, ASM_M | ASM_B)
        if bad:
            return self.fail(ERR_NONFINITE_INPUT, 0, bad)
        return self.fail(ERR_SINGULAR, info, 0)

    cdef void solve_a(self, double *x) noexcept nogil:
        """x <- A^{-1} x through the permutation (pinned coordinates past n_lead: x
        as it is, A's unit diagonal there)."""
        cdef int i, n = self.n_lead
        for i in range(n):
            self.t[i] = x[self.perm[i]]
        ldl_solve(n, self.Lp, self.Li, self.Lx, self.Dinv, self.t)
        for i in range(n):
            x[self.perm[i]] = self.t[i]

    cdef void solve_a_add(self, const double *y, double *x, double *step,
                          double *size) noexcept nogil:
        """x += A^{-1} y, with step = max |A^{-1} y| and size = max |x| after it, in
        the pass that scatters the solve. y must be zero on the pinned coordinates
        past n_lead (A^{-1} y is then zero there too): they are not visited, so x
        keeps its values there, and size counts them only if they are zero (as in
        the refinement, whose x stays zero on them)."""
        cdef int i, j, n = self.n_lead
        cdef double d, xj, nd = 0.0, nx = 0.0
        for i in range(n):
            self.t[i] = y[self.perm[i]]
        ldl_solve(n, self.Lp, self.Li, self.Lx, self.Dinv, self.t)
        for i in range(n):
            j = self.perm[i]
            d = self.t[i]
            xj = x[j] + d
            x[j] = xj
            if fabs(d) > nd:
                nd = fabs(d)
            if fabs(xj) > nx:
                nx = fabs(xj)
        step[0] = nd
        size[0] = nx

    # -- the Engine's building block that reads the blocks ----------------------------
    cdef int nonfinite_input(self, const double *q, const double *v, int flags) noexcept nogil:
        cdef int n = self.n, m = self.m
        if q != NULL and not finite(q, n): return 1
        if v != NULL and not finite(v, n): return 2
        if flags & ASM_M and not finite(self.Mblk, self.mptr[self.asm.n_el]): return 3
        if flags & ASM_H and not finite(self.asm.a.h, n): return 4
        if flags & ASM_F and not finite(self.asm.a.f, n): return 5
        if flags & ASM_B and not finite(self.Bblk, self.bptr[self.asm.n_el]): return 6
        if flags & ASM_C and not finite(self.asm.a.c, m): return 7
        if flags & ASM_G and not finite(self.asm.a.g, m): return 8
        return 0

