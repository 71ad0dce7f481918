# The Python face of the C engine's events (engine/fcc_events.h; see _events.pyx).
from ._cengine cimport fcc_event_spec, fcc_events


cdef class EventSet:
    cdef fcc_event_spec spec
    cdef fcc_events c
    cdef bint live
    cdef object module
    cdef readonly object names
    cdef object mirrored          # the Assembler whose parameters hold the copies
    cdef bint was_folded          # the last run folded its rows (to its end)


cdef fcc_events *ev_state(object events) except? NULL
