# cython: language_level=3
"""Assembly of the global quantities from a generated module's element kernels.

Each element gathers its local coordinates and speeds from the global ones, calls its
class's kernels (a NULL kernel is identically zero and skipped; a kernel writes every
entry of its output, fccgen_model.h) and scatters the results: M, h, f and the force
Jacobians df/dq, df/dq' are sums of element blocks; g, B and the constraint bias hold one row per constraint equation, in
element order. All buffers are allocated once.
"""
from cpython.pycapsule cimport PyCapsule_GetPointer, PyCapsule_IsValid
from libc.math cimport fabs, sqrt
from libc.stdlib cimport calloc, free
from libc.string cimport memcpy, memset

import time

import numpy as np

from fccgen.errors import BuildError

from ._model_table cimport FCC_ABI_VERSION, fcc_element_class, fcc_model_table

CAPSULE_NAME = "fccgen.model_table"
ABI_VERSION = FCC_ABI_VERSION


cdef void *_alloc(size_t n, size_t size) except NULL:
    cdef void *p = calloc(n if n > 0 else 1, size)
    if p == NULL:
        raise MemoryError("cannot allocate the assembly buffers")
    return p


cdef const fcc_model_table *_table_of(object capsule) except NULL:
    """The table inside a generated module's capsule, after checking name and ABI."""
    if not PyCapsule_IsValid(capsule, b"fccgen.model_table"):
        raise BuildError(f"expected a PyCapsule named {CAPSULE_NAME!r} (from a generated "
                         f"module's table_capsule()), got {capsule!r}")
    cdef const fcc_model_table *t = <const fcc_model_table *>PyCapsule_GetPointer(
        capsule, b"fccgen.model_table")
    if t.abi_version != FCC_ABI_VERSION:
        raise BuildError(f"the kernel module was built for runtime ABI version "
                         f"{t.abi_version}, this runtime has version {FCC_ABI_VERSION}; "
                         "regenerate the module")
    return t


def _check_class(i, name, n_q, n_p, n_g, want_name, want_sizes):
    """Raise BuildError unless class i of the module is the plan's class i."""
    got = (name, n_q, n_p, n_g)
    want = (want_name, *(int(x) for x in want_sizes))
    if got != want:
        raise BuildError(
            f"the kernel module does not match the model's plan: class {i} is "
            f"{got[0]} (n_q {got[1]}, n_p {got[2]}, n_g {got[3]}), the plan has "
            f"{want[0]} (n_q {want[1]}, n_p {want[2]}, n_g {want[3]}); "
            "regenerate the module")


