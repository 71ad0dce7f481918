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
