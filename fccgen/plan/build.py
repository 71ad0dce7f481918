"""From a validated model to the element plan: coordinates, elements, classes,
parameters, and the initial state the user asked for."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from ..model.types import (Angle, Attached, BodyPoint, Distance, DriverRow, Force,
                           LinearSpring, Model, PointForce, SlopeNormal,
                           PointOnLine, PointOnPlane, PointRef, Spring, Torque,
                           TorsionSpring, Where)
from .cables import (cable_columns, cable_elements, point_force_element,
                     slope_normal_element)
from .classes import (END_FOLDABLE, FOLDABLE, INPUT_KINDS, ElementClass, element_class,
                      input_parameter)
from ..model.geometry import body_frame_numbers, body_rotation, point_coefficients
from .joint_loads import joint_load_element


@dataclass
class Element:
    """One instance of an element class: where its coordinates are and its numbers."""
    cls: ElementClass
    label: str                   # the model item it comes from, e.g. "bodies.arm"
    slots: tuple[int, ...]       # global triple index of each moving triple, in order
    params: np.ndarray           # values of cls.param_names
    where: Where

    def q_index(self) -> np.ndarray:
        """Global coordinate indices of the local coordinates (3 per slot)."""
        return np.array([3 * s + k for s in self.slots for k in range(3)], dtype=np.intp)


@dataclass
class Plan:
    model: Model
    triples: list[tuple[str, str]]          # moving triples: (name, "point"|"vector"|
                                            # "slope", a cable node's, not unit)
    index: dict[str, int]                   # triple name -> triple index
    elements: list[Element]
    classes: list[ElementClass]             # distinct classes, first-appearance order
    class_of: list[int]                     # per element: index into classes
    bodies: list[tuple[str, int]]           # moving bodies: (name, element index)
    q0: np.ndarray                          # initial coordinates as given
    v_target: np.ndarray                    # initial speeds as given (may be inconsistent)
    notes: list[str] = field(default_factory=list)

    @property
    def n_q(self) -> int:
        return 3 * len(self.triples)

    @property
    def n_g(self) -> int:
        return sum(e.cls.n_g for e in self.elements)

    @property
    def row_groups(self) -> np.ndarray:
        """Per constraint row, the index of the element it belongs to (the rank
        decision scales rows per element: fccgen.rank.row_scales)."""
        return np.repeat(np.arange(len(self.elements)),
                         [e.cls.n_g for e in self.elements])

    def columns(self, all_columns: bool = False) -> list[str]:
        """Result column names (docs/design.md §4), without ``t``: those of
        ``result.names``, or with ``all_columns`` the internal ones of the points and
        vectors the lowering made too (``result.internal``)."""
        mechanism = self.model.mechanism
        made = set(mechanism.internal()) if mechanism is not None and not all_columns \
            else set()
        cols = []
        for name, _ in self.triples:
            if name in made:
                continue
            cols += [f"{name}.{c}" for c in ("x", "y", "z", "vx", "vy", "vz")]
        for name, _ in self.bodies:
            cols += [f"{name}.{c}" for c in ("cx", "cy", "cz", "wx", "wy", "wz")]
        cols += ["energy", "constraint_error"]
        mechanism = []
        if self.model.mechanism is not None:          # joints (fccgen.mechanism)
            mechanism = self.model.mechanism.columns()
        # the members' strain and curvature come before the reactions, which a run
        # adds last (fccgen.mechanism.reactions): 6 per joint, at the end
        end = len(mechanism) - 6 * len(getattr(self.model.mechanism, "joints", ()))
        return cols + mechanism[:end] + cable_columns(self.model) + mechanism[end:]


class _Builder:
    def __init__(self, model: Model):
        self.model = model
        self.triples: list[tuple[str, str]] = []
        self.index: dict[str, int] = {}
        for p in model.points.values():
            if not p.fixed:
                self.index[p.name] = len(self.triples)
                self.triples.append((p.name, "point"))
        for v in model.vectors.values():
            if not v.fixed:
                self.index[v.name] = len(self.triples)
                self.triples.append((v.name, "vector"))
        for d in model.slopes.values():              # cable nodes' slopes (not unit)
            if not d.fixed:
                self.index[d.name] = len(self.triples)
                self.triples.append((d.name, "slope"))
        self.frames = {b.name: body_frame_numbers(model.points[b.i].at, model.points[b.j].at,
                                                  model.vectors[b.u].along)
                       for b in model.bodies.values()}

    # -- triples -----------------------------------------------------------------
    def value(self, name: str) -> np.ndarray:
        m = self.model
        if name in m.slopes:
            return m.slopes[name].along
        return m.points[name].at if name in m.points else m.vectors[name].along

    def triple(self, name: str):
        """(moving?, slot or fixed value)."""
        if name in self.index:
            return True, self.index[name]
        return False, np.asarray(self.value(name), float)

    # -- ends --------------------------------------------------------------------
    def end(self, ref: PointRef, prefix: str):
        """(end kind, {scalar: value}, [(triple name, model name)])."""
        if isinstance(ref, BodyPoint):
            body = self.model.bodies[ref.body]
            l, alpha, beta = self.frames[body.name]
            b = point_coefficients(ref.at, l, alpha, beta)
            scalars = dict(zip(("l", "alpha", "beta", "b1", "b2", "b3"), (l, alpha, beta, *b)))
            return ("body_point", {f"{prefix}.{k}": v for k, v in scalars.items()},
                    [(f"{prefix}.ri", body.i), (f"{prefix}.rj", body.j), (f"{prefix}.u", body.u)])
        return "point", {}, [(f"{prefix}.r", ref)]

    def element(self, kind, label, where, scalars: dict, triples: list, ends=(),
                function: str = ""):
        from ..model.inputs import names_read
        known = getattr(self.model, "inputs", {})
        inputs = names_read(function, known) if kind in INPUT_KINDS else ()
        scalars = {**scalars, **{input_parameter(n): float(known[n])
                                 for n in inputs}}
        fixed, slots, fixed_vals = [], [], []
        for _, model_name in triples:
            moving, val = self.triple(model_name)
            fixed.append(not moving)
            if moving:
                slots.append(val)
            else:
                fixed_vals.extend(val)
        foldable = FOLDABLE[kind] | {n for n in scalars if n.split(".")[-1] in END_FOLDABLE
                                     and "." in n}
        zeros = frozenset(n for n, v in scalars.items() if n in foldable and v == 0.0)
        cls = element_class(kind, tuple(ends), tuple(fixed), zeros, function, inputs)
        params = np.array([scalars[n] for n in cls.scalar_names] + fixed_vals, float)
        return Element(cls, label, tuple(slots), params, where)

    # -- elements ----------------------------------------------------------------
    def body(self, body) -> Element:
        l, alpha, beta = self.frames[body.name]
        a = point_coefficients(body.center, l, alpha, beta)
        I = body.inertia
        g = self.model.gravity
        scalars = {"l": l, "alpha": alpha, "beta": beta, "a1": a[0], "a2": a[1], "a3": a[2],
                   "m": body.mass, "Ixx": I[0, 0], "Iyy": I[1, 1], "Izz": I[2, 2],
                   "Ixy": I[0, 1], "Ixz": I[0, 2], "Iyz": I[1, 2],
                   "gx": g[0], "gy": g[1], "gz": g[2]}
        triples = [("ri", body.i), ("rj", body.j), ("u", body.u)]
        return self.element("body", f"bodies.{body.name}", body.where,
                            {k: float(v) for k, v in scalars.items()}, triples)

    def with_ends(self, kind, label, where, own: dict, refs, names):
        scalars, triples, ends = dict(own), [], []
        for ref, prefix in zip(refs, names):
            end_kind, s, t = self.end(ref, prefix)
            ends.append(end_kind)
            scalars.update(s)
            triples += t
        return self.element(kind, label, where, scalars, triples, ends)

    def body_load(self, kind, label, where, body_name, own: dict, function: str = ""):
        body = self.model.bodies[body_name]
        l, alpha, beta = self.frames[body_name]
        scalars = {"l": l, "alpha": alpha, "beta": beta, **own}
        return self.element(kind, label, where, scalars,
                            [("ri", body.i), ("rj", body.j), ("u", body.u)],
                            function=function)

    def point_position(self, ref: PointRef) -> np.ndarray:
        if isinstance(ref, BodyPoint):
            b = self.model.bodies[ref.body]
            R = body_rotation(self.model.points[b.i].at, self.model.points[b.j].at,
                              self.model.vectors[b.u].along)
            return self.model.points[b.i].at + R @ np.asarray(ref.at, float)
        return np.asarray(self.model.points[ref].at, float)


def _require_moving(el: Element, model: Model, what: str):
    if el.cls.n_q == 0:
        raise ModelError(model.source, el.where.line, el.label,
                         f"{what} involves no moving point or vector, so it would have no effect",
                         show_value=False)


def _mechanism_element(b: _Builder, c, label: str) -> Element:
    """Elements of the mechanism level's constraints (docs/joints.md)."""
    if isinstance(c, Attached) and c.kind.startswith("aligned_"):
        body = b.model.bodies[c.body]
        l, alpha, beta = b.frames[c.body]
        nu = c.rho
        values = {"c1": l * nu[0], "c2": beta * nu[0] + alpha * nu[1],
                  "c3": alpha * l * nu[2]}
        rows = c.kind.split("_")[1]                     # "12", "13" or "23"
        return b.element(f"aligned_vector_{rows}", label, c.where,
                         {f"c{r}": float(values[f"c{r}"]) for r in rows},
                         [("ri", body.i), ("rj", body.j), ("u", body.u), ("w", c.target)])
    if isinstance(c, Attached):
        body = b.model.bodies[c.body]
        l, alpha, beta = b.frames[c.body]
        coef = point_coefficients(c.rho, l, alpha, beta)
        scalars = dict(zip(("l", "alpha", "beta", "b1", "b2", "b3"),
                           (l, alpha, beta, *(float(x) for x in coef))))
        target = "k" if c.kind == "point" else "w"
        return b.element(f"attached_{c.kind}", label, c.where, scalars,
                         [("ri", body.i), ("rj", body.j), ("u", body.u), (target, c.target)])
    if isinstance(c, DriverRow):
        names = {"angle": ("u", "a", "b"), "position": ("u", "ra", "rb"),
                 "distance": ("ra", "rb"), "coordinate": ("r",)}[c.kind]
        return b.element(f"driver_{c.kind}", label, c.where, {"t": 0.0, **c.scalars},
                         list(zip(names, c.triples)), function=c.function)
    if isinstance(c, PointOnPlane):
        return b.element("point_on_plane", label, c.where, {},
                         [("n", c.normal), ("K.r", c.point), ("A.r", c.origin)],
                         ("point", "point"))
    return b.element("dot", label, c.where, {"c": float(c.cos)},
                     [("a", c.vectors[0]), ("b", c.vectors[1])])


