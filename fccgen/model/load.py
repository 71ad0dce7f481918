"""Load a model file (docs/design.md §2) into a validated :class:`Model`.

The file is read with a safe YAML loader into line-aware nodes; each section is then
read by one method of :class:`_ModelReader`. The first rule broken raises
:class:`~fccgen.errors.ModelError` naming the file, the line, the item (a path such as
``bodies.arm.mass`` or ``constraints[0].line[1]``), the rule and the value seen.
"""
from __future__ import annotations


import numpy as np

from ..errors import ModelError, os_reason
from ..settings.methods import EVENT_METHODS, names as _method_names
from . import checks
from .events import EventReader
from .fields import IDENTIFIER, IDENTIFIER_RULE, Reader, child, listing
from .inputs import read_inputs
from .items import ItemReader
from .cables import CableReader
from .drivers import DriverReader
from .joints import MechanismReader
from .names import reserved_model_name
from .tables import TableReader
from .types import GROUND, Body, Initial, Model, Point, PoseBody, Vector, Where
from .yamlnodes import MAX_INPUT_CHARS, YMap, YNode, parse_yaml

# Integration methods a model may name in ``simulate.method`` (fccgen.settings.methods).
METHODS: tuple[str, ...] = _method_names()

MAX_NAME_LENGTH = 64          # the model name becomes a module name and a C symbol;
                              # point, vector and body names become result columns

# Keys of each kind of mapping: (required, optional).
TOP_KEYS = (("name", "points", "bodies"),
            ("gravity", "vectors", "constraints", "loads", "initial", "simulate", "joints",
             "drivers", "events", "cables", "inputs", "tables"))
POINT_KEYS = (("at",), ("fixed",))
VECTOR_KEYS = (("along",), ("fixed",))
BODY_KEYS = (("points", "vector", "mass", "inertia"), ("center",))


def load_model(path) -> Model:
    """Read and validate the model file at ``path`` (``Model.source`` is ``str(path)``)."""
    source = str(path)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read(MAX_INPUT_CHARS + 1)      # a larger file is refused, unread
    except UnicodeDecodeError as exc:
        raise ModelError(source, None, "model file", f"is not UTF-8 text ({exc.reason})",
                         show_value=False) from None
    except OSError as exc:
        raise ModelError(source, None, "model file",
                         f"cannot be read ({os_reason(exc)})", show_value=False) from None
    if len(text) > MAX_INPUT_CHARS:
        raise ModelError(source, None, "model file", f"is longer than {MAX_INPUT_CHARS} "
                         "characters, the most a model file may hold", show_value=False)
    return load_model_text(text, source)


def load_model_text(text: str, source: str = "<string>") -> Model:
    """Validate a model given as YAML text; ``source`` names it in messages."""
    root = parse_yaml(text, source)
    if root is None:
        raise ModelError(source, None, "model file",
                         f"is empty; it needs the keys {listing(TOP_KEYS[0])}",
                         show_value=False)
    return _ModelReader(source).model(root)


