# cython: language_level=3
"""Events in compiled code: event functions, switchable joint rows, impacts.

The event kernels come from the model's generated event module (fccgen_events.h):
s_k(q, v, t), ds_k/dq, and the joint quantities r_j(q) (angles, slides) with their
Jacobian G and bias (dG/dt) v. Integrators (_rk4.pyx) locate sign changes of s_k and
call :func:`ev_apply`; they add the active rows to every acceleration solve through
:func:`ev_constrain` and hold them after each step through :func:`ev_correct`.

Switchable rows. A lock makes r_j(q) = r_j* a constraint without touching the engine's
own rows: with z_j = the engine's constrained response to the force G_j^T (the solve
x = argmin x^T M x / 2 - G_j x subject to B x = 0), the accelerations of the
augmented system are a + Z mu with (G Z) mu = -(G a + (dG/dt) v): the Schur complement
of the added rows, exact for any number of them. Switching is a flag per row: nothing
is regenerated or recompiled.

Impacts (M-orthogonal, consistent with B v = 0 and the active rows):
* lock (plastic): v+ = v- + Z mu, (G Z) mu = -G v-; the kinetic energy lost is
  (v- - v+)^T M (v- - v+) / 2.
* bounce (Newton, restitution e): along z = the response to ds/dq (with the active
  rows' responses projected out), v+ = v- + mu z, mu = -(1 + e) s'- / (ds/dq . z), so
  that s'+ = -e s'-. A bounce slower than v_rest, or the (max_per_step + 1)-th event of
  one step (Zeno), rests: its joint row is locked instead.
"""
from cpython.pycapsule cimport PyCapsule_GetPointer
from libc.math cimport cos, fabs, sin, sqrt
from libc.stdlib cimport calloc, free
from libc.string cimport memcpy, memset

import numpy as np

from ._assemble cimport ASM_E, ASM_G
from ._engine cimport ERR_SINGULAR, Engine
from ._solve cimport csolve_apply

ACTIONS = ("stop", "log", "lock", "unlock", "bounce", "rest")
LOG_COLUMNS = ("t", "event", "action", "impulse", "kinetic_energy_before",
               "kinetic_energy_after", "constraint_error", "dof", "speed_before")