def make_plan(model: Model) -> Plan:
    """Lay out coordinates and elements of a validated model."""
    b = _Builder(model)
    elements: list[Element] = []
    bodies: list[tuple[str, int]] = []
    notes: list[str] = []
    for body in model.bodies.values():
        el = b.body(body)
        if el.cls.n_q == 0:
            notes.append(f"body {body.name} has only fixed points and vectors: it is ground")
            continue
        bodies.append((body.name, len(elements)))
        elements.append(el)
    for cable in model.cables.values():            # flexible members (plan/cables.py)
        elements += cable_elements(b, cable)
    # an attached vector is a unit vector through its body's frame: no u.u - 1 row
    attached = {c.target for c in model.constraints
                if isinstance(c, Attached) and c.kind == "vector"}
    for name, _kind in b.triples:
        if name in model.vectors and name not in attached:
            v = model.vectors[name]
            elements.append(b.element("unit_vector", f"vectors.{name}", v.where, {},
                                      [("u", name)]))
    for k, c in enumerate(model.constraints):
        label = getattr(c, "label", None) or f"constraints[{k}]"
        if isinstance(c, (Attached, PointOnPlane, Angle, DriverRow)):
            el = _mechanism_element(b, c, label)
        elif isinstance(c, PointOnLine):
            el = b.with_ends("point_on_line", label, c.where, {},
                             (c.point, *c.line), ("K", "A", "B"))
        elif isinstance(c, Distance):
            el = b.with_ends("distance", label, c.where, {"L": float(c.length)},
                             c.points, ("A", "B"))
        elif isinstance(c, SlopeNormal):
            el = slope_normal_element(b, c, label)
        else:  # pragma: no cover - the loader admits no other type
            raise TypeError(type(c))
        _require_moving(el, model, f"this {c.type} constraint")
        elements.append(el)
    for k, ld in enumerate(model.loads):
        label = f"loads[{k}]"
        if isinstance(ld, Force):
            body = model.bodies[ld.body]
            l, alpha, beta = b.frames[ld.body]
            rho = body.center if ld.at is None else ld.at
            c = point_coefficients(rho, l, alpha, beta)
            own = {"b1": c[0], "b2": c[1], "b3": c[2]}
            own.update({"t": 0.0} if ld.function else
                       {"Fx": ld.value[0], "Fy": ld.value[1], "Fz": ld.value[2]})
            if ld.joints:
                el = joint_load_element(b, ld, label, "force_q",
                                        {k2: float(v) for k2, v in own.items()})
            else:
                el = b.body_load("force_t" if ld.function else "force", label,
                                 ld.where, ld.body, {k2: float(v) for k2, v in own.items()},
                                 ld.function)
        elif isinstance(ld, Torque):
            own = ({"t": 0.0} if ld.function else
                   {"Tx": ld.value[0], "Ty": ld.value[1], "Tz": ld.value[2]})
            el = (joint_load_element(b, ld, label, "torque_q", own) if ld.joints else
                  b.body_load("torque_t" if ld.function else "torque", label, ld.where,
                              ld.body, {k2: float(v) for k2, v in own.items()},
                              ld.function))
        elif isinstance(ld, Spring):
            length = ld.length
            if length is None:
                length = float(np.linalg.norm(b.point_position(ld.ends[1])
                                              - b.point_position(ld.ends[0])))
            el = b.with_ends("spring", label, ld.where,
                             {"k": float(ld.stiffness), "L0": float(length),
                              "c": float(ld.damping)}, ld.ends, ("A", "B"))
        elif isinstance(ld, TorsionSpring):
            el = _torsion_spring(b, ld, label)
        elif isinstance(ld, PointForce):
            el = point_force_element(b, ld, label)
        elif isinstance(ld, LinearSpring):
            el = b.element("linear_spring", label, ld.where,
                           {"k": float(ld.stiffness), "L": float(ld.free),
                            "c": float(ld.damping)},
                           list(zip(("u", "ra", "rb"), ld.triples)))
        else:  # pragma: no cover
            raise TypeError(type(ld))
        _require_moving(el, model, f"this {ld.type} load")
        elements.append(el)

    classes: list[ElementClass] = []
    seen: dict[ElementClass, int] = {}
    class_of = []
    for el in elements:
        if el.cls not in seen:
            seen[el.cls] = len(classes)
            classes.append(el.cls)
        class_of.append(seen[el.cls])

    q0 = np.concatenate([b.value(n) for n, _ in b.triples]) if b.triples else np.zeros(0)
    v_target = _initial_speeds(model, b)
    return Plan(model, b.triples, b.index, elements, classes, class_of, bodies,
                q0.astype(float), v_target, notes)


