"""Lowering flexible members (docs/flexible.md) onto fccgen's own
coordinates: every node is a point (made by the loader, fccgen.model.cables) and a
*slope* triple d = dr/dx, which is not a unit vector (|d| = 1 + axial strain), so it
gets no u.u - 1 row. The elements themselves are laid out by fccgen.plan.cables.

Ends:

* a pinned end on a moving body is its node attached to the body (three rows, as a
  joint's point: r_k = r_i + b1 r_ij + b2 u + b3 (r_ij x u)/(alpha l), quadratic in q);
  on ground the node is a fixed point; at a named point the node is that point;
* a clamped end also holds the direction of its slope in the body's frame by two rows
  d . n1 = 0 and d . n2 = 0, with n1, n2 unit vectors of the body perpendicular to the
  member's initial direction (on a moving body each is a vector attached to it by three
  rows, as a joint's vectors are; on ground fixed). Each row is a product of two
  triples: quadratic, like every fccgen constraint. The slope's length stays free, so
  the end may stretch: the two rows remove exactly the two turning freedoms of the
  slope relative to the body (a cable has no torsion to hold).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..model.cables import Cable
from ..model.types import Attached, Model, Slope, SlopeNormal, Vector
from ..model.geometry import body_rotation
from .joints import perpendiculars


def lower_cables(model: Model) -> Model:
    """``model`` with the slopes, attachments and clamp rows of its members (itself
    when it has none). Runs after the joints' lowering, when every body is a typical
    body with points i, j and vector u."""
    if not model.cables:
        return model
    out = _CableLowering(model)
    for cable in model.cables.values():
        out.cable(cable)
    return replace(model, vectors=out.vectors, slopes=out.slopes,
                   constraints=[*model.constraints, *out.constraints])


class _CableLowering:
    def __init__(self, model: Model):
        self.model = model
        self.vectors = dict(model.vectors)
        self.slopes = dict(model.slopes)
        self.constraints: list = []

    def cable(self, cable: Cable):
        direction = cable.chord / cable.length          # |d| = chord / stress-free length
        for name in cable.slopes:
            self.slopes[name] = Slope(name, direction.copy(), False, cable.where)
        for k in (0, -1):
            end = cable.ends[k]
            if end.kind != "body":
                continue
            body = self.model.bodies.get(end.body)
            if body is not None:
                self.attach_point(cable, cable.nodes[k], body)
            if end.clamp:
                self.clamp(cable, k, body, direction / np.linalg.norm(direction))

    def frame(self, body):
        m = self.model
        ri = np.asarray(m.points[body.i].at, float)
        return ri, body_rotation(ri, m.points[body.j].at, m.vectors[body.u].along)

    def attach_point(self, cable: Cable, node: str, body):
        ri, R = self.frame(body)
        rho = tuple(float(x) for x in R.T @ (np.asarray(self.model.points[node].at) - ri))
        self.constraints.append(Attached(node, body.name, rho, "point", cable.where,
                                         label=f"cable {cable.name}: node {node} on "
                                               f"{body.name}"))

    def clamp(self, cable: Cable, end: int, body, t: np.ndarray):
        """Two unit vectors perpendicular to the member's direction t, fixed (ground)
        or attached to the body, and one slope_normal row for each."""
        node, slope = cable.nodes[end], cable.slopes[end]
        where, label = cable.where, f"cable {cable.name}: clamp of {node}"
        for k, n in enumerate(perpendiculars(t), 1):
            name = f"{slope[:-len('.slope')]}.clamp{k}"
            self.vectors[name] = Vector(name, np.asarray(n, float), body is None, where)
            if body is not None:
                _, R = self.frame(body)
                nu = tuple(float(x) for x in R.T @ n)
                self.constraints.append(Attached(name, body.name, nu, "vector", where,
                                                 label=f"{label}: vector {name} on "
                                                       f"{body.name}"))
            self.constraints.append(SlopeNormal(slope, name, where,
                                                f"{label}: slope . {name} = 0"))

