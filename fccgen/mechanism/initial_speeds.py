"""Initial speeds given as joint rates and slide speeds (``initial: joints:``).

A joint rate (revolute, cylindrical: ``rate``) or slide speed (prismatic, cylindrical:
``speed``) is linear in the speeds v at fixed positions q: row c_J with c_J v = d_J.
The initial speeds are then

    v = argmin (v - v_t)^T M (v - v_t) / 2   subject to   B v = -dg/dt,  C v = d,

the speeds nearest to the model's other initial speeds v_t in the kinetic-energy metric
that keep every given joint speed *exactly* (the velocity projection alone would move
them: a crank given 6 rad/s came out at 1.66 rad/s). With N a basis of the null space
of B, v = v_p + N z (v_p: the minimum-norm solution of B v = -dg/dt, zero without
drivers) and the reduced problem is a small KKT system in z; given speeds that the
constraints do not allow together (two rates on one degree of freedom that disagree, a
rate on a joint the mechanism cannot move) leave a residual C v - d and are refused.
"""
from __future__ import annotations

import numpy as np

from ..errors import ModelError
from .joints import ANGLE_TYPES, SLIDE_TYPES
from .outputs import joint_columns

QUANTITY_TYPES = {"rate": ANGLE_TYPES, "speed": SLIDE_TYPES}


def speed_rows(solver, q: np.ndarray, wanted: dict) -> tuple[np.ndarray, np.ndarray, list]:
    """(C, d, items) for ``wanted`` {joint: (quantity, value, where)}: each joint
    quantity evaluated at q with v = each unit vector (it is linear in v)."""
    plan = solver.plan
    n = plan.n_q
    eye = np.eye(n)
    columns: dict[str, np.ndarray] = {}
    for k, (name, _) in enumerate(plan.triples):
        for c, axis in enumerate("xyz"):
            columns[f"{name}.{axis}"] = np.full(n, q[3 * k + c])
            columns[f"{name}.v{axis}"] = eye[:, 3 * k + c].copy()
    omega = np.array([solver.body_outputs(q, eye[i])[:, 3:6] for i in range(n)])
    for b, (name, _) in enumerate(plan.bodies):
        for c, axis in enumerate("xyz"):
            columns[f"{name}.w{axis}"] = omega[:, b, c]
    values = joint_columns(plan, columns, n)
    rows, d, items = [], [], []
    for joint, (quantity, value, where) in wanted.items():
        rows.append(values[f"{joint}.{quantity}"])
        d.append(value)
        items.append((f"initial.joints.{joint}.{quantity}", value, where))
    return np.array(rows), np.array(d, float), items


def speeds_with_joints(solver, q: np.ndarray, v_target: np.ndarray, wanted: dict,
                       B: np.ndarray, M: np.ndarray) -> np.ndarray:
    """The initial speeds keeping the joint speeds ``wanted`` exactly (module
    docstring); ModelError naming the first joint speed the constraints refuse."""
    C, d, items = speed_rows(solver, q, wanted)
    import scipy.linalg                  # only on this (rare) path
    N = scipy.linalg.null_space(B) if B.size else np.eye(len(q))
    # drivers: B v = -dg/dt, v = v_p + N z with v_p its minimum-norm solution
    rate = solver.constraint_rate(q) if hasattr(solver, "constraint_rate") else None
    v_p = (np.linalg.lstsq(B, -rate, rcond=1e-10)[0] if rate is not None and B.size
           and np.any(rate) else np.zeros(len(q)))
    CN = C @ N
    K = np.block([[N.T @ M @ N, CN.T], [CN, np.zeros((len(d), len(d)))]])
    rhs = np.concatenate([N.T @ M @ (v_target - v_p), d - C @ v_p])
    sol = np.linalg.lstsq(K, rhs, rcond=None)[0]
    v = v_p + N @ sol[:N.shape[1]]
    residual = C @ v - d
    scale = max(1.0, float(np.max(np.abs(d))))
    bad = np.flatnonzero(np.abs(residual) > 1e-9 * scale)
    if bad.size:
        got = C @ v
        item, _, where = items[int(bad[0])]
        given = ", ".join(f"{it.split('.', 2)[2]} = {val:g}" for it, val, _ in items)
        nearest = ", ".join(f"{it.split('.', 2)[2]} = {g:.6g}"
                            for (it, _, _), g in zip(items, got))
        raise ModelError(where.file, where.line, "initial.joints",
                         "these joint speeds cannot all hold with the constraints (one "
                         "degree of freedom too few, or a joint that cannot move); the "
                         f"nearest consistent speeds are {nearest}", given)
    return v


def initial_speeds(solver, q, v_target) -> np.ndarray:
    """The model's initial speeds at the assembled positions q (both solvers): the
    M-orthogonal projection of v_target onto B v = 0, or, when the model gives joint
    speeds (``initial: joints:``), the nearest speeds that keep them exactly."""
    wanted = dict(getattr(solver.plan.model.initial, "joint_speeds", None) or {})
    if not wanted:
        return solver.project_velocities(q, v_target)
    return speeds_with_joints(solver, q, np.asarray(v_target, float), wanted,
                              solver.constraint_jacobian(q), solver.mass_matrix(q))
