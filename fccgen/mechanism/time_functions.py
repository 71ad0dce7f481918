"""A driver's function of time f(t) and its first two derivatives as a Python
function, for the numeric version (fccgen.numeric) and for post-processing.

The expression is read by the restricted grammar (:mod:`.expressions`); SymPy
differentiates it and ``lambdify`` turns f, f' and f'' (functions of t alone) into
one function over the ``math`` module. The kinematics of the driver rows (their
derivatives in q and the chain rule in t) are written out by hand in
fccgen.numeric.elements, independently of the symbolic path.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Callable


@lru_cache(maxsize=None)
def time_function(text: str) -> Callable[[float], tuple[float, float, float]]:
    """t -> (f(t), f'(t), f''(t)) of the expression ``text`` in t."""
    import sympy

    from .expressions import parse_expression
    t = sympy.Symbol("t", real=True)
    f = parse_expression(text, {"t": t}, source="<driver>", line=None, item="function")
    fd = sympy.diff(f, t)
    fun = sympy.lambdify(t, [f, fd, sympy.diff(fd, t)], modules="math")

    def evaluate(time: float) -> tuple[float, float, float]:
        a, b, c = fun(float(time))
        return float(a), float(b), float(c)
    return evaluate
