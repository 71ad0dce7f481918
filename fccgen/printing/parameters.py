"""Printing of the parameter derivatives of an element class's kernels
(fccgen.derive.parameters): each is a kernel ``(q, v, p, out)`` with
``size(kernel) * n_p`` outputs, parameter-major, CSE over all of them together."""
from __future__ import annotations

from ..derive.parameters import PARAMETER_KERNELS, dp_name, parameter_derivatives
from ..plan.kernels import KERNELS, KernelSpec
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


class PrintedDp:
    """The printed d/dp kernels of one element class, for the dp template."""

    def __init__(self, cls, kernels: dict[str, PrintedKernel | None]):
        self.cls = cls
        self.kernels = kernels

    @property
    def name(self) -> str:
        return self.cls.name

    @property
    def n_ops(self) -> int:
        return sum(k.n_ops for k in self.kernels.values() if k is not None)
