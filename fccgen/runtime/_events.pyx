# cython: language_level=3
"""The Python face of the C engine's events (engine/fcc_events.c,
fcc_event_actions.c): event functions, switchable joint rows, impacts, their location
and the log (the C sources' docstrings say how).

EventSet binds a model's generated event module (fccgen_events.h) to the event
settings of a run: the constants (fcc_event_spec: each event's direction, action,
joint rows and restitution) and one run's state (fcc_events). The integrators' C loops
take its state through ev_state.
"""
from cpython.pycapsule cimport PyCapsule_GetPointer

import numpy as np

from ._cengine cimport (FCC_ACT_BOUNCE, FCC_ACT_LOCK, FCC_ACT_LOG, FCC_ACT_RELEASE,
                        FCC_ACT_REST, FCC_ACT_STOP, FCC_ACT_UNLOCK, FCC_ERR_MEMORY,
                        FCC_ERR_ARGUMENT, FCC_EVENT_ABI_VERSION, FCC_LOG_COLS, FCC_NOTE_REDUNDANT,
                        FCC_NOTE_UNCERTAIN, FCC_OK, fcc_event_spec_free,
                        fcc_event_spec_init, fcc_event_table, fcc_events_free,
                        fcc_events_init, fcc_events_mirror, fcc_events_rank_work,
                        fcc_events_sparse_work, fcc_events_fold,
                        fcc_events_reset, fcc_events_restore, fcc_ev_refresh,
                        fcc_ev_values)
from ._assemble cimport Assembler
from ._engine cimport Engine

ACTIONS = ("stop", "log", "lock", "unlock", "bounce", "rest", "release")
assert [FCC_ACT_STOP, FCC_ACT_LOG, FCC_ACT_LOCK, FCC_ACT_UNLOCK, FCC_ACT_BOUNCE,
        FCC_ACT_REST, FCC_ACT_RELEASE] == list(range(len(ACTIONS)))
LOG_COLUMNS = ("t", "event", "action", "impulse", "kinetic_energy_before",
               "kinetic_energy_after", "constraint_error", "dof", "speed_before", "note",
               "sigma")
NOTES = {"redundant": FCC_NOTE_REDUNDANT, "uncertain": FCC_NOTE_UNCERTAIN}


def _ints(values):
    return np.ascontiguousarray(values, dtype=np.intc).reshape(-1)


cdef const int *_ip(int[::1] x):
    return &x[0] if x.shape[0] else NULL


