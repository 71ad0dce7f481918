"""Reading the ``cables:`` section (docs/flexible.md): slender flexible members as
ANCF cable elements, lowered by :mod:`fccgen.mechanism.cables`.

Each member runs straight, in its stress-free state, from its ``from`` end to its
``to`` end; its ``elements`` elements share it in equal lengths. An end is

* a point name: the end node *is* that point (a pin, shared as bodies share points);
* ``[x, y, z]``: a free end at that global position;
* ``{body: B, at: [x, y, z], clamp: true|false}``: on body B (``ground`` for the fixed
  world), ``at`` written as a point on that body is (body frame from point i for a body
  given by points, the pose frame from the mass centre for one given by its pose,
  global for ground); ``clamp: true`` ties the end's slope to the body's frame.

The nodes are points of the model, so loads, springs, constraints, drivers and events
name them as they name points: ``boom.n0`` ... ``boom.n<N-1>`` and ``boom.tip`` (the
``to`` end), except an end given by a point name, whose node is that point.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import coincide
from .fields import Reader, child, listing
from .types import GROUND, Point, Where
from .yamlnodes import YMap, YNode, YScalar, YSeq

CABLE_KEYS = (("from", "to", "elements", "EA", "EI", "mass_per_length"),
              ("damping", "length", "distributed_load"))
BODY_END_KEYS = (("body", "at"), ("clamp",))
MAX_ELEMENTS = 1000           # 12 coordinates per element; a finer mesh is a typo
END_NAMES = ("from", "to")


@dataclass(frozen=True)
class CableEnd:
    """One end of a member: ``kind`` "point" (pinned at the point ``point``), "free"
    or "body" (on ``body`` at ``rho`` as written, ``clamp`` or pinned); ``at`` is
    its initial global position."""
    kind: str
    at: tuple[float, float, float]
    point: str | None = None
    body: str | None = None
    rho: tuple[float, float, float] | None = None
    clamp: bool = False


@dataclass
class Cable:
    """A flexible member: ``nodes`` are its point names from ``from`` to ``to``
    (elements + 1), ``length`` its stress-free length, ``distributed_load`` a
    constant force per unit (stress-free) length in the global frame, ``damping`` the
    stiffness-proportional coefficient beta (time units: axial force
    EA (eps + beta eps'), bending moment EI (k + beta k'))."""
    name: str
    ends: tuple[CableEnd, CableEnd]
    elements: int
    EA: float
    EI: float
    mass_per_length: float
    damping: float
    length: float
    distributed_load: np.ndarray
    nodes: tuple[str, ...]
    where: Where

    @property
    def slopes(self) -> tuple[str, ...]:
        """The slope triples of the nodes: ``<name>.n<k>.slope``, ``<name>.tip.slope``
        (named after the member, also where a node is a named point)."""
        return tuple(slope_name(n) for n in node_names(self.name, self.elements))

    @property
    def element_length(self) -> float:
        return self.length / self.elements

    @property
    def chord(self) -> np.ndarray:
        return np.asarray(self.ends[1].at, float) - np.asarray(self.ends[0].at, float)


def node_names(name: str, elements: int) -> list[str]:
    """``name.n0`` ... ``name.n<N-1>``, ``name.tip``."""
    return [f"{name}.n{k}" for k in range(elements)] + [f"{name}.tip"]


def slope_name(node: str) -> str:
    """The slope coordinate triple of a node (result columns ``<node>.slope.x`` ...)."""
    return f"{node}.slope"


class CableReader(Reader):
    """Reads ``cables:``; ``points`` gets the nodes (moving points, or fixed ones on
    ground), so that the sections read after it can name them."""

    def __init__(self, source: str, claim, points: dict, bodies: dict, pose_bodies: dict,
                 vectors: dict):
        super().__init__(source)
        self.claim = claim
        self.points, self.bodies, self.pose_bodies = points, bodies, pose_bodies
        self.vectors = vectors

    def cables(self, node: YNode) -> dict[str, Cable]:
        out = {}
        for name, line, value, item in self.entries(node, "cables"):
            self.claim(name, "cable", line, item)
            out[name] = self.cable(name, line, value, item)
        return out

    def cable(self, name: str, line: int, node: YNode, item: str) -> Cable:
        e = self.mapping(node, item, *CABLE_KEYS).entries
        elements = self.count(e["elements"], child(item, "elements"))
        ends = tuple(self.end(e[k], child(item, k)) for k in END_NAMES)
        if ends[0].kind == ends[1].kind == "point" and ends[0].point == ends[1].point:
            raise self.bad(e["to"], child(item, "to"), "must be another point than "
                           "the from end")
        chord = float(np.linalg.norm(np.subtract(ends[1].at, ends[0].at)))
        if coincide(np.asarray(ends[0].at), np.asarray(ends[1].at)):
            raise self.bad(e["to"], child(item, "to"),
                           "is at the same place as the from end; a member runs "
                           "straight from its from end to its to end")
        length = (self.positive(e["length"], child(item, "length")) if "length" in e
                  else chord)
        load = (self.vec3(e["distributed_load"], child(item, "distributed_load"))
                if "distributed_load" in e else np.zeros(3))
        damping = (self.nonnegative(e["damping"], child(item, "damping"))
                   if "damping" in e else 0.0)
        nodes = node_names(name, elements)
        for k, end in ((0, ends[0]), (-1, ends[1])):
            if end.kind == "point":
                nodes[k] = end.point
        where = Where(self.source, line)
        cable = Cable(name, ends, elements,
                      self.positive(e["EA"], child(item, "EA")),
                      self.positive(e["EI"], child(item, "EI")),
                      self.positive(e["mass_per_length"], child(item, "mass_per_length")),
                      damping, length, load, tuple(nodes), where)
        self.add_nodes(cable)
        return cable

    def count(self, node: YNode, item: str) -> int:
        x = self.number(node, item)
        if not (x == int(x) and 1 <= x <= MAX_ELEMENTS):
            raise self.bad(node, item, f"must be a whole number in [1, {MAX_ELEMENTS}]")
        return int(x)

    def end(self, node: YNode, item: str) -> CableEnd:
        if isinstance(node, YScalar) and isinstance(node.value, str):
            name = self.name_in(node, item, self.points, "point", "points")
            return CableEnd("point", tuple(float(x) for x in self.points[name].at),
                            point=name)
        if isinstance(node, YSeq):
            return CableEnd("free", tuple(float(x) for x in self.vec3(node, item)))
        if not isinstance(node, YMap):
            raise self.bad(node, item, "must be a point name, a position [x, y, z] or "
                           "{body: NAME, at: [x, y, z], clamp: true|false}")
        e = self.mapping(node, item, *BODY_END_KEYS).entries
        body = self.text(e["body"], child(item, "body"))
        known = [*self.bodies, *self.pose_bodies]
        if body not in known and body != GROUND:
            raise self.fail(e["body"].line, child(item, "body"),
                            f"names no body; bodies are: {listing([*known, GROUND])}",
                            body)
        rho = tuple(float(x) for x in self.vec3(e["at"], child(item, "at")))
        clamp = self.boolean(e["clamp"], child(item, "clamp")) if "clamp" in e else False
        return CableEnd("body", tuple(float(x) for x in self.body_point(body, rho)),
                        body=body, rho=rho, clamp=clamp)

    def body_point(self, body: str, rho) -> np.ndarray:
        """The global initial position of the body point ``rho`` as written."""
        from .geometry import body_rotation
        rho = np.asarray(rho, float)
        if body in self.bodies:
            b = self.bodies[body]
            ri = self.points[b.i].at
            R = body_rotation(ri, self.points[b.j].at, self.vectors[b.u].along)
            return ri + R @ rho
        if body in self.pose_bodies:
            pb = self.pose_bodies[body]
            return np.asarray(pb.center, float) + np.asarray(pb.frame, float) @ rho
        return rho                                         # ground: global

    def add_nodes(self, cable: Cable):
        """The nodes as points: evenly spaced along the chord; a node on ground is
        fixed, a node that is a named point is that point."""
        a = np.asarray(cable.ends[0].at, float)
        for k, name in enumerate(cable.nodes):
            end = (cable.ends[0] if k == 0 else
                   cable.ends[1] if k == cable.elements else None)
            if end is not None and end.kind == "point":
                continue                  # (other nodes' names hold a dot: never taken)
            fixed = end is not None and end.kind == "body" and end.body == GROUND \
                and end.body not in self.bodies
            at = a + cable.chord * (k / cable.elements)
            self.points[name] = Point(name, at, fixed, cable.where)

