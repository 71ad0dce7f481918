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
* release: a resting contact lets go when its row's multiplier turns tensile (the
  contact would have to pull): the release function of a resting bounce is that
  multiplier times the sign that makes it positive when it pulls, watched and located
  like an event function (ev_watch).

Rank. The rows that enter the solves (ev.used) are decided at every switch by the rule
that decides B's rank at the start of a run (fccgen/rank.py): the SVD gap test on the
row-scaled [B; G_active], each active row kept when it raises the rank (sigma_r >
DECIDE_TOL sigma_1). A lock whose rows follow from B and the rows already locked is
held (its row error is reported) but adds no constraint: the degrees of freedom after
a switch are n - rank(B) - (the used rows).
"""
from cpython.pycapsule cimport PyCapsule_GetPointer
from libc.math cimport cos, fabs, sin, sqrt
from libc.stdlib cimport calloc, free
from libc.string cimport memcpy, memset
from scipy.linalg.cython_lapack cimport dgesvd

import numpy as np

from fccgen import rank as _rank

from ._cengine cimport fcc_assemble, fcc_put_time, fcc_max_abs_g, fcc_scaled_residual
from ._assemble cimport ASM_B, ASM_E, ASM_G
from ._engine cimport ERR_SINGULAR, Engine
from ._solve cimport csolve_apply

ACTIONS = ("stop", "log", "lock", "unlock", "bounce", "rest", "release")
LOG_COLUMNS = ("t", "event", "action", "impulse", "kinetic_energy_before",
               "kinetic_energy_after", "constraint_error", "dof", "speed_before", "note",
               "sigma")
NOTES = {"redundant": NOTE_REDUNDANT, "uncertain": NOTE_UNCERTAIN}

# The rank rule of fccgen/rank.py, its own numbers: independent above DECIDE_TOL
# sigma_1, uncertain in [AMBIGUOUS_LOW, GROW_TOL] sigma_1; rows scaled to unit length,
# B's rows not below ROW_FLOOR times the largest row of their element.
cdef double DECIDE_TOL = _rank.DECIDE_TOL
cdef double AMBIGUOUS_LOW = _rank.AMBIGUOUS_LOW
cdef double GROW_TOL = _rank.GROW_TOL
cdef double ROW_FLOOR = _rank.ROW_FLOOR


cdef void ev_refresh(EvC *ev, const double *q) noexcept nogil:
    """Move the angle references to the angles at q (turn counting)."""
    cdef int j, row
    cdef double th
    if ev.nr == 0:
        return
    ev.tab.quantity_values(q, NULL, 0.0, ev.p, ev.r)
    for j in range(ev.nang):
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
    if k >= ev.ne or ev.direction[k] > 0:           # release functions rise
        return up
    if ev.direction[k] < 0:
        return down
    return up or down


cdef void ev_bracket(EvC *ev, int k, Bracket *br, double b) noexcept nogil:
    """Start the Illinois iteration on watched value k over [0, b], where it crosses
    between ev.s0[k] (at 0) and ev.s1[k] (at b). A start just after an event
    (ev_leaving's +-1e-300) counts as before the crossing: bisect first."""
    br.a, br.b, br.fa, br.fb = 0.0, b, ev.s0[k], ev.s1[k]
    br.side, br.it = 0, 0
    if fabs(br.fa) < 1e-200:
        br.fa = -br.fb


cdef bint ev_bracket_open(EvC *ev, Bracket *br, double scale) noexcept nogil:
    """The bracket, times ``scale`` (its unit in seconds), is wider than the location
    tolerance (and fewer than 200 trials were made)."""
    return (br.b - br.a) * scale > ev.tol and br.it < 200


cdef double ev_bracket_trial(Bracket *br) noexcept nogil:
    """The next trial point: the secant's zero, b - f_b (b - a) / (f_b - f_a), or
    the midpoint where that is not inside (a, b)."""
    cdef double c
    br.it += 1
    c = br.b - br.fb * (br.b - br.a) / (br.fb - br.fa) if br.fb != br.fa else \
        0.5 * (br.a + br.b)
    if not (br.a < c < br.b):
        c = 0.5 * (br.a + br.b)
    return c


cdef void ev_bracket_update(EvC *ev, int k, Bracket *br, double c,
                            double fc) noexcept nogil:
    """Keep the half of the bracket that holds the crossing, given the value fc at
    the trial c; the end kept twice in a row has its value halved (Illinois), so
    that the secant does not stall on one side."""
    if ev_crosses(ev, k, br.fa, fc) or fc == 0.0 and ev_crosses(ev, k, br.fa, br.fb):
        br.b, br.fb = c, fc
        if br.side == -1:
            br.fa *= 0.5
        br.side = -1
    else:
        br.a, br.fa = c, fc
        if br.side == 1:
            br.fb *= 0.5
        br.side = 1


cdef bint _locked(EvC *ev, int k) noexcept nogil:
    """A lock, or a bounce that came to rest, whose rows hold (its function hovers at
    zero: no new event)."""
    return ((ev.action[k] == ACT_LOCK or ev.action[k] == ACT_BOUNCE)
            and ev.row[k] >= 0 and ev.active[ev.row[k]])


cdef bint _rests(EvC *ev, int k) noexcept nogil:
    """Event k is a bounce resting on its row (its release is watched)."""
    return ev.rested[k] and ev.row[k] >= 0 and ev.active[ev.row[k]]


cdef int ev_crossed(EvC *ev, const double *a, const double *b) noexcept nogil:
    """The first watched value that crosses from a to b, or -1: an event function
    k < ne, or the release function ne + k of a resting bounce k."""
    cdef int k
    for k in range(ev.ne):
        if ev_crosses(ev, k, a[k], b[k]) and not _locked(ev, k):
            return k
    for k in range(ev.ne):
        if _rests(ev, k) and ev_crosses(ev, ev.ne + k, a[ev.ne + k], b[ev.ne + k]):
            return ev.ne + k
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
    """Jacobian rows of the quantities at q, and z_j (rows of ev.z, used rows in
    order) with the engine's factorisation at q; returns the number of used rows."""
    cdef int j, m = 0
    ev.tab.quantity_gradients(q, NULL, 0.0, ev.p, ev.rg)
    for j in range(ev.nr):
        if ev.used[j]:
            csolve_apply(&e.sol, ev.rg + j * ev.n, NULL, NULL, ev.z + m * ev.n)
            m += 1
    return m


cdef int _multipliers(Engine e, EvC *ev, int m) noexcept nogil:
    """mu <- (G Z)^-1 mu over the m active rows (G Z from ev.rg, ev.z)."""
    cdef int a, b, i, j, n = ev.n
    cdef double acc
    a = 0
    for i in range(ev.nr):
        if not ev.used[i]:
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
        if ev.used[i]:
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
    if ev.n_used == 0:
        return 0
    m = _responses(e, ev, q)
    ev.tab.quantity_bias(q, v, t, ev.p, ev.rb)
    for i in range(ev.nr):
        if ev.used[i]:
            ev.held[ev.nr + k] = -ev.rb[i]          # target G a = -(dG/dt) v
            k += 1
    return _hold(e, ev, m, a, ev.held + ev.nr, a)


cdef int ev_correct(Engine e, EvC *ev, double *q, double *v) noexcept nogil:
    """After a step's projections (factorisation at q): one Newton correction of the
    active rows' positions, r_j(q) = held_j, then their speeds, G v = 0."""
    cdef int m, i, k = 0
    if ev.n_used == 0:
        return 0
    m = _responses(e, ev, q)
    ev.tab.quantity_values(q, NULL, 0.0, ev.p, ev.r)
    for i in range(ev.nr):
        if ev.used[i]:
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
    fcc_assemble(&e.asm.a, q, v, ASM_E)
    return e.asm.a.energy[0]


cdef double _row_error(EvC *ev, const double *q) noexcept nogil:
    cdef int i
    cdef double big = 0.0
    ev.tab.quantity_values(q, NULL, 0.0, ev.p, ev.r)
    for i in range(ev.nr):
        if ev.active[i] and fabs(ev.r[i] - ev.held[i]) > big:
            big = fabs(ev.r[i] - ev.held[i])
    return big


cdef void _set_rows(EvC *ev, int k, int flag) noexcept nogil:
    """Switch event k's joint rows on (held at their present values, ev.r) or off;
    no bounce on those rows rests any more (a rest sets its flag after)."""
    cdef int j
    if ev.row[k] >= 0:
        ev.active[ev.row[k]] = flag
        ev.held[ev.row[k]] = ev.r[ev.row[k]]
        for j in range(ev.ne):
            if ev.row[j] == ev.row[k]:
                ev.rested[j] = 0
    if ev.row2[k] >= 0:
        ev.active[ev.row2[k]] = flag
        ev.held[ev.row2[k]] = ev.r[ev.row2[k]]


cdef void _scaled_rows(Engine e, EvC *ev, const double *q) noexcept nogil:
    """ev.aug = [B; G] at q, each row divided as by fccgen.rank.row_scales: by its
    length, B's rows by no less than ROW_FLOOR times the longest row of their element
    (consecutive rows with one e.row_group), G's rows each alone."""
    cdef int i, j, k, n = ev.n, rows = ev.m + ev.nr
    cdef double norm, largest
    cdef double *w = ev.sig + rows                  # rows numbers of work after sig
    fcc_assemble(&e.asm.a, q, NULL, ASM_B)
    ev.tab.quantity_gradients(q, NULL, 0.0, ev.p, ev.rg)
    memcpy(ev.aug, e.asm.a.B, ev.m * n * sizeof(double))
    memcpy(ev.aug + ev.m * n, ev.rg, ev.nr * n * sizeof(double))
    for k in range(rows):
        norm = 0.0
        for i in range(n):
            norm += ev.aug[k * n + i] * ev.aug[k * n + i]
        w[k] = sqrt(norm)
    k = 0
    while k < ev.m:
        j, largest = k, 0.0
        while j < ev.m and e.row_group[j] == e.row_group[k]:
            largest = w[j] if w[j] > largest else largest
            j += 1
        for i in range(k, j):
            if w[i] < ROW_FLOOR * largest:
                w[i] = ROW_FLOOR * largest
        k = j
    for k in range(rows):
        norm = 1.0 / w[k] if w[k] > 0.0 else 1.0
        for i in range(n):
            ev.aug[k * n + i] *= norm


cdef int _svd_count(EvC *ev, int rows) noexcept nogil:
    """The number of singular values of the first ``rows`` rows of ev.aug above
    DECIDE_TOL sigma_1 (-1: LAPACK failed); the singular values are left in ev.sig."""
    cdef int n = ev.n, info = 0, one = 1, kmax = ev.n if ev.n < rows else rows, rank = 0
    cdef double dummy = 0.0
    if kmax == 0:
        return 0
    memcpy(ev.svm, ev.aug, rows * n * sizeof(double))
    dgesvd(b"N", b"N", &n, &rows, ev.svm, &n, ev.sig, &dummy, &one, &dummy, &one,
           ev.svw, &ev.lsvw, &info)
    if info != 0:
        return -1
    if not ev.sig[0] > 0.0:
        return 0
    while rank < kmax and ev.sig[rank] > DECIDE_TOL * ev.sig[0]:
        rank += 1
    return rank


cdef void _uncertain(EvC *ev, double ratio) noexcept nogil:
    """Note a relative singular value that decided a row, if in the uncertain band."""
    if AMBIGUOUS_LOW <= ratio <= GROW_TOL:
        if not ev.note & NOTE_UNCERTAIN or ratio < ev.note_sigma:
            ev.note_sigma = ratio
        ev.note |= NOTE_UNCERTAIN


cdef int ev_decide(Engine e, EvC *ev, const double *q) noexcept nogil:
    """Decide which active rows enter the solves (ev.used) at q, by the start's rank
    rule (fccgen/rank.py) on the row-scaled [B; G_active]: each active row, in order,
    is used when it raises the rank by the SVD gap test. The singular value that
    decided a row (the new last kept one, or the first dropped one) inside the
    uncertain band sets NOTE_UNCERTAIN. Without the rank work (reset without an
    engine) every active row is used."""
    cdef int i, rows, rank, r
    cdef int n = ev.n
    ev.n_used = 0
    if ev.aug == NULL:
        for i in range(ev.nr):
            ev.used[i] = ev.active[i]
            ev.n_used += ev.used[i]
        return 0
    _scaled_rows(e, ev, q)
    rows = ev.m
    rank = _svd_count(ev, rows)
    if rank < 0:
        return e.fail(ERR_SINGULAR, -3, 0)
    for i in range(ev.nr):
        ev.used[i] = 0
        if not ev.active[i]:
            continue
        if rows != ev.m + i:                   # the candidate row after the kept ones
            memcpy(ev.aug + rows * n, ev.aug + (ev.m + i) * n, n * sizeof(double))
        r = _svd_count(ev, rows + 1)
        if r < 0:
            return e.fail(ERR_SINGULAR, -3, 0)
        if r > rank:
            _uncertain(ev, ev.sig[r - 1] / ev.sig[0])
            ev.used[i] = 1
            ev.n_used += 1
            rows += 1
            rank = r
        elif rank < (n if n < rows + 1 else rows + 1) and ev.sig[0] > 0.0:
            _uncertain(ev, ev.sig[rank] / ev.sig[0])
    return 0


cdef int _lock_rows(Engine e, EvC *ev, int k, double *q, double *v,
                    double *impulse) noexcept nogil:
    """Activate event k's joint rows at their present values; plastic impact."""
    cdef int m, i
    cdef double norm = 0.0
    ev.tab.quantity_values(q, NULL, 0.0, ev.p, ev.r)
    _set_rows(ev, k, 1)
    if ev_decide(e, ev, q) < 0:
        return -1
    if (ev.row[k] >= 0 and not ev.used[ev.row[k]]
            or ev.row2[k] >= 0 and not ev.used[ev.row2[k]]):
        ev.note |= NOTE_REDUNDANT
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
    cdef double *w = ev.s1 + 2 * ev.ne               # n numbers of work after s1
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
    the same step is a new crossing), anything else where it is. After a release
    (k = ne + j) the bounce j is put on the side before its crossing in ev.s0 (it
    leaves its limit) and its release function is -1."""
    cdef double sd
    if k >= ev.ne:
        if ev.direction[k - ev.ne] != 0:
            ev.s0[k - ev.ne] = 1e-300 if ev.direction[k - ev.ne] < 0 else -1e-300
        return -1.0
    ev_values(ev, q, v, t, ev.s1 + 2 * ev.ne)
    if ev.action[k] == ACT_BOUNCE and ev.direction[k] != 0:
        sd = _rate(ev, k, q, v, t)
        if sd * ev.direction[k] < 0.0:
            return 1e-300 if ev.direction[k] < 0 else -1e-300
    return ev.s1[2 * ev.ne + k]


cdef int _rest_sign(EvC *ev, int k, const double *q, const double *v, double t,
                    double approach) noexcept nogil:
    """Mark bounce k as resting on its row (locked, ev.z its used rows' responses)
    and keep the sign that makes its release function positive when the row's
    multiplier pulls: d sign(ds_k/dq . z_row), d the event's direction (or the sign of
    the approach rate ``approach`` for either), since the row's multiplier mu moves
    s_k by (ds_k/dq . z_row) mu and a contact pushes s_k back against d."""
    cdef int j, pos = 0, d = ev.direction[k]
    cdef double c = 0.0
    if d == 0:
        d = -1 if approach < 0.0 else 1
    for j in range(ev.row[k]):
        pos += ev.used[j]
    ev.rested[k] = 1
    ev.rel_sign[k] = 0.0
    if not ev.used[ev.row[k]]:
        return 0                               # held by other rows: never released
    ev.tab.event_gradients(q, v, t, ev.p, ev.sg)
    for j in range(ev.n):
        c += ev.sg[k * ev.n + j] * ev.z[pos * ev.n + j]
    ev.rel_sign[k] = d * (1.0 if c > 0.0 else -1.0)
    return 0


cdef int ev_watch(Engine e, EvC *ev, const double *q, const double *v, double t,
                  double *out) noexcept nogil:
    """out[:ne] = s_k(q, v, t); out[ne + k] = the release function of bounce k while
    it rests: rel_sign_k mu, mu the multiplier of its row in the accelerations at
    (q, v, t) with the active rows (positive: the contact pulls), else -1. The
    accelerations are solved only while something rests (the factorisation is left
    at q, not valid for the integrator)."""
    cdef int k, j, pos
    cdef bint any_rest = False
    ev_values(ev, q, v, t, out)
    for k in range(ev.ne):
        out[ev.ne + k] = -1.0
        if _rests(ev, k) and ev.rel_sign[k] != 0.0:
            any_rest = True
    if not any_rest:
        return 0
    fcc_put_time(&e.asm.a, t)
    if e.accelerations_at(q, v, ev.acc, False) < 0:
        return -1
    if ev_constrain(e, ev, q, v, t, ev.acc) < 0:
        return -1
    e.factor_valid = False
    for k in range(ev.ne):
        if _rests(ev, k) and ev.rel_sign[k] != 0.0:
            pos = 0
            for j in range(ev.row[k]):
                pos += ev.used[j]
            out[ev.ne + k] = ev.rel_sign[k] * ev.mu[pos]
    return 0


cdef int ev_apply(Engine e, EvC *ev, int k, double *q, double *v,
                  double t) noexcept nogil:
    """Act on event k at the located state (q, v, t), in place, and log it. A bounce
    with |s'| < v_rest, or k < 0 (the Zeno guard: -1 - k is the event), rests;
    k >= ne releases the resting bounce k - ne. Every switch decides the used rows
    anew (ev_decide). Returns 1 (nothing done) for a bounce that does not approach
    its surface."""
    cdef int act
    cdef double ke0, impulse = 0.0, speed = 0.0, cerr, approach = 0.0
    cdef double *rec
    cdef bint rest = k < 0
    if rest:
        k = -1 - k
    ev.note = 0
    ev.note_sigma = 0.0
    if k >= ev.ne:
        k -= ev.ne
        act = ACT_RELEASE
    else:
        act = ev.action[k]
    if e.project_velocities_at(q, v, False) < 0:     # factorisation at q, B v = 0
        return -1
    ke0 = _kinetic(e, q, v)
    if act == ACT_STOP:
        ev.stop = 1
    elif act == ACT_LOCK:
        if _lock_rows(e, ev, k, q, v, &impulse) < 0:
            return -1
    elif act == ACT_UNLOCK or act == ACT_RELEASE:
        _set_rows(ev, k, 0)
        if ev_decide(e, ev, q) < 0:
            return -1
    elif act == ACT_BOUNCE:
        approach = _rate(ev, k, q, v, t)
        if not rest and ev.direction[k] != 0 and approach * ev.direction[k] <= 0:
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
            _rest_sign(ev, k, q, v, t, approach)
    e.factor_valid = False
    fcc_assemble(&e.asm.a, q, NULL, ASM_G)
    cerr = fcc_max_abs_g(&e.asm.a)
    if ev.nr:
        cerr = max(cerr, _row_error(ev, q))
    if ev.n_log < ev.cap_log:
        rec = ev.log + ev.n_log * LOG_COLS
        rec[0], rec[1], rec[2], rec[3] = t, k, act, impulse
        rec[4], rec[5], rec[6] = ke0, _kinetic(e, q, v), cerr
        rec[7], rec[8] = e.sol.nr - ev.n_used, speed
        rec[9], rec[10] = ev.note, ev.note_sigma
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
                  int max_per_step=50, long max_log=100000, constants=()):
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
        c.nang = len(angle_rows)
        if 3 * c.nang + len(constants) != c.np:
            raise ValueError(f"the event module takes {c.np} parameters, not "
                             f"{3 * c.nang} angle references and {len(constants)} "
                             "constants")
        ne, nr, n = c.ne, c.nr, n_q
        c.p = <double *>calloc(c.np + 1, sizeof(double))
        c.s0 = <double *>calloc(2 * ne + 1, sizeof(double))
        c.s1 = <double *>calloc(4 * ne + n + 1, sizeof(double))
        c.sg = <double *>calloc(ne * n + 1, sizeof(double))
        c.r = <double *>calloc(nr + 1, sizeof(double))
        c.rg = <double *>calloc(nr * n + 1, sizeof(double))
        c.rb = <double *>calloc(nr + 1, sizeof(double))
        c.z = <double *>calloc(nr * n + 1, sizeof(double))
        c.gz = <double *>calloc(nr * nr + 1, sizeof(double))
        c.mu = <double *>calloc(nr + 1, sizeof(double))
        c.held = <double *>calloc(2 * nr + 1, sizeof(double))
        c.active = <int *>calloc(nr + 1, sizeof(int))
        c.used = <int *>calloc(nr + 1, sizeof(int))
        c.rested = <int *>calloc(ne + 1, sizeof(int))
        c.rel_sign = <double *>calloc(ne + 1, sizeof(double))
        c.acc = <double *>calloc(n + 1, sizeof(double))
        c.aug = c.svm = c.sig = c.svw = NULL
        c.m = 0
        c.angle_row = <int *>calloc(c.nang + 1, sizeof(int))
        c.direction = <int *>calloc(ne + 1, sizeof(int))
        c.action = <int *>calloc(ne + 1, sizeof(int))
        c.row = <int *>calloc(ne + 1, sizeof(int))
        c.row2 = <int *>calloc(ne + 1, sizeof(int))
        c.restitution = <double *>calloc(ne + 1, sizeof(double))
        c.cap_log = max_log
        c.log = <double *>calloc(max_log * LOG_COLS + 1, sizeof(double))
        if (c.log == NULL or c.p == NULL or c.restitution == NULL or c.z == NULL
                or c.used == NULL or c.rested == NULL or c.rel_sign == NULL
                or c.acc == NULL):
            raise MemoryError("cannot allocate the event state")
        for j, x in enumerate(constants):
            c.p[3 * c.nang + j] = x
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
        free(c.restitution); free(c.log); free(c.used); free(c.rested)
        free(c.rel_sign); free(c.acc); free(c.aug); free(c.svm); free(c.sig); free(c.svw)

    def reset(self, q, Engine engine=None):
        """Start a run at q: angle references 0 (the start's angles are 0 by
        definition), no rows active or resting, an empty log. ``engine``: the run's
        engine, for the rank decision at switches (ev_decide; None: every active row
        is used)."""
        cdef EvC *c = &self.c
        memset(c.p, 0, 3 * c.nang * sizeof(double))
        for j in range(c.nang):
            c.p[3 * j + 1] = 1.0
        memset(c.active, 0, c.nr * sizeof(int))
        memset(c.used, 0, c.nr * sizeof(int))
        c.n_used = 0
        memset(c.rested, 0, c.ne * sizeof(int))
        c.n_log = 0
        c.stop = 0
        if engine is not None and (c.aug == NULL or c.m != engine.m):
            self._rank_work(engine.m)

    def _rank_work(self, int m):
        """Allocate the work of the rank decision for an engine with m rows."""
        cdef EvC *c = &self.c
        cdef int rows = m + c.nr, n = c.n, info = 0, one = 1, lwork = -1
        cdef double query = 0.0, dummy = 0.0
        free(c.aug); free(c.svm); free(c.sig); free(c.svw)
        c.aug = c.svm = c.sig = c.svw = NULL
        if rows > 0:
            dgesvd(b"N", b"N", &n, &rows, &dummy, &n, &dummy, &dummy, &one, &dummy,
                   &one, &query, &lwork, &info)
        c.lsvw = max(<int>query, 5 * (n + rows) + 1)
        c.aug = <double *>calloc(rows * n + 1, sizeof(double))
        c.svm = <double *>calloc(rows * n + 1, sizeof(double))
        c.sig = <double *>calloc(2 * rows + n + 1, sizeof(double))
        c.svw = <double *>calloc(c.lsvw, sizeof(double))
        if c.aug == NULL or c.svm == NULL or c.sig == NULL or c.svw == NULL:
            raise MemoryError("cannot allocate the rank work of the events")
        c.m = m

    @property
    def tol(self):
        return self.c.tol

    def log(self):
        """The events of the last run: a (n, 11) array of LOG_COLUMNS."""
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
