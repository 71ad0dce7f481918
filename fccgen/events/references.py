"""Turn counting for the element kernels that read a joint angle: torsion springs and
loads of joint angles (docs/elements.md, "Angles over turns").

From q alone an angle is known only modulo a turn: atan2 of the relative rotation
jumps by 2 pi at half a turn from its zero. The event kernels (fccgen.events.symbolic)
already count turns: each joint angle they use is theta_r + atan2(...) relative to a
reference theta_r that the runtime moves to the angle of every accepted state (with
its cosine and sine, three runtime parameters per angle; ev_refresh in
fccgen/runtime/_events.pyx). The element kernels take the same three numbers as their
parameters th, cr, sr (fccgen.plan.classes.REFERENCE_SCALARS), and the runtime copies
the event kernels' references into them at every re-basing: one reference per angle,
kept in one place.

This module says which angles the element kernels need (:func:`angle_sources`: a
joint's angle, or for a section-2 torsion spring ``loads[k]`` the rotation about its
shared vector), how to measure each (the first element that reads it: its hinge
triples and scalars, :func:`hinge_constants`) and where the references sit among the
element parameters (:func:`reference_slots`). No SymPy: the runtime reads it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanism.joints import ANGLE_TYPES
from ..plan.classes import REFERENCE_SCALARS

# The measure of a hinge angle in an element (fccgen.plan.classes): two points of each
# side, the axis, and the scalars that turn (D, P) to the initial angle.
HINGE_TRIPLES = ("A.ri", "A.rj", "B.ri", "B.rj", "u")
HINGE_SCALARS = ("lA", "lB", "cos0", "sin0")
HINGE_SIZE = len(HINGE_SCALARS) + 3 * len(HINGE_TRIPLES)


@dataclass(frozen=True)
class AngleSource:
    """An angle that element kernels read: ``name`` (a joint's, or ``loads[k]``), and
    the first element reading it with the prefix of its hinge names ("" for a
    torsion spring, "J.angle." for a load of J's angle)."""
    name: str
    element: int
    prefix: str


def event_quantities(events, joints) -> list[tuple[str, str]]:
    """(joint, angle|position) of every joint quantity that events read or lock."""
    wanted: list[tuple[str, str]] = []

    def want(jname, kind):
        if (jname, kind) not in wanted:
            wanted.append((jname, kind))

    for ev in events:
        for s in sorted(ev.function.free_symbols, key=str):
            jname, _, what = s.name.partition(".")
            if jname in joints:
                want(jname, "angle" if what in ("angle", "rate") else "position")
        if ev.action in ("lock", "unlock"):
            j = joints[ev.joint]
            want(j.name, "angle" if j.type in ANGLE_TYPES else "position")
            if j.type == "cylindrical":
                want(j.name, "position")
    return wanted


def _joints(plan) -> dict:
    lowering = getattr(plan.model, "mechanism", None)
    return {jl.joint.name: jl.joint for jl in lowering.joints} if lowering else {}


def _spring_name(plan, k: int, joints: dict) -> str:
    """A torsion spring's angle: its joint's (joint form: its axis is the joint's axis
    vector between the joint's bodies), else its own, ``loads[k]``."""
    ld = plan.model.loads[k]
    for j in joints.values():
        if tuple(j.bodies) == tuple(ld.bodies) and ld.axis == f"{j.name}_axis":
            return j.name
    return f"loads[{k}]"


def element_angles(plan) -> list[AngleSource]:
    """Every angle an element kernel reads through a reference, in element order (a
    load may read several; each AngleSource names the element that reads it)."""
    joints = _joints(plan)
    out = []
    for e, el in enumerate(plan.elements):
        if el.cls.kind == "torsion_spring":
            k = int(el.label[len("loads["):-1])
            out.append(AngleSource(_spring_name(plan, k, joints), e, ""))
        for joint, family in el.cls.joint_families:
            if family == "angle":
                out.append(AngleSource(joint, e, f"{joint}.angle."))
    return out


def angle_sources(plan) -> list[AngleSource]:
    """The angles element kernels read, each once (its first reader)."""
    out: dict[str, AngleSource] = {}
    for source in element_angles(plan):
        out.setdefault(source.name, source)
    return list(out.values())


def hinge_constants(plan, source: AngleSource) -> np.ndarray:
    """The HINGE_SIZE numbers of ``source``'s measure: its element's lA, lB, cos0,
    sin0, then x, y, z of each HINGE_TRIPLES triple that is fixed (zeros for moving
    ones, which are coordinates)."""
    el = plan.elements[source.element]
    names = el.cls.param_names
    out = [el.params[names.index(source.prefix + s)] for s in HINGE_SCALARS]
    for t in HINGE_TRIPLES:
        key = f"{source.prefix}{t}.x"
        out += (list(el.params[names.index(key):names.index(key) + 3]) if key in names
                else [0.0, 0.0, 0.0])
    return np.array(out, dtype=float)


def reference_slots(plan) -> list[tuple[int, str]]:
    """(index of th in the concatenated element parameters, angle name) of every
    reference an element kernel reads; cr and sr follow th."""
    starts = np.concatenate([[0], np.cumsum([len(el.params) for el in plan.elements])])
    return [(int(starts[s.element])
             + plan.elements[s.element].cls.param_names.index(s.prefix + REFERENCE_SCALARS[0]),
             s.name) for s in element_angles(plan)]
