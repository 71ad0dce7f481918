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

``result.info["setup"]`` says what each phase of a run's set-up cost (CPU seconds) and
whether it was reused: ``{"initial_state": {"seconds": ..., "reused": ...},
"rank_decision": {...}, "seconds": total}``.
"""
from __future__ import annotations

import hashlib
import time
from collections import OrderedDict
from dataclasses import replace

import numpy as np

KEPT = 8                  # set-ups kept per solver (least recently used dropped first)


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

    def record(self, phase: str, seconds: float, reused: bool) -> None:
        """Add a phase's CPU seconds (phases met twice in one run add up; reused only
        if every time was)."""
        entry = self.log.setdefault(phase, {"seconds": 0.0, "reused": True})
        entry["seconds"] += seconds
        entry["reused"] = entry["reused"] and reused

    def report(self) -> dict:
        """The run's set-up for result.info["setup"]."""
        out = {name: dict(entry) for name, entry in self.log.items()}
        out["seconds"] = float(sum(e["seconds"] for e in self.log.values()))
        return out


def kept_decision(solver, q, decide):
    """fccgen.rank's decision at q: the kept one for the same (q, parameters,
    tolerances), else ``decide()`` (kept from now on)."""
    store = solver.setup_store
    start = time.process_time()
    key = store.key("rank", q)
    decision = store.get(key)
    reused = decision is not None
    if not reused:
        decision = decide()
        store.put(key, decision)
    store.record("rank_decision", time.process_time() - start, reused)
    return decision


def kept_initial_state(solver, compute):
    """The solver's consistent initial state: the kept one for the same written
    positions, target speeds, parameters and tolerances, else ``compute()``. Its arrays
    are fresh copies each time (the caller owns them). Its seconds leave out the rank
    decision made within it (logged as rank_decision)."""
    store = solver.setup_store
    start = time.process_time()
    plan = solver.plan
    key = store.key("initial", plan.q0, plan.v_target)
    state = store.get(key)
    reused = state is not None
    within = store.log.get("rank_decision", {}).get("seconds", 0.0)
    if not reused:
        state = compute()
        store.put(key, state)
    else:                                      # as a fresh one leaves the solver:
        solver.set_time(0.0)                   # at t = 0, the rank decided at q
        solver.decide_rank(state.q)
    within = store.log.get("rank_decision", {}).get("seconds", 0.0) - within
    store.record("initial_state", time.process_time() - start - within, reused)
    return replace(state, q=np.array(state.q, dtype=float), v=np.array(state.v, dtype=float))
