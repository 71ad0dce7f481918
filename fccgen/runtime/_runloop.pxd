# What every integrator wrapper (_rk4, _dopri5, _ali3p) shares: the wall clock for
# pauses, given to the C loops as their pause callback. Inline only: no module of its
# own.
from posix.time cimport CLOCK_MONOTONIC, clock_gettime, timespec


cdef inline double now() noexcept nogil:
    """Monotonic wall-clock seconds."""
    cdef timespec ts
    clock_gettime(CLOCK_MONOTONIC, &ts)
    return ts.tv_sec + 1e-9 * ts.tv_nsec


cdef inline int past_deadline(void *deadline) noexcept nogil:
    """The C loops' pause callback: the wall clock is at or past *deadline (seconds of
    now()), time to leave the nogil loop for signals and progress."""
    return now() >= (<double *>deadline)[0]


cdef inline double *array_data(object array):
    """Pointer to the data of a C-contiguous float64 array (NULL if empty)."""
    cdef double[::1] flat = array.reshape(-1)
    return &flat[0] if flat.shape[0] else NULL
