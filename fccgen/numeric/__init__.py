"""The numeric version: every quantity of the equations of motion in NumPy, written from
docs/elements.md independently of the symbolic path (no SymPy). It is the cross-check
of the compiled kernels and the baseline in benchmarks."""
from .constrained import constrained_solve
from .elements import ElementKernels, element_kernel, element_kernels
from . import cables, joint_loads, mechanism_kernels  # noqa: F401  (registers kinds)
from .solver import INTEGRATORS, NumericSolver

__all__ = ["ElementKernels", "INTEGRATORS", "NumericSolver", "constrained_solve",
           "element_kernel", "element_kernels"]
