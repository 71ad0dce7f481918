"""A run's set-up, kept for the next run from the same start, and what it cost.

Every ``simulate`` call sets up before its first step: the consistent initial state (the
Newton projection of the written positions, the initial speeds) and the rank decision
of the constraint Jacobian B at the start (fccgen.rank: an SVD of B, O(n^3) for the
models that take the dense SVD). Both are functions of the start positions, the model's
numbers and the solver's tolerances only, so a solver keeps them keyed by a hash of
(positions, speeds where they enter, parameters, tolerances): a second run from the
same start takes them as they are, a changed q0 (or a solver of other numbers,
``with_parameters``) decides afresh. What is kept is the answer itself, so a reused
set-up gives the run bit for bit the same start as a fresh one.

The rank decisions are kept a second time, for every solver of the process, keyed by
the bytes of the Jacobian they were made from (:func:`shared_decision`): a decision is
a function of B, its row groups and fccgen.rank's constants alone, so a solver of other
masses (``with_parameters``, ``simulate_many``), whose B at the same q is the same, takes
it without an SVD, and a number that moves B (a length, a point) misses it.

``result.info["setup"]`` says what each phase of a run's set-up cost (CPU seconds),
whether it was reused and, for the decisions, how they were made (``method``:
fccgen.rank's RankDecision.how): ``{"initial_state": {"seconds": ..., "reused": ...},
"rank_decision": {..., "method": "svd"}, "off_constraint_test": {...}, "seconds":
total}`` (off_constraint_test: the sparse path's test for rows dependent only on the
constraints, CompiledSolver._manifold_redundancy).
"""
from __future__ import annotations

import hashlib
import threading
import time
from collections import OrderedDict
from dataclasses import replace

import numpy as np

KEPT = 8                  # set-ups kept per solver (least recently used dropped first)
SHARED = 64               # decisions kept per process, by their Jacobian's bytes
_shared: OrderedDict[str, object] = OrderedDict()
_shared_lock = threading.Lock()


class SetupStore:
    """The kept set-ups of one solver and the cost log of the current run."""

    def __init__(self, solver):
        self._kept: OrderedDict[str, object] = OrderedDict()
        params = [np.asarray(el.params, float) for el in solver.plan.elements]
        fixed = hashlib.sha256()
        fixed.update(np.concatenate(params).tobytes() if params else b"")
        fixed.update(repr((solver.rank_tol, solver.position_tol, solver.max_newton,
                           solver.linear_solver)).encode())
        self._fixed = fixed.digest()
        self.log: dict = {}

    def key(self, kind: str, *arrays) -> str:
        """The hash of ``kind``, the arrays, the parameters and the tolerances."""
        h = hashlib.sha256(self._fixed)
        h.update(kind.encode())
        for a in arrays:
            a = np.ascontiguousarray(a, dtype=float)
            h.update(str(a.shape).encode())
            h.update(a.tobytes())
        return h.hexdigest()

    def get(self, key: str):
        if key not in self._kept:
            return None
        self._kept.move_to_end(key)
        return self._kept[key]

    def put(self, key: str, value) -> None:
        self._kept[key] = value
        self._kept.move_to_end(key)
        while len(self._kept) > KEPT:
            self._kept.popitem(last=False)

    def start_run(self) -> None:
        """A new run: its set-up log starts empty."""
        self.log = {}

    def record(self, phase: str, seconds: float, reused: bool, method=None) -> None:
        """Add a phase's CPU seconds (phases met twice in one run add up; reused only
        if every time was; method: how a decision was made, the first one made)."""
        entry = self.log.setdefault(phase, {"seconds": 0.0, "reused": True})
        entry["seconds"] += seconds
        entry["reused"] = entry["reused"] and reused
        if method is not None:
            entry.setdefault("method", method)

    def report(self) -> dict:
        """The run's set-up for result.info["setup"]."""
        out = {name: dict(entry) for name, entry in self.log.items()}
        out["seconds"] = float(sum(e["seconds"] for e in self.log.values()))
        return out


def jacobian_key(kind: str, B, groups, *extra) -> str:
    """The hash of a Jacobian (dense or SciPy sparse: its pattern and values), its row
    groups and ``extra`` numbers: what a rank decision depends on."""
    h = hashlib.sha256(kind.encode())
    if hasattr(B, "indptr"):
        B = B.tocsr()
        parts = [B.indptr, B.indices, B.data]
    else:
        parts = [np.ascontiguousarray(B, dtype=float)]
    h.update(repr((B.shape, extra)).encode())
    for a in parts:
        h.update(np.ascontiguousarray(a).tobytes())
    if groups is not None:
        labels = np.asarray(groups)
        h.update(labels.tobytes() if labels.dtype.kind in "iub" else repr(list(groups)).encode())
    return h.hexdigest()


def forget() -> None:
    """Drop the decisions kept for every solver of the process (each solver's own
    set-ups stay): the next solver of new numbers decides afresh."""
    with _shared_lock:
        _shared.clear()


def shared_decision(key: str, decide):
    """(decision, reused): the process's kept decision under ``key`` (jacobian_key),
    else ``decide()``, kept from now on (the SHARED most recent)."""
    with _shared_lock:
        if key in _shared:
            _shared.move_to_end(key)
            return _shared[key], True
    decision = decide()
    with _shared_lock:
        _shared[key] = decision
        while len(_shared) > SHARED:
            _shared.popitem(last=False)
    return decision, False


def kept_decision(solver, q, jacobian, decide):
    """fccgen.rank's decision at q: the kept one for the same (q, parameters,
    tolerances), else the process's for the same Jacobian (``jacobian()``: B at q),
    else ``decide(B)`` (kept from now on in both)."""
    store = solver.setup_store
    start = time.process_time()
    key = store.key("rank", q)
    decision = store.get(key)
    reused = decision is not None
    if not reused:
        B = jacobian()
        decision, reused = shared_decision(
            jacobian_key("rank", B, solver.row_groups, solver.n_q), lambda: decide(B))
        store.put(key, decision)
    store.record("rank_decision", time.process_time() - start, reused,
                 getattr(decision, "how", None))
    return decision


def _decisions_seconds(store) -> float:
    """The seconds logged so far by the decisions (rank, off-constraint test)."""
    return sum(store.log.get(p, {}).get("seconds", 0.0)
               for p in ("rank_decision", "off_constraint_test"))


def kept_initial_state(solver, compute):
    """The solver's consistent initial state: the kept one for the same written
    positions, target speeds, parameters and tolerances, else ``compute()``. Its arrays
    are fresh copies each time (the caller owns them). Its seconds leave out the
    decisions made within it (logged as rank_decision and off_constraint_test)."""
    store = solver.setup_store
    start = time.process_time()
    plan = solver.plan
    key = store.key("initial", plan.q0, plan.v_target)
    state = store.get(key)
    reused = state is not None
    within = _decisions_seconds(store)
    if not reused:
        state = compute()
        store.put(key, state)
    else:                                      # as a fresh one leaves the solver:
        solver.set_time(0.0)                   # at t = 0, the rank decided at q
        solver.decide_rank(state.q)
    within = _decisions_seconds(store) - within
    store.record("initial_state", time.process_time() - start - within, reused)
    return replace(state, q=np.array(state.q, dtype=float), v=np.array(state.v, dtype=float))
