"""Reading ``events:`` and joint ``limits:`` (docs/design.md §2b) into :class:`Event`.

An event is a scalar event function s(q, v, t) crossing zero in a direction, and an
action::

    events:
      - {name: latch, when: "A.angle >= 3.14159", do: lock, joint: A}
      - {name: floor, when: "P.z", direction: falling, do: bounce, restitution: 0.5}

``when`` is a condition ``lhs OP rhs`` (s = lhs - rhs; >=, > rise, <=, < fall) or a
scalar expression with ``direction: rising | falling | either`` (default either; a
direction given with a condition overrides the operator's). Quantities: ``t``, point
coordinates and velocities ``P.x P.y P.z P.vx P.vy P.vz`` (distances are written out,
``sqrt((P.x-Q.x)**2 + ...)``), joint quantities ``J.angle J.rate`` (revolute,
cylindrical) and ``J.position J.speed`` (prismatic, cylindrical).

``limits: [lo, hi]`` on a revolute, prismatic or cylindrical joint (with optional
``restitution:``, default 0) is shorthand for two bounce events ``J_lower``
(``J.q <= lo``) and ``J_upper`` (``J.q >= hi``), q the joint's angle or position.
"""
from __future__ import annotations

from dataclasses import dataclass

from .fields import Reader, child
from .types import Joint, Where
from .yamlnodes import YNode, YScalar

ACTIONS = ("stop", "log", "lock", "unlock", "bounce")
DIRECTIONS = ("rising", "falling", "either")
EVENT_KEYS = (("name", "when", "do"), ("direction", "joint", "restitution"))
ANGLE_TYPES = ("revolute", "cylindrical")       # as fccgen.mechanism.joints
SLIDE_TYPES = ("prismatic", "cylindrical")
LIMIT_TYPES = ("revolute", "prismatic", "cylindrical")
POINT_QUANTITIES = ("x", "y", "z", "vx", "vy", "vz")


@dataclass
class Event:
    """One event: s = ``function`` (SymPy over :func:`quantity_symbols`) crossing zero
    in ``direction``; ``action`` on ``joint`` (lock, unlock, bounce) with Newton's
    ``restitution`` e (bounce)."""
    name: str
    when: str                      # the text as written (limits: generated)
    function: object               # sympy.Expr
    direction: str                 # rising | falling | either
    action: str
    joint: str | None
    restitution: float
    where: Where


def joint_quantities(joint: Joint) -> list[str]:
    names = []
    if joint.type in ANGLE_TYPES:
        names += [f"{joint.name}.angle", f"{joint.name}.rate"]
    if joint.type in SLIDE_TYPES:
        names += [f"{joint.name}.position", f"{joint.name}.speed"]
    return names


def quantity_symbols(points, joints) -> dict:
    """name -> real Symbol of every quantity an event function may use."""
    import sympy            # only models with events pay for importing SymPy
    names = ["t"]
    names += [f"{p}.{k}" for p in points for k in POINT_QUANTITIES]
    for j in joints:
        names += joint_quantities(j)
    return {n: sympy.Symbol(n, real=True) for n in names}


