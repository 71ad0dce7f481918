"""The reaction subspace of each joint type: the forces and torques (about its point on
the second body) that a joint can apply, as orthonormal columns per result row.

================  ===================================  ==============================
type              force                                torque
================  ===================================  ==============================
spherical         any                                  none
revolute          any                                  perpendicular to the axis
universal         any                                  along a1 x a2
cylindrical       perpendicular to the axis            perpendicular to the axis
prismatic         perpendicular to the axis            any
planar            along the normal                     perpendicular to the normal
weld              any                                  any
point_on_line     perpendicular to the line            none
point_on_plane    along the normal                     none
distance          along r_b - r_a                      none
angle             none                                 along a1 x a2
================  ===================================  ==============================

These are the constraint wrenches that do no work in the joint's freedoms (docs/joints.md
lists the freedoms). A driver on the joint takes its freedom away and its generalized
force joins the reaction: an angle driver adds the torque along the axis (revolute,
cylindrical: the torque becomes any), a position driver the force along it (prismatic,
cylindrical: the force becomes any); a distance driver replaces the distance joint's own
row and keeps its subspace. The axis, normal and the first body's perpendiculars n1, n2 are
the joint's carried vectors at each row.
"""
from __future__ import annotations

import numpy as np

from .body_motion import Motion

EYE = np.eye(3)
# Result column suffixes of a joint's reaction: force, then torque about its point.
COMPONENTS = ("fx", "fy", "fz", "tx", "ty", "tz")


def _perpendiculars(a: np.ndarray) -> np.ndarray:
    """(n, 3, 2): two orthonormal columns perpendicular to each unit row of a."""
    e = EYE[np.argmin(np.abs(a), axis=1)]
    n1 = np.cross(a, e)
    n1 /= np.linalg.norm(n1, axis=1)[:, None]
    return np.stack([n1, np.cross(a, n1)], axis=2)


def _along(a: np.ndarray) -> np.ndarray:
    """(n, 3, 1): the unit direction of each row (a zero row stays zero)."""
    norm = np.linalg.norm(a, axis=1)
    return (a / np.where(norm > 0, norm, 1.0)[:, None])[:, :, None]


def _full(n: int) -> np.ndarray:
    return np.tile(EYE, (n, 1, 1))


def _none(n: int) -> np.ndarray:
    return np.zeros((n, 3, 0))


def bases(jl, motion: Motion, driven=frozenset()):
    """(p, P_f, P_t) of joint lowering ``jl``: the point p (n, 3) on the second body
    about which the torque is taken, force and torque columns (n, 3, k); ``driven``:
    the quantities ("angle", "position") its drivers fix (module docstring)."""
    p, Pf, Pt = _free_bases(jl, motion)
    if "angle" in driven:
        Pt = _full(motion.n)
    if "position" in driven:
        Pf = _full(motion.n)
    return p, Pf, Pt


def _free_bases(jl, motion: Motion):
    """(p, P_f, P_t) of the undriven joint (the table of the module docstring)."""
    j = jl.joint
    n, name, t = motion.n, j.name, j.type

    def at(suffix):
        return motion.triple(name + suffix)[0]

    if t in ("spherical", "revolute", "universal", "weld"):
        p = motion.triple(jl.triples[0].name)[0]         # the shared point (maybe aliased)
    elif t == "angle":
        p = motion.centre(j.bodies[1])[0] if j.bodies[1] in motion.plan.model.bodies \
            else np.zeros((n, 3))
    else:
        p = at("_b")
    if t == "spherical":
        return p, _full(n), _none(n)
    if t == "revolute":
        return p, _full(n), _perpendiculars(at("_axis"))
    if t in ("universal", "angle"):
        torque = _along(np.cross(at("_axis1"), at("_axis2")))
        return p, (_full(n) if t == "universal" else _none(n)), torque
    if t == "weld":
        return p, _full(n), _full(n)
    if t in ("cylindrical", "prismatic", "point_on_line"):
        normals = np.stack([at("_n1"), at("_n2")], axis=2)
        torque = {"cylindrical": normals, "prismatic": _full(n)}.get(t, _none(n))
        return p, normals, torque
    if t in ("planar", "point_on_plane"):
        normal = at("_normal")
        torque = _perpendiculars(normal) if t == "planar" else _none(n)
        return p, _along(normal), torque
    if t == "distance":
        return p, _along(at("_b") - at("_a")), _none(n)
    raise AssertionError(f"no reaction subspace for joint type {t!r}")
