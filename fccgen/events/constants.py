"""The numbers of a model that its event kernels take as runtime parameters.

The event kernels (fccgen.events.symbolic) depend on numbers of the initial
configuration: each body's constants l, alpha, beta (docs/design.md §1), the fixed
points and vectors, and per joint angle the directions that define its zero: the
joint axis a_A and a perpendicular n1 in body A's initial frame, a_A x n1, and
w = C_0^T n1 with C_0 = R_A0^T R_B0 the initial relative rotation. Printed as numbers
they would make a model that starts at another angle, or whose points are moved by
``with_parameters``, a different module; as parameters, one build serves them all.

``layout`` names the groups in the order of the parameter vector (after the 3 angle
references per angle quantity), ``values`` computes them for a plan, without SymPy
expressions. The kernels' symbols are made from the same layout.
"""
from __future__ import annotations

import math

import numpy as np

from ..mechanism.joints import perpendiculars
from ..model.types import GROUND
from .references import HINGE_SIZE, angle_sources, event_quantities, hinge_constants

SIZES = {"body": 3, "triple": 3, "angle": 12, "hinge": HINGE_SIZE, "input": 1}


def event_inputs(model) -> list[str]:
    """The model's inputs that its event functions read, in the model file's order.
    Their values are the last group of the constants: the runtime writes each input's
    held value there as it writes it into the element kernels' parameters."""
    read = set()
    for ev in model.events:
        read |= {s.name for s in ev.function.free_symbols}
    return [name for name in getattr(model, "inputs", {}) if name in read]


def layout(plan, angle_joints: list[str]) -> list[tuple[str, str]]:
    """(kind, name) of each group of constants: every body (l, alpha, beta), every
    fixed point and vector (x, y, z), every angle quantity's joint (a_A, n1, a_A x n1,
    w; or, for an angle only element kernels read, the "hinge" numbers of
    fccgen.events.references.hinge_constants), every input the events read (its
    value), in that order."""
    model = plan.model
    out = [("body", name) for name in model.bodies if name != GROUND]
    out += [("triple", name) for name in (*model.points, *model.vectors)
            if name not in plan.index]
    lowering = getattr(model, "mechanism", None)
    joints = {jl.joint.name: jl.joint for jl in lowering.joints} if lowering else {}
    events = {name for name, kind in event_quantities(model.events, joints)
              if kind == "angle"}
    out += [("angle" if name in events else "hinge", name) for name in angle_joints]
    return out + [("input", name) for name in event_inputs(model)]


def _positions(model) -> dict:
    return {**{n: p.at for n, p in model.points.items()},
            **{n: v.along for n, v in model.vectors.items()}}


def body_constants(model, body: str) -> tuple[float, float, float]:
    """(l, alpha, beta) of a body at the initial configuration."""
    b = model.bodies[body]
    pos = _positions(model)
    rij = np.asarray(pos[b.j], float) - np.asarray(pos[b.i], float)
    l = float(np.linalg.norm(rij))
    beta = float(rij @ np.asarray(pos[b.u], float)) / l
    return l, math.sqrt(1.0 - beta * beta), beta


def rotation0(model, body: str) -> np.ndarray:
    """R of a body at the initial configuration (ground: the identity)."""
    if body == GROUND:
        return np.eye(3)
    b = model.bodies[body]
    pos = _positions(model)
    e1 = np.asarray(pos[b.j], float) - np.asarray(pos[b.i], float)
    e1 /= np.linalg.norm(e1)
    e3 = np.cross(e1, pos[b.u])
    e3 /= np.linalg.norm(e3)
    return np.column_stack([e1, np.cross(e3, e1), e3])


def angle_constants(model, joint) -> np.ndarray:
    """(a_A, n1, a_A x n1, w) of a joint's angle: 12 numbers."""
    A, B = joint.bodies
    RA0, RB0 = rotation0(model, A), rotation0(model, B)
    a_A = RA0.T @ joint.axes[0]
    n1 = perpendiculars(a_A)[0]
    w = (RA0.T @ RB0).T @ n1
    return np.concatenate([a_A, n1, np.cross(a_A, n1), w])


def values(plan, angle_joints: list[str]) -> np.ndarray:
    """The constants of ``layout(plan, angle_joints)`` for this plan."""
    model = plan.model
    lowering = getattr(model, "mechanism", None)
    joints = {jl.joint.name: jl.joint for jl in lowering.joints} if lowering else {}
    hinges = {s.name: s for s in angle_sources(plan)}
    pos = _positions(model)
    out = []
    for kind, name in layout(plan, angle_joints):
        if kind == "body":
            out += body_constants(model, name)
        elif kind == "triple":
            out += [float(x) for x in pos[name]]
        elif kind == "hinge":
            out += [float(x) for x in hinge_constants(plan, hinges[name])]
        elif kind == "input":
            out.append(float(model.inputs[name]))
        else:
            out += [float(x) for x in angle_constants(model, joints[name])]
    return np.array(out, dtype=float)


def input_positions(plan, angle_joints: list[str]) -> dict[str, int]:
    """name -> the index among the constants of each input the events read."""
    out, k = {}, 0
    for kind, name in layout(plan, angle_joints):
        if kind == "input":
            out[name] = k
        k += SIZES[kind]
    return out
