# The compiled engine's building blocks (see _engine.pyx), shared with the integrators.
from ._assemble cimport Assembler
from ._solve cimport CSolve

# Error codes and where they happened (kept in step with _messages.py).
cdef enum:
    ERR_NONE = 0
    ERR_SINGULAR = 1          # reduced mass matrix not positive definite
    ERR_LAPACK = 2            # LAPACK argument error (a bug)
    ERR_NONFINITE_INPUT = 3   # a state or assembled quantity is not finite (err_detail)
    ERR_NONFINITE_RESULT = 4  # the solve produced a non-finite result
    ERR_DIVERGED = 5          # the state grew past the run's bound (err_detail: q or v)
    ERR_PATTERN = 6           # sparse path: a block entry zero at the written positions is not

cdef enum:
    AT_CALL = 0               # a direct call
    AT_STAGE = 1              # integrator stage err_stage
    AT_POSITIONS = 2          # position projection
    AT_VELOCITIES = 3         # velocity projection
    AT_STEP = 4               # the state after a step


cdef enum:
    RANK_LOG_SIZE = 64


cdef bint finite(const double *x, Py_ssize_t n) noexcept nogil


cdef class Engine:
    cdef readonly Assembler asm
    cdef CSolve sol
    cdef readonly double position_tol
    cdef readonly int max_newton
    cdef double diverge_residual         # a projection starting above this: diverged
    cdef int n, m
    cdef double *work                    # one block for rhs, nb, dq, vtmp
    cdef double *rhs
    cdef double *nb
    cdef double *dq
    cdef double *vtmp
    cdef int *row_group                  # per constraint row: its element's first row
    cdef double *stages                  # 10 n numbers for an integrator's stages
    cdef bint factor_valid               # sol holds the factorisation of M, B at the state
    cdef bint b_fresh                    # the last position projection left B at its q
    cdef bint running                    # an integrator is using the engine
    # rank decisions: each accepted increase of the decided rank (time, old, new)
    cdef double ke_peak                  # largest kinetic energy met by a velocity projection
    cdef double ke_cut_max               # largest fraction of it one projection removed
    cdef double ke_cut_t                 # ... and when
    cdef int n_rank_log
    cdef double rank_log[RANK_LOG_SIZE][3]
    # error record
    cdef int err, err_info, err_where, err_stage, err_detail
    cdef double err_t, err_h, err_value, err_bound

    cdef int fail(self, int code, int info, int detail) noexcept nogil
    cdef int nonfinite_input(self, const double *q, const double *v, int flags) noexcept nogil
    cdef int factor(self, const double *q) noexcept nogil
    cdef int accelerations_at(self, const double *q, const double *v, double *a,
                              bint reuse) noexcept nogil
    cdef int baumgarte_at(self, const double *q, const double *v, double *a,
                          double alpha, double beta) noexcept nogil
    cdef void assemble_constraints(self, const double *q, int flags) noexcept nogil
    cdef double constraint_residual(self) noexcept nogil
    cdef void solve_constrained(self, const double *Q, const double *w, const double *b,
                                double *x) noexcept nogil
    cdef void solve_newton(self, const double *b, double *x) noexcept nogil
    cdef int project_positions_at(self, double *q, int *iterations,
                                  bint reuse) noexcept nogil
    cdef bint chord_ready(self) noexcept nogil
    cdef int chord_step(self, double *q, double *res) noexcept nogil
    cdef int project_velocities_at(self, const double *q, double *v,
                                   bint have_B) noexcept nogil
    cdef void watch_kinetic_energy(self, const double *v, const double *w) noexcept nogil
    cdef double[::1] vector(self, object x, str name, bint copy=*)
    cdef dict error_record(self)
    cdef raise_error(self, int where)
