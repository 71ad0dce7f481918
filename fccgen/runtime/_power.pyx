# cython: language_level=3
"""The work of the forces that have no potential, integrated by the steps' own
quadrature, so that the energy check holds for models that exchange energy
(fccgen/runtime/energy_check.py, docs/reliability.md "Energy").

Along a motion dE/dt = v . f_nc + (driven models) lambda . dg/dt: the applied forces
without potential (dampers, constant torques, loads of time or of joint quantities)
and the drivers' constraint forces do work; gravity, constant forces and springs do
not change E = T + V. The integrators add the stage powers P_i = stage_power(...)
with their own weights, W += h sum b_i P_i (RK4: 1/6, 1/3, 1/3, 1/6; DOPRI5: its
fifth-order weights, and its continuous extension for the records), so that
E(t) - W(t) + (the impacts' losses) stays E(0) to the integration's own error.

f_nc is assembled by a second Assembler of the same kernels over the elements whose
forces have no potential (or part of one: damped springs, with their stiffness set to
zero), its parameters copied from the engine's at every stage (the time, the angle
references). The constraint forces' power is -v . (B^T lambda) = v . (M a + h - f),
with M, h, f of the stage (M dense, or the sparse path's element blocks): exact for
the index-1 equations at any state, and lambda . dg/dt on the constraint manifold.
"""
from libc.stdlib cimport calloc, free

import numpy as np

from ._assemble cimport Assembler
from ._engine cimport Engine
from ._sparse_blocks cimport SparseBlocks


cdef class WorkTracker:
    """The numbers of stage_power for one model: the Assembler ``nc`` of the elements
    with forces without potential, the engine's parameter behind each of its
    parameters (src), those to zero in it (zero), and for driven models the
    constraint forces' power (n: the coordinates; sparse: the engine's path)."""
    cdef Power c
    cdef Assembler nc

    def __cinit__(self, Assembler nc, src, zero, bint constraints, bint sparse=False,
                  int n=0):
        cdef int i
        self.nc = nc
        self.c.on = 1
        self.c.nc = <void *>nc
        self.c.n_params = nc.pptr[nc.n_el]
        if len(src) != self.c.n_params:
            raise ValueError("need the engine's index of every parameter of nc")
        self.c.n_zero = len(zero)
        self.c.constraints = constraints
        self.c.sparse = sparse
        self.c.src = <int *>calloc(self.c.n_params + 1, sizeof(int))
        self.c.zero = <int *>calloc(self.c.n_zero + 1, sizeof(int))
        self.c.ma = <double *>calloc(n + 1, sizeof(double))
        if self.c.src == NULL or self.c.zero == NULL or self.c.ma == NULL:
            raise MemoryError("cannot allocate the work tracker")
        for i in range(self.c.n_params):
            self.c.src[i] = src[i]
        for i in range(self.c.n_zero):
            if not 0 <= zero[i] < self.c.n_params:
                raise ValueError(f"parameter slot {zero[i]} out of range")
            self.c.zero[i] = zero[i]

    def __dealloc__(self):
        free(self.c.src)
        free(self.c.zero)
        free(self.c.ma)

    def power(self, Engine engine, q, v, a):
        """P at (q, v) with accelerations a that the engine solved at (q, v) just before
        (its M, h and f are still assembled there)."""
        cdef double[::1] qv = np.ascontiguousarray(q, float)
        cdef double[::1] vv = np.ascontiguousarray(v, float)
        cdef double[::1] av = np.ascontiguousarray(a, float)
        cdef int i, top = engine.asm.pptr[engine.asm.n_el]
        if not (qv.shape[0] == vv.shape[0] == av.shape[0] == engine.n == self.nc.n_q):
            raise ValueError(f"q, v and a must hold {engine.n} numbers")
        for i in range(self.c.n_params):
            if not 0 <= self.c.src[i] < top:
                raise ValueError("the tracker does not fit this engine's parameters")
        if self.c.sparse != isinstance(engine, SparseBlocks):
            raise ValueError("the tracker is for the other linear-solver path")
        return stage_power(engine, &self.c, &qv[0], &vv[0], &av[0])


cdef Power *power_state(object tracker) except? NULL:
    """The C state of a WorkTracker (NULL for None)."""
    if tracker is None:
        return NULL
    return &(<WorkTracker>tracker).c
