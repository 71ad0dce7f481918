"""Design parameters of a compiled model: how the elements' numbers and the start
depend on a ``with_parameters`` key.

A key the model's numbers depend on affinely (masses, inertias, mass-centre
positions, stiffnesses, dampings, free lengths, load values, gravity, cable
properties, initial speeds) has exact derivatives from one forward difference of any
size: dP = (P(x + d) - P(x)) / d for the elements' parameters P and the consistent
start (q0, v0). The difference is taken twice (d and 2 d); if the two disagree past
rounding, the key is not affine and is refused with a sentence. Geometry keys (points,
load points, distance constraints' lengths) enter nonlinearly and move the assembled
start: fccgen.runtime.sensitivity.geometry.
"""
from __future__ import annotations

import weakref

import numpy as np

from ...errors import ModelError
from ..params import _target, split_key, value_of
from .geometry import geometry_direction, kind

RUN_SETTINGS = ("t_end", "dt", "output_dt")
# The relative size of the difference: large, so that rounding (eps |P| / d) is small.
REL_STEP = 0.125
# Per solver: each linear key's (dP row, S0 row), found once (they depend on the
# solver's model only, which a solver never changes: with_parameters makes another).
_LINEAR = weakref.WeakKeyDictionary()


def current_value(model, key: str) -> float:
    """The model's number at ``key`` (one number; a list needs its component)."""
    tokens = split_key(key)
    component = tokens.pop() if len(tokens) > 1 and isinstance(tokens[-1], int) else None
    obj, name, where = _target(model, tokens, key)
    line = getattr(where, "line", None)
    if name in RUN_SETTINGS:
        raise ModelError(model.source, line, key, "is a setting of the run, not a number "
                         "of the model: it has no sensitivity", show_value=False)
    if name == "inertia" and component is None:
        raise ModelError(model.source, line, key, "an inertia sensitivity is per "
                         "component: add [k], k = 0..5 (Ixx, Iyy, Izz, Ixy, Ixz, Iyz)",
                         show_value=False)
    value = value_of(model, key)
    if np.ndim(value) != 0:
        raise ModelError(model.source, line, key, f"{name} is a list: a sensitivity is "
                         "with respect to one number, add its component [k]",
                         show_value=False)
    return float(value)


def _numbers(solver, key: str, x: float):
    """(element parameters, q0, v0) of the model with ``key`` set to x."""
    other = solver.with_parameters({key: x})
    init = other.initial_state()
    params = np.concatenate([el.params for el in other.plan.elements])
    return params, np.asarray(init.q, float), np.asarray(init.v, float)


NOT_LINEAR = (
    "the model's numbers are not linear in this key, as a key of this kind must be",
    "the assembled start is not linear in this key, as a key of this kind must be",
    "the initial speeds depend on this key nonlinearly (speeds that the constraints and "
    "the given joint rates leave free are chosen in the kinetic-energy metric); give "
    "initial speeds the constraints allow, or joint rates for every freedom")


def _shifted(solver, model, key: str, x: float):
    """The numbers at x + d and x + 2 d for the largest d of +-REL_STEP |x| / 8^k that
    the model's rules accept (an inertia must keep the triangle inequality, a mass
    stay positive), and d."""
    size = abs(x) if x != 0 else 1.0
    last = None
    for k in range(6):
        for sign in (1.0, -1.0):
            d = sign * REL_STEP * size / 8 ** k
            try:
                return _numbers(solver, key, x + d), _numbers(solver, key, x + 2 * d), d
            except ModelError as exc:
                last = exc
    raise ModelError(model.source, last.line, key, "a sensitivity needs the model with "
                     f"this number changed a little, which fails: {last.rule}",
                     show_value=False)


def _time_mask(plan) -> np.ndarray:
    mask = []
    for el in plan.elements:
        mask += [name == "t" for name in el.cls.param_names]
    return np.array(mask, dtype=bool)


def directions(solver, keys) -> tuple[np.ndarray, np.ndarray]:
    """(dP, S0): dP[j] the elements' parameters' derivative with respect to keys[j]
    (n_p numbers), S0[j] = [dq0/dp_j; dv0/dp_j]. ModelError for a key that names
    nothing settable, a run setting, a structural zero, or a geometry key that
    fccgen.runtime.sensitivity.geometry refuses."""
    model = solver.plan.model
    known = _LINEAR.setdefault(solver, {})
    base = None
    mask = _time_mask(solver.plan)
    dP, S0 = [], []
    for key in keys:
        if key in known:
            dP.append(known[key][0])
            S0.append(known[key][1])
            continue
        x = current_value(model, key)
        if not np.isfinite(x):
            raise ModelError(model.source, None, key, "the component index is too large",
                             show_value=False)
        if kind(key) is not None:
            one_dP, one_S0 = geometry_direction(solver, key, x, mask)
            dP.append(one_dP)
            S0.append(one_S0)
            continue
        if base is None:
            base = _numbers(solver, key, x)
        one, two, d = _shifted(solver, model, key, x)
        d1 = [(a - b) / d for a, b in zip(one, base)]
        d2 = [(a - b) / (2 * d) for a, b in zip(two, base)]
        for part, (g1, g2, b) in enumerate(zip(d1, d2, base)):
            if part == 0:                  # the time slots: the run writes t there
                g1[mask] = g2[mask] = 0.0
            scale = np.max(np.abs(b), initial=0.0) / d + np.max(np.abs(g1), initial=0.0)
            if np.max(np.abs(g1 - g2), initial=0.0) > 1e-11 * scale:
                raise ModelError(model.source, None, key, NOT_LINEAR[part],
                                 show_value=False)
        known[key] = (d1[0], np.concatenate([d1[1], d1[2]]))
        dP.append(known[key][0])
        S0.append(known[key][1])
    return np.array(dP), np.array(S0)
