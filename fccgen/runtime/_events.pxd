# Events in compiled code (see _events.pyx): the C state the integrators drive.
from ._engine cimport Engine

cdef extern from "fccgen_events.h":
    ctypedef void (*fcc_event_kernel)(const double *q, const double *v, double t,
                                      const double *p, double *out) noexcept nogil
    ctypedef struct fcc_event_table:
        int abi_version
        int n_q
        int n_p
        int n_events
        int n_quantities
        fcc_event_kernel event_values
        fcc_event_kernel event_gradients
        fcc_event_kernel quantity_values
        fcc_event_kernel quantity_gradients
        fcc_event_kernel quantity_bias

cdef enum:
    ACT_STOP = 0
    ACT_LOG = 1
    ACT_LOCK = 2
    ACT_UNLOCK = 3
    ACT_BOUNCE = 4
    ACT_REST = 5              # a bounce too slow to go on: the limit holds (a lock)
    ACT_RELEASE = 6           # a resting contact whose force turned tensile lets go
    LOG_COLS = 11             # t, event, action, impulse, ke before, ke after,
                              # constraint error, dof, speed before, note, sigma
    NOTE_REDUNDANT = 1        # note bits: a lock that adds no constraint on the motion
    NOTE_UNCERTAIN = 2        # ... the rank after the switch is in the uncertain band

cdef struct EvC:
    const fcc_event_table *tab
    int n, ne, nr, np
    int nang                  # angle quantities: p[3j:3j+3] their references
    double tol                # location tolerance in time
    double v_rest             # a bounce with |ds/dt| below this becomes a rest (lock)
    int max_per_step          # more events than this in one step: Zeno, rest
    double *p                 # angle references (theta, cos, sin) per angle quantity
    int *angle_row            # per parameter triple: its quantity row
    int nm                    # element kernels' copies of the references: how many,
    int *mslot                # ... where (index of theta in mdst; cos, sin follow)
    int *mang                 # ... and of which angle (its parameter triple)
    double *mdst              # the element parameters (the engine's Assembler)
    double *mkeep             # ... their values outside runs (3 nm)
    double max_turn           # the largest re-basing |angle - theta_r| of the run
    int max_turn_j            # ... its angle (parameter triple), -1: none yet
    double *s0                # watched values (2 ne: the event functions, then the
    double *s1                # release functions) at the step's start; at its end (or
                              # a trial time), then n numbers of work
    double *sg                # event gradients (ne x n)
    double *r                 # quantity values, gradients (nr x n), bias
    double *rg
    double *rb
    double *z                 # nr x n: constrained responses to the active rows
    double *gz                # nr x nr work
    double *mu
    double *held              # per quantity row: the value a lock holds
    int *active               # per quantity row: the row is an active constraint
    int *used                 # ... and independent: it enters the solves (rank)
    int n_used                # how many rows are used (set with used, by ev_decide)
    int *rested               # per event: its bounce rests (release is watched)
    double *rel_sign          # per event: the sign making its release function > 0
                              # when the resting contact's multiplier pulls
    double *acc               # n: accelerations for the release functions
    int m                     # the engine's constraint rows (0: rank work not set)
    double *aug               # (m + nr) x n: the row-scaled [B; G_active] (rank)
    double *svm               # its copy for dgesvd; singular values; work
    double *sig
    double *svw
    int lsvw
    int note                  # NOTE_ bits of the last switch
    double note_sigma         # the smallest relative singular value in the band
    int *direction            # per event: +1 rising, -1 falling, 0 either
    int *action
    int *row                  # per event: its joint's first quantity row (or -1)
    int *row2                 # ... second row (cylindrical) or -1
    double *restitution
    int stop                  # a stop event happened
    long n_log
    long cap_log
    double *log               # cap_log x LOG_COLS

cdef struct Bracket:          # Illinois (modified regula falsi) on one watched value
    double a, b               # the bracket holding its crossing, b past it
    double fa, fb
    int side                  # the end kept last: -1 a, +1 b (0: none yet)
    int it

cdef void ev_bracket(EvC *ev, int k, Bracket *br, double b) noexcept nogil
cdef bint ev_bracket_open(EvC *ev, Bracket *br, double scale) noexcept nogil
cdef double ev_bracket_trial(Bracket *br) noexcept nogil
cdef void ev_bracket_update(EvC *ev, int k, Bracket *br, double c,
                            double fc) noexcept nogil
cdef void ev_refresh(EvC *ev, const double *q) noexcept nogil
cdef void ev_values(EvC *ev, const double *q, const double *v, double t,
                    double *out) noexcept nogil
cdef int ev_watch(Engine e, EvC *ev, const double *q, const double *v, double t,
                  double *out) noexcept nogil
cdef bint ev_watched(EvC *ev, int k, const double *a, const double *b) noexcept nogil
cdef int ev_crossed(EvC *ev, const double *a, const double *b) noexcept nogil
cdef bint ev_crosses(EvC *ev, int k, double a, double b) noexcept nogil
cdef int ev_constrain(Engine e, EvC *ev, const double *q, const double *v,
                      double t, double *a) noexcept nogil
cdef int ev_correct(Engine e, EvC *ev, double *q, double *v) noexcept nogil
cdef int ev_apply(Engine e, EvC *ev, int k, double *q, double *v,
                  double t) noexcept nogil
cdef double ev_leaving(EvC *ev, int k, const double *q, const double *v,
                       double t) noexcept nogil
cdef EvC *ev_state(object events) except? NULL