def _torsion_spring(b: _Builder, ld: TorsionSpring, label: str) -> Element:
    """The torsion spring element (docs/elements.md). With p = r_ij - (l beta) u, the
    reference direction of a body perpendicular to the axis u, the angle of body B
    relative to body A is atan2(u.(p_A x p_B), p_A.p_B); it is theta_init at the
    initial positions (cos0, sin0 its cosine and sine). The free position is
    theta_init + angle (free = angle, from the initial configuration). The reference
    th, cr, sr is the free angle outside runs, so that a kernel called alone measures
    the deflection within half a turn of the free angle; a run moves it from the
    start's angle on (turn counting)."""
    m = b.model
    sides = ld.sides or tuple((m.bodies[n].i, m.bodies[n].j) for n in ld.bodies)
    u = np.asarray(m.vectors[ld.axis].along, float)
    ref, lam = [], []
    for i, j in sides:
        rij = np.asarray(b.value(j), float) - np.asarray(b.value(i), float)
        lam.append(float(rij @ u))                   # l beta
        ref.append(rij - lam[-1] * u)
    theta_init = float(np.arctan2(u @ np.cross(ref[0], ref[1]), ref[0] @ ref[1]))
    scalars = {"k": float(ld.stiffness), "c": float(ld.damping), "lA": lam[0],
               "lB": lam[1], "cos0": float(np.cos(theta_init)),
               "sin0": float(np.sin(theta_init)), "free": float(ld.angle),
               "th": float(ld.angle), "cr": float(np.cos(ld.angle)),
               "sr": float(np.sin(ld.angle))}
    (a_i, a_j), (b_i, b_j) = sides
    triples = [("A.ri", a_i), ("A.rj", a_j), ("B.ri", b_i), ("B.rj", b_j), ("u", ld.axis)]
    return b.element("torsion_spring", label, ld.where, scalars, triples)


