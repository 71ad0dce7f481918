"""Reading the ``drivers:`` list of a model file (docs/design.md §2b, docs/joints.md):
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

import numpy as np

from ..errors import ModelError
from .inputs import NOT_IN_DRIVERS, refuse_inputs
from .fields import Reader, child, listing
from .types import GROUND, Driver, Joint, Where
from .yamlnodes import YMap, YNode, YScalar

# quantity key -> joint types that have that freedom
DRIVEN_QUANTITIES = {"angle": ("revolute", "cylindrical"),
                     "position": ("prismatic", "cylindrical"),
                     "distance": ("distance",)}
# Rates: the driven quantity is their integral from 0 (closed form by SymPy, given at
# most INTEGRAL_SECONDS).
RATES = {"rate": "angle", "speed": "position"}
INTEGRAL_SECONDS = 10.0
FUNCTION_KEYS = (*DRIVEN_QUANTITIES, *RATES)
DRIVER_KEYS = ("name", "joint")
# joint types whose lowering has a shared point named after the joint
SHARED_POINT_TYPES = ("spherical", "revolute", "universal", "weld")


class DriverReader(Reader):
    """Reads drivers of the joints already read; ``claim`` reserves the driver's name."""

    def __init__(self, source: str, claim):
        super().__init__(source)
        self.claim = claim

    def drivers(self, node: YNode, joints: list[Joint], points=None) -> list[Driver]:
        """points: {name: Point} of the model (a coordinate driver names one, or the
        shared point of a spherical, revolute, universal or weld joint)."""
        seq = self.sequence(node, "drivers")
        by_name = {j.name: j for j in joints}
        self.points = dict(points or {})
        out = [self.coordinate(n, f"drivers[{k}]", by_name) if self.is_coordinate(n)
               else self.driver(n, f"drivers[{k}]", by_name)
               for k, n in enumerate(seq.items)]
        seen: dict[str, str] = {}
        for d in out:
            if d.quantity == "coordinate":
                continue
            key = f"{d.joint}.{d.quantity}"
            if key in seen:
                raise self.fail(d.where.line, "drivers", f"drive {key} twice (also "
                                f"{seen[key]}); a joint quantity has one driver", d.name)
            seen[key] = d.name
        return out

    def driver(self, node: YNode, item: str, joints: dict[str, Joint]) -> Driver:
        m = self.mapping(node, item, DRIVER_KEYS, FUNCTION_KEYS)
        e = m.entries
        name = self.identifier(e["name"], child(item, "name"))
        self.claim(name, "driver", e["name"].line, child(item, "name"))
        joint_name = self.text(e["joint"], child(item, "joint"))
        if joint_name not in joints:
            raise self.fail(e["joint"].line, child(item, "joint"), "names no joint; joints "
                            "are: " + (listing(joints) if joints else "none"), joint_name)
        given = [k for k in FUNCTION_KEYS if k in e]
        if len(given) != 1:
            raise self.fail(m.line, item, "needs exactly one of "
                            + listing(FUNCTION_KEYS), ", ".join(given) or "none",
                            show_value=bool(given))
        key = given[0]
        quantity = RATES.get(key, key)
        joint = joints[joint_name]
        if joint.type not in DRIVEN_QUANTITIES[quantity]:
            have = [q for q, types in DRIVEN_QUANTITIES.items() if joint.type in types]
            rule = (f"drives the {quantity} of joint {joint_name}, a {joint.type} joint "
                    f"without that freedom (a {quantity} driver needs a "
                    f"{' or '.join(DRIVEN_QUANTITIES[quantity])} joint"
                    + (f"; this joint has {listing(have)})" if have else ")"))
            raise self.fail(e[key].line, child(item, key), rule, joint_name)
        text = self.function(e[key], child(item, key), integrate=key in RATES)
        return Driver(name, joint_name, quantity, text, Where(self.source, m.line))

    @staticmethod
    def is_coordinate(node: YNode) -> bool:
        return isinstance(node, YMap) and "point" in node.entries

    def coordinate(self, node: YNode, item: str, joints: dict[str, Joint]) -> Driver:
        """``{name, point: P, direction: [x, y, z], value: f(t)}``: the coordinate of a
        moving point along a fixed direction, from its initial position."""
        m = self.mapping(node, item, ("name", "point", "direction", "value"))
        e = m.entries
        name = self.identifier(e["name"], child(item, "name"))
        self.claim(name, "driver", e["name"].line, child(item, "name"))
        point = self.text(e["point"], child(item, "point"))
        shared = {j for j, joint in joints.items()
                  if joint.type in SHARED_POINT_TYPES and GROUND not in joint.bodies}
        if point in self.points and self.points[point].fixed:
            raise self.fail(e["point"].line, child(item, "point"), "is a fixed point; a "
                            "coordinate driver moves a moving point", point)
        if point not in self.points and point not in shared:
            known = [p for p, x in self.points.items() if not x.fixed] + sorted(shared)
            raise self.fail(e["point"].line, child(item, "point"), "names no moving point "
                            "(a point of the model or the point of a joint between two "
                            "moving bodies); they are: " + (listing(known) or "none"), point)
        direction = self.vec3(e["direction"], child(item, "direction"))
        norm = float(np.linalg.norm(direction))
        if not norm > 1e-12:
            raise self.bad(e["direction"], child(item, "direction"),
                           "must be a direction (its length is zero)")
        text = self.function(e["value"], child(item, "value"))
        return Driver(name, "", "coordinate", text, Where(self.source, m.line),
                      point=point, direction=direction / norm)

    def function(self, node: YNode, item: str, integrate: bool = False) -> str:
        """The expression's text, checked by the restricted grammar over t alone
        (SymPy is imported here, by models with drivers only); integrate: the text of
        its integral from 0 to t instead (:func:`integral_text`)."""
        import sympy

        from ..mechanism.expressions import parse_expression
        if isinstance(node, YMap):
            return self.table(node, item, integrate)
        if isinstance(node, YScalar):
            value = node.value
            text = value if isinstance(value, (bool, int, float)) else node.text
        else:
            text = node.plain()
        t = sympy.Symbol("t", real=True)
        inputs = getattr(self, "inputs", {})
        expr = parse_expression(text, {"t": t, **{n: sympy.Symbol(n, real=True)
                                                  for n in inputs}},
                                source=self.source, line=node.line, item=item)
        refuse_inputs(self, expr, inputs, node.line, item, text, NOT_IN_DRIVERS)
        text = " ".join((text if isinstance(text, str) else repr(text)).split())
        if not integrate:
            self.smooth_at_start(expr, t, node.line, item, text)
            return text
        out = bounded_integral_text(expr, t)
        try:
            f = parse_expression(out or "", {"t": t}, source=self.source,
                                 line=node.line, item=item)
        except ModelError:
            out = None
        if out is None:
            raise self.fail(node.line, item, "has no integral from 0 to t in closed form "
                            "within the expression grammar (SymPy found none within "
                            f"{INTEGRAL_SECONDS:g} s); give the angle or position itself",
                            text)
        self.smooth_at_start(f, t, node.line, item, text)
        return out

    def smooth_at_start(self, f, t, line, item: str, text: str) -> None:
        """Refuse a driver whose kernels would not be finite: abs, min or max of t (the
        rate jumps where they switch, the acceleration is a Dirac delta, which no
        kernel can print), or a value, rate or acceleration that is not a finite
        number at t = 0 (sqrt(t), log(t), sin(t)/t)."""
        import sympy

        from ..mechanism.expressions import finite_value
        if f.has(sympy.Abs, sympy.Min, sympy.Max, sympy.sign, sympy.Heaviside):
            raise self.fail(line, item, "must be smooth in t: abs, min and max make the "
                            "driver's rate jump where they switch, and its acceleration "
                            "a Dirac delta (write a smooth expression, or give a table, "
                            "which is smooth)", text)
        for order, what in enumerate(("value", "rate", "acceleration")):
            value = sympy.diff(f, t, order).subs(t, 0)
            if not finite_value(value):
                raise self.fail(line, item, f"the driver's {what} at t = 0 is not a "
                                f"finite number ({sympy.sstr(value)}): value, rate and "
                                "acceleration must be finite at the start (sqrt(t), "
                                "log(t), sin(t)/t are not)", text)

    def table(self, node: YMap, item: str, integrate: bool) -> str:
        """``{table: file.csv}``: the checked table's function text
        (:func:`fccgen.mechanism.tables.table_text`); a rate or speed is refused (give
        the angle or position table)."""
        from ..mechanism.tables import read_table, table_text
        m = self.mapping(node, item, ("table",))
        path = self.text(m.entries["table"], child(item, "table"))
        if integrate:
            raise self.fail(node.line, item, "a table gives an angle, position, distance "
                            "or value, not a rate or speed (tabulate the angle or "
                            "position instead)", path)
        t, y = read_table(path, source=self.source, line=m.entries["table"].line,
                          item=child(item, "table"))
        return table_text(t, y)


