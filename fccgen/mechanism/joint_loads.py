"""Loads whose expressions use joint quantities (docs/elements.md, "Loads of joint
quantities"): which joints a force or torque reads, and the triples that measure them.

A load ``{type: torque, body: B, value: ["-2*A.angle - 0.1*A.rate", ...]}`` reads the
joint A's angle family (angle and rate); ``S.position`` and ``S.speed`` read the
position family. Per family the lowering names the triples the element class uses:

* angle: the axis ``J_axis`` and two points (i, j) per side, whose directions
  p = r_ij - (r_ij . u) u perpendicular to the axis measure the angle exactly as the
  torsion spring does (ground: two fixed points ``J_load0`` on the axis and
  ``J_load1`` off it);
* position: ``J_axis``, ``J_a``, ``J_b`` as the linear spring-damper.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..model.types import GROUND, Force, Point, Torque
from .joints import perpendiculars

FAMILY = {"angle": "angle", "rate": "angle", "position": "position", "speed": "position"}


@dataclass(frozen=True)
class JointUse:
    """One joint quantity family a load reads, with the model triples measuring it
    (angle: A.ri, A.rj, B.ri, B.rj, u; position: u, r_a, r_b)."""
    joint: str
    family: str
    triples: tuple[str, ...]


def used_families(function: str, joint_names, inputs=()) -> list[tuple[str, str]]:
    """(joint, family) pairs named in ``function`` ("ex;ex;ex", checked by the
    grammar when the model was loaded), in order of first use; read again by the
    grammar over every joint quantity, never evaluated."""
    import sympy

    from .expressions import parse_expression
    names = {"t", *inputs} | {f"{j}.{q}" for j in joint_names for q in FAMILY}
    symbols = {n: sympy.Symbol(n, real=True) for n in names}
    out = []
    for part in function.split(";"):
        e = parse_expression(part, symbols, source="<load>", line=None, item="value")
        for s in sorted(e.free_symbols, key=str):
            if s.name == "t" or s.name in inputs:         # the time, the model's inputs
                continue
            joint, quantity = s.name.rsplit(".", 1)
            pair = (joint, FAMILY[quantity])
            if pair not in out:
                out.append(pair)
    return out


def with_joint_uses(lowerer, ld):
    """``ld`` (a Force or Torque) with its JointUse list set; other loads unchanged."""
    if not isinstance(ld, (Force, Torque)) or not ld.function:
        return ld
    pairs = used_families(ld.function, lowerer.by_joint,
                          tuple(getattr(lowerer.model, "inputs", {})))
    if not pairs:
        return ld
    uses = []
    for joint, family in pairs:
        j = lowerer.by_joint[joint].joint
        if family == "position":
            triples = (f"{j.name}_axis", f"{j.name}_a", f"{j.name}_b")
        else:
            sides = tuple(_side(lowerer, j, body) for body in j.bodies)
            triples = (*sides[0], *sides[1], f"{j.name}_axis")
        uses.append(JointUse(joint, family, triples))
    return replace(ld, joints=tuple(uses))


# A side measures an angle about the axis by its direction's part perpendicular to
# the axis; a direction along the axis has none, and one nearly along it measures the
# coordinates' rounding. The body's frame points i, j measure it when their line is at
# least this sine off the axis (the kernels of existing models stay as they were),
# else the better of them and the body's unit vector u. The body rules keep u at
# least 1e-3 (sine) off r_ij (fccgen.model.checks.PARALLEL_SIN), so one of the two is
# about 5e-4 or more off any axis.
SIDE_SIN_PREFERRED = 0.1


def body_side(lowerer, j, body: str, origin: str, what: str):
    """Two triples (r_i, r_j) of ``body`` (not ground) whose difference is a direction
    of the body off the joint axis: its frame points i, j, or, when they lie along the
    axis, a fixed point ``origin`` at 0 and the body's unit vector u (u - 0 = u).
    ``origin`` is made once and shared by both sides and every reader of the joint's
    angle; ``what`` names the reader in a clash of names."""
    if body in lowerer.frames:
        i, jj, u = lowerer.frames[body]
    else:
        i, jj, u = (lowerer.bodies[body].i, lowerer.bodies[body].j, lowerer.bodies[body].u)
    axis = np.asarray(j.axes[0], float)
    axis = axis / np.linalg.norm(axis)
    pair = _off_axis(lowerer.points[jj].at - lowerer.points[i].at, axis)
    if pair >= SIDE_SIN_PREFERRED or pair >= _off_axis(lowerer.vectors[u].along, axis):
        return i, jj
    if origin in lowerer.taken:
        raise lowerer.clash(j.where.line, f"joints.{j.name}", origin, what)
    if origin not in lowerer.points:                 # both sides share it
        lowerer.points[origin] = Point(origin, np.zeros(3), True, j.where)
    return origin, u


def _off_axis(direction, axis) -> float:
    """Sine of the angle between ``direction`` and the unit ``axis`` (0: along it)."""
    d = np.asarray(direction, float)
    n = float(np.linalg.norm(d))
    return float(np.linalg.norm(np.cross(d, axis)) / n) if n > 0.0 else 0.0


def _side(lowerer, j, body: str) -> tuple[str, str]:
    """Two triples of ``body`` whose difference is not along the joint axis."""
    if body != GROUND:
        return body_side(lowerer, j, body, f"{j.name}_origin",
                         "a load reading this joint's angle")
    names = (f"{j.name}_load0", f"{j.name}_load1")
    if names[0] not in lowerer.points:
        at = (j.at[0], j.at[0] + perpendiculars(j.axes[0])[0])
        for name, value in zip(names, at):
            if name in lowerer.taken or name in lowerer.points:
                raise lowerer.clash(j.where.line, f"joints.{j.name}", name,
                                    "a load reading this joint's angle")
            lowerer.points[name] = Point(name, np.asarray(value, float), True, j.where)
    return names
