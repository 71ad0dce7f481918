"""Random consistent states of a model, for comparing solvers (a helper module)."""
from __future__ import annotations

import numpy as np


def length_scale(plan) -> float:
    """The largest body length of the plan (1 if it has no body)."""
    ls = [el.params[0] for el in plan.elements if el.cls.kind == "body"]
    return float(max(ls)) if ls else 1.0


def random_state(solver, rng, spread=0.05, speed=1.0):
    """A state on the constraint manifold near the initial one: positions perturbed by
    ``spread`` length scales and projected back, random speeds (``speed`` length scales
    per second) projected onto B v = 0."""
    plan = solver.plan
    L = length_scale(plan)
    q0 = solver.initial_state().q
    q, _ = solver.project_positions(q0 + rng.normal(scale=spread * L, size=q0.shape)
                                    * _scale_vectors(plan, L))
    v = solver.project_velocities(q, rng.normal(scale=speed * L, size=q.shape)
                                  * _scale_vectors(plan, L))
    return q, v


def _scale_vectors(plan, L):
    """Per coordinate: 1 for points, 1/L for unit vectors (they are of size 1)."""
    s = np.ones(plan.n_q)
    for k, (_, kind) in enumerate(plan.triples):
        if kind == "vector":
            s[3 * k:3 * k + 3] = 1.0 / L
    return s
