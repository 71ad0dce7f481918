"""The symbols of an element class: local coordinates q, speeds v and parameters p,
and the symbolic value of every scalar and triple the element's equations name.

Layouts follow :mod:`fccgen.plan.classes`: ``q``/``v`` hold the moving triples in
``triple_names`` order, ``p[k]`` is ``cls.param_names[k]``. A fixed triple is three
parameters with zero speed; a scalar named in ``cls.zeros`` is the number 0, so the
terms it multiplies vanish while the expressions are built (structural zeros).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import sympy

from ..plan.classes import ElementClass

# A linear map from local speeds, kept per triple: triple name -> (rows x 3) block.
# Only moving triples have blocks; a missing block is zero.
Lin = dict[str, sympy.Matrix]


@dataclass(frozen=True)
class Triple:
    """A point or unit vector of the element: position, velocity, and whether its
    coordinates are generalized coordinates (moving) or parameters (fixed)."""
    name: str
    pos: sympy.Matrix            # 3 x 1
    vel: sympy.Matrix            # 3 x 1, zero when fixed
    moving: bool


class ClassSymbols:
    """Symbols q, v, p of one element class and lookups by name."""

    def __init__(self, cls: ElementClass):
        self.cls = cls
        self.q = tuple(sympy.symbols(f"q0:{cls.n_q}")) if cls.n_q else ()
        self.v = tuple(sympy.symbols(f"v0:{cls.n_q}")) if cls.n_q else ()
        self.p = tuple(sympy.symbols(f"p0:{cls.n_p}")) if cls.n_p else ()
        self._param = dict(zip(cls.param_names, self.p))

    @cached_property
    def offsets(self) -> dict[str, int]:
        """Column offset of every moving triple in the local coordinates."""
        return {name: 3 * k for k, name in enumerate(self.cls.moving_triples)}

    def scalar(self, name: str) -> sympy.Expr:
        """A scalar parameter, or 0 when the class folds it as a structural zero."""
        if name in self.cls.zeros:
            return sympy.S.Zero
        return self._param[name]

    def triple(self, name: str) -> Triple:
        """A triple of ``cls.triple_names``: q/v symbols if moving, parameters if fixed."""
        if name in self.offsets:
            k = self.offsets[name]
            return Triple(name, sympy.Matrix(self.q[k:k + 3]),
                          sympy.Matrix(self.v[k:k + 3]), True)
        pos = sympy.Matrix([self._param[f"{name}.{c}"] for c in "xyz"])
        return Triple(name, pos, sympy.zeros(3, 1), False)

    def local(self, lin: Lin, rows: int) -> sympy.Matrix:
        """The ``rows x n_q`` matrix of a per-triple linear map, in local columns."""
        out = sympy.zeros(rows, self.cls.n_q)
        for name, block in lin.items():
            k = self.offsets[name]
            out[:, k:k + 3] = out[:, k:k + 3] + block
        return out


def class_symbols(cls: ElementClass) -> ClassSymbols:
    """The symbols of ``cls`` (q0.., v0.., p0..) and its scalar/triple lookups."""
    return ClassSymbols(cls)
