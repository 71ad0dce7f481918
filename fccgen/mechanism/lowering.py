"""Lowering a model with joints and pose-form bodies onto section 2's points, vectors
and constraints (docs/design.md §2b).

1. Every joint gives carried triples and relations (:mod:`fccgen.mechanism.joints`).
2. Every pose-form body picks i, j, u among the triples it carries
   (:mod:`fccgen.mechanism.bodies`) and becomes a typical body; a body given by
   points keeps its own.
3. Every other triple a moving body carries is *attached* to it:
   a point  r_k - [r_i + b1 r_ij + b2 u + b3 (r_ij x u)/(alpha l)] = 0,
   a vector w - (nu1 e1 + nu2 e2 + nu3 e3) = 0 (3 rows each; b from the body-frame
   coordinates rho as in docs/design.md §1, rho and nu from the initial configuration).
   An attached vector gets no u.u - 1 row: its body frame makes it a unit vector.
   A triple carried by ground is fixed and needs no rows for ground.

A shared vector tied to two frames gives three rows but only two conditions once the
first frame fixes it (both sides are unit vectors): such a row is redundant, which
the solvers handle (docs/design.md §1) and ``fccgen check`` reports by joint. The
choice of u prefers shared vectors so that this happens only where it must.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import ModelError
from ..model import checks
from ..model.types import (GROUND, Angle, Attached, BodyPoint, Distance, DriverRow, Force,
                           Initial, JointSpring, LinearSpring, Model, Point, PointOnPlane,
                           TorsionSpring, Vector)
from ..model.geometry import body_rotation
from .bodies import choose_frame, typical_body
from .cables import lower_cables
from .joint_loads import body_side, with_joint_uses

# |nu3| (the component of a tied vector along the body's e3) from which its two-row
# form (components on e1, e2) is used: below it the two rows lose rank as w nears
# the e1-e2 plane, where the sign of nu3 is no longer held. 0.5: within 60 degrees
# of e3, a condition number of at most 2.
ALIGN_MIN = 0.5
from .joints import (CarriedTriple, JointLowering, lower_joint, output_columns,
                     perpendiculars)
from .reaction_bases import COMPONENTS as REACTION_COMPONENTS


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
    drivers: list = field(default_factory=list)       # fccgen.model.types.Driver
    made: list = field(default_factory=list)          # points and vectors it named
    # body -> (r_i, R, F): the FCC frame's origin and rotation at the initial
    # configuration and the pose frame of the file (columns x, y, z, global), so that
    # numbers the file gives in its own terms (an inertia in ``frame``, the global mass
    # centre) can be set again in those terms (fccgen.runtime.params)
    poses: dict = field(default_factory=dict)

    def internal(self) -> list[str]:
        """The points and vectors the lowering made that a user did not name: all it
        made but a joint's own point ``J`` (the joint's place, named by the user)."""
        joints = {jl.joint.name for jl in self.joints}
        return [n for n in self.made if n not in joints]

    def columns(self) -> list[str]:
        """The joint result columns (J.angle, J.rate, J.position, J.speed), the
        drivers' generalized forces (D.torque, D.force), then the reactions (J.fx ...
        J.tz; absent from a run that skips or refuses them, see
        fccgen.mechanism.reactions)."""
        return ([c for jl in self.joints for c in output_columns(jl.joint)]
                + [driver_column(d) for d in self.drivers]
                + [f"{jl.joint.name}.{c}" for jl in self.joints for c in REACTION_COMPONENTS])

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


def driver_column(driver) -> str:
    """The result column of a driver's generalized force: ``D.torque`` for an angle,
    ``D.force`` for a position or a distance."""
    return f"{driver.name}.{'torque' if driver.quantity == 'angle' else 'force'}"


def driver_label(driver) -> str:
    if driver.quantity == "coordinate":
        along = ", ".join(f"{x:.6g}" for x in driver.direction)
        return f"driver {driver.name} (coordinate of point {driver.point} along [{along}])"
    return f"driver {driver.name} ({driver.quantity} of joint {driver.joint})"


def _label(jl: JointLowering, what: str) -> str:
    return f"joint {jl.joint.name} ({jl.joint.type}): {what}"


def lower(model: Model) -> Model:
    """The section-2 model of ``model`` (itself when it has no mechanism level), with
    ``model.mechanism`` the :class:`Lowering`, and its cables lowered
    (fccgen.mechanism.cables)."""
    if model.pose_bodies or model.joints or model.drivers:
        model = _Lowerer(model).run()
    return lower_cables(model)             # flexible members, on typical bodies


def two_rows(nu, fixed: bool) -> str | None:
    """Which two body-frame components hold an already-unit vector with components
    nu: for a fixed vector the two smallest (the third is then at least 1/sqrt(3), and
    w.(r_ij x u) is quadratic); for a moving one e1, e2 when |nu3| >= ALIGN_MIN
    (w.(r_ij x u) would be cubic); None when neither is regular."""
    if fixed:
        drop = int(np.argmax(np.abs(nu)))
        return "".join(str(k + 1) for k in range(3) if k != drop)
    return "12" if abs(nu[2]) >= ALIGN_MIN else None


class _Lowerer:
    """The steps of :func:`lower`, in order: joints, triples, bodies, rows."""

    def __init__(self, model: Model):
        self.model = model
        frames = {GROUND: np.eye(3), **{n: b.frame for n, b in model.pose_bodies.items()}}
        self.lowered = [lower_joint(j, frames) for j in model.joints]
        self.by_joint = {jl.joint.name: jl for jl in self.lowered}
        self.driver_triples = {d.name: self.driver_vectors(d) for d in model.drivers
                               if d.quantity != "coordinate"}
        self.taken = (set(model.points) | set(model.vectors) | set(model.bodies)
                      | set(model.pose_bodies) | set(self.by_joint))
        self.triples: dict[str, CarriedTriple] = {}
        self.points, self.vectors = dict(model.points), dict(model.vectors)
        self.bodies = dict(model.bodies)
        self.constraints: list = []
        self.labels: dict[str, list[str]] = {name: [] for name in self.by_joint}
        self.frames: dict[str, tuple[str, str, str]] = {}
        self.rotations: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        # per attached vector: [(body, nu)], rows decided once all bodies are known
        self.vector_ties: dict[str, list[tuple[str, np.ndarray]]] = {}

    def run(self) -> Model:
        self.collect_triples()
        for name, pb in self.model.pose_bodies.items():
            self.body(name, pb)
        for name, body in self.model.bodies.items():      # given by points: i, j, u kept
            self.section2_body(name, body)
        self.vector_rows()
        self.relation_rows()
        self.driver_rows()
        m = self.model
        pose = {n: (*self.rotations[n], b.center, b.frame) for n, b in m.pose_bodies.items()}
        loads = [self.joint_load(ld) if isinstance(ld, JointSpring)
                 else with_joint_uses(self, ld) for ld in m.loads]
        out = replace(m, points=self.points, vectors=self.vectors, bodies=self.bodies,
                      constraints=[*_converted(m.constraints, pose), *self.constraints],
                      loads=_converted(loads, pose),
                      initial=_initial(m.initial, m.pose_bodies), pose_bodies={}, joints=[])
        made = [n for n in [*self.points, *self.vectors]
                if n not in m.points and n not in m.vectors]
        out.mechanism = Lowering(self.lowered, self.frames, self.labels,
                                 list(m.drivers), made,
                                 {n: (*self.rotations[n], np.asarray(b.frame, float))
                                  for n, b in m.pose_bodies.items()})
        return out

    def driver_vectors(self, d) -> tuple[str, str, str]:
        """The triples (u, a, b) of an angle driver -- the joint axis and two new unit
        vectors, one on each body, perpendicular to it and equal at the start -- or
        (u, r_a, r_b) of a position driver (the joint's own triples)."""
        jl = self.by_joint[d.joint]
        name = jl.joint.name
        if d.quantity == "position":
            return (f"{name}_axis", f"{name}_a", f"{name}_b")
        if d.quantity == "distance":                 # replaces the joint's own row
            jl.relations = [r for r in jl.relations if r[0] != "distance"]
            return (f"{name}_a", f"{name}_b")
        A, B = jl.joint.bodies
        n1 = perpendiculars(jl.joint.axes[0])[0]
        return (f"{name}_axis", jl.add("_drive_a", "vector", n1, (A,)),
                jl.add("_drive_b", "vector", n1, (B,)))

    def joint_load(self, ld: JointSpring):
        """A torsion spring on a joint: the torsion_spring element about the joint's
        axis vector, each side's frame given by two of its body's points (ground: two
        new fixed points, the joint's location and one off the axis). A linear spring:
        the linear_spring element on the joint's axis and points J_a, J_b."""
        jl = self.by_joint[ld.joint]
        j = jl.joint
        if ld.kind == "linear":
            return LinearSpring((f"{j.name}_axis", f"{j.name}_a", f"{j.name}_b"),
                                ld.stiffness, ld.free, ld.damping, ld.where)
        sides = []
        for body in j.bodies:
            if body == GROUND:
                names = (f"{j.name}_spring0", f"{j.name}_spring1")
                at = (j.at[0], j.at[0] + perpendiculars(j.axes[0])[0])
                for name, value in zip(names, at):
                    if name in self.taken or name in self.points:
                        raise self.clash(j.where.line, f"joints.{j.name}", name,
                                         "this joint's torsion spring")
                    self.points[name] = Point(name, np.asarray(value, float), True,
                                              ld.where)
                sides.append(names)
            else:
                sides.append(body_side(self, j, body, f"{j.name}_origin",
                                       "this joint's torsion spring"))
        return TorsionSpring(j.bodies, f"{j.name}_axis", ld.stiffness, ld.free,
                             ld.damping, ld.where, sides=tuple(sides))

    def driver_rows(self):
        for d in self.model.drivers:
            label = driver_label(d)
            if d.quantity == "coordinate":
                self.constraints.append(self.coordinate_row(d, label))
                continue
            self.constraints.append(DriverRow(d.quantity, self.driver_triples[d.name],
                                              d.function, d.where, label))
            self.labels[d.joint].append(label)

    def coordinate_row(self, d, label: str) -> DriverRow:
        """e.(r - r0) - f for the point (a joint's shared point: its triple, which may
        be a section-2 point it coincides with) and the unit direction e."""
        name = d.point
        if name in self.by_joint:
            name = next(t.name for t in self.by_joint[name].triples if t.kind == "point")
        e = np.asarray(d.direction, float)
        c0 = float(e @ np.asarray(self.points[name].at, float))
        return DriverRow("coordinate", (name,), d.function, d.where, label,
                         scalars={"ex": float(e[0]), "ey": float(e[1]), "ez": float(e[2]),
                                  "c0": c0})

    def clash(self, line, item: str, name: str, what: str) -> ModelError:
        return ModelError(self.model.source, line, item, f"the name {name}, which {what} "
                          "needs, is already used; rename one of them", name)

    def collect_triples(self):
        """Every joint's triples as points and vectors (fixed when ground carries them)."""
        for jl in self.lowered:
            j = jl.joint
            for t in jl.triples:
                alias = self.section2_point(t)
                if alias is not None:           # the joint's point is a body's i or j
                    t.name = alias
                    if alias in self.triples:
                        self.triples[alias].carriers += [c for c in t.carriers
                                                         if c not in self.triples[alias].carriers]
                    else:
                        self.triples[alias] = t
                    continue
                if t.name in self.taken - {j.name} or t.name in self.triples:
                    raise self.clash(j.where.line, f"joints.{j.name}", t.name,
                                     "this joint's lowering")
                self.triples[t.name] = t
                fixed = GROUND in t.carriers
                if t.kind == "point":
                    self.points[t.name] = Point(t.name, t.value, fixed, j.where)
                else:
                    self.vectors[t.name] = Vector(t.name, t.value, fixed, j.where)

    def section2_point(self, t: CarriedTriple) -> str | None:
        """The point i or j of a body given by points that the shared joint point ``t``
        is (same place, and both moving), so that it needs no triple of its own."""
        if t.kind != "point" or t.name != t.joint or GROUND in t.carriers:
            return None
        for body in (self.model.bodies.get(c) for c in t.carriers):
            for name in (body.i, body.j) if body is not None else ():
                p = self.model.points[name]
                if not p.fixed and checks.coincide(p.at, t.value):
                    return name
        return None

    def body(self, name: str, pb):
        """Choose i, j, u; attach the other points now, collect the vectors' ties."""
        carried = [t for t in self.triples.values() if name in t.carriers]
        used_u = {u for _, _, u in self.frames.values()}
        choice = choose_frame(
            pb, [(t.name, t.value) for t in carried if t.kind == "point"],
            [(t.name, t.value, GROUND in t.carriers) for t in carried if t.kind == "vector"],
            used_u)
        for new_name, kind, value in choice.new:
            if new_name in self.taken or new_name in self.triples:
                raise self.clash(pb.where.line, f"bodies.{name}", new_name,
                                 "this body's frame")
            table, cls = (self.points, Point) if kind == "point" else (self.vectors, Vector)
            table[new_name] = cls(new_name, np.asarray(value, float), False, pb.where)
        ri, rj = self.points[choice.i].at, self.points[choice.j].at
        self.bodies[name], R = typical_body(pb, ri, rj, self.vectors[choice.u].along, choice)
        self.frames[name] = (choice.i, choice.j, choice.u)
        self.rotations[name] = (ri, R)
        self.tie(name, carried, ri, R, (choice.i, choice.j, choice.u))

    def section2_body(self, name: str, body):
        """A body given by points carries its joints' triples by attachment alone."""
        carried = [t for t in self.triples.values() if name in t.carriers]
        if carried:
            ri, rj = self.points[body.i].at, self.points[body.j].at
            R = body_rotation(ri, rj, self.vectors[body.u].along)
            self.tie(name, carried, ri, R, (body.i, body.j, body.u))

    def tie(self, name: str, carried, ri, R, own):
        """Attach the carried points now and collect the vectors' ties (not ``own``)."""
        for t in carried:
            if t.name in own:
                continue
            if t.kind == "vector":
                self.vector_ties.setdefault(t.name, []).append((name, R.T @ t.value))
                continue
            rho = tuple(float(x) for x in R.T @ (t.value - ri))
            where = self.by_joint[t.joint].joint.where
            self.attach(t, Attached(t.name, name, rho, "point", where),
                        f"point {t.name} on {name}")

    def attach(self, t: CarriedTriple, c: Attached, what: str):
        jl = self.by_joint[t.joint]
        c.label = _label(jl, what)
        self.labels[t.joint].append(c.label)
        self.constraints.append(c)

    def vector_rows(self):
        """Three rows w - R nu = 0 for the one tie of a moving vector that makes it a
        unit vector (the tie with the smallest |nu3|), two rows for every other tie
        (:func:`two_rows`), or three when no two rows are regular (one redundant)."""
        for name, ties in self.vector_ties.items():
            t = self.triples[name]
            where = self.by_joint[t.joint].joint.where
            fixed = self.vectors[name].fixed
            ties = sorted(ties, key=lambda bn: abs(bn[1][2]))
            for k, (body, nu) in enumerate(ties):
                rows = None if (k == 0 and not fixed) else two_rows(nu, fixed)
                nu_t = tuple(float(x) for x in nu)
                if rows:
                    self.attach(t, Attached(name, body, nu_t, f"aligned_{rows}", where),
                                f"vector {name} along {body} (components e{rows[0]}, "
                                f"e{rows[1]})")
                else:
                    self.attach(t, Attached(name, body, nu_t, "vector", where),
                                f"vector {name} on {body}")

    def relation_rows(self):
        for jl in self.lowered:
            where = jl.joint.where
            for kind, a, b, extra in jl.relations:
                if kind == "plane":
                    label = _label(jl, f"{a} on the plane through {b} normal to {extra}")
                    self.constraints.append(PointOnPlane(a, b, extra, where, label))
                elif kind == "dot":
                    label = _label(jl, f"{a} . {b} = {extra:.6g}")
                    self.constraints.append(Angle((a, b), extra, where, label))
                else:
                    label = _label(jl, f"|{b} - {a}| = {extra:.6g}")
                    self.constraints.append(JointDistance((a, b), extra, where, label=label))
                self.labels[jl.joint.name].append(label)


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
    out = Initial(dict(initial.point_velocities), dict(initial.body_angular_velocities),
                  dict(initial.joint_speeds), dict(initial.joint_positions))
    for name, w in initial.body_angular_velocities.items():
        if name in pose_bodies and w.frame == "body":
            out.body_angular_velocities[name] = replace(
                w, value=pose_bodies[name].frame @ w.value, frame="global")
    return out
