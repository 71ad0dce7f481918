"""The result of the derivation stage: the kernel expressions of one element class."""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from ..plan.classes import ElementClass
from ..plan.kernels import KERNEL_NAMES, KERNELS
from .elements import BUILDERS
from .symbols import class_symbols


@dataclass
class DerivedClass:
    """Kernel expressions of an element class, in the layouts of fccgen.plan.classes.

    ``kernels`` has every name of KERNEL_NAMES: a column Matrix of the row-major
    outputs (KernelSpec.size of them) in the symbols ``q``, ``v``, ``p``, or None when
    the kernel does not apply to the class or every output is structurally zero.
    ``p[k]`` is ``cls.param_names[k]``; kernels with ``uses_v=False`` hold no ``v``.
    """
    cls: ElementClass
    q: tuple[sympy.Symbol, ...]
    v: tuple[sympy.Symbol, ...]
    p: tuple[sympy.Symbol, ...]
    kernels: dict[str, sympy.Matrix | None]


def derive_class(cls: ElementClass) -> DerivedClass:
    """Build the kernel expressions of ``cls`` (no simplification: plain trees for CSE)."""
    s = class_symbols(cls)
    outputs = BUILDERS[cls.kind](s)
    unknown = set(outputs) - set(KERNEL_NAMES)
    if unknown:
        raise AssertionError(f"{cls.kind}: builder returned unknown kernels {sorted(unknown)}")
    kernels: dict[str, sympy.Matrix | None] = {}
    for spec in KERNELS:
        size = spec.size(cls)
        exprs = outputs.get(spec.name)
        if size == 0 or exprs is None or all(e == 0 for e in exprs):
            kernels[spec.name] = None
            continue
        if len(exprs) != size:
            raise AssertionError(f"{cls.name}: {spec.name} has {len(exprs)} outputs, "
                                 f"expected {size}")
        kernels[spec.name] = sympy.Matrix(exprs)
    return DerivedClass(cls, s.q, s.v, s.p, kernels)
