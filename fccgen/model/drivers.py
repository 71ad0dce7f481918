"""Reading the ``drivers:`` list of a model file (DESIGN section 2b, docs/joints.md):
a joint quantity prescribed as an expression of the time t.

    drivers:
      - {name: motor, joint: A, angle: "10*t"}        # revolute or cylindrical
      - {name: push,  joint: S, position: "0.1*sin(2*t)"}   # prismatic or cylindrical

The expression is checked here by the restricted grammar
(:mod:`fccgen.mechanism.expressions`, only ``t`` is known) so that a bad one is
reported with its file and line; it is read again when the driver's kernels are
derived.
"""
from __future__ import annotations

from .fields import Reader, child, listing
from .types import Driver, Joint, Where
from .yamlnodes import YNode, YScalar

# quantity key -> joint types that have that freedom
DRIVEN_QUANTITIES = {"angle": ("revolute", "cylindrical"),
                     "position": ("prismatic", "cylindrical")}
DRIVER_KEYS = ("name", "joint")


class DriverReader(Reader):
    """Reads drivers of the joints already read; ``claim`` reserves the driver's name."""

    def __init__(self, source: str, claim):
        super().__init__(source)
        self.claim = claim

    def drivers(self, node: YNode, joints: list[Joint]) -> list[Driver]:
        seq = self.sequence(node, "drivers")
        by_name = {j.name: j for j in joints}
        out = [self.driver(n, f"drivers[{k}]", by_name) for k, n in enumerate(seq.items)]
        seen: dict[str, str] = {}
        for d in out:
            key = f"{d.joint}.{d.quantity}"
            if key in seen:
                raise self.fail(d.where.line, "drivers", f"drive {key} twice (also "
                                f"{seen[key]}); a joint quantity has one driver", d.name)
            seen[key] = d.name
        return out

    def driver(self, node: YNode, item: str, joints: dict[str, Joint]) -> Driver:
        m = self.mapping(node, item, DRIVER_KEYS, tuple(DRIVEN_QUANTITIES))
        e = m.entries
        name = self.identifier(e["name"], child(item, "name"))
        self.claim(name, "driver", e["name"].line, child(item, "name"))
        joint_name = self.text(e["joint"], child(item, "joint"))
        if joint_name not in joints:
            raise self.fail(e["joint"].line, child(item, "joint"), "names no joint; joints "
                            "are: " + (listing(joints) if joints else "none"), joint_name)
        given = [k for k in DRIVEN_QUANTITIES if k in e]
        if len(given) != 1:
            raise self.fail(m.line, item, "needs exactly one of "
                            + listing(DRIVEN_QUANTITIES), ", ".join(given) or "none",
                            show_value=bool(given))
        quantity = given[0]
        joint = joints[joint_name]
        if joint.type not in DRIVEN_QUANTITIES[quantity]:
            have = [q for q, types in DRIVEN_QUANTITIES.items() if joint.type in types]
            rule = (f"drives the {quantity} of joint {joint_name}, a {joint.type} joint "
                    f"without that freedom (a {quantity} driver needs a "
                    f"{' or '.join(DRIVEN_QUANTITIES[quantity])} joint"
                    + (f"; this joint has {listing(have)})" if have else ")"))
            raise self.fail(e[quantity].line, child(item, quantity), rule, joint_name)
        text = self.function(e[quantity], child(item, quantity))
        return Driver(name, joint_name, quantity, text, Where(self.source, m.line))

    def function(self, node: YNode, item: str) -> str:
        """The expression's text, checked by the restricted grammar over t alone
        (SymPy is imported here, by models with drivers only)."""
        import sympy

        from ..mechanism.expressions import parse_expression
        if isinstance(node, YScalar):
            value = node.value
            text = value if isinstance(value, (bool, int, float)) else node.text
        else:
            text = node.plain()
        parse_expression(text, {"t": sympy.Symbol("t", real=True)}, source=self.source,
                         line=node.line, item=item)
        return " ".join((text if isinstance(text, str) else repr(text)).split())
