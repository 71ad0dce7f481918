"""Reading the mechanism level of a model file (docs/design.md §2b): bodies in pose
form and the ``joints:`` list. Both are lowered onto points, vectors and constraints
by :mod:`fccgen.mechanism`; here they are only validated.
"""
from __future__ import annotations

import math

import numpy as np

from . import checks, shapes
from .fields import Reader, child
from .types import GROUND, Joint, PoseBody, Where
from .yamlnodes import YMap, YNode

POSE_BODY_KEYS = (("mass", "inertia", "center"), ("frame", "shape"))
SHAPED_BODY_KEYS = (("center", "shape"), ("mass", "density", "inertia", "frame"))
FRAME_KEYS = (("x", "y"), ())
# Per joint type: (required keys besides name, type, bodies; optional keys).
JOINT_KEYS = {
    "spherical": (("at",), ()),
    "revolute": (("at", "axis"), ("limits", "restitution")),
    "cylindrical": (("at", "axis"), ("limits", "restitution")),
    "prismatic": (("at", "axis"), ("limits", "restitution")),
    "universal": (("at", "axes"), ()),
    "weld": (("at",), ()),
    "planar": (("at", "normal"), ()),
    "point_on_line": (("at", "axis"), ()),
    "point_on_plane": (("at", "normal"), ()),
    "distance": (("at",), ("length",)),
    "angle": (("axes",), ("angle",)),
}
JOINT_COMMON = ("name", "type", "bodies")
# A direction is too short to normalise when its length is below this (user units).
MIN_DIRECTION = 1e-12
# Body axes x, y are orthogonal when |x.y| (after normalising) is below this.
ORTHOGONAL_TOLERANCE = 1e-9


