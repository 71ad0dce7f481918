"""Initial positions given as joint angles and slide positions (``initial: joints:
{A: {angle: 0.3}}``, ``{S: {position: 0.05}}``): the mechanism is assembled at them.

Joint angles are measured from the configuration the model file writes, slide
positions from the coincidence of the joint's two points (both 0 there; docs/design.md
section 2b). Starting from the written configuration assembled onto g = 0, the given
values c_J(q) = d_J are reached by continuation in steps of at most STEP_ANGLE rad and
STEP_LENGTH body lengths, each closed by Newton on

    g(q) = 0,   c(q) - d_k = 0     (d_k: the k-th step towards d)

with the minimum-norm change dq = -[B; C]^+ [g; c - d_k]: the second body's side turns
or slides, the rest follows as little as the loops allow. C is the joint's rate (slide
speed) row, the derivative of c along the constraint manifold
(:func:`fccgen.mechanism.initial_speeds.speed_rows`), exact once g = 0, so Newton
converges quadratically near the solution. An angle is reached the short way (whole
turns taken off: they give the same configuration), so the walk turns at most half a
turn; a slide is walked in at most MAX_STEPS steps (longer ones when it is far).
Values the mechanism cannot take (beyond a four-bar's limit position, two angles on
one degree of freedom that disagree, a joint that cannot move) leave Newton without
convergence and are refused with the nearest values reached.

Angle drivers. A driver's row sin(theta - f) vanishes at theta = f and at f + pi, so
the first projection, which starts from the written angle, meets the nearer root: a
driver with f(0) more than a quarter turn from the written angle would be assembled
on the other branch and follow f - pi for the whole run. When a driven angle is on
that branch, the mechanism is assembled again from the written configuration by the
same continuation, the angle drivers' rows left out and their joints taken to f(0)
(with the ``initial: joints`` values), so the run starts on f(0).
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import ModelError
from .initial_speeds import speed_rows
from .outputs import joint_columns

STEP_ANGLE = 0.1           # rad per continuation step
STEP_LENGTH = 0.05         # body lengths per continuation step
JOINT_TOL = 1e-12          # rad, and body lengths for positions
MAX_NEWTON = 30
MAX_STEPS = 1000           # continuation steps at most: a far slide takes longer steps
RATE_OF = {"angle": "rate", "position": "speed"}


def _values(plan, q_ref: np.ndarray, q: np.ndarray, wanted: dict) -> np.ndarray:
    """Each wanted quantity at q: an angle relative to q_ref, a position absolute."""
    columns: dict[str, np.ndarray] = {}
    for k, (name, _) in enumerate(plan.triples):
        for c, axis in enumerate("xyz"):
            columns[f"{name}.{axis}"] = np.array([q_ref[3 * k + c], q[3 * k + c]])
            columns[f"{name}.v{axis}"] = np.zeros(2)
    values = joint_columns(plan, columns, 2, near_given=False)   # no 1e6-rad offsets
    return np.array([values[f"{j}.{qty}"][1] - (qty == "angle") * values[f"{j}.{qty}"][0]
                     for j, (qty, _, _) in wanted.items()])


def _refuse(wanted: dict, reached: np.ndarray, aim: np.ndarray, why: str) -> ModelError:
    where = next(iter(wanted.values()))[2]
    given = ", ".join(f"{j}.{qty} = {v:g}" for j, (qty, v, _) in wanted.items())
    near = ", ".join(f"{j}.{qty} = {r:.6g}" for (j, (qty, _, _)), r
                     in zip(wanted.items(), reached))
    aimed = ", ".join(f"{a:.6g}" for a in aim)
    return ModelError(where.file, where.line, "initial.joints",
                      f"the mechanism cannot be assembled at these joint values ({why}); "
                      f"it assembles up to {near} and fails on the way to {aimed}", given)


def driven_angles(plan) -> list[tuple[str, float, object, int]]:
    """(joint, f(0), where, constraint row) of every angle driver."""
    lowering = getattr(plan.model, "mechanism", None)
    drivers = [d for d in (getattr(lowering, "drivers", None) or [])
               if d.quantity == "angle"]
    if not drivers:
        return []
    from ..expressions.time_jets import time_function
    from .lowering import driver_label
    rows, start = {}, 0
    for el in plan.elements:
        rows[el.label] = start
        start += el.cls.n_g
    return [(d.joint, float(time_function(d.function)(0.0)[0]), d.where,
             rows[driver_label(d)]) for d in drivers]


def _flipped(plan, q: np.ndarray, driven: list) -> list:
    """The angle drivers whose joint at q sits on the branch f(0) + pi (module
    docstring): cos(theta - f(0)) < 0, theta measured from the written angle."""
    if not driven:
        return []
    wanted = {j: ("angle", f0, where) for j, f0, where, _ in driven}
    theta = _values(plan, np.asarray(plan.q0, float), q, wanted)
    return [d for d, th in zip(driven, theta) if math.cos(th - d[1]) < 0.0]


def assemble_at_joints(solver, q: np.ndarray) -> np.ndarray:
    """q (assembled at the written configuration) moved to the model's initial joint
    angles and positions, and to the angle drivers' f(0) where the first projection
    met the other branch; q itself when none of these applies (module docstring)."""
    plan = solver.plan
    wanted = dict(getattr(plan.model.initial, "joint_positions", None) or {})
    driven = driven_angles(plan)
    flipped = _flipped(plan, q, driven)
    keep = None
    if flipped:
        keep = np.ones(plan.n_g, bool)
        for joint, f0, where, row in driven:
            keep[row] = False
            wanted.setdefault(joint, ("angle", f0, where))
        q = np.array(plan.q0, float)
    if not wanted:
        return q
    return _continue(solver, q, wanted, keep)


def _continue(solver, q: np.ndarray, wanted: dict, keep) -> np.ndarray:
    """The continuation of the module docstring from q (assembled, or the written
    configuration) to the ``wanted`` values ({joint: (quantity, value, where)});
    keep: the constraint rows it holds (None: all)."""
    plan = solver.plan
    length = solver.length_scale
    rates = {j: (RATE_OF[qty], 0.0, where) for j, (qty, _, where) in wanted.items()}
    is_angle = np.array([qty == "angle" for qty, _, _ in wanted.values()])
    target = np.array([v for _, v, _ in wanted.values()], float)
    scale = np.where(is_angle, 1.0, length)
    q_ref = np.array(q, float)
    start = np.where(is_angle, 0.0, _values(plan, q_ref, q_ref, wanted))
    # An angle and the same angle plus whole turns are one configuration: the walk
    # goes the short way, at most half a turn (it went 1e9 rad in 0.1 rad steps).
    target = np.where(is_angle, start + np.remainder(target - start + math.pi,
                                                     2 * math.pi) - math.pi, target)
    step = np.where(is_angle, STEP_ANGLE, STEP_LENGTH * length)
    n_steps = min(MAX_STEPS, max(1, math.ceil(float(np.max(np.abs(target - start)
                                                           / step)))))
    q, accumulated = q_ref.copy(), start.copy()
    keep = np.ones(plan.n_g, bool) if keep is None else keep
    for k in range(1, n_steps + 1):
        d = start + (target - start) * k / n_steps
        q, value = _newton(solver, q, q_ref if k == 1 else q_prev, accumulated, d,
                           wanted, rates, is_angle, scale, length, keep)
        q_prev, accumulated = q.copy(), value
    return q


def _newton(solver, q, q_prev, accumulated, d, wanted, rates, is_angle, scale, length,
            keep):
    """(q, values) with g(q) = 0 (the rows kept) and the joint values d, from q;
    ModelError if not."""
    plan = solver.plan
    for _ in range(MAX_NEWTON):
        rel = _values(plan, q_prev, q, wanted)
        value = np.where(is_angle, accumulated + rel, rel)
        g = solver.constraints(q)[keep]
        miss = (value - d) / scale
        if np.max(np.abs(g), initial=0.0) <= solver.position_tol and \
                np.max(np.abs(miss)) <= JOINT_TOL:
            return q, value
        if not np.all(np.isfinite(g)) or np.max(np.abs(g), initial=0.0) > 10 * length:
            break
        A = np.vstack([solver.constraint_jacobian(q)[keep],
                       speed_rows(solver, q, rates)[0]])
        q = q + np.linalg.lstsq(A, -np.concatenate([g, value - d]), rcond=None)[0]
    raise _refuse(wanted, accumulated, d,
                  "a value beyond the mechanism's reach, values that contradict each "
                  "other, or a joint the constraints hold fixed")
