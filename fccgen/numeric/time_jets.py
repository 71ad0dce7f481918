"""A function of time written in the restricted grammar (docs/expressions.md, in t
alone), with its first two derivatives, evaluated without SymPy: second-order
forward-mode differentiation on the syntax tree.

A *jet* is (f, f', f'') at one t. Sums and products follow the Leibniz rule,
(a b)'' = a'' b + 2 a' b' + a b''; a function phi of a jet u gives
(phi(u), phi'(u) u', phi''(u) u'^2 + phi'(u) u''), and atan2(y, x) uses
theta' = (x y' - y x') / (x^2 + y^2) and the quotient rule once more. The text was
checked by fccgen.mechanism.expressions when the model was loaded; anything else
here is refused.
"""
from __future__ import annotations

import ast
import math
from functools import lru_cache
from typing import Callable

Jet = tuple[float, float, float]


def _const(x: float) -> Jet:
    return (float(x), 0.0, 0.0)


def _mul(a: Jet, b: Jet) -> Jet:
    return (a[0] * b[0], a[1] * b[0] + a[0] * b[1],
            a[2] * b[0] + 2.0 * a[1] * b[1] + a[0] * b[2])


def _chain(u: Jet, f: float, d1: float, d2: float) -> Jet:
    """phi(u) from phi(u0) = f, phi'(u0) = d1, phi''(u0) = d2."""
    return (f, d1 * u[1], d2 * u[1] * u[1] + d1 * u[2])


def _power(a: Jet, b: Jet) -> Jet:
    if b[1] == 0.0 and b[2] == 0.0:          # constant exponent p
        p, x = b[0], a[0]
        if p == 0.0:
            return _const(1.0)
        d1 = p * x ** (p - 1.0) if p != 1.0 else 1.0
        d2 = p * (p - 1.0) * x ** (p - 2.0) if p not in (1.0, 2.0) else (
            0.0 if p == 1.0 else 2.0)
        return _chain(a, x ** p, d1, d2)
    return _exp(_mul(b, _log(a)))             # a^b = exp(b log a), a > 0


def _exp(u: Jet) -> Jet:
    e = math.exp(u[0])
    return _chain(u, e, e, e)


def _log(u: Jet) -> Jet:
    return _chain(u, math.log(u[0]), 1.0 / u[0], -1.0 / (u[0] * u[0]))


def _sqrt(u: Jet) -> Jet:
    r = math.sqrt(u[0])
    return _chain(u, r, 0.5 / r, -0.25 / (r * u[0]))


def _tan(u: Jet) -> Jet:
    t = math.tan(u[0])
    return _chain(u, t, 1.0 + t * t, 2.0 * t * (1.0 + t * t))


def _atan2(y: Jet, x: Jet) -> Jet:
    n = x[0] * y[1] - y[0] * x[1]
    d = x[0] * x[0] + y[0] * y[0]
    dn = x[0] * y[2] - y[0] * x[2]
    dd = 2.0 * (x[0] * x[1] + y[0] * y[1])
    return (math.atan2(y[0], x[0]), n / d, (dn * d - n * dd) / (d * d))


UNARY = {
    "sin": lambda u: _chain(u, math.sin(u[0]), math.cos(u[0]), -math.sin(u[0])),
    "cos": lambda u: _chain(u, math.cos(u[0]), -math.sin(u[0]), -math.cos(u[0])),
    "tan": _tan, "exp": _exp, "log": _log, "sqrt": _sqrt,
    "abs": lambda u: _chain(u, abs(u[0]), math.copysign(1.0, u[0]), 0.0),
}


def _eval(node: ast.AST, t: Jet, env=None) -> Jet:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
            and not isinstance(node.value, bool):
        return _const(node.value)
    if isinstance(node, ast.Name) and node.id in ("t", "pi"):
        return t if node.id == "t" else _const(math.pi)
    if isinstance(node, ast.Name) and env and node.id in env:   # an input: constant
        return _const(env[node.id])
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        u = _eval(node.operand, t, env)
        return tuple(-x for x in u) if isinstance(node.op, ast.USub) else u
    if isinstance(node, ast.BinOp):
        a, b = _eval(node.left, t, env), _eval(node.right, t, env)
        if isinstance(node.op, ast.Add):
            return tuple(x + y for x, y in zip(a, b))
        if isinstance(node.op, ast.Sub):
            return tuple(x - y for x, y in zip(a, b))
        if isinstance(node.op, ast.Mult):
            return _mul(a, b)
        if isinstance(node.op, ast.Div):
            return _mul(a, _power(b, _const(-1.0)))
        if isinstance(node.op, ast.Pow):
            return _power(a, b)
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords:
        args = [_eval(a, t, env) for a in node.args]
        name = node.func.id
        if name in UNARY and len(args) == 1:
            return UNARY[name](args[0])
        if name == "atan2" and len(args) == 2:
            return _atan2(*args)
        if name in ("min", "max") and len(args) >= 2:
            return (min if name == "min" else max)(args, key=lambda j: j[0])
    raise ValueError(f"{ast.unparse(node)!r} is not an expression of t in the "
                     "restricted grammar (docs/expressions.md)")


def table_jet(text: str) -> Callable[[float], Jet]:
    """t -> (f, f', f'') of a table's function text (fccgen.mechanism.tables): SciPy's
    clamped cubic spline through the rows, evaluated by SciPy (not by the polynomials
    that the kernels print), held at the end values with zero derivatives outside."""
    from scipy.interpolate import CubicSpline

    from ..mechanism.tables import table_rows
    knots, values = table_rows(text)
    spline = CubicSpline(knots, values, bc_type="clamped")

    def evaluate(time: float) -> Jet:
        if time < knots[0]:
            return _const(values[0])
        if time >= knots[-1]:
            return _const(values[-1])
        return tuple(float(spline(time, nu)) for nu in range(3))
    return evaluate


@lru_cache(maxsize=None)
def time_function(text: str) -> Callable[[float], Jet]:
    """t -> (f(t), f'(t), f''(t)) of the expression ``text`` in t (or of a table,
    :func:`table_jet`); ``evaluate(t, inputs)`` reads the model's inputs (name ->
    value, held constant: zero derivatives) from the mapping ``inputs``."""
    if text.startswith("table:"):
        return table_jet(text)
    tree = ast.parse(text.strip(), mode="eval").body

    def evaluate(time: float, inputs=None) -> Jet:
        try:
            return _eval(tree, (float(time), 1.0, 0.0), inputs)
        except ValueError as exc:         # the user's text, never a syntax tree
            raise ValueError(f"the expression {text.strip()!r}: {exc}") from None
    return evaluate
