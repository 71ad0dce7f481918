# cython: language_level=3
"""The Python face of the C assembler (engine/fcc_assemble.c): the element kernels of a
generated module bound to a plan's instance data.

The C side holds the constants (fcc_model: classes, coordinate and parameter indices)
and one instance (fcc_assembly: parameters and assembled quantities); this wrapper
checks the arguments, builds both, and hands every quantity to Python as a fresh
array.
"""
from cpython.pycapsule cimport PyCapsule_GetPointer, PyCapsule_IsValid
from libc.string cimport memcpy

import time

import numpy as np

from fccgen.errors import BuildError

from ._cengine cimport (FCC_OK, fcc_assemble, fcc_assembly_free, fcc_assembly_init,
                        fcc_jacobian_size, fcc_jacobian_triplets, fcc_kernel_flags,
                        fcc_model_free, fcc_model_init, fcc_model_set_time_slots,
                        fcc_model, fcc_put_time)
from ._model_table cimport FCC_ABI_VERSION, fcc_element_class, fcc_model_table

CAPSULE_NAME = "fccgen.model_table"
ABI_VERSION = FCC_ABI_VERSION


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


cdef _check_instance(const fcc_model_table *table, int[::1] cof, int[::1] qp,
                    int[::1] qi, int[::1] pp, double[::1] pv, int[::1] be, int n_q):
    """Raise ValueError unless the instance data fits the table (the C side trusts
    its arguments)."""
    cdef int e, j, c, n_el = cof.shape[0]
    cdef const fcc_element_class *k
    if qp.shape[0] != n_el + 1 or pp.shape[0] != n_el + 1:
        raise ValueError("q_ptr and param_ptr need one entry per element plus one")
    if qp[n_el] != qi.shape[0] or pp[n_el] != pv.shape[0]:
        raise ValueError("q_ptr/param_ptr do not end at the lengths of q_idx/params")
    for e in range(n_el):
        c = cof[e]
        if c < 0 or c >= table.n_classes:
            raise ValueError(f"element {e}: class index {c} out of range")
        k = &table.classes[c]
        if qp[e + 1] - qp[e] != k.n_q or pp[e + 1] - pp[e] != k.n_p:
            raise ValueError(f"element {e}: {qp[e + 1] - qp[e]} coordinates and "
                             f"{pp[e + 1] - pp[e]} parameters, its class "
                             f"{(<bytes>k.name).decode()} has {k.n_q} and {k.n_p}")
    for j in range(qi.shape[0]):
        if qi[j] < 0 or qi[j] >= n_q:
            raise ValueError(f"coordinate index {qi[j]} out of range (n_q {n_q})")
    for j in range(be.shape[0]):
        if be[j] < 0 or be[j] >= n_el:
            raise ValueError(f"body {j}: element index {be[j]} out of range")


