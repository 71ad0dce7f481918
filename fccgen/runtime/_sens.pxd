# The Python face of the engine's forward sensitivities (engine/fcc_sens.h; see _sens.pyx).
from ._cengine cimport fcc_events, fcc_sens


cdef class Sensitivities:
    cdef fcc_sens c
    cdef readonly object dp_module       # keeps the tangent kernels' module alive
    cdef readonly object dP              # np x n_p: the elements' parameters' derivative
    cdef readonly object S0              # np x 2n: the start's sensitivities
    cdef public object records           # records x np x 2n, filled by a run
    cdef public object event_records     # logged events x np: d(time)/dp (events)
    cdef bint live


cdef fcc_sens *sens_state(object sens, long n_records) except? NULL
cdef int sens_events(object sens, fcc_events *ev, long cap) except -1
