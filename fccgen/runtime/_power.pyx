# cython: language_level=3
"""The work of the forces that have no potential, integrated by the steps' own
quadrature, so that the energy check holds for models that exchange energy
(fccgen/runtime/energy_check.py, docs/reliability.md "Energy with the work added
back").

Along a motion dE/dt = v . f_nc + (driven models) lambda . dg/dt: the applied forces
without potential (dampers, constant torques, loads of time or of joint quantities)
and the drivers' constraint forces do work; gravity, constant forces and springs do
not change E = T + V. The integrators add the stage powers P_i = stage_power(...)
with their own weights, W += h sum b_i P_i (RK4: 1/6, 1/3, 1/3, 1/6; DOPRI5: its
fifth-order weights, and its continuous extension for the records), so that
E(t) - W(t) + (the impacts' losses) stays E(0) to the integration's own error.

f_nc is the engine's own assembly with the conservative parameters zeroed (the
element parameters swapped for a copy during one assembly of f). The constraint
forces' power is -v . (B^T lambda) = v . (M a + h - f), with M, h, f of the stage
(M dense, or the sparse path's element blocks): exact for the index-1 equations at
any state, and lambda . dg/dt on the constraint manifold.
"""
from libc.stdlib cimport calloc, free

import numpy as np

from ._engine cimport Engine
from ._sparse_blocks cimport SparseBlocks


cdef class WorkTracker:
    """The numbers of stage_power for one model: the element parameters to zero and,
    for driven models, the constraint forces' power (n: the coordinates; sparse: the
    engine takes the sparse path)."""
    cdef Power c

    def __cinit__(self, zero_slots, int n_params, bint constraints, bint sparse=False,
                  int n=0):
        self.c.on = 1
        self.c.n_params = n_params
        self.c.n_zero = len(zero_slots)
        self.c.constraints = constraints
        self.c.sparse = sparse
        self.c.nc = <double *>calloc(n_params + 1, sizeof(double))
        self.c.zero = <int *>calloc(self.c.n_zero + 1, sizeof(int))
        self.c.ma = <double *>calloc(n + 1, sizeof(double))
        if self.c.nc == NULL or self.c.zero == NULL or self.c.ma == NULL:
            raise MemoryError("cannot allocate the work tracker")
        for i, slot in enumerate(zero_slots):
            if not 0 <= slot < n_params:
                raise ValueError(f"parameter slot {slot} out of range")
            self.c.zero[i] = slot

    def __dealloc__(self):
        free(self.c.nc)
        free(self.c.zero)
        free(self.c.ma)

    def power(self, Engine engine, q, v, a):
        """P at (q, v) with accelerations a that the engine solved at (q, v) just before
        (its M, h and f are still assembled there)."""
        cdef double[::1] qv = np.ascontiguousarray(q, float)
        cdef double[::1] vv = np.ascontiguousarray(v, float)
        cdef double[::1] av = np.ascontiguousarray(a, float)
        if not (qv.shape[0] == vv.shape[0] == av.shape[0] == engine.n):
            raise ValueError(f"q, v and a must hold {engine.n} numbers")
        if self.c.n_params != engine.asm.pptr[engine.asm.n_el]:
            raise ValueError("the tracker does not fit this engine's parameters")
        if self.c.sparse != isinstance(engine, SparseBlocks):
            raise ValueError("the tracker is for the other linear-solver path")
        return stage_power(engine, &self.c, &qv[0], &vv[0], &av[0])


cdef Power *power_state(object tracker) except? NULL:
    """The C state of a WorkTracker (NULL for None)."""
    if tracker is None:
        return NULL
    return &(<WorkTracker>tracker).c
