# cython: language_level=3
"""Forward sensitivities for the C engine's RK4 (engine/fcc_sens.c): the tangent
kernels of a model's parameter-derivative module (fccgen.sensitivity.build), the
derivative of every element parameter with respect to each design parameter, and the
start's sensitivities; a run (_rk4.simulate_rk4(sens=...)) fills ``records``."""
from cpython.pycapsule cimport PyCapsule_GetPointer

import numpy as np

from ._assemble cimport Assembler
from ._cengine cimport (FCC_ERR_MEMORY, FCC_OK, fcc_dp_table, fcc_events,
                        fcc_sens_events_init, fcc_sens_free, fcc_sens_init, fcc_sens_start)


cdef class Sensitivities:
    """Sensitivities of a run of ``asm``'s model with respect to np design
    parameters: dP (np x n_p) the elements' parameters' derivatives, S0 (np x 2 n_q)
    the start's [dq0/dp; dv0/dp]."""

    def __cinit__(self, Assembler asm, dp_module, dP, S0):
        self.dP = np.ascontiguousarray(dP, dtype=float)
        self.S0 = np.ascontiguousarray(S0, dtype=float)
        n_p_all = asm.model.n_p
        if self.dP.ndim != 2 or self.dP.shape[1] != n_p_all or self.dP.shape[0] < 1:
            raise ValueError(f"dP must be (np >= 1) x {n_p_all}")
        if self.S0.shape != (self.dP.shape[0], 2 * asm.n_q):
            raise ValueError(f"S0 must be {self.dP.shape[0]} x {2 * asm.n_q}")
        self.dp_module = dp_module
        cdef const fcc_dp_table *table = <const fcc_dp_table *>PyCapsule_GetPointer(
            dp_module.table_capsule(), "fccgen.dp_table")
        cdef double[:, ::1] d = self.dP
        rc = fcc_sens_init(&self.c, &asm.model, table, d.shape[0], &d[0, 0])
        if rc == FCC_ERR_MEMORY:
            raise MemoryError("cannot allocate the sensitivities' work arrays")
        if rc != FCC_OK:
            raise ValueError("the parameter-derivative module does not hold this model's "
                             "element classes (build it from the same plan)")
        self.live = True
        self.records = None
        self.event_records = None

    def __dealloc__(self):
        if self.live:
            fcc_sens_free(&self.c)

    @property
    def n_params(self):
        return self.c.np


cdef fcc_sens *sens_state(object sens, long n_records) except? NULL:
    """The C state of a Sensitivities (NULL for None), started at S0, with fresh
    records for n_records records."""
    if sens is None:
        return NULL
    cdef Sensitivities s = <Sensitivities>sens
    s.records = np.zeros((n_records, s.c.np, 2 * s.c.n))
    cdef double[:, :, ::1] rec = s.records
    cdef double[:, ::1] s0 = s.S0
    s.c.out = &rec[0, 0, 0]
    fcc_sens_start(&s.c, &s0[0, 0])
    return &s.c


cdef int sens_events(object sens, fcc_events *ev, long cap) except -1:
    """Carry the sensitivities of ``sens`` through the events ev of a run (cap: the rows
    of its log); ``event_records`` (cap x np) receives d(time)/dp of each logged
    event."""
    cdef Sensitivities s = <Sensitivities>sens
    s.event_records = np.full((max(cap, 1), s.c.np), np.nan)
    cdef double[:, ::1] rec = s.event_records
    if fcc_sens_events_init(&s.c, ev, &rec[0, 0], cap) != FCC_OK:
        raise MemoryError("cannot allocate the sensitivities' event work")
    return 0
