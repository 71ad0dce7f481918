"""Reading the sections that refer to points and bodies: constraints, loads, initial
velocities and simulation defaults."""
from __future__ import annotations

import math

import numpy as np

from ..methods import METHODS as REGISTRY
from ..run_settings import LINEAR_SOLVERS, RunSettingError, schedule
from .inputs import NOT_IN_POINT_FORCES, refuse_inputs
from .fields import Reader, child, listing
from .types import (Angle, AngularVelocity, Body, BodyPoint, Constraint, Distance, Force,
                    Initial, JointSpring, Load, Point, PointOnLine, PointOnPlane,
                    PointForce, PointRef,
                    SimulateDefaults, Spring, Torque, TorsionSpring, Where)
from .yamlnodes import YMap, YNode, YScalar, YSeq

# Keys of each item type: (required, optional).
CONSTRAINT_KEYS = {
    "point_on_line": (("type", "point", "line"), ()),
    "distance": (("type", "points", "length"), ()),
    # mechanism-level rows on named points and unit vectors (docs/joints.md)
    "point_on_plane": (("type", "point", "origin", "normal"), ()),
    "angle": (("type", "vectors", "angle"), ()),
}
LOAD_KEYS = {
    "force": (("type", "body", "value"), ("at",)),
    "torque": (("type", "body", "value"), ()),
    "spring": (("type", "ends", "stiffness"), ("length", "damping")),
    "torsion_spring": (("type", "bodies", "axis", "stiffness"), ("angle", "damping")),
}
# Spring-dampers on a joint's freedom (mechanism level): keys of the ``joint:`` form.
JOINT_LOAD_KEYS = {
    "torsion_spring": (("type", "joint", "stiffness"), ("angle", "damping")),
    "linear_spring": (("type", "joint", "stiffness"), ("length", "damping")),
}
# joint types with the freedom each joint spring acts on
JOINT_SPRING_TYPES = {"torsion_spring": ("revolute", "cylindrical"),
                      "linear_spring": ("prismatic", "cylindrical")}
BODY_POINT_KEYS = (("body", "at"), ())
INITIAL_KEYS = ((), ("points", "bodies", "joints"))
# Joint speeds an initial state may fix: quantity -> joint types that have it.
JOINT_SPEED_TYPES = {"rate": ("revolute", "cylindrical"),
                     "speed": ("prismatic", "cylindrical")}
# Joint positions an initial state may fix (assembly at a given joint value).
JOINT_POSITION_TYPES = {"angle": ("revolute", "cylindrical"),
                        "position": ("prismatic", "cylindrical")}
INITIAL_BODY_KEYS = (("angular_velocity",), ("frame",))
SIMULATE_KEYS = ((), ("t_end", "dt", "method", "output_dt", "rank_tol", "position_tol",
                      "max_newton", "linear_solver"))
FRAMES = ("global", "body")


