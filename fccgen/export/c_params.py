"""Which ``with_parameters`` keys an exported model can set, and how (docs/export.md).

The element parameters are laid out from the model by the plan (Python). For each key
of a body's mass and inertia, gravity and the loads' numbers, the export lays the plan
out at two other values of the key and keeps the key when the element parameters move
along a straight line (checked at a third value, to rounding) and when all such keys
together are additive (checked with every key moved at once). The C side then sets
``params = base + sum_k (x_k - x_k0) d_k`` exactly as the plan would. Geometry keys
(points, vectors, centres, lengths) move the initial configuration, which the Python
build assembles with its own set-up; they need a new export. Keys whose effect is not
linear, or not additive with the others (gravity with the masses: the weight is m g),
are left out, with the gravity keys the first to go.
"""
from __future__ import annotations

import numpy as np

from ..plan import make_plan
from ..runtime.params import set_parameters, value_of

# relative agreement of the straight-line and additivity checks (plan arithmetic is
# a few roundings per parameter)
LINEAR_RTOL = 1e-12


def candidate_keys(model) -> list[str]:
    """Keys of the numbers the export tries, bodies first, gravity last."""
    keys = []
    for name in model.bodies:
        keys.append(f"bodies.{name}.mass")
        keys += [f"bodies.{name}.inertia[{k}]" for k in range(3)]
    for k, load in enumerate(model.loads):
        for field in ("stiffness", "damping"):
            if getattr(load, field, None) is not None:
                keys.append(f"loads[{k}].{field}")
        value = getattr(load, "value", None)
        if value is not None:
            keys += [f"loads[{k}].value"] if np.ndim(value) == 0 else \
                [f"loads[{k}].value[{c}]" for c in range(3)]
    keys += [f"gravity[{c}]" for c in range(3)]
    return keys


def current_value(model, key: str) -> float:
    """The number a key addresses now, in the model file's terms."""
    return float(value_of(model, key))


def flat_params(plan) -> np.ndarray:
    return np.concatenate([el.params for el in plan.elements]) if plan.elements \
        else np.zeros(0)


def _params_at(plan, values: dict):
    """The element parameters with ``values`` set; None when the plan's elements or
    coordinates would change (the compiled classes would not fit)."""
    try:
        new = make_plan(set_parameters(plan.model, values))
    except (ValueError, ArithmeticError):
        return None
    if new.triples != plan.triples or [e.cls for e in new.elements] != \
            [e.cls for e in plan.elements]:
        return None
    return flat_params(new)


def parameter_map(plan) -> list[tuple[str, float, np.ndarray]]:
    """(key, its value now, d params / d value) of every key the export can set."""
    base = flat_params(plan)
    scale = max(1.0, float(np.max(np.abs(base)))) if base.size else 1.0
    kept = []
    for key in candidate_keys(plan.model):
        try:
            x0 = current_value(plan.model, key)
        except (ValueError, IndexError, AttributeError, TypeError):
            continue
        for step in ((1e-3 * abs(x0) if x0 != 0 else 1.0) * s for s in (1, -1)):
            p1 = _params_at(plan, {key: x0 + step})
            p2 = _params_at(plan, {key: x0 + 2 * step})
            if p1 is not None and p2 is not None:
                break
        else:
            continue
        slope = (p1 - base) / step
        if not np.allclose(p2, base + 2 * step * slope, rtol=0, atol=LINEAR_RTOL * scale):
            continue
        kept.append((key, x0, slope, step))
    while kept:                                 # additive, all moved at once
        values = {key: x0 + step for key, x0, _, step in kept}
        together = _params_at(plan, values)
        expected = base + sum(step * slope for _, _, slope, step in kept)
        if together is not None and np.allclose(together, expected, rtol=0,
                                                atol=LINEAR_RTOL * scale * len(kept)):
            break
        gravity = [k for k in kept if k[0].startswith("gravity")]
        if not gravity:
            return []
        kept.remove(gravity[-1])
    return [(key, x0, slope) for key, x0, slope, _ in kept]
