"""Geometry keys: points' positions (``points.NAME.at[k]``), load points
(``loads[K].at[k]``) and distance constraints' lengths (``constraints[K].length``).

They enter the elements' parameters nonlinearly (a body's length l, its angles alpha
and beta, its mass centre and inertia in the body's basis are norms, cosines and
quotients of the written geometry) and they move the consistent start. The kernels'
derivatives with respect to the elements' parameters are the generated ones
(fccgen.derive.parameters), as for every other key; what a geometry key adds is

- dP/dp, the elements' parameters' derivative: the lowering of the model file is
  closed-form algebra of its numbers, smooth where the model is accepted, and is
  differentiated by central differences combined by Richardson's rule over two step
  pairs (h, h/2) and (h/2, h/4), h = STEP times the model's length scale. Their
  truncation error is O(h^4), about 1e-12 relative, and rounding about 1e-14 / STEP;
  the two Richardson values must agree to AGREE relative, or the key is refused (a
  kink: the lowering changes its branch here);
- the start's derivative. The start is assembled by Newton's method with M-weighted
  minimal corrections from the written positions q_w. Where q_w already satisfies the
  constraints (the start is the written configuration, as in every model whose
  lengths follow from its points), the first Newton step from q_w(p + d) is the
  whole change to first order in d, so

      dq0/dp = y:   M (y - dq_w/dp) + B^T mu = 0,   B y = -(dg/dp)|_q,

  the same linearised projection the run applies to the sensitivities after every
  step (B, M at the start; (dg/dp)|_q the constraints' change at fixed coordinates).
  A start Newton has moved away from q_w (written positions off the constraints,
  initial joint angles, an angle driver's other branch) depends on Newton's path
  and is refused with a sentence; so is a key that makes the constraints
  inconsistent near the start (a redundant mechanism whose redundancy the key
  breaks: y has no solution). The initial speeds' derivative is zero for a model
  released from rest without drivers; otherwise it is the same Richardson difference
  of the initial speeds computed at (p + h, q0 + h dq0/dp).

``vectors.NAME.along[k]`` is refused: a direction is a unit vector, so one
component cannot change alone.
"""
from __future__ import annotations

import numpy as np

from ...errors import ModelError
from ...mechanism.initial_speeds import initial_speeds
from ..params import split_key

STEP = 2e-3            # h relative to the model's length scale
AGREE = 1e-8           # the two Richardson values' largest difference, relative
START_MOVED = 1e-10    # |q0 - q_w| relative to the length scale: the start was assembled
ROUNDING = 1e3         # the rounding of a difference: this many eps |F| / h
CONSISTENT = 1e-8      # |B y + dg/dp| relative to |dg/dp| + |B| |y|: y solves its rows


def kind(key: str) -> str | None:
    """'point', 'load point', 'length' or 'direction' for a geometry key, else None."""
    tokens = split_key(key)
    if len(tokens) < 3 or not isinstance(tokens[2], str):
        return None
    head, name = tokens[0], tokens[2]
    return {("points", "at"): "point", ("loads", "at"): "load point",
            ("constraints", "length"): "length",
            ("vectors", "along"): "direction"}.get((head, name))


def _refuse(model, key: str, text: str) -> ModelError:
    return ModelError(model.source, None, key, text, show_value=False)


def _shifted(solver, key: str, x: float, h: float, q0: np.ndarray):
    """(params, written q, g at q0) of the model with key = x + h."""
    other = solver.with_parameters({key: x + h})
    other.set_time(0.0)
    params = np.concatenate([el.params for el in other.plan.elements])
    return other, [params, np.array(other.plan.q0, float),
                   np.asarray(other.constraints(q0), float)]


def richardson(values: dict, h: float, scales) -> tuple[list, float]:
    """The Richardson derivative from values[s] (s in +-h, +-h/2, +-h/4; each a list
    of arrays) and the largest difference of its two estimates past the differences'
    rounding, relative to the derivative's size. The rounding is ROUNDING eps F / h,
    F the larger of |values| and ``scales`` (one per array: the size of the terms a
    value is a difference of, as a constraint's residual is of squared lengths; a
    derivative that is exactly zero shows only that rounding)."""
    def central(s):
        return [(a - b) / (2 * s) for a, b in zip(values[s], values[-s])]
    d1, d2, d4 = central(h), central(h / 2), central(h / 4)
    r1 = [(4 * b - a) / 3 for a, b in zip(d1, d2)]
    r2 = [(4 * b - a) / 3 for a, b in zip(d2, d4)]
    worst = 0.0
    for a, b, f, scale in zip(r1, r2, values[h], scales):
        rounding = ROUNDING * np.finfo(float).eps * \
            max(np.max(np.abs(f), initial=0.0), scale) / h
        past = max(np.max(np.abs(a - b), initial=0.0) - rounding, 0.0)
        if past > 0:
            worst = max(worst, past / max(np.max(np.abs(b)), rounding))
    return r2, worst


