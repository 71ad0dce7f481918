# cython: language_level=3
"""The work of the forces that have no potential, integrated by the steps' own
quadrature, so that the energy check holds for models that exchange energy
(fccgen/runs/energy_check.py, docs/reliability.md "Energy").

The C engine computes the stage powers and adds them up in its integrators
(engine/fcc_work.c says how); this wrapper sets up its fcc_power from a second
Assembler of the same kernels over the elements whose forces have no potential (or
part of one: damped springs, with their stiffness set to zero), and hands the powers
to loops that step in Python (fccgen.runs.scipy_ivp).
"""
import numpy as np

from ._cengine cimport (FCC_ERR_ARGUMENT, FCC_OK, fcc_power_fits, fcc_power_free,
                        fcc_power_init, fcc_stage_power)
from ._engine cimport Engine


cdef class WorkTracker:
    """The numbers of fcc_stage_power for one model: the Assembler ``nc`` of the
    elements with forces without potential, the engine's parameter behind each of its
    parameters (src), those to zero in it (zero), and for driven models the
    constraint forces' power (n: the coordinates; sparse: the engine's path)."""

    def __cinit__(self, Assembler nc, src, zero, bint constraints, bint sparse=False,
                  int n=0):
        cdef int[::1] s = np.ascontiguousarray(src, dtype=np.intc).reshape(-1)
        cdef int[::1] z = np.ascontiguousarray(zero, dtype=np.intc).reshape(-1)
        if s.shape[0] != nc.a.model.n_p:
            raise ValueError("need the engine's index of every parameter of nc")
        if n != nc.n_q:
            raise ValueError(f"nc has {nc.n_q} coordinates, not {n}")
        self.nc = nc
        self.sparse = sparse
        rc = fcc_power_init(&self.c, &nc.a, n, &s[0] if s.shape[0] else NULL,
                            z.shape[0], &z[0] if z.shape[0] else NULL, constraints)
        if rc == FCC_ERR_ARGUMENT:
            raise ValueError(f"a parameter slot to zero is out of range: {list(zero)}")
        if rc != FCC_OK:
            raise MemoryError("cannot allocate the work tracker")
        self.live = True

    def __dealloc__(self):
        if self.live:
            fcc_power_free(&self.c)

    def fits(self, Engine engine):
        """Raise ValueError unless the tracker fits the engine (parameters, path)."""
        if fcc_power_fits(&self.c, &engine.c) != FCC_OK:
            raise ValueError("the tracker does not fit this engine's parameters")
        if self.sparse != bool(engine.c.sparse):
            raise ValueError("the tracker is for the other linear-solver path")
        return None

    def power(self, Engine engine, q, v, a):
        """P at (q, v) with accelerations a that the engine solved at (q, v) just before
        (its M, h and f are still assembled there)."""
        cdef double[::1] qv = np.ascontiguousarray(q, float)
        cdef double[::1] vv = np.ascontiguousarray(v, float)
        cdef double[::1] av = np.ascontiguousarray(a, float)
        if not (qv.shape[0] == vv.shape[0] == av.shape[0] == engine.c.n):
            raise ValueError(f"q, v and a must hold {engine.c.n} numbers")
        self.fits(engine)
        if engine.c.n == 0:
            return 0.0
        return fcc_stage_power(&engine.c, &self.c, &qv[0], &vv[0], &av[0])


cdef fcc_power *power_state(object tracker) except? NULL:
    """The C state of a WorkTracker (NULL for None)."""
    if tracker is None:
        return NULL
    return &(<WorkTracker>tracker).c