class _ModelReader(Reader):
    """Reads the sections of a model file in order, keeping what later ones refer to."""

    def __init__(self, source: str):
        super().__init__(source)
        self.names: dict[str, tuple[str, int]] = {}    # name -> (kind, line)
        self.points: dict[str, Point] = {}
        self.vectors: dict[str, Vector] = {}
        self.bodies: dict[str, Body] = {}
        self.pose_bodies: dict[str, PoseBody] = {}
        self.mechanism = MechanismReader(source, self.claim)
        self.driver_reader = DriverReader(source, self.claim)

    def where(self, line: int | None) -> Where:
        return Where(self.source, line)

    def model(self, root: YNode) -> Model:
        if not isinstance(root, YMap):
            raise self.bad(root, "model file",
                           f"must be a mapping with the keys {listing(TOP_KEYS[0])}")
        required, optional = TOP_KEYS
        if "joints" in root.entries or "points" not in root.entries:
            # mechanism level: points are optional (bodies may be in pose form)
            required = tuple(k for k in required if k != "points")
            optional = ("points", *optional)
        if "cables" in root.entries:         # flexible members need no body or point
            optional = (*(k for k in required if k != "name"), *optional)
            required = ("name",)
        top = self.mapping(root, "", required, optional)
        e = top.entries
        self.top_keys = set(e)
        name = self.model_name(e["name"])
        gravity = self.vec3(e["gravity"], "gravity") if "gravity" in e else np.zeros(3)
        if "points" in e:
            self.read_points(e["points"])
        if "vectors" in e:
            self.read_vectors(e["vectors"])
        if "bodies" in e or "cables" not in e:
            self.read_bodies(e["bodies"], allow_none="cables" in e)
        self.check_membership()
        cables = {}
        if "cables" in e:                  # before the sections that name the nodes
            cables = CableReader(self.source, self.claim, self.points, self.bodies,
                                 self.pose_bodies, self.vectors).cables(e["cables"])
        joints = []
        if "joints" in e:
            joints = self.mechanism.joints(e["joints"], [*self.bodies, *self.pose_bodies])
        inputs = {}
        if "inputs" in e:                  # before the sections whose expressions read them
            inputs = read_inputs(self, e["inputs"], self.claim,
                                 set(TOP_KEYS[0]) | set(TOP_KEYS[1]))
        self.driver_reader.inputs = inputs
        drivers = []
        if "drivers" in e:
            drivers = self.driver_reader.drivers(e["drivers"], joints, self.points)
        items = ItemReader(self.source, self.points, {**self.bodies, **self.pose_bodies},
                           self.vectors)
        items.joints = {j.name: j for j in joints}
        items.inputs = inputs
        if "tables" in e:                  # before the loads that call them
            items.tables = TableReader(self.source, self.claim).tables(e["tables"])
        constraints = items.constraints(e["constraints"]) if "constraints" in e else []
        loads = items.loads(e["loads"]) if "loads" in e else []
        initial = items.initial(e["initial"], joints) if "initial" in e else Initial()
        simulate = items.simulate(e.get("simulate"), METHODS,
                                  self.values_per_output(cables))
        event_reader = EventReader(self.source, self.points, joints, drivers)
        event_reader.inputs = inputs
        events = event_reader.events(e.get("events"))
        for ev in events:
            if ev.name in inputs:
                raise self.fail(ev.where.line, "events", "names an event like the input "
                                f"on line {self.names[ev.name][1]}; names must differ",
                                ev.name)
        self.check_event_method(events, simulate, e.get("simulate"))
        return Model(name=name, source=self.source, gravity=gravity, points=self.points,
                     vectors=self.vectors, bodies=self.bodies, constraints=constraints,
                     loads=loads, initial=initial, simulate=simulate,
                     where={k: self.where(line) for k, line in top.key_lines.items()},
                     pose_bodies=self.pose_bodies, joints=joints, drivers=drivers,
                     events=events, cables=cables, inputs=inputs)

    def check_event_method(self, events, simulate, node) -> None:
        """Events are located by the rk4 and dopri5 methods only (the compiled run
        refuses the others): a model with events that names another method is refused
        here, so that check refuses it as simulate does."""
        if not events or simulate.method in EVENT_METHODS:
            return
        line = node.key_lines.get("method", node.line) if isinstance(node, YMap) else None
        raise self.fail(line, "simulate.method", f"must be one of {listing(EVENT_METHODS)} "
                        f"in a model with events (events are located by those methods "
                        f"only; this model has {len(events)})", simulate.method)

    def values_per_output(self, cables=None) -> int:
        """Numbers one output row of a run records (docs/design.md §4): t, 6 per moving
        point and vector, 6 per body (an upper bound: ground bodies have none),
        energy and constraint_error; per cable node (a point, counted above) 6 for
        its slope and its strain and curvature."""
        moving = sum(not x.fixed for table in (self.points, self.vectors)
                     for x in table.values())
        nodes = sum(len(c.nodes) for c in (cables or {}).values())
        return 3 + 6 * (moving + len(self.bodies)) + 8 * nodes

    # -- names ---------------------------------------------------------------------
    def model_name(self, node: YNode) -> str:
        name = self.identifier(node, "name")
        if len(name) > MAX_NAME_LENGTH:
            raise self.fail(node.line, "name",
                            f"must be at most {MAX_NAME_LENGTH} characters long", name)
        problem = reserved_model_name(name)
        if problem:
            raise self.fail(node.line, "name", problem, name)
        return name

    def claim(self, name: str, kind: str, line: int, item: str):
        """Check a name and reserve it: names become result columns and the names
        expressions read, so they must be unique across every kind that has one."""
        if not IDENTIFIER.fullmatch(name):
            raise self.fail(line, item, IDENTIFIER_RULE, name)
        if len(name) > MAX_NAME_LENGTH:
            raise self.fail(line, item, f"must be at most {MAX_NAME_LENGTH} characters "
                                        "long", name)
        if name in self.names:
            other, other_line = self.names[name]
            raise self.fail(line, item, f"name already used by the {other} on line "
                                        f"{other_line} (the names of points, vectors, "
                                        "bodies, joints, drivers, cables, inputs and "
                                        "tables must all differ)", name)
        self.names[name] = (kind, line)

    # -- points and vectors ------------------------------------------------------------
    def short_or_long(self, node: YNode, item: str, key: str, keys) -> tuple[np.ndarray, bool]:
        """``[x, y, z]`` (moving) or ``{<key>: [x, y, z], fixed: bool}``."""
        if isinstance(node, YMap):
            m = self.mapping(node, item, *keys)
            fixed = self.boolean(m.entries["fixed"], child(item, "fixed")) \
                if "fixed" in m.entries else False
            return self.vec3(m.entries[key], child(item, key)), fixed
        return self.vec3(node, item), False

    def read_points(self, node: YNode):
        for name, line, value, item in self.entries(node, "points"):
            self.claim(name, "point", line, item)
            at, fixed = self.short_or_long(value, item, "at", POINT_KEYS)
            self.points[name] = Point(name, at, fixed, self.where(line))

    def read_vectors(self, node: YNode):
        for name, line, value, item in self.entries(node, "vectors"):
            self.claim(name, "vector", line, item)
            along, fixed = self.short_or_long(value, item, "along", VECTOR_KEYS)
            problem = checks.unit_vector_problem(along)
            if problem:
                raise self.bad(value, item, problem)
            along = along / np.linalg.norm(along)
            self.vectors[name] = Vector(name, along, fixed, self.where(line))

    # -- bodies ----------------------------------------------------------------------------
    def read_bodies(self, node: YNode, allow_none: bool = False):
        bodies = self.mapping_any(node, "bodies")
        if not bodies.entries and not allow_none:
            raise self.bad(bodies, "bodies", "must name at least one body")
        for name, line, value, item in self.entries(bodies, "bodies"):
            self.claim(name, "body", line, item)
            if name == GROUND and "joints" in self.top_keys:
                raise self.fail(line, item, "is the fixed body that joints name; it is "
                                "not declared", name)
            if isinstance(value, YMap) and not {"points", "vector"} & set(value.entries):
                self.pose_bodies[name] = self.mechanism.pose_body(name, line, value, item)
            else:
                self.bodies[name] = self.body(name, line, value, item)

    def body(self, name: str, line: int, node: YNode, item: str) -> Body:
        m = self.mapping(node, item, *BODY_KEYS)
        e = m.entries
        ends = self.sequence(e["points"], child(item, "points"), 2)
        i, j = (self.name_in(n, child(child(item, "points"), k), self.points,
                             "point", "points") for k, n in enumerate(ends.items))
        if i == j:
            raise self.bad(ends, child(item, "points"), "must be two different points")
        u = self.name_in(e["vector"], child(item, "vector"), self.vectors,
                         "vector", "vectors")
        mass = self.positive(e["mass"], child(item, "mass"))
        center = self.vec3(e["center"], child(item, "center")) if "center" in e \
            else np.zeros(3)
        inertia = checks.inertia_tensor(self.numbers(e["inertia"], child(item, "inertia"),
                                                     (3, 6)))
        problem = checks.inertia_problem(inertia)
        if problem:
            raise self.bad(e["inertia"], child(item, "inertia"), problem)
        self.check_geometry(name, i, j, u, ends, e["vector"], item)
        return Body(name, i, j, u, mass, center, inertia, self.where(line))

    def check_geometry(self, name, i, j, u, ends_node, vector_node, item):
        """Points i, j must be apart and u must not be parallel to r_ij."""
        ri, rj = self.points[i].at, self.points[j].at
        if checks.coincide(ri, rj):
            raise self.bad(ends_node, child(item, "points"),
                           f"points {i} and {j} are at the same place "
                           f"[{', '.join(f'{x:g}' for x in ri)}]; a body needs two "
                           "distinct points")
        angle = checks.parallel_angle(ri, rj, self.vectors[u].along)
        if angle is not None:
            raise self.bad(vector_node, child(item, "vector"),
                           f"vector {u} is parallel to the line from {i} to {j} (angle "
                           f"{angle:.3g} degrees); a body needs sin(angle) >= "
                           f"{checks.PARALLEL_SIN:g}")

    def check_membership(self):
        """Every moving point and vector must belong to a body, or it has no mass."""
        used = {n for b in self.bodies.values() for n in (b.i, b.j, b.u)}
        for kind, table in (("point", self.points), ("vector", self.vectors)):
            for obj in table.values():
                if not obj.fixed and obj.name not in used:
                    raise self.fail(obj.where.line, f"{kind}s.{obj.name}",
                                    f"moving {kind} belongs to no body, so it has no mass; "
                                    "put it in a body or make it fixed", obj.name)
