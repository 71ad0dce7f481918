"""The elements of flexible members (fccgen.plan.cable_kinds, docs/flexible.md): one
``cable`` element per element of a member, one ``slope_normal`` per clamp row, and the
point forces.

All elements of all members with the same structure (which of their node triples are
fixed, which of damping, gravity and distributed load are zero) share one element
class, so one kernel serves them and generation time does not grow with the number of
elements; their lengths and stiffnesses are runtime parameters.
"""
from __future__ import annotations

from ..model.cables import Cable, node_names

# result columns per node (fccgen.mechanism.cable_outputs)
NODE_QUANTITIES = ("strain", "curvature")


def cable_columns(model) -> list[str]:
    """The names of the strain and curvature columns of a model's members."""
    return [f"{node}.{q}" for c in model.cables.values()
            for node in node_names(c.name, c.elements) for q in NODE_QUANTITIES]


def cable_elements(b, cable: Cable) -> list:
    """The ``cable`` elements of a member, from its ``from`` end; ``b`` is the plan's
    builder (fccgen.plan.build._Builder)."""
    g, q = b.model.gravity, cable.distributed_load
    scalars = {"L": cable.element_length, "EA": cable.EA, "EI": cable.EI,
               "rhoA": cable.mass_per_length, "c": cable.damping,
               "gx": g[0], "gy": g[1], "gz": g[2], "qx": q[0], "qy": q[1], "qz": q[2]}
    scalars = {k: float(v) for k, v in scalars.items()}
    out = []
    for k in range(cable.elements):
        triples = [("r1", cable.nodes[k]), ("d1", cable.slopes[k]),
                   ("r2", cable.nodes[k + 1]), ("d2", cable.slopes[k + 1])]
        out.append(b.element("cable", f"cables.{cable.name}[{k}]", cable.where, scalars,
                             triples))
    return out


def slope_normal_element(b, c, label: str):
    """One clamp row d . n = 0 (fccgen.mechanism.cables.SlopeNormal)."""
    return b.element("slope_normal", label, c.where, {},
                     [("d", c.slope), ("n", c.normal)])


def point_force_element(b, ld, label: str):
    """A force on a point (fccgen.model.types.PointForce): constant, or of time."""
    if ld.function:
        return b.element("point_force_t", label, ld.where, {"t": 0.0}, [("r", ld.point)],
                         function=ld.function)
    F = {"Fx": ld.value[0], "Fy": ld.value[1], "Fz": ld.value[2]}
    return b.element("point_force", label, ld.where, {k: float(v) for k, v in F.items()},
                     [("r", ld.point)])
