"""Stage 4 of the pipeline: derived kernels printed as C (SymPy CSE + C99 printer).

This package imports SymPy; the runtime path never imports it.
"""
from .c99 import KernelPrinter, slot_map
from .kernel import PrintedClass, PrintedKernel, print_class, print_kernel

__all__ = ["KernelPrinter", "PrintedClass", "PrintedKernel", "print_class", "print_kernel",
           "slot_map"]
