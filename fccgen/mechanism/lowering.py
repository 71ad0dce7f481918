"""Lowering a model with joints and pose-form bodies onto section 2's points, vectors
and constraints (DESIGN section 2b).

1. Every joint gives carried triples and relations (:mod:`fccgen.mechanism.joints`).
2. Every pose-form body picks i, j, u among the triples it carries
   (:mod:`fccgen.mechanism.bodies`) and becomes a typical body.
3. Every other triple a moving body carries is *attached* to it:
   a point  r_k - [r_i + b1 r_ij + b2 u + b3 (r_ij x u)/(alpha l)] = 0,
   a vector w - (nu1 e1 + nu2 e2 + nu3 e3) = 0 (3 rows each; b from the body-frame
   coordinates rho as in DESIGN section 1, rho and nu from the initial configuration).
   An attached vector gets no u.u - 1 row: its body frame makes it a unit vector.
   A triple carried by ground is fixed and needs no rows for ground.

A shared vector tied to two frames gives three rows but only two conditions once the
first frame fixes it (both sides are unit vectors): such a row is redundant, which
the solvers handle (DESIGN section 1) and ``fccgen check`` reports by joint. The
choice of u prefers shared vectors so that this happens only where it must.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import ModelError
from ..model.types import (GROUND, Angle, Attached, BodyPoint, Distance, Force, Initial,
                           Model, Point, PointOnPlane, Vector)
from .bodies import choose_frame, typical_body
from .joints import CarriedTriple, JointLowering, lower_joint


@dataclass
class JointDistance(Distance):
    """A distance constraint that says which joint it comes from."""
    label: str | None = None


@dataclass
class Lowering:
    """What the mechanism level became: per joint its triples and constraint labels,
    per pose-form body its i, j, u and FCC rotation at the initial configuration."""
    joints: list[JointLowering]
    frames: dict[str, tuple[str, str, str]]           # body -> (i, j, u)
    labels: dict[str, list[str]] = field(default_factory=dict)   # joint -> labels

    def joint(self, name: str) -> JointLowering:
        return next(j for j in self.joints if j.joint.name == name)

    def describe(self) -> list[str]:
        """One line per joint and per body, for ``fccgen check``."""
        lines = []
        for jl in self.joints:
            j = jl.joint
            parts = []
            for t in jl.triples:
                on = ", ".join(t.carriers)
                parts.append(f"{t.kind} {t.name} on {on}")
            lines.append(f"joint {j.name} ({j.type}, {j.bodies[0]} -> {j.bodies[1]}): "
                         + "; ".join(parts))
            for label in self.labels.get(j.name, []):
                lines.append(f"  {label}")
        for body, (i, j, u) in self.frames.items():
            lines.append(f"body {body}: i = {i}, j = {j}, u = {u}")
        return lines


def _label(jl: JointLowering, what: str) -> str:
    return f"joint {jl.joint.name} ({jl.joint.type}): {what}"


def lower(model: Model) -> Model:
    """The section-2 model of ``model`` (itself when it has no mechanism level), with
    ``model.mechanism`` the :class:`Lowering`."""
    if not model.pose_bodies and not model.joints:
        return model
    frames = {GROUND: np.eye(3), **{n: b.frame for n, b in model.pose_bodies.items()}}
    lowered = [lower_joint(j, frames) for j in model.joints]
    triples: dict[str, CarriedTriple] = {}
    taken = set(model.points) | set(model.vectors) | set(model.bodies) \
        | set(model.pose_bodies) | {j.name for j in model.joints}
    for jl in lowered:
        for t in jl.triples:
            if t.name in taken - {jl.joint.name} or t.name in triples:
                raise ModelError(model.source, jl.joint.where.line, f"joints.{jl.joint.name}",
                                 f"the name {t.name} that this joint's points and vectors "
                                 "take is already used; rename one of them", t.name)
            triples[t.name] = t
    points, vectors = dict(model.points), dict(model.vectors)
    bodies, constraints, used_u = dict(model.bodies), [], set()
    labels: dict[str, list[str]] = {jl.joint.name: [] for jl in lowered}
    body_frames: dict[str, tuple[str, str, str]] = {}
    rotations: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for t in triples.values():
        fixed = GROUND in t.carriers
        where = next(jl.joint.where for jl in lowered if jl.joint.name == t.joint)
        if t.kind == "point":
            points[t.name] = Point(t.name, t.value, fixed, where)
        else:
            vectors[t.name] = Vector(t.name, t.value, fixed, where)
    for name, pb in model.pose_bodies.items():
        carried = [t for t in triples.values() if name in t.carriers]
        choice = choose_frame(
            pb, [(t.name, t.value) for t in carried if t.kind == "point"],
            [(t.name, t.value, GROUND in t.carriers) for t in carried if t.kind == "vector"],
            used_u)
        for new_name, kind, value in choice.new:
            if new_name in taken or new_name in triples:
                raise ModelError(model.source, pb.where.line, f"bodies.{name}",
                                 f"the name {new_name} that this body's frame takes is "
                                 "already used; rename one of them", new_name)
            table, cls = (points, Point) if kind == "point" else (vectors, Vector)
            table[new_name] = cls(new_name, np.asarray(value, float), False, pb.where)
        used_u.add(choice.u)
        ri, rj, u = points[choice.i].at, points[choice.j].at, vectors[choice.u].along
        bodies[name], R = typical_body(pb, ri, rj, u, choice)
        body_frames[name] = (choice.i, choice.j, choice.u)
        rotations[name] = (ri, R)
        for t in carried:
            if t.name in (choice.i, choice.j, choice.u):
                continue
            rho = R.T @ (t.value - ri) if t.kind == "point" else R.T @ t.value
            jl = next(jl for jl in lowered if jl.joint.name == t.joint)
            label = _label(jl, f"{t.kind} {t.name} on {name}")
            labels[t.joint].append(label)
            constraints.append(Attached(t.name, name, tuple(float(x) for x in rho), t.kind,
                                        jl.joint.where, label))
    for jl in lowered:
        for rel in jl.relations:
            kind, a, b, extra = rel
            where = jl.joint.where
            if kind == "plane":
                label = _label(jl, f"{a} on the plane through {b} normal to {extra}")
                constraints.append(PointOnPlane(a, b, extra, where, label))
            elif kind == "dot":
                label = _label(jl, f"{a} . {b} = {extra:.6g}")
                constraints.append(Angle((a, b), extra, where, label))
            else:
                label = _label(jl, f"|{b} - {a}| = {extra:.6g}")
                constraints.append(JointDistance((a, b), extra, where, label=label))
            labels[jl.joint.name].append(label)
    pose = {n: (*rotations[n], b.center, b.frame) for n, b in model.pose_bodies.items()}
    out = replace(model, points=points, vectors=vectors, bodies=bodies,
                  constraints=[*_converted(model.constraints, pose), *constraints],
                  loads=_converted(model.loads, pose),
                  initial=_initial(model.initial, model.pose_bodies),
                  pose_bodies={}, joints=[])
    out.mechanism = Lowering(lowered, body_frames, labels)
    return out


# -- items that name pose-form bodies --------------------------------------------------

def _pose_rho(pose, body: str, at) -> tuple[float, float, float]:
    """A pose-form body's point ``at`` (pose frame, from the mass centre) as FCC
    body-frame coordinates from point i."""
    ri, R, centre, frame = pose[body]
    r = centre + frame @ np.asarray(at, float)
    return tuple(float(x) for x in R.T @ (r - ri))


def _converted(items, pose):
    """Constraints and loads with the points of pose-form bodies in FCC body-frame
    coordinates (a force without ``at`` acts at the mass centre)."""
    out = []
    for it in items:
        if isinstance(it, Force) and it.body in pose:
            it = replace(it, at=_pose_rho(pose, it.body, it.at or (0.0, 0.0, 0.0)))
        for attr in ("ends", "points", "line", "point"):
            refs = getattr(it, attr, None)
            if refs is None:
                continue
            single = not isinstance(refs, tuple)
            new = tuple(_ref(pose, r) for r in ((refs,) if single else refs))
            it = replace(it, **{attr: new[0] if single else new})
        out.append(it)
    return out


def _ref(pose, ref):
    if isinstance(ref, BodyPoint) and ref.body in pose:
        return BodyPoint(ref.body, _pose_rho(pose, ref.body, ref.at))
    return ref


def _initial(initial: Initial, pose_bodies) -> Initial:
    """Body-frame angular velocities of pose-form bodies turned global."""
    out = Initial(dict(initial.point_velocities), dict(initial.body_angular_velocities))
    for name, w in initial.body_angular_velocities.items():
        if name in pose_bodies and w.frame == "body":
            out.body_angular_velocities[name] = replace(
                w, value=pose_bodies[name].frame @ w.value, frame="global")
    return out