cdef const int *_ints(int[::1] x):
    return &x[0] if x.shape[0] else NULL


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
        cdef const fcc_model_table *table = _table_of(capsule)
        if structure_hash is not None:
            found = (<bytes>table.structure_hash).decode() \
                if table.structure_hash != NULL else None
            if found != structure_hash:
                raise BuildError(f"the capsule's structure hash {found!r} differs from "
                                 f"the module's STRUCTURE_HASH {structure_hash!r}")
        names = list(class_names)
        sizes = np.asarray(class_sizes, dtype=np.intc)
        if table.n_classes != len(names):
            raise BuildError(f"the kernel module has {table.n_classes} element "
                             f"classes, the model's plan has {len(names)}; regenerate it")
        cdef int i
        cdef const fcc_element_class *k
        for i in range(table.n_classes):
            k = &table.classes[i]
            _check_class(i, k.name.decode(), k.n_q, k.n_p, k.n_g, names[i], sizes[i])
        cdef int[::1] cof = np.ascontiguousarray(class_of, dtype=np.intc)
        cdef int[::1] qp = np.ascontiguousarray(q_ptr, dtype=np.intc)
        cdef int[::1] qi = np.ascontiguousarray(q_idx, dtype=np.intc)
        cdef int[::1] pp = np.ascontiguousarray(param_ptr, dtype=np.intc)
        cdef double[::1] pv = np.ascontiguousarray(params, dtype=float)
        cdef int[::1] be = np.ascontiguousarray(body_elements, dtype=np.intc)
        _check_instance(table, cof, qp, qi, pp, pv, be, n_q)
        if fcc_model_init(&self.model, table, n_q, cof.shape[0], _ints(cof), &qp[0],
                          _ints(qi), &pp[0], be.shape[0], _ints(be), 0, NULL) != FCC_OK:
            raise MemoryError("cannot allocate the assembly buffers")
        if fcc_assembly_init(&self.a, &self.model,
                             &pv[0] if pv.shape[0] else NULL) != FCC_OK:
            fcc_model_free(&self.model)
            raise MemoryError("cannot allocate the assembly buffers")
        self.live = True
        self.n_q = n_q
        self.n_el = self.model.n_el
        self.n_g = self.model.n_g
        self.n_bodies = self.model.n_bodies

    def __dealloc__(self):
        if self.live:
            fcc_assembly_free(&self.a)
            fcc_model_free(&self.model)

    def instance_arrays(self):
        """The arguments of fcc_model_init and fcc_assembly_init this assembler was
        built from (class_of, q_ptr, q_idx, param_ptr, params, n_q, body_elements,
        time_slots), as fresh arrays: what another instance of the engine is built
        from. params holds the time last written into the time slots."""
        cdef int e, j, n_el = self.model.n_el
        cdef const fcc_model *m = &self.model
        return dict(
            class_of=np.array([<int>(m.cls[e] - m.table.classes) for e in range(n_el)],
                              dtype=np.intc),
            q_ptr=np.array([m.qptr[e] for e in range(n_el + 1)], dtype=np.intc),
            q_idx=np.array([m.qidx[j] for j in range(m.qptr[n_el])], dtype=np.intc),
            param_ptr=np.array([m.pptr[e] for e in range(n_el + 1)], dtype=np.intc),
            params=np.array([self.a.params[j] for j in range(m.n_p)], dtype=float),
            n_q=m.n_q,
            body_elements=np.array([e for e in range(n_el) if m.body_of[e] >= 0],
                                   dtype=np.intc)[np.argsort(
                                       [m.body_of[e] for e in range(n_el)
                                        if m.body_of[e] >= 0], kind="stable")],
            time_slots=np.array([m.time_slot[j] for j in range(m.n_time)], dtype=np.intc))

    # -- time ----------------------------------------------------------------------
    def set_time_slots(self, slots):
        """The indices into the concatenated parameters of every parameter named "t"
        (classes whose equations depend on the time); set_time writes t there."""
        cdef int[::1] s = np.ascontiguousarray(slots, dtype=np.intc)
        cdef int j, n_p = self.model.n_p
        for j in range(s.shape[0]):
            if s[j] < 0 or s[j] >= n_p:
                raise ValueError(f"time slot {s[j]} out of range (parameters {n_p})")
        if fcc_model_set_time_slots(&self.model, s.shape[0], _ints(s)) != FCC_OK:
            raise MemoryError("cannot allocate the time slots")
        fcc_put_time(&self.a, self.a.t)

    def put_params(self, slots, values):
        """Write values[i] into the concatenated parameters at slots[i] (the model's
        inputs, fccgen.runtime.inputs): later assemblies read them."""
        cdef int[::1] s = np.ascontiguousarray(slots, dtype=np.intc)
        cdef double[::1] x = np.ascontiguousarray(values, dtype=float)
        cdef int j
        if s.shape[0] != x.shape[0]:
            raise ValueError("need one value per slot")
        for j in range(s.shape[0]):
            if s[j] < 0 or s[j] >= self.model.n_p:
                raise ValueError(f"parameter slot {s[j]} out of range ({self.model.n_p})")
        for j in range(s.shape[0]):
            self.a.params[s[j]] = x[j]

    def set_time(self, double t):
        """Evaluate every later assembly at the time t (see set_time_slots)."""
        fcc_put_time(&self.a, t)

    @property
    def t(self):
        return self.a.t

    @property
    def n_time(self):
        return self.model.n_time

    # -- Python access: every array returned is a fresh copy ------------------------
    def quantity(self, int flag, q, v=None):
        """One assembled quantity (flag: one ASM_* bit) at (q, v), as a fresh array;
        energy as (kinetic, potential)."""
        cdef double[::1] qv = self._state(q, "q")
        cdef double[::1] vv = self._state(v, "v") if v is not None else None
        with nogil:
            fcc_assemble(&self.a, &qv[0] if self.n_q else self.a.zeros,
                         &vv[0] if vv is not None and self.n_q else NULL, flag)
        cdef int N = self.n_q
        if flag == ASM_M: return _copy(self.a.M, N * N, (N, N))
        if flag == ASM_H: return _copy(self.a.h, N, (N,))
        if flag == ASM_F: return _copy(self.a.f, N, (N,))
        if flag == ASM_G: return _copy(self.a.g, self.n_g, (self.n_g,))
        if flag == ASM_B: return _copy(self.a.B, self.n_g * N, (self.n_g, N))
        if flag == ASM_C: return _copy(self.a.c, self.n_g, (self.n_g,))
        if flag == ASM_E: return self.a.energy[0], self.a.energy[1]
        if flag == ASM_BODY: return _copy(self.a.body, 6 * self.n_bodies, (self.n_bodies, 6))
        if flag == ASM_KQ: return _copy(self.a.fq, N * N, (N, N))
        if flag == ASM_KV: return _copy(self.a.fv, N * N, (N, N))
        if flag == ASM_T: return _copy(self.a.gt, self.n_g, (self.n_g,))
        raise ValueError(f"flag {flag} names no single quantity")

    def jacobian_triplets(self, q):
        """(rows, columns, values) of the constraint Jacobian B at q, one triplet per
        entry of each element's block (a coordinate shared by elements repeats: a COO
        matrix sums the repeats), without the dense n_g x n_q array."""
        cdef double[::1] qv = self._state(q, "q")
        if self.n_q == 0:
            return np.zeros(0, np.intc), np.zeros(0, np.intc), np.zeros(0)
        total = fcc_jacobian_size(&self.model)
        rows = np.empty(total, dtype=np.intc)
        cols = np.empty(total, dtype=np.intc)
        vals = np.empty(total, dtype=float)
        cdef int[::1] rv = rows, cv = cols
        cdef double[::1] vv = vals
        if total:
            with nogil:
                fcc_jacobian_triplets(&self.a, &qv[0], &rv[0], &cv[0], &vv[0])
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
        cdef const double *qp = &qv[0] if self.n_q else self.a.zeros
        cdef const double *vp = &vv[0] if self.n_q else self.a.zeros
        t0 = time.perf_counter()
        with nogil:
            for i in range(batch):
                fcc_assemble(&self.a, qp, vp, flags)
        return time.perf_counter() - t0

    def kernel_flags(self):
        """{kernel name: flag} of the kernels that at least one element's class has."""
        cdef int present = fcc_kernel_flags(&self.model)
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
