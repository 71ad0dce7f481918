# What every compiled integrator (_rk4, _dopri5, _ali3p) shares: run status codes, the
# wall clock for pauses, and writing one output record. Inline only: no module of its own.
from libc.string cimport memcpy
from posix.time cimport CLOCK_MONOTONIC, clock_gettime, timespec

from ._cengine cimport fcc_assemble, fcc_put_time, fcc_max_abs_g, fcc_scaled_residual
from ._assemble cimport ASM_BODY, ASM_E, ASM_G
from ._engine cimport Engine

cdef enum:
    RUN_DONE = 0              # reached the end
    RUN_PAUSE = 1             # left the nogil loop for signals and progress
    RUN_ERROR = -1            # stopped; the engine's error record says why


cdef inline double now() noexcept nogil:
    """Monotonic wall-clock seconds."""
    cdef timespec ts
    clock_gettime(CLOCK_MONOTONIC, &ts)
    return ts.tv_sec + 1e-9 * ts.tv_nsec


cdef inline double write_record(Engine e, Py_ssize_t j, const double *q, const double *v,
                                double *q_out, double *v_out, double *body_out,
                                double *e_out, double *c_out) noexcept nogil:
    """Write record j of the state (q, v): coordinates, speeds, body outputs, energy and
    max |g|; return that max |g|."""
    cdef Py_ssize_t n = e.asm.n_q, nb6 = 6 * e.asm.n_bodies
    fcc_assemble(&e.asm.a, q, v, ASM_G | ASM_E | ASM_BODY)
    memcpy(q_out + j * n, q, n * sizeof(double))
    memcpy(v_out + j * n, v, n * sizeof(double))
    if nb6:
        memcpy(body_out + j * nb6, e.asm.a.body, nb6 * sizeof(double))
    e_out[j] = e.asm.a.energy[0] + e.asm.a.energy[1]
    c_out[j] = fcc_max_abs_g(&e.asm.a)
    return c_out[j]