def _linearised_projection(solver, q0, dqw, dg) -> np.ndarray:
    """y with M (y - dqw) + B^T mu = 0, B y = -dg (module docstring), by least squares
    on the KKT system (redundant rows: any mu); None when the rows are inconsistent."""
    M = np.asarray(solver.mass_matrix(q0), float)
    B = np.asarray(solver.constraint_jacobian(q0), float)
    n, m = M.shape[0], B.shape[0]
    if m == 0:
        return dqw
    K = np.block([[M, B.T], [B, np.zeros((m, m))]])
    rhs = np.concatenate([M @ dqw, -dg])
    sol = np.linalg.lstsq(K, rhs, rcond=None)[0]
    y = sol[:n]
    scale = np.max(np.abs(dg), initial=0.0) + np.max(np.abs(B), initial=0.0) * \
        np.max(np.abs(y), initial=0.0)
    if np.max(np.abs(B @ y + dg), initial=0.0) > CONSISTENT * max(scale, 1e-300):
        return None
    return y


def _speeds(solver, q):
    solver.set_time(0.0)
    solver.decide_rank(q)
    return np.asarray(initial_speeds(solver, q, solver.plan.v_target), float)


def geometry_direction(solver, key: str, x: float, mask: np.ndarray):
    """(dP, S0) of one geometry key (module docstring), or ModelError saying why not."""
    model, plan = solver.plan.model, solver.plan
    what = kind(key)
    if what == "direction":
        raise _refuse(model, key, "a direction is a unit vector, so one of its components "
                      "cannot change alone: it has no sensitivity (move the points that "
                      "define the bodies' directions instead)")
    init = solver.initial_state()
    q0, v0 = np.asarray(init.q, float), np.asarray(init.v, float)
    length = solver.length_scale
    moved = np.max(np.abs(q0 - np.asarray(plan.q0, float)), initial=0.0)
    if moved > START_MOVED * length:
        raise _refuse(model, key, "the start is assembled away from the written positions "
                      f"(by {moved:.3g} m: positions off the constraints, initial joint "
                      "values or an angle driver's start), along Newton's path, whose "
                      "derivative is not taken: write positions that satisfy the "
                      "constraints for a sensitivity to geometry")
    h = STEP * length
    solvers, values = {}, {}
    try:
        for s in (h, -h, h / 2, -h / 2, h / 4, -h / 4):
            solvers[s], values[s] = _shifted(solver, key, x, s, q0)
    except ModelError as exc:
        raise _refuse(model, key, f"a sensitivity needs the model with this number changed "
                      f"by {h:.3g}, which fails: {exc.rule}") from None
    (dP, dqw, dg), worst = richardson(values, h, (0.0, length, max(length, length ** 2)))
    if worst > AGREE:
        raise _refuse(model, key, "the elements' numbers are not smooth in this key here "
                      f"(two difference estimates of their derivative differ by {worst:.2g} "
                      "relative): the model changes its form at this value")
    dP[mask] = 0.0                              # the time slots: the run writes t there
    dq0 = _linearised_projection(solver, q0, dqw, dg)
    if dq0 is None:
        raise _refuse(model, key, "changing this number leaves the constraints without a "
                      "solution near the start (it breaks the mechanism's redundant "
                      "closure): it has no sensitivity")
    still = not np.any(plan.v_target) and not np.any(solver.constraint_rate(q0)) \
        and not getattr(model.initial, "joint_speeds", None)
    if still:
        dv0 = np.zeros_like(v0)
    else:
        speeds = {s: [_speeds(other, q0 + s * dq0)] for s, other in solvers.items()}
        (dv0,), worst = richardson(speeds, h, (np.max(np.abs(v0), initial=0.0),))
        if worst > AGREE:
            raise _refuse(model, key, "the initial speeds are not smooth in this key here "
                          f"(two difference estimates differ by {worst:.2g} relative)")
        solver.decide_rank(q0)
    return dP, np.concatenate([dq0, dv0])