def _initial_speeds(model: Model, b: _Builder) -> np.ndarray:
    """Speeds from the user's point velocities and body angular velocities.

    Unspecified points start at rest unless a body with a given angular velocity
    carries them: then r_j' = r_i' + w x r_ij (or the other way round) and u' = w x u.
    The result may violate B q' = 0; the solver projects it and reports the residual.
    """
    n = len(b.triples)
    v = np.zeros((n, 3))
    known: set[str] = set()
    for name, vel in model.initial.point_velocities.items():
        if name in b.index:
            v[b.index[name]] = vel
        known.add(name)                      # fixed points are known at rest
    for p in model.points.values():
        if p.fixed:
            known.add(p.name)
    omegas = {}
    for name, w in model.initial.body_angular_velocities.items():
        body = model.bodies[name]
        if w.frame == "body":
            R = body_rotation(model.points[body.i].at, model.points[body.j].at,
                              model.vectors[body.u].along)
            omegas[name] = R @ w.value
        else:
            omegas[name] = np.asarray(w.value, float)

    def vel(name):
        return v[b.index[name]] if name in b.index else np.zeros(3)

    def set_vel(name, value):
        if name in b.index:
            v[b.index[name]] = value
        known.add(name)

    pending = list(omegas)
    while pending:
        ready = [n for n in pending
                 if model.bodies[n].i in known or model.bodies[n].j in known]
        if not ready:                    # no carried point known: the first one is at rest
            known.add(model.bodies[pending[0]].i)
            continue
        for name in ready:
            body, w = model.bodies[name], omegas[name]
            rij = model.points[body.j].at - model.points[body.i].at
            if body.i not in known:
                set_vel(body.i, vel(body.j) - np.cross(w, rij))
            if body.j not in known:
                set_vel(body.j, vel(body.i) + np.cross(w, rij))
            if body.u not in known:
                set_vel(body.u, np.cross(w, model.vectors[body.u].along))
            pending.remove(name)
    return v.reshape(-1)
