"""The joint rows that a run's events hold at each record, and the accelerations with
them held: what the joint reactions and the driver forces, computed after a run
(fccgen.mechanism.reactions, fccgen.mechanism.driver_forces), need once a latch has
locked.

A lock (and a bounce that rests) holds its joint's quantities r_j(q), the angle of a
revolute joint, the slide of a prismatic one, both of a cylindrical one, until an
unlock (a release) of them (docs/events.md). A record at an event's time shows the
state after the event, so a record at t holds what the events up to t left held.

With the rows r_j held the motion obeys M q'' + B^T lambda + G^T nu = f - h,
B q'' = -c, G q'' = -(dG/dt) q' (G = dr_j/dq). The solver's own accelerations a0
leave G out; the held ones are a = a0 + Z mu, with z_j the constrained response to
the generalized force G_j^T (M z + B^T l = G_j^T, B z = 0) and (G Z) mu =
-(G a0 + (dG/dt) q'), the Schur complement the engine uses in the step. Z comes from
the solver's own M-orthogonal velocity projection P: for any w with
M w = G^T + B^T y, z = P(w) - P(0); w = (M + s B^T B)^-1 G^T is one (s > 0: A is
definite where the motion is defined, even with massless coordinates). Held rows
that follow from B and from each other (a redundant lock) leave G Z singular; its
least-squares mu gives the same a, since each direction of its null space has
z^T M z = 0."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..errors import SimulationError

# Relative singular values of G Z (its largest = 1) below this are redundant locks.
RCOND = 1e-10
# Coordinates up to which A = M + s B^T B is formed and solved dense (SciPy's sparse
# LU costs more than the dense solve below a few hundred).
DENSE_MAX = 300
# Largest |G a + (dG/dt) q'| of the held accelerations relative to |G a0| + |bias|:
# the Schur solve leaves rounding; a larger residual means rows that cannot hold.
RESIDUAL_TOL = 1e-7


def joint_kinds(joint_type: str) -> tuple[str, ...]:
    """The quantities a lock of a joint of this type holds (fccgen.numeric.events)."""
    if joint_type == "revolute":
        return ("angle",)
    if joint_type == "cylindrical":
        return ("angle", "position")
    return ("position",)


class Segment(NamedTuple):
    """Records start .. stop - 1 hold the rows ``keys`` ((joint, kind) pairs)."""
    start: int
    stop: int
    keys: frozenset


def held_segments(model, times, events: list[dict]) -> list[Segment]:
    """The maximal runs of records with the same held rows (records without any
    included), from the run's event table (fccgen.events.table.event_rows)."""
    by_name = {e.name: e for e in model.events}
    joints = {jl.joint.name: jl.joint for jl in model.mechanism.joints} \
        if getattr(model, "mechanism", None) is not None else {}
    times = np.asarray(times, float)
    held: frozenset = frozenset()
    changes = [(0, held)]
    for row in events:
        event = by_name[row["name"]]
        if event.joint is None or event.joint not in joints:
            continue
        keys = {(event.joint, kind) for kind in joint_kinds(joints[event.joint].type)}
        if row["action"] in ("lock", "rest"):
            new = held | keys
        elif row["action"] in ("unlock", "release"):
            new = held - keys
        else:
            continue
        if new != held:
            held = new
            changes.append((int(np.searchsorted(times, row["t"], side="left")), held))
    out, n = [], len(times)
    for (start, keys), (stop, _) in zip(changes, changes[1:] + [(n, None)]):
        if stop > start:
            if out and out[-1].keys == keys:
                out[-1] = Segment(out[-1].start, stop, keys)
            else:
                out.append(Segment(start, stop, keys))
    return out


def of_run(solver, result, rows, dropped: int = 0) -> "HeldRows | None":
    """The held rows of a finished run with events (None when no record holds any);
    rows: as :class:`HeldRows` takes it; dropped: events past the log's rows."""
    segments = held_segments(solver.plan.model, result.t, result.events)
    if not any(seg.keys for seg in segments) and not dropped:
        return None
    known = len(result.t)
    if dropped:
        # the log kept the first events: what the later ones held is not known
        last = result.events[-1]["t"] if result.events else 0.0
        known = int(np.searchsorted(np.asarray(result.t, float), last, side="left"))
    return HeldRows(solver, segments, rows, known)


class HeldRows:
    """The held rows of one finished run: its segments and the accelerations with
    them. ``rows(q, v, keys)`` gives (G (k, n), (dG/dt) q' (k,)) of the quantities
    ``keys`` in order: the solver's own kernels (compiled: the event module; NumPy:
    its joint quantities). Records from ``known`` on come after events that the log
    dropped: what they hold is not known."""

    def __init__(self, solver, segments: list[Segment], rows, known: int):
        self.solver, self.segments, self.rows, self.known = solver, segments, rows, known

    def unknown_reason(self, times) -> str:
        """Why the records from ``known`` on have no held rows ("" if all are known)."""
        if self.known >= len(times):
            return ""
        return ("the run's event log is full (the events past its rows were dropped), "
                f"so the joints its locks held from t = {times[self.known]:.9g} s on "
                "are not known")

    def accelerations(self, q, v, keys) -> np.ndarray:
        """q'' at (q, q') with the rows ``keys`` held (module docstring), at the
        solver's time (set by the caller)."""
        return self.solve(q, v, keys)[0]

    def solve(self, q, v, keys) -> tuple[np.ndarray, np.ndarray]:
        """(q'', G): :meth:`accelerations` and the held rows' gradients (k, n), in the
        order of sorted(keys), that they hold."""
        s = self.solver
        a0 = s.accelerations(q, v)
        if not keys:
            return a0, np.zeros((0, len(q)))
        G, bias = self.rows(q, v, sorted(keys))
        Z = self._responses(q, G)
        S = G @ Z
        rhs = -(G @ a0 + bias)
        mu = np.linalg.lstsq(S, rhs, rcond=RCOND)[0]
        a = a0 + Z @ mu
        scale = np.abs(G @ a0).max() + np.abs(bias).max() + 1e-300
        left = np.abs(G @ a + bias).max()
        if not left <= RESIDUAL_TOL * scale:
            raise SimulationError(
                f"the held joint rows {', '.join(f'{j}.{k}' for j, k in sorted(keys))}"
                f" cannot hold at this record (their accelerations are left at "
                f"{left:.3g} against {scale:.3g})")
        return a, G

    def _responses(self, q, G: np.ndarray) -> np.ndarray:
        """(n, k): the constrained responses z_j to the forces G_j^T."""
        s = self.solver
        if len(q) <= DENSE_MAX:
            M, B = s.mass_matrix(q), s.constraint_jacobian(q)
            scale = (np.diag(M).max() / max(np.einsum("ij,ij->i", B, B).max(), 1e-300)
                     if B.shape[0] else 0.0)
            w = np.linalg.solve(M + scale * (B.T @ B), G.T)
        else:
            M = sp.csr_matrix(s.mass_matrix(q))
            B = sp.csr_matrix(s.constraint_jacobian_sparse(q))
            scale = (M.diagonal().max() / max(B.multiply(B).sum(axis=1).max(), 1e-300)
                     if B.shape[0] else 0.0)
            w = splu((M + scale * (B.T @ B)).tocsc()).solve(np.ascontiguousarray(G.T))
        zero = s.project_velocities(q, np.zeros(len(q)))
        return np.column_stack([s.project_velocities(q, w[:, j]) - zero
                                for j in range(G.shape[0])])