def bounded_integral_text(rate, t, seconds: float | None = None) -> str | None:
    """:func:`integral_text`, given at most ``seconds`` (default INTEGRAL_SECONDS):
    SymPy's integration has no time limit of its own (sin(t)**5*cos(t)**3 took
    minutes), so it runs in a forked child process that is killed when the time is
    up (None then). Where processes cannot be forked, it runs here, unbounded."""
    import multiprocessing
    import warnings

    import sympy
    # SymPy imports parts of its integrator on first use: done here, so that the
    # child imports nothing (another thread may hold the import lock when it forks).
    import sympy.integrals.heurisch  # noqa: F401
    import sympy.integrals.manualintegrate  # noqa: F401
    import sympy.integrals.meijerint  # noqa: F401
    import sympy.integrals.risch  # noqa: F401

    seconds = INTEGRAL_SECONDS if seconds is None else seconds
    key = sympy.srepr((rate, t))
    if key in _INTEGRALS:
        return _INTEGRALS[key]
    try:
        context = multiprocessing.get_context("fork")
    except ValueError:
        return integral_text(rate, t)
    receive, send = context.Pipe(duplex=False)

    def child():
        try:
            send.send(integral_text(rate, t))
        except BaseException:                # anything SymPy raises: no integral
            send.send(None)

    with warnings.catch_warnings():          # fork of a process that has threads
        warnings.simplefilter("ignore", DeprecationWarning)
        process = context.Process(target=child, daemon=True)
        process.start()
    send.close()
    try:
        out = receive.recv() if receive.poll(seconds) else None
    except EOFError:                         # the child died
        out = None
    finally:
        receive.close()
        if process.is_alive():
            process.kill()
        process.join()
    if out is not None:                      # only answers are kept, never a time-out
        _INTEGRALS[key] = out
    return out


_INTEGRALS: dict[str, str] = {}          # srepr of (rate, t) -> integral text


def integral_text(rate, t) -> str | None:
    """The text of f(t) = integral of ``rate`` from 0 to t, with the rate's decimal
    numbers made exact rationals first (so that the text holds them exactly), or
    None when SymPy leaves an unevaluated integral or needs a case split."""
    import sympy
    from sympy.printing.str import StrPrinter

    class GrammarPrinter(StrPrinter):
        """SymPy's text in the names of the expression grammar (abs, min, max)."""

        def _print_Abs(self, e):
            return f"abs({self._print(e.args[0])})"

        def _print_Min(self, e):
            return f"min({', '.join(self._print(a) for a in e.args)})"

        def _print_Max(self, e):
            return f"max({', '.join(self._print(a) for a in e.args)})"

    tau = sympy.Dummy("tau", real=True)
    exact = sympy.nsimplify(rate, rational=True).subs(t, tau)
    try:
        f = sympy.integrate(exact, (tau, 0, t))
    except (ValueError, NotImplementedError, TypeError):
        return None
    if f.has(sympy.Integral, sympy.Piecewise):
        return None
    return GrammarPrinter().doprint(f)