class ItemReader(Reader):
    """Reads items that name the model's points and bodies (already validated)."""

    def __init__(self, source: str, points: dict[str, Point], bodies: dict[str, Body],
                 vectors: dict | None = None):
        super().__init__(source)
        self.points = points
        self.bodies = bodies
        self.vectors = vectors or {}
        self.joints: dict = {}             # name -> Joint (set by the loader)

    # -- point references --------------------------------------------------------------
    def ref(self, node: YNode, item: str) -> PointRef:
        """A point name, or ``{body: NAME, at: [x, y, z]}`` (a point on a body)."""
        if isinstance(node, YMap):
            m = self.mapping(node, item, *BODY_POINT_KEYS)
            body = self.body_name(m.entries["body"], child(item, "body"))
            at = self.vec3(m.entries["at"], child(item, "at"))
            return BodyPoint(body, tuple(float(x) for x in at))
        return self.name_in(node, item, self.points, "point", "points")

    def ref_list(self, node: YNode, item: str) -> tuple[PointRef, ...]:
        """Two or more point references, all different."""
        refs = tuple(self.ref(n, child(item, k)) for k, n in enumerate(node.items))
        if len(set(refs)) != len(refs):
            raise self.bad(node, item, "must name different points")
        return refs

    def body_name(self, node: YNode, item: str) -> str:
        return self.name_in(node, item, self.bodies, "body", "bodies")

    def typed(self, node: YNode, item: str, keys: dict) -> YMap:
        """A mapping whose ``type`` is a key of ``keys``, with that type's keys."""
        m = self.mapping_any(node, item)
        if "type" not in m.entries:
            raise self.fail(m.line, child(item, "type"), "missing required key",
                            show_value=False)
        kind = self.choice(m.entries["type"], child(item, "type"), keys, "type")
        return self.mapping(m, item, *keys[kind])

    # -- constraints -------------------------------------------------------------------
    def constraints(self, node: YNode) -> list[Constraint]:
        seq = self.sequence(node, "constraints")
        return [self.constraint(n, f"constraints[{k}]") for k, n in enumerate(seq.items)]

    def constraint(self, node: YNode, item: str) -> Constraint:
        m = self.typed(node, item, CONSTRAINT_KEYS)
        e, where = m.entries, Where(self.source, m.line)
        if e["type"].text in ("point_on_plane", "angle"):
            return self.mechanism_constraint(e, item, where)
        if e["type"].text == "point_on_line":
            line_item = child(item, "line")
            ends = self.sequence(e["line"], line_item, 2)
            point = self.ref(e["point"], child(item, "point"))
            a, b = self.ref_list(ends, line_item)
            if point in (a, b):
                raise self.bad(e["point"], child(item, "point"),
                               "must not be an end of its own line")
            return PointOnLine(point, (a, b), where)
        points_item = child(item, "points")
        pair = self.ref_list(self.sequence(e["points"], points_item, 2), points_item)
        length = self.positive(e["length"], child(item, "length"))
        return Distance(pair, length, where)

    def mechanism_constraint(self, e, item: str, where: Where) -> Constraint:
        """``{type: point_on_plane, point: K, origin: A, normal: n}``: n.(r_K - r_A) = 0;
        ``{type: angle, vectors: [a, b], angle: radians}``: a.b = cos(angle). Named
        points and vectors only, so that the rows stay quadratic."""
        if e["type"].text == "point_on_plane":
            point = self.name_in(e["point"], child(item, "point"), self.points, "point",
                                 "points")
            origin = self.name_in(e["origin"], child(item, "origin"), self.points, "point",
                                  "points")
            if origin == point:
                raise self.bad(e["origin"], child(item, "origin"),
                               "must be another point than the one on the plane")
            normal = self.name_in(e["normal"], child(item, "normal"), self.vectors,
                                  "vector", "vectors")
            return PointOnPlane(point, origin, normal, where)
        pair = self.sequence(e["vectors"], child(item, "vectors"), 2)
        a, b = (self.name_in(n, child(child(item, "vectors"), k), self.vectors, "vector",
                             "vectors") for k, n in enumerate(pair.items))
        if a == b:
            raise self.bad(pair, child(item, "vectors"), "must name two different vectors")
        angle = self.number(e["angle"], child(item, "angle"))
        if not 0.0 <= angle <= math.pi:
            raise self.bad(e["angle"], child(item, "angle"),
                           "must be an angle in radians from 0 to pi")
        return Angle((a, b), math.cos(angle), where)

    # -- loads ----------------------------------------------------------------------------
    def loads(self, node: YNode) -> list[Load]:
        seq = self.sequence(node, "loads")
        return [self.load(n, f"loads[{k}]") for k, n in enumerate(seq.items)]

    def load(self, node: YNode, item: str) -> Load:
        if _point_form(node):
            return self.point_force(node, item)
        if self.joint_form(node):
            return self.joint_spring(self.typed(node, item, JOINT_LOAD_KEYS), item)
        m = self.typed(node, item, LOAD_KEYS)
        e, where, kind = m.entries, Where(self.source, m.line), m.entries["type"].text
        if kind in ("force", "torque"):
            body = self.body_name(e["body"], child(item, "body"))
            value, function = self.load_value(e["value"], child(item, "value"))
            if kind == "torque":
                return Torque(body, value, where, function=function)
            at = None
            if "at" in e:
                at = tuple(float(x) for x in self.vec3(e["at"], child(item, "at")))
            return Force(body, value, at, where, function=function)
        if kind == "torsion_spring":
            return self.torsion_spring(e, item, where)
        ends_item = child(item, "ends")
        ends = self.ref_list(self.sequence(e["ends"], ends_item, 2), ends_item)
        stiffness = self.nonnegative(e["stiffness"], child(item, "stiffness"))
        length = (self.nonnegative(e["length"], child(item, "length"))
                  if "length" in e else None)
        damping = (self.nonnegative(e["damping"], child(item, "damping"))
                   if "damping" in e else 0.0)
        return Spring(ends, stiffness, length, damping, where)

    def load_value(self, node: YNode, item: str, names=None) -> tuple[np.ndarray, str]:
        """(value, "") for three numbers; (zeros, "ex;ex;ex") when a component is
        text: expressions of the time t and the joints' quantities (restricted grammar,
        docs/expressions.md); ``names``: the quantities allowed, if fewer."""
        if not (isinstance(node, YSeq) and any(
                isinstance(n, YScalar) and isinstance(n.value, str) for n in node.items)):
            return self.vec3(node, item), ""
        import sympy                       # only for models with such loads

        from ..mechanism.expressions import parse_expression
        from .events import joint_quantities
        seq = self.sequence(node, item, 3)
        point_force = names is not None
        if names is None:
            names = ["t", *(q for j in self.joints.values() for q in joint_quantities(j))]
        inputs = getattr(self, "inputs", {})
        t = {n: sympy.Symbol(n, real=True) for n in [*names, *inputs]}
        parts = []
        for k, n in enumerate(seq.items):
            text = n.value if isinstance(n, YScalar) and isinstance(
                n.value, (bool, int, float)) else (n.text if isinstance(n, YScalar)
                                                   else n.plain())
            expr = parse_expression(text, t, source=self.source, line=n.line,
                                    item=child(item, k))
            if point_force:
                refuse_inputs(self, expr, inputs, n.line, child(item, k), text,
                              NOT_IN_POINT_FORCES)
            # the start's checks with the inputs at their start values
            at_start = expr.subs({t[name]: x for name, x in inputs.items()})
            self.load_expression_rules(at_start, t, n.line, child(item, k), text)
            parts.append(" ".join((text if isinstance(text, str) else repr(text)).split()))
        return np.zeros(3), ";".join(parts)

    def load_expression_rules(self, expr, symbols: dict, line, item: str, text) -> None:
        """A load's expression must be affine in the joint rates and speeds (the
        compiled force Jacobian df/dq' is a kernel of q alone, docs/elements.md), and
        finite at the start: t = 0 and the written configuration (every joint
        quantity 0)."""
        import sympy

        from ..mechanism.expressions import finite_value
        speeds = [s for n, s in symbols.items() if n.endswith((".rate", ".speed"))]
        for s in speeds:
            if expr.has(s) and sympy.diff(expr, s).has(*speeds):
                name = next(n for n, x in symbols.items() if x == s)
                raise self.fail(line, item, f"must be linear in the joint rates and "
                                f"speeds, as a damper is ({name} enters otherwise: abs, "
                                "min, max, log, powers or products of rates are not "
                                "supported, since the force's Jacobian in the speeds is "
                                "computed without them)", text)
        value = expr.subs({s: 0 for s in symbols.values()})
        if not finite_value(value):
            held = ", every input at its start value" if getattr(self, "inputs", None) \
                else ""
            raise self.fail(line, item, "is not a finite number at the start (t = 0, "
                            f"every joint quantity 0{held}: {sympy.sstr(value)}); "
                            "1/A.angle, log(t), sin(t)/t are not", text)

    def point_force(self, node: YNode, item: str) -> PointForce:
        """``{type: force, point: P, value: [x, y, z]}``: a force on a moving point (a
        cable node, docs/flexible.md), its components numbers or expressions of t."""
        e = self.mapping(node, item, ("type", "point", "value"), ()).entries
        point = self.name_in(e["point"], child(item, "point"), self.points, "point",
                             "points")
        if self.points[point].fixed:
            raise self.fail(e["point"].line, child(item, "point"), "is a fixed point; a "
                            "force on it would do nothing", point)
        value, function = self.load_value(e["value"], child(item, "value"), ("t",))
        return PointForce(point, value, Where(self.source, node.line), function)

    @staticmethod
    def joint_form(node: YNode) -> bool:
        """A torsion spring with ``joint:``, or a linear spring (always on a joint)."""
        if not isinstance(node, YMap) or not isinstance(node.entries.get("type"), YScalar):
            return False
        kind = node.entries["type"].text
        return kind == "linear_spring" or (kind == "torsion_spring"
                                           and "joint" in node.entries)

    def joint_spring(self, m: YMap, item: str) -> JointSpring:
        """``{type: torsion_spring | linear_spring, joint: J, stiffness, angle | length,
        damping}`` on a joint that has that freedom."""
        e, kind = m.entries, m.entries["type"].text
        joints = getattr(self, "joints", {})
        name = self.text(e["joint"], child(item, "joint"))
        if name not in joints:
            raise self.fail(e["joint"].line, child(item, "joint"), "names no joint; joints "
                            "are: " + (listing(joints) if joints else "none"), name)
        if joints[name].type not in JOINT_SPRING_TYPES[kind]:
            raise self.fail(e["joint"].line, child(item, "joint"),
                            f"is a {joints[name].type} joint; a {kind} acts on the "
                            f"freedom of a {' or '.join(JOINT_SPRING_TYPES[kind])} joint",
                            name)
        free_key = "angle" if kind == "torsion_spring" else "length"
        # any free angle: the spring's angle is counted over turns (docs/elements.md)
        free = self.number(e[free_key], child(item, free_key)) if free_key in e else 0.0
        stiffness = self.nonnegative(e["stiffness"], child(item, "stiffness"))
        damping = (self.nonnegative(e["damping"], child(item, "damping"))
                   if "damping" in e else 0.0)
        return JointSpring("torsion" if kind == "torsion_spring" else "linear", name,
                           stiffness, free, damping, Where(self.source, m.line))

    def torsion_spring(self, e: dict, item: str, where: Where) -> TorsionSpring:
        """``{type: torsion_spring, bodies: [A, B], axis: u, stiffness: k, angle: theta0,
        damping: c}``: the axis must be the vector of both bodies (the hinge axis a
        revolute joint shares)."""
        bodies_item = child(item, "bodies")
        seq = self.sequence(e["bodies"], bodies_item, 2)
        a, b = (self.body_name(n, child(bodies_item, k)) for k, n in enumerate(seq.items))
        if a == b:
            raise self.bad(seq, bodies_item, "must name two different bodies")
        axis = self.text(e["axis"], child(item, "axis"))
        for name in (a, b):
            if self.bodies[name].u != axis:
                raise self.fail(e["axis"].line, child(item, "axis"),
                                f"must be the vector of both bodies (the hinge axis they "
                                f"share); body {name} has vector "
                                f"{self.bodies[name].u}", axis)
        stiffness = self.nonnegative(e["stiffness"], child(item, "stiffness"))
        angle = self.number(e["angle"], child(item, "angle")) if "angle" in e else 0.0
        damping = (self.nonnegative(e["damping"], child(item, "damping"))
                   if "damping" in e else 0.0)
        return TorsionSpring((a, b), axis, stiffness, angle, damping, where)

    # -- initial state ---------------------------------------------------------------------
    def initial(self, node: YNode, joints=()) -> Initial:
        m = self.mapping(node, "initial", *INITIAL_KEYS)
        result = Initial()
        if "joints" in m.entries:
            result.joint_speeds, result.joint_positions = self.joint_speeds(
                m.entries["joints"], {j.name: j for j in joints})
        if "points" in m.entries:
            for name, line, value, item in self.entries(m.entries["points"],
                                                        "initial.points"):
                if name not in self.points:
                    raise self.fail(line, item, "names no point; points are: "
                                    + listing(self.points), name)
                if self.points[name].fixed:
                    raise self.fail(line, item, "is a fixed point; only moving points "
                                    "can be given a velocity", name)
                result.point_velocities[name] = self.vec3(value, item)
        if "bodies" in m.entries:
            for name, line, value, item in self.entries(m.entries["bodies"],
                                                        "initial.bodies"):
                if name not in self.bodies:
                    raise self.fail(line, item, "names no body; bodies are: "
                                    + listing(self.bodies), name)
                result.body_angular_velocities[name] = self.angular_velocity(value, item,
                                                                              line)
        return result

    def joint_speeds(self, node: YNode, joints: dict) -> tuple[dict, dict]:
        """``initial.joints``: {J: {rate: w}} or {J: {speed: s}}, kept exactly, and
        {J: {angle: a}} or {J: {position: x}}, the joint values to assemble at (both
        may be given): (speeds, positions), each {J: (quantity, value, where)}."""
        speeds, positions = {}, {}
        kinds = {**JOINT_SPEED_TYPES, **JOINT_POSITION_TYPES}
        for name, line, value, item in self.entries(node, "initial.joints"):
            if name not in joints:
                raise self.fail(line, item, "names no joint; joints are: "
                                + listing(joints), name)
            e = self.mapping(value, item, (), tuple(kinds)).entries
            for group, out, rule in (
                    (JOINT_SPEED_TYPES, speeds, "rate (revolute, cylindrical) or speed "
                     "(prismatic, cylindrical)"),
                    (JOINT_POSITION_TYPES, positions, "angle (revolute, cylindrical) or "
                     "position (prismatic, cylindrical)")):
                given = {k: v for k, v in e.items() if k in group}
                if len(given) > 1 or not e:
                    raise self.fail(line, item, f"must give exactly one of {rule}",
                                    sorted(e))
                for quantity, number in given.items():
                    types = kinds[quantity]
                    if joints[name].type not in types:
                        raise self.bad(number, child(item, quantity),
                                       f"a {joints[name].type} joint has no {quantity}; "
                                       f"{quantity} is for {' and '.join(types)} joints")
                    out[name] = (quantity, self.number(number, child(item, quantity)),
                                 Where(self.source, number.line))
        return speeds, positions

    def angular_velocity(self, node: YNode, item: str, line: int) -> AngularVelocity:
        e = self.mapping(node, item, *INITIAL_BODY_KEYS).entries
        w = self.vec3(e["angular_velocity"], child(item, "angular_velocity"))
        frame = (self.choice(e["frame"], child(item, "frame"), FRAMES, "frame")
                 if "frame" in e else "global")
        return AngularVelocity(w, frame, Where(self.source, line))

    # -- simulation defaults ---------------------------------------------------------------
    def simulate(self, node: YNode | None, methods: tuple[str, ...],
                 values_per_output: int = 0) -> SimulateDefaults:
        """Defaults of ``fccgen simulate`` (docs/design.md §5); ``node`` None: all
        defaults. Checked as ``fccgen simulate`` checks them, with the method's default
        options (fccgen.run_settings.schedule), so that ``fccgen check`` refuses them
        too."""
        out = SimulateDefaults(values_per_output=values_per_output)
        if node is not None:
            self.simulate_keys(node, methods, out)
        try:
            method = REGISTRY[out.method]
            schedule(method, out, options=method.defaults())
        except RunSettingError as exc:
            entries = node.entries if isinstance(node, YMap) else {}
            key = exc.culprit(entries)
            line = entries[key].line if key in entries else getattr(node, "line", None)
            raise self.fail(line, f"simulate.{key}", exc.rules[key],
                            exc.values.get(key)) from None
        return out

    def simulate_keys(self, node: YNode, methods: tuple[str, ...], out: SimulateDefaults):
        """The keys of a ``simulate`` section into ``out``, each checked alone."""
        e = self.mapping(node, "simulate", *SIMULATE_KEYS).entries
        if "t_end" in e:
            out.t_end = self.positive(e["t_end"], "simulate.t_end")
        if "dt" in e:
            out.dt = self.positive(e["dt"], "simulate.dt")
        if "method" in e:
            out.method = self.choice(e["method"], "simulate.method", methods, "method")
        if "output_dt" in e:
            out.output_dt = self.positive(e["output_dt"], "simulate.output_dt")
        for key in ("rank_tol", "position_tol"):
            if key in e:
                value = self.positive(e[key], f"simulate.{key}")
                if not value < 1.0:
                    raise self.bad(e[key], f"simulate.{key}",
                                   "must be a number in (0, 1): a relative tolerance")
                setattr(out, key, value)
        if "linear_solver" in e:
            out.linear_solver = self.choice(e["linear_solver"], "simulate.linear_solver",
                                            LINEAR_SOLVERS, "linear solver")
        if "max_newton" in e:
            value = self.number(e["max_newton"], "simulate.max_newton")
            if not (value == int(value) and 1 <= value <= 1000):
                raise self.bad(e["max_newton"], "simulate.max_newton",
                               "must be a whole number in [1, 1000]")
            out.max_newton = int(value)
        if out.dt > out.t_end:
            key = "dt" if "dt" in e else "t_end"
            rule = (f"must be at most t_end ({out.t_end:g})" if key == "dt"
                    else f"must be at least dt ({out.dt:g}, the default)")
            raise self.bad(e[key], f"simulate.{key}", rule)
        if out.output_dt is not None and out.output_dt < out.dt:
            raise self.bad(e["output_dt"], "simulate.output_dt",
                           f"must be at least dt ({out.dt:g})")


def _point_form(node: YNode) -> bool:
    """A force given on a point (``point:``) instead of a body."""
    return (isinstance(node, YMap) and isinstance(node.entries.get("type"), YScalar)
            and node.entries["type"].text == "force" and "point" in node.entries)