cdef class Assembler:
    """Instance data of a plan bound to a generated module's kernels.

    capsule: the module's ``table_capsule()``; class_names, class_sizes ((n_classes, 3):
    n_q, n_p, n_g): the plan's classes, checked against the module's; class_of: class
    index per element; q_ptr/q_idx and param_ptr/params: each element's global coordinate
    indices and parameters, concatenated (CSR style); body_elements: element index of
    each body (order of the body outputs).
    """

    def __cinit__(self, capsule, class_names, class_sizes, class_of, q_ptr, q_idx,
                  param_ptr, params, int n_q, body_elements, structure_hash=None,
                  owner=None):
        self.owner = owner
        self.table = _table_of(capsule)
        if structure_hash is not None:
            found = (<bytes>self.table.structure_hash).decode() \
                if self.table.structure_hash != NULL else None
            if found != structure_hash:
                raise BuildError(f"the capsule's structure hash {found!r} differs from "
                                 f"the module's STRUCTURE_HASH {structure_hash!r}")
        self._check_classes(list(class_names), np.asarray(class_sizes, dtype=np.intc))
        cdef int[::1] cof = np.ascontiguousarray(class_of, dtype=np.intc)
        cdef int[::1] qp = np.ascontiguousarray(q_ptr, dtype=np.intc)
        cdef int[::1] qi = np.ascontiguousarray(q_idx, dtype=np.intc)
        cdef int[::1] pp = np.ascontiguousarray(param_ptr, dtype=np.intc)
        cdef double[::1] pv = np.ascontiguousarray(params, dtype=float)
        cdef int[::1] be = np.ascontiguousarray(body_elements, dtype=np.intc)
        self.n_q = n_q
        self.n_el = cof.shape[0]
        self.n_bodies = be.shape[0]
        if qp.shape[0] != self.n_el + 1 or pp.shape[0] != self.n_el + 1:
            raise ValueError("q_ptr and param_ptr need one entry per element plus one")
        if qp[self.n_el] != qi.shape[0] or pp[self.n_el] != pv.shape[0]:
            raise ValueError("q_ptr/param_ptr do not end at the lengths of q_idx/params")
        self._copy_instance(cof, qp, qi, pp, pv, be)
        self._allocate()

    cdef _check_classes(self, list names, object sizes):
        cdef const fcc_element_class *k
        cdef int i
        if self.table.n_classes != len(names):
            raise BuildError(f"the kernel module has {self.table.n_classes} element "
                             f"classes, the model's plan has {len(names)}; regenerate it")
        for i in range(self.table.n_classes):
            k = &self.table.classes[i]
            _check_class(i, k.name.decode(), k.n_q, k.n_p, k.n_g, names[i], sizes[i])

    cdef _copy_instance(self, int[::1] cof, int[::1] qp, int[::1] qi, int[::1] pp,
                        double[::1] pv, int[::1] be):
        cdef int e, j, c
        cdef const fcc_element_class *k
        self.cls = <const fcc_element_class **>_alloc(self.n_el, sizeof(void *))
        self.qptr = <int *>_alloc(self.n_el + 1, sizeof(int))
        self.qidx = <int *>_alloc(qi.shape[0], sizeof(int))
        self.pptr = <int *>_alloc(self.n_el + 1, sizeof(int))
        self.params = <double *>_alloc(pv.shape[0], sizeof(double))
        self.gptr = <int *>_alloc(self.n_el + 1, sizeof(int))
        self.body_of = <int *>_alloc(self.n_el, sizeof(int))
        for e in range(self.n_el):
            c = cof[e]
            if c < 0 or c >= self.table.n_classes:
                raise ValueError(f"element {e}: class index {c} out of range")
            k = &self.table.classes[c]
            self.cls[e] = k
            if qp[e + 1] - qp[e] != k.n_q or pp[e + 1] - pp[e] != k.n_p:
                raise ValueError(f"element {e}: {qp[e + 1] - qp[e]} coordinates and "
                                 f"{pp[e + 1] - pp[e]} parameters, its class "
                                 f"{(<bytes>k.name).decode()} has {k.n_q} and {k.n_p}")
            self.gptr[e + 1] = self.gptr[e] + k.n_g
            self.body_of[e] = -1
        self.n_g = self.gptr[self.n_el]
        for e in range(self.n_el + 1):
            self.qptr[e] = qp[e]
            self.pptr[e] = pp[e]
        for j in range(qi.shape[0]):
            if qi[j] < 0 or qi[j] >= self.n_q:
                raise ValueError(f"coordinate index {qi[j]} out of range (n_q {self.n_q})")
            self.qidx[j] = qi[j]
        for j in range(pv.shape[0]):
            self.params[j] = pv[j]
        for j in range(be.shape[0]):
            if be[j] < 0 or be[j] >= self.n_el:
                raise ValueError(f"body {j}: element index {be[j]} out of range")
            self.body_of[be[j]] = j

    cdef _allocate(self):
        cdef int e, size, biggest = 6, local = 1
        cdef const fcc_element_class *k
        for e in range(self.n_el):
            k = self.cls[e]
            size = max(k.n_q * k.n_q, k.n_g * k.n_q, k.n_q, k.n_g)
            biggest = max(biggest, size)
            local = max(local, k.n_q)    # may exceed n_q: a triple can appear twice
        cdef size_t n = self.n_q
        self.out = <double *>_alloc(biggest, sizeof(double))
        self.lq = <double *>_alloc(local, sizeof(double))
        self.lv = <double *>_alloc(local, sizeof(double))
        self.zeros = <double *>_alloc(n, sizeof(double))
        self.M = <double *>_alloc(n * n, sizeof(double))
        self.h = <double *>_alloc(n, sizeof(double))
        self.f = <double *>_alloc(n, sizeof(double))
        self.g = <double *>_alloc(self.n_g, sizeof(double))
        self.B = <double *>_alloc(<size_t>self.n_g * n, sizeof(double))
        self.c = <double *>_alloc(self.n_g, sizeof(double))
        self.body = <double *>_alloc(6 * self.n_bodies, sizeof(double))
        self.fq = <double *>_alloc(n * n, sizeof(double))
        self.fv = <double *>_alloc(n * n, sizeof(double))
        self.gt = <double *>_alloc(self.n_g, sizeof(double))
        self.time_slot = <int *>_alloc(1, sizeof(int))

    def __dealloc__(self):
        free(self.cls); free(self.qptr); free(self.qidx); free(self.pptr)
        free(self.params); free(self.gptr); free(self.body_of); free(self.out)
        free(self.lq); free(self.lv); free(self.zeros); free(self.M); free(self.h)
        free(self.f); free(self.g); free(self.B); free(self.c); free(self.body)
        free(self.fq); free(self.fv); free(self.gt); free(self.time_slot)

    cdef void assemble(self, const double *q, const double *v, int flags) noexcept nogil:
        """Assemble the quantities named by ``flags`` (ASM_*) at (q, v); v may be NULL
        when only kernels of q are asked for."""
        cdef int e, i, j, n, r, n_g, N = self.n_q, row
        cdef const fcc_element_class *k
        cdef const int *idx
        cdef const double *p
        cdef double *o = self.out
        if v == NULL:
            v = self.zeros
        if flags & ASM_M: memset(self.M, 0, <size_t>N * N * sizeof(double))
        if flags & ASM_H: memset(self.h, 0, <size_t>N * sizeof(double))
        if flags & ASM_F: memset(self.f, 0, <size_t>N * sizeof(double))
        if flags & ASM_G: memset(self.g, 0, <size_t>self.n_g * sizeof(double))
        if flags & ASM_B: memset(self.B, 0, <size_t>self.n_g * N * sizeof(double))
        if flags & ASM_C: memset(self.c, 0, <size_t>self.n_g * sizeof(double))
        if flags & ASM_E: self.energy[0] = 0.0; self.energy[1] = 0.0
        if flags & ASM_BODY: memset(self.body, 0, <size_t>self.n_bodies * 6 * sizeof(double))
        if flags & ASM_KQ: memset(self.fq, 0, <size_t>N * N * sizeof(double))
        if flags & ASM_KV: memset(self.fv, 0, <size_t>N * N * sizeof(double))
        if flags & ASM_T: memset(self.gt, 0, <size_t>self.n_g * sizeof(double))
        for e in range(self.n_el):
            k = self.cls[e]
            n = k.n_q
            n_g = k.n_g
            idx = self.qidx + self.qptr[e]
            p = self.params + self.pptr[e]
            row = self.gptr[e]
            for i in range(n):
                self.lq[i] = q[idx[i]]
                self.lv[i] = v[idx[i]]
            if flags & ASM_M and k.mass_matrix != NULL:
                k.mass_matrix(self.lq, p, o)
                for i in range(n):
                    for j in range(n):
                        self.M[idx[i] * N + idx[j]] += o[i * n + j]
            element_vectors(k, self.lq, self.lv, p, idx, row, flags & (ASM_H | ASM_F),
                            o, self.h, self.f, self.c)
            if flags & ASM_G and k.constraints != NULL:
                k.constraints(self.lq, p, o)
                for r in range(n_g):
                    self.g[row + r] = o[r]
            if flags & ASM_B and k.constraint_jacobian != NULL:
                k.constraint_jacobian(self.lq, p, o)
                for r in range(n_g):
                    for j in range(n):
                        self.B[(row + r) * N + idx[j]] += o[r * n + j]
            element_vectors(k, self.lq, self.lv, p, idx, row, flags & ASM_C, o, self.h,
                            self.f, self.c)
            if flags & ASM_E and k.energy != NULL:
                k.energy(self.lq, self.lv, p, o)
                self.energy[0] += o[0]
                self.energy[1] += o[1]
            if flags & ASM_BODY and k.body_outputs != NULL and self.body_of[e] >= 0:
                k.body_outputs(self.lq, self.lv, p, o)
                for i in range(6):
                    self.body[6 * self.body_of[e] + i] = o[i]
            if flags & ASM_KQ and k.force_jacobian_q != NULL:
                k.force_jacobian_q(self.lq, self.lv, p, o)
                for i in range(n):
                    for j in range(n):
                        self.fq[idx[i] * N + idx[j]] += o[i * n + j]
            if flags & ASM_KV and k.force_jacobian_v != NULL:
                k.force_jacobian_v(self.lq, p, o)
                for i in range(n):
                    for j in range(n):
                        self.fv[idx[i] * N + idx[j]] += o[i * n + j]
            if flags & ASM_T and k.constraint_rate != NULL:
                k.constraint_rate(self.lq, p, o)
                for r in range(n_g):
                    self.gt[row + r] = o[r]

    # -- time ----------------------------------------------------------------------
    def set_time_slots(self, slots):
        """The indices into the concatenated parameters of every parameter named "t"
        (classes whose equations depend on the time); set_time writes t there."""
        cdef int[::1] s = np.ascontiguousarray(slots, dtype=np.intc)
        cdef int j, n_p = self.pptr[self.n_el]
        for j in range(s.shape[0]):
            if s[j] < 0 or s[j] >= n_p:
                raise ValueError(f"time slot {s[j]} out of range (parameters {n_p})")
        free(self.time_slot)
        self.time_slot = <int *>_alloc(s.shape[0], sizeof(int))
        for j in range(s.shape[0]):
            self.time_slot[j] = s[j]
        self.n_time = s.shape[0]
        self.put_time(self.t)

    cdef void put_time(self, double t) noexcept nogil:
        """Write the time t into every time slot (the kernels then evaluate at t)."""
        cdef int j
        self.t = t
        for j in range(self.n_time):
            self.params[self.time_slot[j]] = t

    def set_time(self, double t):
        """Evaluate every later assembly at the time t (see set_time_slots)."""
        self.put_time(t)

    cdef double scaled_residual(self) noexcept nogil:
        """max_k |g_k| / ||B_k|| of the assembled g and B (|g_k| for a zero row);
        NaN if any g_k is not finite."""
        cdef int k, j, N = self.n_q
        cdef double worst = 0.0, norm, val
        for k in range(self.n_g):
            norm = 0.0
            for j in range(N):
                norm += self.B[k * N + j] * self.B[k * N + j]
            val = fabs(self.g[k])
            if norm > 0.0:
                val /= sqrt(norm)
            if not val <= worst:          # larger, or NaN (kept as NaN)
                worst = val
                if val != val:
                    return val
        return worst

    cdef double max_abs_g(self) noexcept nogil:
        cdef int k
        cdef double worst = 0.0
        for k in range(self.n_g):
            if not fabs(self.g[k]) <= worst:
                worst = fabs(self.g[k])
                if worst != worst:
                    return worst
        return worst

    # -- Python access: every array returned is a fresh copy ------------------------
    def quantity(self, int flag, q, v=None):
        """One assembled quantity (flag: one ASM_* bit) at (q, v), as a fresh array;
        energy as (kinetic, potential)."""
        cdef double[::1] qv = self._state(q, "q")
        cdef double[::1] vv = self._state(v, "v") if v is not None else None
        with nogil:
            self.assemble(&qv[0] if self.n_q else self.zeros,
                          &vv[0] if vv is not None and self.n_q else NULL, flag)
        cdef int N = self.n_q
        if flag == ASM_M: return _copy(self.M, N * N, (N, N))
        if flag == ASM_H: return _copy(self.h, N, (N,))
        if flag == ASM_F: return _copy(self.f, N, (N,))
        if flag == ASM_G: return _copy(self.g, self.n_g, (self.n_g,))
        if flag == ASM_B: return _copy(self.B, self.n_g * N, (self.n_g, N))
        if flag == ASM_C: return _copy(self.c, self.n_g, (self.n_g,))
        if flag == ASM_E: return self.energy[0], self.energy[1]
        if flag == ASM_BODY: return _copy(self.body, 6 * self.n_bodies, (self.n_bodies, 6))
        if flag == ASM_KQ: return _copy(self.fq, N * N, (N, N))
        if flag == ASM_KV: return _copy(self.fv, N * N, (N, N))
        if flag == ASM_T: return _copy(self.gt, self.n_g, (self.n_g,))
        raise ValueError(f"flag {flag} names no single quantity")

    def jacobian_triplets(self, q):
        """(rows, columns, values) of the constraint Jacobian B at q, one triplet per
        entry of each element's block (a coordinate shared by elements repeats: a COO
        matrix sums the repeats), without the dense n_g x n_q array."""
        cdef double[::1] qv = self._state(q, "q")
        cdef int e, i, r, n, n_g, total = 0, at = 0
        cdef const fcc_element_class *k
        if self.n_q == 0:
            return np.zeros(0, np.intc), np.zeros(0, np.intc), np.zeros(0)
        for e in range(self.n_el):
            k = self.cls[e]
            if k.constraint_jacobian != NULL:
                total += k.n_g * k.n_q
        rows = np.empty(total, dtype=np.intc)
        cols = np.empty(total, dtype=np.intc)
        vals = np.empty(total, dtype=float)
        cdef int[::1] rv = rows, cv = cols
        cdef double[::1] vv = vals
        cdef const int *idx
        with nogil:
            for e in range(self.n_el):
                k = self.cls[e]
                if k.constraint_jacobian == NULL:
                    continue
                n, n_g, idx = k.n_q, k.n_g, self.qidx + self.qptr[e]
                for i in range(n):
                    self.lq[i] = qv[idx[i]]
                k.constraint_jacobian(self.lq, self.params + self.pptr[e], self.out)
                for r in range(n_g):
                    for i in range(n):
                        rv[at] = self.gptr[e] + r
                        cv[at] = idx[i]
                        vv[at] = self.out[r * n + i]
                        at += 1
        return rows, cols, vals

    cdef double[::1] _state(self, object x, str name):
        a = np.ascontiguousarray(x, dtype=float)          # read only: no copy needed
        if not a.flags.writeable:                         # typed views need writeable
            a = a.copy()
        if a.shape != (self.n_q,):
            raise ValueError(f"{name} must have shape ({self.n_q},), got {a.shape}")
        if self.n_q == 0:
            return None
        return a

    def time_assembly(self, int flags, q, v, long batch):
        """Seconds taken by ``batch`` assemblies of ``flags`` at (q, v), in one compiled
        loop (for benchmarks)."""
        cdef double[::1] qv = self._state(q, "q")
        cdef double[::1] vv = self._state(v, "v")
        cdef long i
        cdef const double *qp = &qv[0] if self.n_q else self.zeros
        cdef const double *vp = &vv[0] if self.n_q else self.zeros
        t0 = time.perf_counter()
        with nogil:
            for i in range(batch):
                self.assemble(qp, vp, flags)
        return time.perf_counter() - t0

    def kernel_flags(self):
        """{kernel name: flag} of the kernels that at least one element's class has."""
        cdef int e, present = 0
        cdef const fcc_element_class *k
        for e in range(self.n_el):
            k = self.cls[e]
            present |= ((ASM_M if k.mass_matrix != NULL else 0)
                        | (ASM_H if k.h_vector != NULL else 0)
                        | (ASM_F if k.applied_forces != NULL else 0)
                        | (ASM_G if k.constraints != NULL else 0)
                        | (ASM_B if k.constraint_jacobian != NULL else 0)
                        | (ASM_C if k.constraint_bias != NULL else 0)
                        | (ASM_E if k.energy != NULL else 0)
                        | (ASM_BODY if k.body_outputs != NULL and self.body_of[e] >= 0
                           else 0)
                        | (ASM_KQ if k.force_jacobian_q != NULL else 0)
                        | (ASM_KV if k.force_jacobian_v != NULL else 0)
                        | (ASM_T if k.constraint_rate != NULL else 0))
        return {name: flag for name, flag in FLAGS.items() if present & flag}


cdef object _copy(const double *src, Py_ssize_t n, tuple shape):
    """A fresh array of the given shape holding src[:n]."""
    out = np.empty(shape)
    cdef double[::1] o = out.reshape(-1)
    if n:
        memcpy(&o[0], src, n * sizeof(double))
    return out


FLAGS = {"mass_matrix": ASM_M, "h_vector": ASM_H, "applied_forces": ASM_F,
         "constraints": ASM_G, "constraint_jacobian": ASM_B, "constraint_bias": ASM_C,
         "energy": ASM_E, "body_outputs": ASM_BODY, "force_jacobian_q": ASM_KQ,
         "force_jacobian_v": ASM_KV, "constraint_rate": ASM_T}
