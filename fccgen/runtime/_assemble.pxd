# Assembly of the global quantities from the element kernels (see _assemble.pyx).
from ._model_table cimport fcc_element_class, fcc_model_table

# What to assemble: a bit mask.
cdef enum:
    ASM_M = 1          # mass matrix M (n_q x n_q)
    ASM_H = 2          # inertia terms h
    ASM_F = 4          # applied forces f
    ASM_G = 8          # constraints g
    ASM_B = 16         # constraint Jacobian B (n_g x n_q, rows in element order)
    ASM_C = 32         # constraint bias (dB/dt) v
    ASM_E = 64         # energy [kinetic, potential]
    ASM_BODY = 128     # body outputs, 6 per body
    ASM_KQ = 256       # df/dq of the applied forces (n_q x n_q); stiffness K = -df/dq
    ASM_KV = 512       # df/dq' of the applied forces (n_q x n_q); damping C = -df/dq'
    ASM_T = 1024       # partial dg/dt of the constraints (rheonomic rows, else 0)


cdef class Assembler:
    cdef readonly int n_q, n_g, n_el, n_bodies
    cdef readonly object owner           # keeps the kernels' module alive
    cdef const fcc_model_table *table
    cdef const fcc_element_class **cls   # per element
    cdef int *qptr                       # per element: start in qidx (n_el + 1)
    cdef int *qidx                       # global coordinate index of each local one
    cdef int *pptr                       # per element: start in params (n_el + 1)
    cdef double *params
    cdef int *gptr                       # per element: first constraint row (n_el + 1)
    cdef int *body_of                    # per element: body index or -1
    cdef double *lq                      # gathered local q, v and kernel output
    cdef double *lv
    cdef double *out
    cdef double *zeros                   # n_q zeros: v for kernels of q alone
    # assembled quantities
    cdef double *M
    cdef double *h
    cdef double *f
    cdef double *g
    cdef double *B
    cdef double *c
    cdef double energy[2]
    cdef double *body
    cdef double *fq                      # df/dq
    cdef double *fv                      # df/dq'
    cdef double *gt                      # partial dg/dt
    # time: the parameter slots named "t" (set_time writes t into each)
    cdef readonly double t
    cdef readonly int n_time
    cdef int *time_slot

    cdef _check_classes(self, list names, object sizes)
    cdef _copy_instance(self, int[::1] cof, int[::1] qp, int[::1] qi, int[::1] pp,
                        double[::1] pv, int[::1] be)
    cdef _allocate(self)
    cdef double[::1] _state(self, object x, str name)
    cdef void assemble(self, const double *q, const double *v, int flags) noexcept nogil
    cdef double scaled_residual(self) noexcept nogil
    cdef double max_abs_g(self) noexcept nogil
    cdef void put_time(self, double t) noexcept nogil


cdef inline void element_vectors(const fcc_element_class *k, const double *lq,
                                 const double *lv, const double *p, const int *idx,
                                 int row, int flags, double *o, double *h, double *f,
                                 double *c) noexcept nogil:
    """One element's h (ASM_H), f (ASM_F) and c (ASM_C) at its gathered (lq, lv),
    added into h and f at its coordinates idx and written into c from its first row;
    o: room for the kernel's output."""
    cdef int i
    if flags & ASM_H and k.h_vector != NULL:
        k.h_vector(lq, lv, p, o)
        for i in range(k.n_q):
            h[idx[i]] += o[i]
    if flags & ASM_F and k.applied_forces != NULL:
        k.applied_forces(lq, lv, p, o)
        for i in range(k.n_q):
            f[idx[i]] += o[i]
    if flags & ASM_C and k.constraint_bias != NULL:
        k.constraint_bias(lq, lv, p, o)
        for i in range(k.n_g):
            c[row + i] = o[i]
