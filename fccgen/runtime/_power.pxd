# The Python face of the C engine's work tracking (engine/fcc_work.h; see _power.pyx).
from ._assemble cimport Assembler
from ._cengine cimport fcc_power


cdef class WorkTracker:
    cdef fcc_power c
    cdef Assembler nc             # owns the subset's assembly the C struct points at
    cdef bint sparse
    cdef bint live


cdef fcc_power *power_state(object tracker) except? NULL
