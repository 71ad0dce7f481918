# The Python face of the C engine (engine/fcc_engine.h; see _engine.pyx), shared with
# the wrappers of the events and the integrators.
from ._assemble cimport Assembler
from ._cengine cimport (FCC_AT_CALL, FCC_AT_POSITIONS, FCC_AT_STAGE, FCC_AT_STEP,
                        FCC_AT_VELOCITIES, FCC_ERR_DIVERGED, FCC_ERR_LAPACK,
                        FCC_ERR_NONFINITE_INPUT, FCC_ERR_NONFINITE_RESULT, FCC_ERR_PATTERN,
                        FCC_ERR_SINGULAR, FCC_OK, fcc_engine)

# Error codes and where they happened (fcc_base.h; kept in step with _messages.py).
cdef enum:
    ERR_NONE = FCC_OK
    ERR_SINGULAR = FCC_ERR_SINGULAR
    ERR_LAPACK = FCC_ERR_LAPACK
    ERR_NONFINITE_INPUT = FCC_ERR_NONFINITE_INPUT
    ERR_NONFINITE_RESULT = FCC_ERR_NONFINITE_RESULT
    ERR_DIVERGED = FCC_ERR_DIVERGED
    ERR_PATTERN = FCC_ERR_PATTERN

cdef enum:
    AT_CALL = FCC_AT_CALL
    AT_STAGE = FCC_AT_STAGE
    AT_POSITIONS = FCC_AT_POSITIONS
    AT_VELOCITIES = FCC_AT_VELOCITIES
    AT_STEP = FCC_AT_STEP


cdef class Engine:
    cdef readonly Assembler asm
    cdef fcc_engine c
    cdef bint live

    cdef double[::1] vector(self, object x, str name, bint copy=*)
    cdef dict error_record(self)
    cdef raise_error(self, int where)
