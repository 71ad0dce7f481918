"""What each joint type becomes (docs/design.md §2b, docs/joints.md).

A joint between bodies A and B (``bodies: [A, B]``) is lowered onto *carried triples*
-- points and unit vectors, each rigidly carried by one or both bodies -- and onto
constraints between triples. A triple carried by both bodies is *shared*: one
coordinate triple tied to both frames. A triple carried by ground is fixed.

================  ===============================================================
type              lowering (J = joint name, p = at, a = axis)
================  ===============================================================
spherical         point J at p shared                                (3 freedoms)
revolute          point J shared, vector J_axis = a shared                     (1)
cylindrical       vector J_axis shared; points J_a (A), J_b (B) at p; normals
                  J_n1, J_n2 of A perpendicular to a; n_k.(r_Jb - r_Ja) = 0    (2)
prismatic         cylindrical + vector J_nb of B (= J_n2 initially),
                  J_n1 . J_nb = 0                                              (1)
universal         point J shared; J_axis1 (A), J_axis2 (B); their dot product
                  keeps its initial value (0 for perpendicular axes)          (2)
weld              point J shared; vectors J_x, J_y (A's body axes) shared     (0)
planar            vector J_normal shared; points J_a (A), J_b (B) at p;
                  J_normal.(r_Jb - r_Ja) = 0                                   (3)
point_on_line     J_a, J_b, J_n1, J_n2 as in cylindrical, without the axis     (4)
point_on_plane    J_a, J_b, J_normal (A); J_normal.(r_Jb - r_Ja) = 0           (5)
distance          J_a at at[0] (A), J_b at at[1] (B); |r_Jb - r_Ja| = length  (5)
angle             J_axis1 (A), J_axis2 (B); J_axis1 . J_axis2 = cos(angle)    (5)
================  ===============================================================

Freedoms are those of B relative to A. Every equation is linear or quadratic in q:
the plane and dot rows are products of two triples, and attachments (see
:mod:`fccgen.mechanism.lowering`) are those of docs/design.md §1.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..model.types import Joint


# Joint types with result columns J.angle, J.rate and J.position, J.speed.
ANGLE_TYPES = ("revolute", "cylindrical")
SLIDE_TYPES = ("prismatic", "cylindrical")


def output_columns(joint: Joint) -> list[str]:
    """The result columns of a joint (docs/design.md §2b), in the order they are added."""
    cols = []
    if joint.type in ANGLE_TYPES:
        cols += [f"{joint.name}.angle", f"{joint.name}.rate"]
    if joint.type in SLIDE_TYPES:
        cols += [f"{joint.name}.position", f"{joint.name}.speed"]
    return cols


@dataclass
class CarriedTriple:
    name: str
    kind: str                          # "point" | "vector"
    value: np.ndarray                  # initial global position / direction
    carriers: list[str]                # bodies that carry it (may include ground)
    joint: str


@dataclass
class JointLowering:
    """The triples a joint carries and the constraints it adds between them:
    ("plane", point, origin, normal), ("dot", a, b, cos), ("distance", a, b, length)."""
    joint: Joint
    triples: list[CarriedTriple] = field(default_factory=list)
    relations: list[tuple] = field(default_factory=list)

    def add(self, suffix: str, kind: str, value, carriers) -> str:
        name = self.joint.name + suffix
        self.triples.append(CarriedTriple(name, kind, np.asarray(value, float),
                                          list(carriers), self.joint.name))
        return name


def perpendiculars(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit n1, n2 with (n1, n2, a) right-handed and orthonormal: n1 from the global
    axis least aligned with a."""
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    n1 = np.cross(a, e)
    n1 /= np.linalg.norm(n1)
    return n1, np.cross(a, n1)


def lower_joint(j: Joint, frames: dict[str, np.ndarray]) -> JointLowering:
    """The carried triples and relations of joint ``j``; ``frames`` holds each body's
    pose-frame rotation (ground: the identity)."""
    out = JointLowering(j)
    A, B = j.bodies
    both = (A, B)
    p = j.at[0] if j.at else None
    a = j.axes[0] if j.axes else None
    t = j.type
    if t in ("spherical", "revolute", "universal", "weld"):
        out.add("", "point", p, both)
    if t in ("revolute", "cylindrical", "prismatic"):
        out.add("_axis", "vector", a, both)
    if t in ("cylindrical", "prismatic", "point_on_line"):
        n1, n2 = perpendiculars(a)
        ka, kb = out.add("_a", "point", p, (A,)), out.add("_b", "point", p, (B,))
        m1, m2 = out.add("_n1", "vector", n1, (A,)), out.add("_n2", "vector", n2, (A,))
        out.relations += [("plane", kb, ka, m1), ("plane", kb, ka, m2)]
        if t == "prismatic":
            nb = out.add("_nb", "vector", n2, (B,))
            out.relations.append(("dot", m1, nb, 0.0))
    if t in ("universal", "angle"):
        a1 = out.add("_axis1", "vector", j.axes[0], (A,))
        a2 = out.add("_axis2", "vector", j.axes[1], (B,))
        cos = (float(j.axes[0] @ j.axes[1]) if j.value is None else math.cos(j.value))
        out.relations.append(("dot", a1, a2, cos))
    if t == "weld":
        # Any two directions fixed in both bodies weld them; a pose body's frame axes
        # are taken where there is one, else (two bodies of points and a vector,
        # which have no frame matrix) the global axes.
        frame = frames.get(A, frames.get(B, np.eye(3)))
        out.add("_x", "vector", frame[:, 0], both)
        out.add("_y", "vector", frame[:, 1], both)
    if t in ("planar", "point_on_plane"):
        normal = out.add("_normal", "vector", a, both if t == "planar" else (A,))
        ka, kb = out.add("_a", "point", p, (A,)), out.add("_b", "point", p, (B,))
        out.relations.append(("plane", kb, ka, normal))
    if t == "distance":
        ka = out.add("_a", "point", j.at[0], (A,))
        kb = out.add("_b", "point", j.at[1], (B,))
        length = (float(np.linalg.norm(j.at[1] - j.at[0])) if j.value is None
                  else j.value)
        out.relations.append(("distance", ka, kb, length))
    return out
