"""Joint quantities as result columns (docs/design.md sections 2b and 4), computed after a
run from the recorded coordinates and speeds, vectorised over the output samples.

* ``J.angle`` (revolute, cylindrical): the rotation of body B relative to body A
  about the joint axis, right-handed, 0 in the configuration the model file writes
  (plan.q0: 0 at t = 0 unless ``initial: joints:`` gives an angle, which it then
  starts at), counted over turns along the records (:mod:`.turns`). With
  C = R_A^T R_B (B's frame seen from A's) and D = C C_0^T (C_0 as written), a_A the
  axis in A's frame (as written) and n1 a unit vector perpendicular to it:
  angle = atan2(a_A.(n1 x D n1), n1.D n1).
* ``J.rate``: (w_B - w_A).a, a = R_A a_A the axis now.
* ``J.position`` (prismatic, cylindrical): (r_Jb - r_Ja).a, the slide of B's joint
  point from A's along the axis (0 at t = 0); ``J.speed``: (v_Jb - v_Ja).a, exact on
  the constraint manifold where r_Jb - r_Ja is parallel to a and a' is perpendicular.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import RunWarning
from ..model.types import GROUND
from .joints import ANGLE_TYPES, SLIDE_TYPES, perpendiculars
from .turns import count_turns


class _Series:
    """Positions and speeds of the model's triples over the samples of a result."""

    def __init__(self, plan, columns: dict[str, np.ndarray], n: int):
        self.plan, self.columns, self.n = plan, columns, n

    def triple(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(n, 3) position and speed of a point or vector (fixed: constant, at rest)."""
        if name in self.plan.index:
            c = self.columns
            return (np.column_stack([c[f"{name}.{k}"] for k in "xyz"]),
                    np.column_stack([c[f"{name}.v{k}"] for k in "xyz"]))
        m = self.plan.model
        value = m.points[name].at if name in m.points else m.vectors[name].along
        return np.tile(np.asarray(value, float), (self.n, 1)), np.zeros((self.n, 3))

    def rotation(self, body: str) -> np.ndarray:
        """(n, 3, 3) body frame R = [e1 e2 e3] of a body (ground: the identity)."""
        if body == GROUND:
            return np.tile(np.eye(3), (self.n, 1, 1))
        b = self.plan.model.bodies[body]
        ri, rj, u = (self.triple(x)[0] for x in (b.i, b.j, b.u))
        e1 = rj - ri
        e1 /= np.linalg.norm(e1, axis=1)[:, None]
        e3 = np.cross(e1, u)
        e3 /= np.linalg.norm(e3, axis=1)[:, None]
        return np.stack([e1, np.cross(e3, e1), e3], axis=2)

    def omega(self, body: str) -> np.ndarray:
        names = [f"{body}.w{k}" for k in "xyz"]
        if all(n in self.columns for n in names):
            return np.column_stack([self.columns[n] for n in names])
        return np.zeros((self.n, 3))


def joint_columns(plan, columns: dict[str, np.ndarray], n: int, *,
                  near_given: bool = True, raw: dict | None = None
                  ) -> dict[str, np.ndarray]:
    """The joint columns of a lowered model's result (empty without joints), angles
    unwrapped by numpy.unwrap's nearest branch (records of a run count them with
    their rates instead: :func:`add_joint_columns`); near_given=False: angles not
    moved by whole turns towards the initial ones. raw: filled with {angle column:
    (angles within half a turn, rates)}."""
    lowering = getattr(plan.model, "mechanism", None)
    if lowering is None or n == 0:
        return {}
    s, written = _Series(plan, columns, n), _written(plan)
    out: dict[str, np.ndarray] = {}
    for jl in lowering.joints:
        j = jl.joint
        A, B = j.bodies
        if j.type in ANGLE_TYPES:
            RA, RB = s.rotation(A), s.rotation(B)
            a_A = written.rotation(A)[0].T @ j.axes[0]
            n1 = perpendiculars(a_A)[0]
            C = np.einsum("nki,nkj->nij", RA, RB)
            D = np.einsum("nij,kj->nik", C, written.rotation(A)[0].T @ written.rotation(B)[0])
            Dn = D @ n1
            angle = np.arctan2(np.cross(n1, Dn) @ a_A, Dn @ n1)
            a = RA @ a_A
            rate = np.einsum("ni,ni->n", s.omega(B) - s.omega(A), a)
            if raw is not None:
                raw[f"{j.name}.angle"] = (angle, rate)
            angle = np.unwrap(angle)
            out[f"{j.name}.angle"] = _near_given(plan, j.name, angle) if near_given \
                else angle
            out[f"{j.name}.rate"] = rate
        if j.type in SLIDE_TYPES:
            (ra, va), (rb, vb) = s.triple(f"{j.name}_a"), s.triple(f"{j.name}_b")
            a = s.triple(f"{j.name}_axis")[0]
            out[f"{j.name}.position"] = np.einsum("ni,ni->n", rb - ra, a)
            out[f"{j.name}.speed"] = np.einsum("ni,ni->n", vb - va, a)
    return out


def _written(plan) -> _Series:
    """The configuration the model file writes (plan.q0), as a one-row series."""
    columns = {}
    for k, (name, _) in enumerate(plan.triples):
        for c, axis in enumerate("xyz"):
            columns[f"{name}.{axis}"] = np.array([plan.q0[3 * k + c]])
            columns[f"{name}.v{axis}"] = np.zeros(1)
    return _Series(plan, columns, 1)


def _near_given(plan, joint: str, angle: np.ndarray) -> np.ndarray:
    """An unwrapped angle moved by whole turns so that it starts nearest the initial
    angle the model gives the joint (``initial: joints: {J: {angle: a}}``), if any."""
    given = (getattr(plan.model.initial, "joint_positions", None) or {}).get(joint)
    if given is None or given[0] != "angle" or not len(angle):
        return angle
    return angle + 2 * np.pi * np.round((given[1] - angle[0]) / (2 * np.pi))


def add_joint_columns(plan, result, warn: bool = True) -> None:
    """Append the joint columns to ``result`` (in place), its angles counted over turns
    along its records and across its events (``result.events``). An angle whose turns
    the records are too far apart to count is NaN from there, named with the time in
    ``info["angle_turns_lost"]`` and, with ``warn``, in a warning."""
    raw: dict[str, tuple] = {}
    result.columns.update(joint_columns(plan, result.columns, len(result.t), raw=raw))
    result.angles_within_a_turn = raw        # for settle_turns
    _count_angles(plan, result, warn)


def _count_angles(plan, result, warn: bool) -> None:
    """The angle columns of ``result`` counted over turns along its records
    (:func:`fccgen.mechanism.turns.count_turns`) from the angles within half a turn
    and the rates its columns were made of, across its events."""
    impacts = sorted(e["t"] for e in getattr(result, "events", None) or ())
    lost: dict[str, float] = {}
    for name, (angle, rate) in result.angles_within_a_turn.items():
        counted, known, _ = count_turns(angle[None], rate[None], result.t, impacts)
        counted, known = counted[0], int(known[0])
        if known < len(result.t):
            counted[known:] = np.nan
            lost[name] = float(result.t[known])
        result.columns[name] = _near_given(plan, name[:-len(".angle")], counted)
    result.info.pop("angle_turns_lost", None)
    if lost:
        result.info["angle_turns_lost"] = lost
    if warn:
        warn_turns_lost(result)


def settle_turns(plan, result) -> None:
    """After a run whose joint columns were made without warnings, and once its
    events are known: the angles counted again across the events (which break the
    rates), and the warnings of the angles whose turns are lost."""
    if getattr(result, "events", None) and hasattr(result, "angles_within_a_turn"):
        _count_angles(plan, result, True)
    else:
        warn_turns_lost(result)


def warn_turns_lost(result) -> None:
    for name, t in (result.info.get("angle_turns_lost") or {}).items():
        text = (f"{name} is NaN from t = {t:.9g} s on: the records are too far apart "
                "to count its turns (it moved more than a quarter turn from what its "
                "rates say); record more often (output_dt)")
        said = result.info.setdefault("warnings", [])
        if text not in said:
            said.append(text)
            warnings.warn(text, RunWarning, stacklevel=3)
