"""Printing of the parameter derivatives of an element class's kernels
(fccgen.derive.parameters): each is a kernel ``(q, v, p, out)`` with
``size(kernel) * n_p`` outputs, parameter-major, CSE over all of them together."""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from ..derive.parameters import (PARAMETER_KERNELS, dp_name, parameter_derivatives,
                                 tangent_kernel)
from ..plan.kernels import KERNELS, KernelSpec
from .c99 import KernelPrinter, slot_map
from .kernel import PrintedKernel, print_kernel

TANGENT_ARGUMENTS = ("q", "v", "p", "a", "lam", "dq", "dv", "dp")

_BASE = {k.name: k for k in KERNELS}


def dp_spec(kernel: str) -> KernelSpec:
    """The KernelSpec of d/dp of ``kernel`` (every one reads q, v and p)."""
    base = _BASE[kernel]
    return KernelSpec(dp_name(kernel), True, lambda c: base.size(c) * c.n_p,
                      f"d/dp_j of {kernel} ({base.equation}), parameter-major")


def print_parameter_kernels(derived) -> dict[str, PrintedKernel | None]:
    """``{kernel: printed d/dp kernel or None}`` for every kernel of PARAMETER_KERNELS."""
    exprs = parameter_derivatives(derived)
    return {k: (None if exprs[dp_name(k)] is None
                else print_kernel(dp_spec(k), derived, exprs[dp_name(k)]))
            for k in PARAMETER_KERNELS}


@dataclass(frozen=True)
class PrintedTangent:
    """The printed tangent kernel of a class (fccgen.derive.parameters.tangent_kernel):
    arguments TANGENT_ARGUMENTS, out[n_q + 3 n_g]."""
    function: str
    unused: tuple[str, ...]
    temporaries: tuple[tuple[str, str], ...]
    outputs: tuple[str, ...]
    n_ops: int


def print_tangent(derived) -> PrintedTangent:
    """CSE over the tangent kernel's outputs together, then print them."""
    inp, matrix = tangent_kernel(derived)
    exprs = list(matrix)
    arrays = {"q": derived.q, "v": derived.v, "p": derived.p, "a": inp.a,
              "lam": inp.lam, "dq": inp.dq, "dv": inp.dv, "dp": inp.dp}
    slots = slot_map(derived.q, derived.v, derived.p)
    for name in ("a", "lam", "dq", "dv", "dp"):
        slots.update({x: f"{name}[{k}]" for k, x in enumerate(arrays[name])})
    used = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
    stray = used - set(slots)
    if stray:
        raise ValueError(f"{derived.cls.name}.tangent uses symbols that are not inputs: "
                         f"{sorted(map(str, stray))}")
    unused = tuple(a for a in TANGENT_ARGUMENTS if not used & set(arrays[a]))
    temps, reduced = sympy.cse(exprs, symbols=sympy.numbered_symbols("x", exclude=used))
    printer = KernelPrinter(slots)
    n_ops = (sum(sympy.count_ops(e) for _, e in temps)
             + sum(sympy.count_ops(e) for e in reduced))
    return PrintedTangent(f"{derived.cls.name}_tangent", unused,
                          tuple((str(x), printer.doprint(e)) for x, e in temps),
                          tuple(printer.doprint(e) for e in reduced), int(n_ops))


class PrintedDp:
    """The printed d/dp kernels and the tangent kernel of one element class, for the
    dp template."""

    def __init__(self, cls, kernels: dict[str, PrintedKernel | None],
                 tangent: PrintedTangent):
        self.cls = cls
        self.kernels = kernels
        self.tangent = tangent

    @property
    def name(self) -> str:
        return self.cls.name

    @property
    def n_ops(self) -> int:
        return (sum(k.n_ops for k in self.kernels.values() if k is not None)
                + self.tangent.n_ops)