class EventReader(Reader):
    """Reads ``events:`` against the model's points and joints."""

    def __init__(self, source: str, points, joints: list[Joint], drivers=()):
        super().__init__(source)
        self.joints = {j.name: j for j in joints}
        # joint -> the driver that prescribes its motion (no lock, bounce or limit on it)
        self.driven = {d.joint: d.name for d in drivers if d.joint in self.joints}
        self.points = points
        self.symbols_cache = None
        self.names: set[str] = set()

    @property
    def symbols(self) -> dict:
        if self.symbols_cache is None:
            self.symbols_cache = quantity_symbols(self.points, self.joints.values())
        return self.symbols_cache

    def events(self, node: YNode | None) -> list[Event]:
        out = self.limit_events()
        if node is not None:
            seq = self.sequence(node, "events")
            out += [self.event(n, f"events[{k}]") for k, n in enumerate(seq.items)]
        return out

    def event(self, node: YNode, item: str) -> Event:
        m = self.mapping(node, item, *EVENT_KEYS)
        e = m.entries
        name = self.identifier(e["name"], child(item, "name"))
        self.claim(name, e["name"].line, child(item, "name"))
        from ..expressions.grammar import parse_event_function
        when = e["when"]
        text = when.value if isinstance(when, YScalar) else None
        import sympy
        inputs = getattr(self, "inputs", {})
        symbols = {**self.symbols, **{n: sympy.Symbol(n, real=True) for n in inputs}}
        s, direction = parse_event_function(text, symbols, source=self.source,
                                            line=when.line, item=child(item, "when"))
        if "direction" in e:
            direction = self.choice(e["direction"], child(item, "direction"), DIRECTIONS,
                                    "direction")
        action = self.choice(e["do"], child(item, "do"), ACTIONS, "action")
        if action == "bounce" and s.free_symbols & self.speed_symbols():
            raise self.fail(when.line, child(item, "when"),
                            "reads speeds, but a bounce needs an event function of "
                            "positions and time (its gradient gives the impact's "
                            "direction); use do: log or stop, or a function of positions",
                            text)
        joint = self.joint(m, item, action)
        restitution = 0.0
        if "restitution" in e:
            if action != "bounce":
                raise self.bad(e["restitution"], child(item, "restitution"),
                               "applies only to do: bounce")
            restitution = self.restitution(e["restitution"], child(item, "restitution"))
        return Event(name, str(text), s, direction or "either", action, joint,
                     restitution, Where(self.source, node.line))

    def joint(self, m, item: str, action: str) -> str | None:
        """The joint a lock or unlock acts on (required), a bounce's (optional)."""
        e = m.entries
        if "joint" not in e:
            if action in ("lock", "unlock"):
                raise self.fail(m.line, child(item, "joint"),
                                f"missing required key: do: {action} needs the joint "
                                "it acts on", show_value=False)
            return None
        if action in ("stop", "log"):
            raise self.bad(e["joint"], child(item, "joint"),
                           f"applies only to lock, unlock and bounce, not to {action}")
        name = self.name_in(e["joint"], child(item, "joint"), self.joints, "joint",
                            "joints")
        if name in self.driven:
            raise self.fail(e["joint"].line, child(item, "joint"),
                            f"is driven by driver {self.driven[name]!r}, which prescribes "
                            f"its motion: a {action} cannot act on it; remove the driver "
                            f"or the event", name)
        if self.joints[name].type not in LIMIT_TYPES:
            raise self.fail(e["joint"].line, child(item, "joint"),
                            f"names a {self.joints[name].type} joint, which has no "
                            f"angle or slide to {action}; joints with one are: "
                            f"{', '.join(LIMIT_TYPES)}", name)
        return name

    def speed_symbols(self) -> set:
        """The symbols of speeds: joint rates and speeds, point velocities."""
        return {sym for name, sym in self.symbols.items()
                if name.rsplit(".", 1)[-1] in ("rate", "speed", "vx", "vy", "vz")}

    def restitution(self, node: YNode, item: str) -> float:
        e = self.number(node, item)
        if not 0.0 <= e <= 1.0:
            raise self.bad(node, item, "must be a restitution from 0 to 1")
        return e

    def claim(self, name: str, line: int, item: str):
        if name in self.names:
            raise self.fail(line, item, "is the name of another event", name)
        self.names.add(name)

    def limit_events(self) -> list[Event]:
        out = []
        for j in self.joints.values():
            if j.limits is None:
                continue
            if j.name in self.driven:
                raise self.fail(j.where.line, f"joints.{j.name}.limits",
                                f"the joint is driven by driver {self.driven[j.name]!r}, "
                                f"which prescribes its motion: limits cannot act on it; "
                                f"remove the driver or the limits", list(j.limits))
            q = f"{j.name}.angle" if j.type in ANGLE_TYPES else f"{j.name}.position"
            lo, hi = j.limits
            sym = self.symbols[q]
            for suffix, s, op, bound, direction in (("lower", sym - lo, "<=", lo, "falling"),
                                                    ("upper", sym - hi, ">=", hi, "rising")):
                name = f"{j.name}_{suffix}"
                self.claim(name, j.where.line, f"joints.{j.name}.limits")
                out.append(Event(name, f"{q} {op} {bound!r}", s, direction, "bounce",
                                 j.name, j.restitution, j.where))
        return out