cdef class EventSet:
    """The compiled events of one model for one engine: their kernels (from the
    model's event module), directions, actions, joint rows and settings, and the log
    of what happened in a run."""

    def __cinit__(self, module, int n_q, directions, actions, rows, rows2,
                  restitution, angle_rows, double tol=1e-12, double v_rest=1e-6,
                  int max_per_step=50, long max_log=100000, constants=()):
        self.module = module
        self.names = tuple(module.EVENT_NAMES)
        cdef const fcc_event_table *tab = <const fcc_event_table *>PyCapsule_GetPointer(
            module.table_capsule(), "fccgen.event_table")
        if tab.abi_version != FCC_EVENT_ABI_VERSION or tab.n_q != n_q:
            raise ValueError(f"the event module does not fit this model (ABI "
                             f"{tab.abi_version}, {tab.n_q} coordinates, want {n_q})")
        if not (tol > 0 and v_rest >= 0 and max_per_step >= 1):
            raise ValueError("need tol > 0, v_rest >= 0, max_per_step >= 1")
        nang = len(angle_rows)
        if 3 * nang + len(constants) != tab.n_p:
            raise ValueError(f"the event module takes {tab.n_p} parameters, not "
                             f"{3 * nang} angle references and {len(constants)} "
                             "constants")
        ne = tab.n_events
        cdef int[::1] ang = _ints(angle_rows)
        cdef int[::1] dirs = _ints([{"rising": 1, "falling": -1, "either": 0}[directions[k]]
                                    for k in range(ne)])
        cdef int[::1] acts = _ints([ACTIONS.index(actions[k]) for k in range(ne)])
        cdef int[::1] r1 = _ints(list(rows)[:ne]), r2 = _ints(list(rows2)[:ne])
        cdef double[::1] rest = np.ascontiguousarray(list(restitution)[:ne], dtype=float)
        cdef double[::1] const = np.ascontiguousarray(constants, dtype=float).reshape(-1)
        if fcc_event_spec_init(&self.spec, tab, nang, _ip(ang), _ip(dirs), _ip(acts),
                               _ip(r1), _ip(r2), &rest[0] if ne else NULL, tol, v_rest,
                               max_per_step, max_log) != FCC_OK:
            raise MemoryError("cannot allocate the event state")
        if fcc_events_init(&self.c, &self.spec,
                           &const[0] if const.shape[0] else NULL) != FCC_OK:
            fcc_event_spec_free(&self.spec)
            raise MemoryError("cannot allocate the event state")
        self.live = True

    def __dealloc__(self):
        if self.live:
            fcc_events_free(&self.c)
            fcc_event_spec_free(&self.spec)

    def mirror(self, Assembler asm, slots, angles):
        """Copy the angle references into ``asm``'s element parameters at every
        re-basing and reset (fcc_events_mirror): the reference of angle ``angles[i]``
        (its index among the angle quantities) to the parameters slots[i], slots[i] +
        1, slots[i] + 2 (th, cr, sr; fccgen.events.references.reference_slots). Their
        values now are kept for :meth:`restore`."""
        if len(angles) != len(slots):
            raise ValueError("need one angle per slot")
        cdef int[::1] sl = _ints(slots), an = _ints(angles)
        rc = fcc_events_mirror(&self.c, &asm.a, sl.shape[0], _ip(sl), _ip(an))
        if rc == FCC_ERR_ARGUMENT:
            raise ValueError(f"reference copy out of range: angles {list(angles)}, "
                             f"slots {list(slots)}")
        if rc != FCC_OK:
            raise MemoryError("cannot allocate the reference copies")
        self.mirrored = asm

    def put_inputs(self, slots, values):
        """Write the inputs the event functions read (their held values) into the
        event kernels' parameters ``slots`` (fccgen.runtime.event_settings)."""
        if len(slots) != len(values):
            raise ValueError("need one value per slot")
        for slot, value in zip(slots, values):
            if not 3 * self.spec.nang <= slot < self.spec.np:
                raise ValueError(f"input slot {slot} is not among the event constants")
            self.c.p[slot] = float(value)

    def restore(self):
        """Put back the element parameters' values from before the run (outside
        runs a torsion spring's reference is its free angle)."""
        fcc_events_restore(&self.c)

    def refresh(self, q):
        """Move the angle references (and their copies) to the angles at q: for loops
        that step in Python (fccgen.runs.scipy_ivp), after each accepted step."""
        qa = np.ascontiguousarray(q, float)
        cdef double[::1] qv = qa
        if qa.shape[0] != self.spec.n:
            raise ValueError(f"q must hold {self.spec.n} numbers")
        if self.spec.n:
            fcc_ev_refresh(&self.c, &qv[0])

    @property
    def largest_turn(self):
        """(|angle - theta_r| at the largest re-basing of the last run, the index of
        its angle among the angle quantities; -1 before any)."""
        return self.c.max_turn, self.c.max_turn_j

    @property
    def n_events(self):
        return self.spec.ne

    def reset(self, q, Engine engine=None, bint fold=False):
        """Start a run at q: angle references 0 (the start's angles are 0 by
        definition) and their copies in the element parameters, no rows active or
        resting, an empty log. ``engine``: the run's
        engine, for the rank decision at switches (fcc_ev_decide; None: every active
        row is used). The sparse path decides without the dense rank work. ``fold``:
        the run folds the used rows into the sparse engine's factorisation when its
        pattern holds them (engine/fcc_events_fold.c; :meth:`unfold` after the run),
        else they are a Schur complement."""
        if engine is not None and engine.c.sparse and self.c.mz != engine.c.m:
            if fcc_events_sparse_work(&self.c, engine.c.m) != FCC_OK:
                raise MemoryError("cannot allocate the warm starts of the events")
        fcc_events_reset(&self.c)
        if engine is not None and not engine.c.sparse and (
                self.c.aug == NULL or self.c.m != engine.c.m):
            rc = fcc_events_rank_work(&self.c, engine.c.lapack, engine.c.m)
            if rc == FCC_ERR_MEMORY:
                raise MemoryError("cannot allocate the rank work of the events")
            if rc != FCC_OK:
                raise ValueError("the events' rank decision needs the dense path's "
                                 "LAPACK table")
        if engine is not None:
            fcc_events_fold(&self.c, &engine.c, fold)

    def unfold(self, Engine engine):
        """Take the run's rows out of the engine's solves (after a run)."""
        self.was_folded = bool(self.c.fold)
        fcc_events_fold(&self.c, &engine.c, 0)

    @property
    def folded(self):
        """Whether the last run folded its rows (and kept them folded to its end)."""
        return self.was_folded

    @property
    def fold_trial(self):
        """Whether runs choose between the fold and the Schur complement after each
        switch by measuring both (engine/fcc_events_fold.c, "Which is cheaper"; the
        default), or keep the fold."""
        return bool(self.c.fold_trial)

    @fold_trial.setter
    def fold_trial(self, bint on):
        self.c.fold_trial = on

    @property
    def fold_trials(self):
        """(trials decided in the last run, of which the fold won)."""
        return self.c.n_trials, self.c.n_trials_folded

    @property
    def fold_left(self):
        """Runs that left the fold for the Schur complement (a row read a
        coordinate outside its pattern)."""
        return self.c.n_fold_off

    @property
    def switch_solves(self):
        """The last run's constrained solves for the rows' responses in the
        decisions of its switches (on the sparse path; one per row and instant)."""
        return self.c.n_switch_solves

    @property
    def tol(self):
        return self.spec.tol

    @property
    def dropped(self):
        """The events of the last run past the log's rows: counted, not in log()."""
        return max(0, self.c.n_log - self.spec.cap_log)

    def log(self):
        """The events of the last run: a (n, 11) array of LOG_COLUMNS (the first
        cap_log of them; ``dropped`` counts the rest)."""
        n = min(self.c.n_log, self.spec.cap_log)
        out = np.empty((n, FCC_LOG_COLS))
        for i in range(n):
            for j in range(FCC_LOG_COLS):
                out[i, j] = self.c.log[i * FCC_LOG_COLS + j]
        return out

    def quantity_kernels(self, q, v):
        """(r, G, (dG/dt) v) of the joint quantities at (q, v) with the current angle
        references: fresh arrays (for checks)."""
        qa = np.ascontiguousarray(q, float)
        va = np.ascontiguousarray(v, float)
        cdef double[::1] qv = qa, vv = va
        cdef int n = self.spec.n, nr = self.spec.nr
        if qa.shape[0] != n or va.shape[0] != n:
            raise ValueError(f"q and v must hold {n} numbers")
        r, g, b = np.empty(nr), np.empty((nr, n)), np.empty(nr)
        if nr:
            self.spec.tab.quantity_values(&qv[0], &vv[0], 0.0, self.c.p, self.c.r)
            self.spec.tab.quantity_gradients(&qv[0], &vv[0], 0.0, self.c.p, self.c.rg)
            self.spec.tab.quantity_bias(&qv[0], &vv[0], 0.0, self.c.p, self.c.rb)
            for i in range(nr):
                r[i], b[i] = self.c.r[i], self.c.rb[i]
                for j in range(n):
                    g[i, j] = self.c.rg[i * n + j]
        return r, g, b

    def gradient_rows(self, q):
        """(ptr, idx, values, dense) of the joint quantities' Jacobian at q with the
        current angle references: its structural nonzeros as the engine reads them
        (row j: values[ptr[j]:ptr[j + 1]] in the columns idx[ptr[j]:ptr[j + 1]]), and
        the dense kernel's (nr, n) rows written into a buffer of NaN (for checks)."""
        qa = np.ascontiguousarray(q, float)
        cdef double[::1] qv = qa
        cdef const fcc_event_table *tab = self.spec.tab
        cdef int n = self.spec.n, nr = self.spec.nr, nz = tab.n_gradient_nz
        if qa.shape[0] != n:
            raise ValueError(f"q must hold {n} numbers")
        ptr = np.array([tab.gradient_ptr[j] for j in range(nr + 1)], dtype=np.intp)
        idx = np.array([tab.gradient_idx[k] for k in range(nz)], dtype=np.intp)
        values, dense = np.full(max(nz, 1), np.nan), np.full(max(nr * n, 1), np.nan)
        cdef double[::1] vv = values, dv = dense
        if nr:
            tab.quantity_gradient_values(&qv[0], NULL, 0.0, self.c.p, &vv[0])
            tab.quantity_gradients(&qv[0], NULL, 0.0, self.c.p, &dv[0])
        return ptr, idx, values[:nz], dense[:nr * n].reshape(nr, n)

    def values(self, q, v, double t):
        """s_k at (q, v, t) with the current angle references: a fresh array."""
        qa = np.ascontiguousarray(q, float)
        va = np.ascontiguousarray(v, float)
        out = np.empty(self.spec.ne)
        cdef double[::1] qv = qa, vv = va, ov = out
        if self.spec.ne:
            fcc_ev_values(&self.c, &qv[0], &vv[0], t, &ov[0])
        return out


cdef fcc_events *ev_state(object events) except? NULL:
    """The C state of an EventSet (NULL for None)."""
    if events is None:
        return NULL
    return &(<EventSet>events).c