cdef void ev_refresh(EvC *ev, const double *q) noexcept nogil:
    """Move the angle references to the angles at q (turn counting)."""
    cdef int j, row
    cdef double th
    if ev.nr == 0:
        return
    ev.tab.quantity_values(q, NULL, 0.0, ev.p, ev.r)
    for j in range(ev.np // 3):
        row = ev.angle_row[j]
        th = ev.r[row]
        ev.p[3 * j] = th
        ev.p[3 * j + 1] = cos(th)
        ev.p[3 * j + 2] = sin(th)


cdef void ev_values(EvC *ev, const double *q, const double *v, double t,
                    double *out) noexcept nogil:
    ev.tab.event_values(q, v, t, ev.p, out)


cdef bint ev_crosses(EvC *ev, int k, double a, double b) noexcept nogil:
    """s_k goes from a to b across zero in the event's direction."""
    cdef bint up = a < 0.0 <= b, down = a > 0.0 >= b
    if ev.direction[k] > 0:
        return up
    if ev.direction[k] < 0:
        return down
    return up or down


cdef bint _locked(EvC *ev, int k) noexcept nogil:
    """A lock, or a bounce that came to rest, whose rows hold (its function hovers at
    zero: no new event)."""
    return ((ev.action[k] == ACT_LOCK or ev.action[k] == ACT_BOUNCE)
            and ev.row[k] >= 0 and ev.active[ev.row[k]])


cdef int ev_crossed(EvC *ev, const double *a, const double *b) noexcept nogil:
    """The first event that crosses from values a to b, or -1."""
    cdef int k
    for k in range(ev.ne):
        if ev_crosses(ev, k, a[k], b[k]) and not _locked(ev, k):
            return k
    return -1


cdef int _solve_small(double *A, double *b, int k) noexcept nogil:
    """b <- A^-1 b for a k x k A (row-major, destroyed), partial pivoting; -1 if
    singular (a pivot below 1e-13 of the largest diagonal entry)."""
    cdef int i, j, c, piv
    cdef double big = 0.0, f, tmp
    for i in range(k):
        if fabs(A[i * k + i]) > big:
            big = fabs(A[i * k + i])
    for c in range(k):
        piv = c
        for i in range(c + 1, k):
            if fabs(A[i * k + c]) > fabs(A[piv * k + c]):
                piv = i
        if not fabs(A[piv * k + c]) > 1e-13 * big:
            return -1
        if piv != c:
            for j in range(k):
                tmp = A[c * k + j]; A[c * k + j] = A[piv * k + j]; A[piv * k + j] = tmp
            tmp = b[c]; b[c] = b[piv]; b[piv] = tmp
        for i in range(c + 1, k):
            f = A[i * k + c] / A[c * k + c]
            for j in range(c, k):
                A[i * k + j] -= f * A[c * k + j]
            b[i] -= f * b[c]
    for c in range(k - 1, -1, -1):
        for j in range(c + 1, k):
            b[c] -= A[c * k + j] * b[j]
        b[c] /= A[c * k + c]
    return 0


cdef int _responses(Engine e, EvC *ev, const double *q) noexcept nogil:
    """Jacobian rows of the quantities at q, and z_j (rows of ev.z, active rows in
    order) with the engine's factorisation at q; returns the number of active rows."""
    cdef int j, m = 0
    ev.tab.quantity_gradients(q, NULL, 0.0, ev.p, ev.rg)
    for j in range(ev.nr):
        if ev.active[j]:
            csolve_apply(&e.sol, ev.rg + j * ev.n, NULL, NULL, ev.z + m * ev.n)
            m += 1
    return m


cdef int _multipliers(Engine e, EvC *ev, int m) noexcept nogil:
    """mu <- (G Z)^-1 mu over the m active rows (G Z from ev.rg, ev.z)."""
    cdef int a, b, i, j, n = ev.n
    cdef double acc
    a = 0
    for i in range(ev.nr):
        if not ev.active[i]:
            continue
        for b in range(m):
            acc = 0.0
            for j in range(n):
                acc += ev.rg[i * n + j] * ev.z[b * n + j]
            ev.gz[a * m + b] = acc
        a += 1
    if _solve_small(ev.gz, ev.mu, m) < 0:
        return e.fail(ERR_SINGULAR, -1, 0)
    return 0


cdef void _add(EvC *ev, int m, double *x) noexcept nogil:
    """x += Z mu."""
    cdef int b, j
    for b in range(m):
        for j in range(ev.n):
            x[j] += ev.z[b * ev.n + j] * ev.mu[b]


cdef int _hold(Engine e, EvC *ev, int m, const double *x, const double *target,
               double *y) noexcept nogil:
    """y += Z mu with (G Z) mu = target - G x for the active rows (target NULL: 0)."""
    cdef int a = 0, i, j, n = ev.n
    cdef double acc
    for i in range(ev.nr):
        if ev.active[i]:
            acc = 0.0
            for j in range(n):
                acc += ev.rg[i * n + j] * x[j]
            ev.mu[a] = (target[a] if target != NULL else 0.0) - acc
            a += 1
    if _multipliers(e, ev, m) < 0:
        return -1
    _add(ev, m, y)
    return 0


cdef int ev_constrain(Engine e, EvC *ev, const double *q, const double *v,
                      double t, double *a) noexcept nogil:
    """a <- the accelerations with the active rows added (the engine's factorisation
    must be the one at q, as accelerations_at leaves it)."""
    cdef int m, i, k = 0
    if ev.nr == 0:
        return 0
    for i in range(ev.nr):
        k += ev.active[i]
    if k == 0:
        return 0
    m = _responses(e, ev, q)
    ev.tab.quantity_bias(q, v, t, ev.p, ev.rb)
    k = 0
    for i in range(ev.nr):
        if ev.active[i]:
            ev.held[ev.nr + k] = -ev.rb[i]          # target G a = -(dG/dt) v
            k += 1
    return _hold(e, ev, m, a, ev.held + ev.nr, a)


cdef int ev_correct(Engine e, EvC *ev, double *q, double *v) noexcept nogil:
    """After a step's projections (factorisation at q): one Newton correction of the
    active rows' positions, r_j(q) = held_j, then their speeds, G v = 0."""
    cdef int m, i, k = 0
    if ev.nr == 0:
        return 0
    for i in range(ev.nr):
        k += ev.active[i]
    if k == 0:
        return 0
    m = _responses(e, ev, q)
    ev.tab.quantity_values(q, NULL, 0.0, ev.p, ev.r)
    k = 0
    for i in range(ev.nr):
        if ev.active[i]:
            ev.mu[k] = ev.held[i] - ev.r[i]
            k += 1
    if _multipliers(e, ev, m) < 0:
        return -1
    _add(ev, m, q)
    if _hold(e, ev, m, v, NULL, v) < 0:
        return -1
    e.factor_valid = False                    # q moved: the next stage refactors
    return 0


cdef double _kinetic(Engine e, const double *q, const double *v) noexcept nogil:
    e.asm.assemble(q, v, ASM_E)
    return e.asm.energy[0]


cdef double _row_error(EvC *ev, const double *q) noexcept nogil:
    cdef int i
    cdef double big = 0.0
    ev.tab.quantity_values(q, NULL, 0.0, ev.p, ev.r)
    for i in range(ev.nr):
        if ev.active[i] and fabs(ev.r[i] - ev.held[i]) > big:
            big = fabs(ev.r[i] - ev.held[i])
    return big


cdef void _set_rows(EvC *ev, int k, int flag) noexcept nogil:
    """Switch event k's joint rows on (held at their present values, ev.r) or off."""
    if ev.row[k] >= 0:
        ev.active[ev.row[k]] = flag
        ev.held[ev.row[k]] = ev.r[ev.row[k]]
    if ev.row2[k] >= 0:
        ev.active[ev.row2[k]] = flag
        ev.held[ev.row2[k]] = ev.r[ev.row2[k]]


cdef int _lock_rows(Engine e, EvC *ev, int k, double *q, double *v,
                    double *impulse) noexcept nogil:
    """Activate event k's joint rows at their present values; plastic impact."""
    cdef int m, i
    cdef double norm = 0.0
    ev.tab.quantity_values(q, NULL, 0.0, ev.p, ev.r)
    _set_rows(ev, k, 1)
    m = _responses(e, ev, q)
    if _hold(e, ev, m, v, NULL, v) < 0:
        return -1
    for i in range(m):
        norm += ev.mu[i] * ev.mu[i]
    impulse[0] = sqrt(norm)
    return 0


cdef int _bounce(Engine e, EvC *ev, int k, double *q, double *v, double t,
                 double *impulse, double *speed) noexcept nogil:
    """Newton's law s'+ = -e s'- along the constrained response to ds_k/dq."""
    cdef int i, j, m, n = ev.n
    cdef double *g = ev.sg + k * n
    cdef double *w = ev.s1 + ev.ne                   # n numbers of work after s1
    cdef double sd = 0.0, gz = 0.0, mu
    ev.tab.event_gradients(q, v, t, ev.p, ev.sg)
    for j in range(n):
        sd += g[j] * v[j]
    speed[0] = sd
    csolve_apply(&e.sol, g, NULL, NULL, w)
    m = _responses(e, ev, q)
    if m > 0 and _hold(e, ev, m, w, NULL, w) < 0:
        return -1
    for j in range(n):
        gz += g[j] * w[j]
    if not gz > 0.0:
        return e.fail(ERR_SINGULAR, -2, 0)
    mu = -(1.0 + ev.restitution[k]) * sd / gz
    for j in range(n):
        v[j] += mu * w[j]
    impulse[0] = mu
    return 0


cdef double _rate(EvC *ev, int k, const double *q, const double *v,
                  double t) noexcept nogil:
    """ds_k/dt = ds_k/dq . v (event functions of q and t only)."""
    cdef int j
    cdef double sd = 0.0
    ev.tab.event_gradients(q, v, t, ev.p, ev.sg)
    for j in range(ev.n):
        sd += ev.sg[k * ev.n + j] * v[j]
    return sd


cdef double ev_leaving(EvC *ev, int k, const double *q, const double *v,
                       double t) noexcept nogil:
    """The value s_k counts as at a state just after an event on k: a bounce that
    leaves its surface is on the side before the crossing (so that a return within
    the same step is a new crossing), anything else where it is."""
    cdef double sd
    ev_values(ev, q, v, t, ev.s1 + ev.ne)
    if ev.action[k] == ACT_BOUNCE and ev.direction[k] != 0:
        sd = _rate(ev, k, q, v, t)
        if sd * ev.direction[k] < 0.0:
            return 1e-300 if ev.direction[k] < 0 else -1e-300
    return ev.s1[ev.ne + k]


cdef int ev_apply(Engine e, EvC *ev, int k, double *q, double *v,
                  double t) noexcept nogil:
    """Act on event k at the located state (q, v, t), in place, and log it. A bounce
    with |s'| < v_rest, or k < 0 (the Zeno guard: -1 - k is the event), rests.
    Returns 1 (nothing done) for a bounce that does not approach its surface."""
    cdef int act, i, free_rows = 0
    cdef double ke0, impulse = 0.0, speed = 0.0, cerr
    cdef double *rec
    cdef bint rest = k < 0
    if rest:
        k = -1 - k
    act = ev.action[k]
    if e.project_velocities_at(q, v, False) < 0:     # factorisation at q, B v = 0
        return -1
    ke0 = _kinetic(e, q, v)
    if act == ACT_STOP:
        ev.stop = 1
    elif act == ACT_LOCK:
        if _lock_rows(e, ev, k, q, v, &impulse) < 0:
            return -1
    elif act == ACT_UNLOCK:
        _set_rows(ev, k, 0)
    elif act == ACT_BOUNCE:
        if not rest and ev.direction[k] != 0 and _rate(ev, k, q, v, t) * ev.direction[k] <= 0:
            return 1                           # not approaching: no impact
        if not rest:
            if _bounce(e, ev, k, q, v, t, &impulse, &speed) < 0:
                return -1
            rest = fabs(speed) < ev.v_rest
            if rest:                                   # undo: it rests instead
                ev.tab.event_gradients(q, v, t, ev.p, ev.sg)
        if rest and ev.row[k] >= 0:
            act = ACT_REST
            if e.project_velocities_at(q, v, False) < 0:
                return -1
            if _lock_rows(e, ev, k, q, v, &impulse) < 0:
                return -1
    e.factor_valid = False
    e.asm.assemble(q, NULL, ASM_G)
    cerr = e.asm.max_abs_g()
    if ev.nr and _row_error(ev, q) > cerr:
        cerr = _row_error(ev, q)
    for i in range(ev.nr):
        free_rows += ev.active[i]
    if ev.n_log < ev.cap_log:
        rec = ev.log + ev.n_log * LOG_COLS
        rec[0], rec[1], rec[2], rec[3] = t, k, act, impulse
        rec[4], rec[5], rec[6] = ke0, _kinetic(e, q, v), cerr
        rec[7], rec[8] = e.sol.nr - free_rows, speed
    ev.n_log += 1
    return 0


cdef class EventSet:
    """The compiled events of one model for one engine: their kernels (from the
    model's event module), directions, actions, joint rows and settings, and the log
    of what happened in a run."""
    cdef EvC c
    cdef object module
    cdef readonly object names

    def __cinit__(self, module, int n_q, directions, actions, rows, rows2,
                  restitution, angle_rows, double tol=1e-12, double v_rest=1e-6,
                  int max_per_step=50, long max_log=100000):
        self.module = module
        self.names = tuple(module.EVENT_NAMES)
        cdef const fcc_event_table *tab = <const fcc_event_table *>PyCapsule_GetPointer(
            module.table_capsule(), "fccgen.event_table")
        if tab.abi_version != 1 or tab.n_q != n_q:
            raise ValueError(f"the event module does not fit this model (ABI "
                             f"{tab.abi_version}, {tab.n_q} coordinates, want {n_q})")
        if not (tol > 0 and v_rest >= 0 and max_per_step >= 1):
            raise ValueError("need tol > 0, v_rest >= 0, max_per_step >= 1")
        cdef EvC *c = &self.c
        c.tab, c.n, c.ne, c.nr, c.np = tab, n_q, tab.n_events, tab.n_quantities, tab.n_p
        c.tol, c.v_rest, c.max_per_step = tol, v_rest, max_per_step
        ne, nr, n = c.ne, c.nr, n_q
        c.p = <double *>calloc(c.np + 1, sizeof(double))
        c.s0 = <double *>calloc(ne + 1, sizeof(double))
        c.s1 = <double *>calloc(ne + n + 1, sizeof(double))
        c.sg = <double *>calloc(ne * n + 1, sizeof(double))
        c.r = <double *>calloc(nr + 1, sizeof(double))
        c.rg = <double *>calloc(nr * n + 1, sizeof(double))
        c.rb = <double *>calloc(nr + 1, sizeof(double))
        c.z = <double *>calloc(nr * n + 1, sizeof(double))
        c.gz = <double *>calloc(nr * nr + 1, sizeof(double))
        c.mu = <double *>calloc(nr + 1, sizeof(double))
        c.held = <double *>calloc(2 * nr + 1, sizeof(double))
        c.active = <int *>calloc(nr + 1, sizeof(int))
        c.angle_row = <int *>calloc(c.np // 3 + 1, sizeof(int))
        c.direction = <int *>calloc(ne + 1, sizeof(int))
        c.action = <int *>calloc(ne + 1, sizeof(int))
        c.row = <int *>calloc(ne + 1, sizeof(int))
        c.row2 = <int *>calloc(ne + 1, sizeof(int))
        c.restitution = <double *>calloc(ne + 1, sizeof(double))
        c.cap_log = max_log
        c.log = <double *>calloc(max_log * LOG_COLS + 1, sizeof(double))
        if c.log == NULL or c.p == NULL or c.restitution == NULL or c.z == NULL:
            raise MemoryError("cannot allocate the event state")
        for k in range(ne):
            c.direction[k] = {"rising": 1, "falling": -1, "either": 0}[directions[k]]
            c.action[k] = ACTIONS.index(actions[k])
            c.row[k], c.row2[k] = rows[k], rows2[k]
            c.restitution[k] = restitution[k]
        for j, row in enumerate(angle_rows):
            c.angle_row[j] = row

    def __dealloc__(self):
        cdef EvC *c = &self.c
        free(c.p); free(c.s0); free(c.s1); free(c.sg); free(c.r); free(c.rg)
        free(c.rb); free(c.z); free(c.gz); free(c.mu); free(c.held); free(c.active)
        free(c.angle_row); free(c.direction); free(c.action); free(c.row); free(c.row2)
        free(c.restitution); free(c.log)

    def reset(self, q):
        """Start a run at q: angle references 0 (the start's angles are 0 by
        definition), no rows active, an empty log."""
        cdef EvC *c = &self.c
        memset(c.p, 0, c.np * sizeof(double))
        for j in range(c.np // 3):
            c.p[3 * j + 1] = 1.0
        memset(c.active, 0, c.nr * sizeof(int))
        c.n_log = 0
        c.stop = 0

    @property
    def tol(self):
        return self.c.tol

    def log(self):
        """The events of the last run: a (n, 9) array of LOG_COLUMNS."""
        n = min(self.c.n_log, self.c.cap_log)
        out = np.empty((n, LOG_COLS))
        for i in range(n):
            for j in range(LOG_COLS):
                out[i, j] = self.c.log[i * LOG_COLS + j]
        return out

    def quantity_kernels(self, q, v):
        """(r, G, (dG/dt) v) of the joint quantities at (q, v) with the current angle
        references: fresh arrays (for checks)."""
        qa = np.ascontiguousarray(q, float)
        va = np.ascontiguousarray(v, float)
        cdef double[::1] qv = qa, vv = va
        cdef EvC *c = &self.c
        if qa.shape[0] != c.n or va.shape[0] != c.n:
            raise ValueError(f"q and v must hold {c.n} numbers")
        r, g, b = np.empty(c.nr), np.empty((c.nr, c.n)), np.empty(c.nr)
        if c.nr:
            c.tab.quantity_values(&qv[0], &vv[0], 0.0, c.p, c.r)
            c.tab.quantity_gradients(&qv[0], &vv[0], 0.0, c.p, c.rg)
            c.tab.quantity_bias(&qv[0], &vv[0], 0.0, c.p, c.rb)
            for i in range(c.nr):
                r[i], b[i] = c.r[i], c.rb[i]
                for j in range(c.n):
                    g[i, j] = c.rg[i * c.n + j]
        return r, g, b

    def values(self, q, v, double t):
        """s_k at (q, v, t) with the current angle references: a fresh array."""
        qa = np.ascontiguousarray(q, float)
        va = np.ascontiguousarray(v, float)
        out = np.empty(self.c.ne)
        cdef double[::1] qv = qa, vv = va, ov = out
        if self.c.ne:
            ev_values(&self.c, &qv[0], &vv[0], t, &ov[0])
        return out


cdef EvC *ev_state(object events) except? NULL:
    """The C state of an EventSet (NULL for None)."""
    if events is None:
        return NULL
    return &(<EventSet>events).c
