"""Kernel expressions of the mechanism level's drivers, loads of time and linear
spring-dampers (docs/elements.md, docs/joints.md "Drivers"), registered in
:data:`fccgen.derive.elements.BUILDERS` when the package is imported."""
from __future__ import annotations

import sympy

from .elements import BUILDERS, Outputs, with_force_jacobians
from .elements import force, torque
from .kinematics import cross, dot
from .symbols import ClassSymbols


# -- drivers: rheonomic rows g(q, t) (docs/joints.md, "Drivers") -----------------------

def _time_function(s: ClassSymbols) -> tuple[sympy.Symbol, sympy.Expr]:
    """(t, f(t)) of a driver class: its expression read again by the restricted
    grammar (it was checked when the model was loaded) over a real symbol t, or its
    table's spline (fccgen.mechanism.tables)."""
    from ..mechanism.expressions import parse_expression
    from ..mechanism.tables import is_table_text, table_text_expression
    t = sympy.Symbol("t", real=True)
    if is_table_text(s.cls.function):          # a table: the spline of tables.py
        return t, table_text_expression(s.cls.function, t)
    f = parse_expression(s.cls.function, {"t": t}, source="<driver class>", line=None,
                         item=s.cls.name)
    return t, f


def _rheonomic(s: ClassSymbols, g: sympy.Expr, t: sympy.Symbol) -> Outputs:
    """Kernels of one row g(q, t) (t a real symbol, replaced by the parameter "t"):
    B = dg/dq, dg/dt, and the bias g'' - B q'' = (dg'/dq) q' + dg'/dt with
    g' = B q' + dg/dt (q' held fixed in the partial derivatives)."""
    jac = [sympy.diff(g, x) for x in s.q]
    rate = sympy.diff(g, t)
    g_dot = sum((b * v for b, v in zip(jac, s.v)), sympy.S.Zero) + rate
    bias = sum((sympy.diff(g_dot, x) * v for x, v in zip(s.q, s.v)), sympy.S.Zero) \
        + sympy.diff(g_dot, t)
    p_t = s.scalar("t")
    return {"constraints": [g.subs(t, p_t)],
            "constraint_jacobian": [e.subs(t, p_t) for e in jac],
            "constraint_bias": [bias.subs(t, p_t)],
            "constraint_rate": [rate.subs(t, p_t)]}


def driver_angle(s: ClassSymbols) -> Outputs:
    """Joint angle driven to f(t): g = b.(-sin f a + cos f (u x a)) with u the joint
    axis and a (first body), b (second body) unit vectors perpendicular to it, equal
    at t = 0. With b = cos th a + sin th (u x a), g = sin(th - f): zero on the branch
    th = f (the one the motion starts on) and on th = f + pi."""
    t, f = _time_function(s)
    u, a, b = (s.triple(n).pos for n in ("u", "a", "b"))
    g = dot(b, -sympy.sin(f) * a + sympy.cos(f) * cross(u, a))
    return _rheonomic(s, g, t)


def driver_position(s: ClassSymbols) -> Outputs:
    """Joint slide driven to f(t): g = u.(r_b - r_a) - f (u the axis, r_a, r_b the
    joint's points on its two bodies)."""
    t, f = _time_function(s)
    u, ra, rb = (s.triple(n).pos for n in ("u", "ra", "rb"))
    return _rheonomic(s, dot(u, rb - ra) - f, t)


def driver_distance(s: ClassSymbols) -> Outputs:
    """Distance of a distance joint driven to f(t) > 0: g = d.d - f^2, d = r_b - r_a
    (quadratic, like the joint's own row)."""
    t, f = _time_function(s)
    ra, rb = (s.triple(n).pos for n in ("ra", "rb"))
    d = rb - ra
    return _rheonomic(s, dot(d, d) - f ** 2, t)


def driver_coordinate(s: ClassSymbols) -> Outputs:
    """Coordinate of a point along a fixed unit direction e driven to f(t), from its
    initial value c0 = e.r(0): g = e.r - c0 - f (linear in q)."""
    t, f = _time_function(s)
    e = sympy.Matrix([s.scalar(n) for n in ("ex", "ey", "ez")])
    return _rheonomic(s, dot(e, s.triple("r").pos) - s.scalar("c0") - f, t)


BUILDERS.update({"driver_angle": driver_angle, "driver_position": driver_position,
                 "driver_distance": driver_distance,
                 "driver_coordinate": driver_coordinate})


# -- loads given as expressions of time (kinds force_t, torque_t) ----------------------

def _functions_of_time(s: ClassSymbols) -> sympy.Matrix:
    """The class's three components (its ``function``, "ex;ex;ex") read by the
    restricted grammar over t, with t the parameter the runtime writes."""
    from ..mechanism.expressions import parse_expression
    t = sympy.Symbol("t", real=True)
    symbols, values = input_symbols(s)
    symbols["t"], values[t] = t, s.scalar("t")
    parts = s.cls.function.split(";")
    return sympy.Matrix([parse_expression(x, symbols, source="<load class>", line=None,
                                          item=s.cls.name).xreplace(values)
                         for x in parts])


def input_symbols(s: ClassSymbols) -> tuple[dict, dict]:
    """(name -> real symbol, symbol -> the class's parameter) of the inputs the class
    reads: an input is a parameter held constant over a step (its derivative in t is
    zero), written by the runtime between steps."""
    from ..plan.classes import input_parameter
    symbols = {n: sympy.Symbol(n, real=True) for n in s.cls.inputs}
    return symbols, {x: s.scalar(input_parameter(n)) for n, x in symbols.items()}


def force_t(s: ClassSymbols) -> Outputs:
    """f = Dhat^T F(t) at the body point (b1, b2, b3); no potential."""
    return force(s, _functions_of_time(s))


def torque_t(s: ClassSymbols) -> Outputs:
    """f = Phi_b^T (R^T T(t)); no potential."""
    return torque(s, _functions_of_time(s))


BUILDERS.update({"force_t": with_force_jacobians(force_t),
                 "torque_t": with_force_jacobians(torque_t)})


def linear_spring(s: ClassSymbols) -> Outputs:
    """Spring-damper along a joint axis: s = u.(r_b - r_a), s' = u'.(r_b - r_a) +
    u.(r_b' - r_a'); V = k (s - L)^2 / 2 and f = -(k (s - L) + c s') ds/dq (the
    gradient of V plus the damping along the same direction)."""
    u, ra, rb = (s.triple(n) for n in ("u", "ra", "rb"))
    k, length, c = s.scalar("k"), s.scalar("L"), s.scalar("c")
    pos = dot(u.pos, rb.pos - ra.pos)
    speed = dot(u.vel, rb.pos - ra.pos) + dot(u.pos, rb.vel - ra.vel)
    tension = k * (pos - length) + c * speed
    return {"applied_forces": [-tension * sympy.diff(pos, x) for x in s.q],
            "energy": [sympy.S.Zero, k * (pos - length) ** 2 / 2]}


BUILDERS["linear_spring"] = with_force_jacobians(linear_spring)
