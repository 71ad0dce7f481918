"""Printing of the parameter derivatives of an element class's kernels
(fccgen.derive.parameters): each is a kernel ``(q, v, p, out)`` with
``size(kernel) * n_p`` outputs, parameter-major, CSE over all of them together."""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from ..derive.parameters import (PARAMETER_KERNELS, dp_name, parameter_derivatives,
                                 tangent_jacobian)
from ..plan.kernels import KERNELS, KernelSpec
from .c99 import KernelPrinter, slot_map
from .kernel import PrintedKernel, print_kernel

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
class PrintedColumn:
    """One parameter's column of the tangent's matrix J (fcc_dp.h, ``column``): the
    n_q + 3 n_g numbers J[:, 2 n_q + c] at (q, v, p, a, lam), CSE over the column."""
    unused: tuple[str, ...]
    temporaries: tuple[tuple[str, str], ...]
    outputs: tuple[str, ...]                 # every row, "0.0" where J is zero
    n_ops: int


@dataclass(frozen=True)
class PrintedTangent:
    """The printed tangent kernel of a class (fccgen.derive.parameters), in parts:
    ``prepare`` (arguments PREPARE_ARGUMENTS) evaluates the nonzero entries of the
    state columns of the tangent's matrix J (those of dq and dv) that are not numbers
    into w[n_w], once per state; ``apply`` (arguments APPLY_ARGUMENTS) forms
    out[n_q + 3 n_g] = J_state [dq; dv] from them, once per direction; ``columns[c]``
    is the parameter p_c's column of J (None where it is zero), evaluated only for the
    parameters some design parameter moves (a key moves few of an element's numbers,
    and most elements' none)."""
    function: str
    prepare_unused: tuple[str, ...]
    temporaries: tuple[tuple[str, str], ...]
    weights: tuple[str, ...]                 # w[k] = weights[k]
    apply_unused: tuple[str, ...]
    outputs: tuple[str, ...]
    columns: tuple[PrintedColumn | None, ...]
    n_ops: int

    @property
    def n_w(self) -> int:
        return len(self.weights)


PREPARE_ARGUMENTS = ("q", "v", "p", "a", "lam")
APPLY_ARGUMENTS = ("dq", "dv")


def _column(J, col: int, arrays, slots, used) -> PrintedColumn | None:
    """Column ``col`` of J printed alone (None when it is zero)."""
    exprs = [J[r, col] for r in range(J.rows)]
    if all(e == 0 for e in exprs):
        return None
    live = [e for e in exprs if not e.is_Number]
    temps, reduced = sympy.cse(live, symbols=sympy.numbered_symbols("x", exclude=used))
    printer = KernelPrinter(slots)
    values = iter(reduced)
    outputs = tuple(printer.doprint(e if e.is_Number else next(values)) if e != 0
                    else "0.0" for e in exprs)
    seen = set().union(*(e.free_symbols for e in live), *(e.free_symbols for _, e in temps))
    n_ops = (sum(sympy.count_ops(e) for _, e in temps)
             + sum(sympy.count_ops(e) for e in reduced))
    return PrintedColumn(tuple(a for a in PREPARE_ARGUMENTS if not seen & set(arrays[a])),
                         tuple((str(x), printer.doprint(e)) for x, e in temps),
                         outputs, int(n_ops))


def print_tangent(derived) -> PrintedTangent:
    """CSE over the entries of the state columns of the tangent's matrix J together
    (the direction-independent part, printed once per state), then the products with
    the direction; each parameter's column printed alone."""
    inp, J = tangent_jacobian(derived)
    n = derived.cls.n_q
    arrays = {"q": derived.q, "v": derived.v, "p": derived.p, "a": inp.a,
              "lam": inp.lam, "dq": inp.dq, "dv": inp.dv, "dp": inp.dp}
    slots = slot_map(derived.q, derived.v, derived.p)
    for name in ("a", "lam", "dq", "dv", "dp"):
        slots.update({x: f"{name}[{k}]" for k, x in enumerate(arrays[name])})
    every = [J[r, c] for r in range(J.rows) for c in range(J.cols) if J[r, c] != 0]
    used = set().union(*(e.free_symbols for e in every)) if every else set()
    stray = used - set(slots)
    if stray:
        raise ValueError(f"{derived.cls.name}.tangent uses symbols that are not inputs: "
                         f"{sorted(map(str, stray))}")
    entries = [(r, c, J[r, c]) for r in range(J.rows) for c in range(2 * n)
               if J[r, c] != 0]
    stored = [e for _, _, e in entries if not e.is_Number]
    temps, reduced = sympy.cse(stored, symbols=sympy.numbered_symbols("x", exclude=used))
    weights: dict[sympy.Expr, sympy.Symbol] = {}      # equal entries share a slot
    for e in reduced:
        weights.setdefault(e, sympy.Symbol(f"w_{len(weights)}"))
    columns = tuple(_column(J, 2 * n + c, arrays, slots, used)
                    for c in range(derived.cls.n_p))
    slots.update({w: f"w[{k}]" for k, w in enumerate(weights.values())})
    direction = list(inp.dq) + list(inp.dv)
    rows = [sympy.S.Zero] * J.rows
    entry = iter(reduced)
    for r, c, e in entries:
        rows[r] += (e if e.is_Number else weights[next(entry)]) * direction[c]
    printer = KernelPrinter(slots)
    state = set().union(*(e.free_symbols for _, _, e in entries)) if entries else set()
    in_prepare = state.union(*(e.free_symbols for _, e in temps))
    in_apply = set().union(*(e.free_symbols for e in rows))
    n_ops = (sum(sympy.count_ops(e) for _, e in temps)
             + sum(sympy.count_ops(e) for e in weights)
             + sum(sympy.count_ops(e) for e in rows)
             + sum(c.n_ops for c in columns if c is not None))
    return PrintedTangent(
        f"{derived.cls.name}_tangent",
        tuple(a for a in PREPARE_ARGUMENTS if not in_prepare & set(arrays[a])),
        tuple((str(x), printer.doprint(e)) for x, e in temps),
        tuple(printer.doprint(e) for e in weights),
        tuple(a for a in APPLY_ARGUMENTS if not in_apply & set(arrays[a])),
        tuple(printer.doprint(e) for e in rows), columns, int(n_ops))


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