class MechanismReader(Reader):
    """Reads pose-form bodies and joints; ``claim`` reserves a name (the loader's)."""

    def __init__(self, source: str, claim):
        super().__init__(source)
        self.claim = claim

    # -- pose-form bodies ----------------------------------------------------------------
    def pose_body(self, name: str, line: int, node: YNode, item: str) -> PoseBody:
        if isinstance(node, YMap) and "shape" in node.entries:    # fccgen.model.shapes
            e = self.mapping(node, item, *SHAPED_BODY_KEYS).entries
            mass, inertia, shape = shapes.mass_terms(self, e, item)
        else:
            e = self.mapping(node, item, *POSE_BODY_KEYS).entries
            mass, shape = self.positive(e["mass"], child(item, "mass")), None
            inertia = checks.inertia_tensor(self.numbers(e["inertia"],
                                                         child(item, "inertia"), (3, 6)))
        center = self.vec3(e["center"], child(item, "center"))
        problem = checks.inertia_problem(inertia)
        if problem:
            key = "inertia" if shape is None else "shape"
            raise self.bad(e[key], child(item, key), problem)
        frame = self.frame(e["frame"], child(item, "frame")) if "frame" in e else np.eye(3)
        return PoseBody(name, mass, center, frame, inertia, Where(self.source, line),
                        shape)

    def frame(self, node: YNode, item: str) -> np.ndarray:
        """Columns x, y, z = x × y of the body axes given as ``{x: [..], y: [..]}``."""
        e = self.mapping(node, item, *FRAME_KEYS).entries
        x = self.direction(e["x"], child(item, "x"))
        y = self.direction(e["y"], child(item, "y"))
        if abs(float(x @ y)) > ORTHOGONAL_TOLERANCE:
            raise self.bad(node, item, f"axes x and y must be orthogonal (|x.y| <= "
                                       f"{ORTHOGONAL_TOLERANCE:g} after normalising); "
                                       f"x.y = {float(x @ y):.6g}")
        y = y - (x @ y) * x
        y /= np.linalg.norm(y)
        return np.column_stack([x, y, np.cross(x, y)])

    def direction(self, node: YNode, item: str) -> np.ndarray:
        """Three numbers of non-zero length, normalised."""
        v = self.vec3(node, item)
        norm = float(np.linalg.norm(v))
        if not norm > MIN_DIRECTION:
            raise self.bad(node, item, f"must be a direction of non-zero length "
                                       f"(|v| > {MIN_DIRECTION:g})")
        return v / norm

    # -- joints ------------------------------------------------------------------------
    def joints(self, node: YNode, body_names) -> list[Joint]:
        """Joints between the bodies ``body_names`` (in either form) and ground."""
        seq = self.sequence(node, "joints")
        return [self.joint(n, f"joints[{k}]", body_names) for k, n in enumerate(seq.items)]

    def joint(self, node: YNode, item: str, body_names) -> Joint:
        m = self.mapping_any(node, item)
        for key in ("type", "name"):
            if key not in m.entries:
                raise self.fail(m.line, child(item, key), "missing required key",
                                show_value=False)
        kind = self.choice(m.entries["type"], child(item, "type"), JOINT_KEYS, "joint type")
        required, optional = JOINT_KEYS[kind]
        e = self.mapping(m, item, (*JOINT_COMMON, *required), optional).entries
        name = self.identifier(e["name"], child(item, "name"))
        self.claim(name, "joint", e["name"].line, child(item, "name"))
        bodies = self.joint_bodies(e["bodies"], child(item, "bodies"), body_names)
        at, axes, value = (), (), None
        if kind == "distance":
            pair = self.sequence(e["at"], child(item, "at"), 2)
            at = tuple(self.vec3(n, child(child(item, "at"), k))
                       for k, n in enumerate(pair.items))
            if checks.coincide(*at):
                raise self.bad(pair, child(item, "at"), "must be two different locations "
                               "(the distance row has no gradient where they meet)")
            if "length" in e:
                value = self.positive(e["length"], child(item, "length"))
        elif "at" in e:
            at = (self.vec3(e["at"], child(item, "at")),)
        for key in ("axis", "normal"):
            if key in e:
                axes = (self.direction(e[key], child(item, key)),)
        if "axes" in e:
            pair = self.sequence(e["axes"], child(item, "axes"), 2)
            axes = tuple(self.direction(n, child(child(item, "axes"), k))
                         for k, n in enumerate(pair.items))
        if "angle" in e:
            value = self.number(e["angle"], child(item, "angle"))
            if not 0.0 <= value <= math.pi:
                raise self.bad(e["angle"], child(item, "angle"),
                               "must be an angle in radians from 0 to pi")
        limits, restitution = self.limits(e, item)
        return Joint(name, kind, bodies, at, axes, value, Where(self.source, m.line),
                     limits, restitution)

    def limits(self, e, item: str) -> tuple[tuple[float, float] | None, float]:
        """``limits: [lo, hi]`` (lo <= 0 <= hi: the joint starts at 0, within them) and
        their ``restitution`` (0 to 1, default 0)."""
        limits, restitution = None, 0.0
        if "limits" in e:
            lo, hi = self.numbers(e["limits"], child(item, "limits"), (2,))
            if not lo <= 0.0 <= hi or not lo < hi:
                raise self.bad(e["limits"], child(item, "limits"),
                               "must be [lower, upper] with lower < upper and lower <= 0 "
                               "<= upper (joint quantities are 0 at the start)")
            limits = (float(lo), float(hi))
        if "restitution" in e:
            if limits is None:
                raise self.bad(e["restitution"], child(item, "restitution"),
                               "applies only to a joint with limits")
            restitution = self.number(e["restitution"], child(item, "restitution"))
            if not 0.0 <= restitution <= 1.0:
                raise self.bad(e["restitution"], child(item, "restitution"),
                               "must be a restitution from 0 to 1")
        return limits, restitution

    def joint_bodies(self, node: YNode, item: str, body_names) -> tuple[str, str]:
        pair = self.sequence(node, item, 2)
        names = [GROUND, *body_names]
        a, b = (self.name_in(n, child(item, k), names, "body", "bodies")
                for k, n in enumerate(pair.items))
        if a == b:
            raise self.bad(node, item, "must name two different bodies (a joint between "
                                       "a body and itself has no effect)")
        return a, b
