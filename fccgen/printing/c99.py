"""The C99 printer of generated kernels: SymPy's, with an element's inputs read from
arrays, small powers written as products, and every number a double holds exactly or
rounds once.

Numbers: an integer n with |n| <= 2**53 (every such integer is a double exactly) is
written as a C integer constant, which C converts exactly; a larger one as the double
nearest to it (``1.8446744073709552e+19``), never as a C integer constant, which a
compiler truncates to 64 bits with only a warning. A rational p/q is written as
``p.0/q.0`` when p and q are both exact doubles (one correctly rounded division), else
as the double nearest to p/q. A number too large for a double is an error, never
``inf``."""
from __future__ import annotations

from typing import Mapping

import sympy
from sympy.printing.c import C99CodePrinter
from sympy.printing.precedence import PRECEDENCE

# Integer powers up to this order are printed as products (x*x*x): faster than pow()
# and within an ulp or two of it; larger ones go to pow().
MAX_PRODUCT_POWER = 4
# The largest integer magnitude below which every integer is a double exactly.
MAX_EXACT_INTEGER = 2 ** 53


def double_literal(value) -> str:
    """The C text of the double nearest to ``value`` (an int or a Fraction-like p/q
    pair's quotient, computed exactly by Python and rounded once); ValueError when it
    is not finite as a double."""
    try:
        x = float(value)
    except OverflowError:
        raise ValueError(f"the number {value} is too large for a double") from None
    text = repr(x)
    if text in ("inf", "-inf", "nan"):
        raise ValueError(f"the number {value} is not finite as a double")
    return text if any(c in text for c in ".e") else text + ".0"


def slot_map(q, v, p) -> dict[sympy.Symbol, str]:
    """Symbol -> C array slot for an element's coordinates, speeds and parameters."""
    slots = {}
    for array, symbols in (("q", q), ("v", v), ("p", p)):
        for k, s in enumerate(symbols):
            slots[s] = f"{array}[{k}]"
    return slots


class KernelPrinter(C99CodePrinter):
    """C99 printer that prints input symbols as array slots (``q0`` -> ``q[0]``).

    Symbols without a slot (the temporaries of common-subexpression elimination)
    print by name.
    """

    def __init__(self, slots: Mapping[sympy.Symbol, str], settings: dict | None = None):
        super().__init__(settings or {})
        self._slots = dict(slots)

    def _print_Integer(self, expr):
        n = int(expr.p)
        if abs(n) <= MAX_EXACT_INTEGER:
            return super()._print_Integer(expr)
        return double_literal(n)

    def _print_Rational(self, expr):
        p, q = int(expr.p), int(expr.q)
        if abs(p) <= MAX_EXACT_INTEGER and q <= MAX_EXACT_INTEGER:
            return super()._print_Rational(expr)
        from fractions import Fraction
        return double_literal(Fraction(p, q))

    def _print_Symbol(self, expr):
        slot = self._slots.get(expr)
        if slot is not None:
            return slot
        return super()._print_Symbol(expr)

    def _product(self, base, n: int) -> str:
        factor = self.parenthesize(base, PRECEDENCE["Mul"])
        return "*".join([factor] * n)

    def _print_Pow(self, expr):
        # Replacements are parenthesized: the Mul printer places a Pow without
        # parentheses (it binds tighter than * and /), a product does not.
        base, exp = expr.base, expr.exp
        if exp.is_Integer and 2 <= abs(int(exp)) <= MAX_PRODUCT_POWER:
            product = self._product(base, abs(int(exp)))
            return f"({product})" if exp > 0 else f"(1.0/({product}))"
        root = f"sqrt({self._print(base)})"
        if exp == sympy.Rational(-1, 2):
            return f"(1.0/{root})"
        if exp == sympy.Rational(3, 2):
            return f"({self._product(base, 1)}*{root})"
        if exp == sympy.Rational(-3, 2):
            return f"(1.0/({self._product(base, 1)}*{root}))"
        return super()._print_Pow(expr)
