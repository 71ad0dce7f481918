# The table of LAPACK and BLAS routines the C engine calls through (see _solve.pyx).
from ._cengine cimport fcc_lapack

cdef const fcc_lapack *lapack_table() noexcept nogil
