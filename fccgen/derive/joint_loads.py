"""Kernel expressions of forces and torques whose components read joint quantities
(kinds force_q, torque_q; docs/elements.md "Loads of joint quantities"), registered
in :data:`fccgen.derive.elements.BUILDERS` when the package is imported.

The components F(t, z) are read from the class's ``function`` by the restricted
grammar over real symbols, and the joint quantities z are replaced by their
expressions in the class's q, v and parameters:

    angle    = th + atan2(S, C),  S = c D - s P,  C = c P + s D,
               (c, s) = cos, sin of theta_init + th  (cos0, sin0 turned by cr, sr),
               D = u.(p_A x p_B),  P = p_A.p_B,  p = r_j - r_i - lam u,
    rate     = (C S' - S C') / (S^2 + C^2)      (S', C' by the product rule),
    position = u.(r_b - r_a) - s0,
    speed    = u'.(r_b - r_a) + u.(r_b' - r_a').

The angle is measured from the initial configuration and counted over turns, as the
torsion spring's: th is the reference the runtime keeps at the joint angle of the
last accepted state (fccgen.events.references), so the atan2 stays near 0 within a
step. f = Dhat^T F (force) or
Phi_b^T R^T T (torque) of the load's body; df/dq, df/dq' by the chain rule through
the polynomials S, C, S', C' (and s, s'), which keeps the expressions small.
"""
from __future__ import annotations

import sympy

from .elements import BUILDERS, Outputs, force, reference_rotation, torque
from .kinematics import cross, dot
from .symbols import ClassSymbols


def _angle(s: ClassSymbols, prefix: str, inter: dict) -> tuple[sympy.Expr, sympy.Expr]:
    ai, aj, bi, bj, u = (s.triple(prefix + n) for n in ("A.ri", "A.rj", "B.ri", "B.rj", "u"))
    la, lb = s.scalar(prefix + "lA"), s.scalar(prefix + "lB")
    cos0, sin0 = reference_rotation(s, prefix)
    pa, pb = aj.pos - ai.pos - la * u.pos, bj.pos - bi.pos - lb * u.pos
    va, vb = aj.vel - ai.vel - la * u.vel, bj.vel - bi.vel - lb * u.vel
    big_d, big_p = dot(u.pos, cross(pa, pb)), dot(pa, pb)
    d_dot = dot(u.vel, cross(pa, pb)) + dot(u.pos, cross(va, pb)) + dot(u.pos, cross(pa, vb))
    p_dot = dot(va, pb) + dot(pa, vb)
    big_s, big_c, s_dot, c_dot = (_intermediate(inter, prefix + n, e) for n, e in (
        ("S", cos0 * big_d - sin0 * big_p), ("C", cos0 * big_p + sin0 * big_d),
        ("Sd", cos0 * d_dot - sin0 * p_dot), ("Cd", cos0 * p_dot + sin0 * d_dot)))
    # th enters as a real symbol (a parameter of the kernel): the loads' |.| (min, max)
    # then differentiate to sign(), never to re() and im(), which C does not print
    th = _intermediate(inter, prefix + "th", s.scalar(prefix + "th"))
    return (th + sympy.atan2(big_s, big_c),
            (big_c * s_dot - big_s * c_dot) / (big_s ** 2 + big_c ** 2))


def _position(s: ClassSymbols, prefix: str, inter: dict) -> tuple[sympy.Expr, sympy.Expr]:
    u, ra, rb = (s.triple(prefix + n) for n in ("u", "ra", "rb"))
    d, dd = rb.pos - ra.pos, rb.vel - ra.vel
    return (_intermediate(inter, prefix + "s", dot(u.pos, d) - s.scalar(prefix + "s0")),
            _intermediate(inter, prefix + "sd", dot(u.vel, d) + dot(u.pos, dd)))


def _intermediate(inter: dict, name: str, expr: sympy.Expr) -> sympy.Symbol:
    """A real symbol standing for the polynomial ``expr`` of q, v, p."""
    sym = sympy.Symbol(name, real=True)
    inter[sym] = expr
    return sym


QUANTITIES = {"angle": (_angle, ("angle", "rate")),
              "position": (_position, ("position", "speed"))}


def components(s: ClassSymbols) -> tuple[sympy.Matrix, dict]:
    """(F, Y): F(t, z) of the class, its three expressions with t the parameter "t"
    and every joint quantity z written in intermediate symbols Y (S, C, S', C' of an
    angle; s, s' of a position), Y -> its polynomial in q, v, p."""
    from ..mechanism.expressions import parse_expression
    from .mechanism import input_symbols
    t = sympy.Symbol("t", real=True)
    symbols, values = input_symbols(s)
    inter = {}
    symbols["t"], values[t] = t, s.scalar("t")
    for joint, family in s.cls.joint_families:
        build, names = QUANTITIES[family]
        for name, expr in zip(names, build(s, f"{joint}.{family}.", inter)):
            sym = sympy.Symbol(f"{joint}.{name}", real=True)
            symbols[f"{joint}.{name}"] = sym
            values[sym] = expr
    text = s.cls.function.split("|", 1)[1]
    return sympy.Matrix([_without_min_max(parse_expression(
        x, symbols, source="<load class>", line=None, item=s.cls.name)).xreplace(values)
        for x in text.split(";")]), inter


def _without_min_max(e: sympy.Expr) -> sympy.Expr:
    """max(a, b) = (a + b + |a - b|)/2, min(a, b) = (a + b - |a - b|)/2, folded over
    more arguments: the same values, but SymPy's Max and Min compare their arguments
    when rebuilt, which takes very long once they are polynomials of q."""
    def fold(sign):
        def pair(*args):
            out = args[0]
            for a in args[1:]:
                out = (out + a + sign * sympy.Abs(out - a)) / 2
            return out
        return pair
    return e.replace(sympy.Max, fold(1)).replace(sympy.Min, fold(-1))


def _chained(s: ClassSymbols, f: list, inter: dict) -> Outputs:
    """f and its Jacobians by the chain rule through the intermediates Y:
    df/dq = (partial f/partial q)_Y + sum_Y (df/dY) dY/dq, df/dq' = sum_Y (df/dY)
    dY/dq' (f reads q' only through Y), then Y replaced by its polynomial."""
    grads = {y: ([sympy.diff(e, x) for x in s.q], [sympy.diff(e, x) for x in s.v])
             for y, e in inter.items()}
    jq, jv = [], []
    for fi in f:
        by_y = {y: sympy.diff(fi, y) for y in inter if fi.has(y)}
        for k, x in enumerate(s.q):
            jq.append(sympy.diff(fi, x) + sum((d * grads[y][0][k] for y, d in by_y.items()),
                                              sympy.S.Zero))
        for k in range(len(s.v)):
            jv.append(sum((d * grads[y][1][k] for y, d in by_y.items()), sympy.S.Zero))
    sub = dict(inter)
    return {"applied_forces": [e.xreplace(sub) for e in f],
            "force_jacobian_q": [e.xreplace(sub) for e in jq],
            "force_jacobian_v": [e.xreplace(sub) for e in jv]}


def force_q(s: ClassSymbols) -> Outputs:
    """f = Dhat^T F(t, z) at the body point (b1, b2, b3); no potential."""
    F, inter = components(s)
    return _chained(s, force(s, F)["applied_forces"], inter)


def torque_q(s: ClassSymbols) -> Outputs:
    """f = Phi_b^T (R^T T(t, z)); no potential."""
    T, inter = components(s)
    return _chained(s, torque(s, T)["applied_forces"], inter)


BUILDERS.update({"force_q": force_q, "torque_q": torque_q})
