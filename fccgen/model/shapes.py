"""Shapes of pose-form bodies (docs/model-file.md, "Shapes"): a uniform solid whose
mass centre is the body's ``center`` and whose axes are the body's ``frame``, with a
``mass`` or a ``density``; fccgen computes the mass and the central inertia from the
closed forms of a uniform solid (m the mass, axes x, y, z of the frame):

=====================================  ==============  ===================================
shape                                   volume          inertia (I_xx, I_yy, I_zz)
=====================================  ==============  ===================================
``{box: [a, b, c]}`` (edges on x, y, z) a b c           m/12 (b²+c², a²+c², a²+b²)
``{cylinder: {radius: r, length: L}}``  π r² L          m r²/2, m (3 r² + L²)/12 (twice)
``{rod: {length: L, radius: r}}``       π r² L          as the cylinder (a bar along x)
``{sphere: r}``                         4/3 π r³        2/5 m r² (thrice)
=====================================  ==============  ===================================

The axis of a cylinder or rod is the frame's x. The animation draws the shape
(:mod:`fccgen.viz.scene`).
"""
from __future__ import annotations

import math

import numpy as np

from .fields import child
from .types import Solid
from .yamlnodes import YMap, YSeq

KINDS = ("box", "cylinder", "rod", "sphere")


def volume(solid: Solid) -> float:
    kind, size = solid.kind, solid.size
    if kind == "box":
        return size[0] * size[1] * size[2]
    if kind == "sphere":
        return 4.0 / 3.0 * math.pi * size[0] ** 3
    return math.pi * size[0] ** 2 * size[1]             # cylinder, rod: radius, length


def principal_inertia(solid: Solid, mass: float) -> np.ndarray:
    """(I_xx, I_yy, I_zz) about the mass centre in the solid's axes."""
    kind, size = solid.kind, solid.size
    if kind == "box":
        a, b, c = size
        return mass / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    if kind == "sphere":
        return np.full(3, 0.4 * mass * size[0] ** 2)
    r, length = size
    transverse = mass * (3.0 * r * r + length * length) / 12.0
    return np.array([0.5 * mass * r * r, transverse, transverse])


def read_shape(reader, node, item: str) -> Solid:
    """A ``shape:`` value: a mapping of one kind to its sizes."""
    e = reader.mapping(node, item, (), KINDS).entries
    if len(e) != 1:
        raise reader.bad(node, item, f"must name one shape: {', '.join(KINDS)}")
    (kind, value), = e.items()
    where = child(item, kind)
    if kind == "sphere":
        return Solid(kind, (reader.positive(value, where),))
    if kind == "box":
        if not isinstance(value, YSeq):
            raise reader.bad(value, where, "must be a list of 3 edge lengths [a, b, c]")
        edges = reader.sequence(value, where, 3).items
        return Solid(kind, tuple(reader.positive(n, child(where, k))
                                 for k, n in enumerate(edges)))
    if not isinstance(value, YMap):
        raise reader.bad(value, where, "must be a mapping {radius: r, length: L}")
    sizes = reader.mapping(value, where, ("radius", "length")).entries
    return Solid(kind, (reader.positive(sizes["radius"], child(where, "radius")),
                        reader.positive(sizes["length"], child(where, "length"))))


def mass_terms(reader, entries: dict, item: str) -> tuple[float, np.ndarray, Solid]:
    """(mass, inertia tensor in the body frame, solid) of a pose-form body with
    ``shape:`` and exactly one of ``mass:`` or ``density:`` (no ``inertia:``)."""
    solid = read_shape(reader, entries["shape"], child(item, "shape"))
    if "inertia" in entries:
        raise reader.bad(entries["inertia"], child(item, "inertia"),
                         "is computed from shape: give shape or inertia, not both")
    given = [k for k in ("mass", "density") if k in entries]
    if len(given) != 1:
        node = entries["shape"]
        raise reader.fail(node.line, item, "a body with shape: needs exactly one of "
                          "mass: or density:", ", ".join(given) or "neither",)
    if given == ["mass"]:
        mass = reader.positive(entries["mass"], child(item, "mass"))
    else:
        density = reader.positive(entries["density"], child(item, "density"))
        mass = density * volume(solid)
        if not mass > 0 or not math.isfinite(mass):
            raise reader.bad(entries["density"], child(item, "density"),
                             f"gives a mass of {mass:g} with this shape")
    return mass, np.diag(principal_inertia(solid, mass)), solid
