"""Stage 3 of the pipeline: SymPy expressions of every kernel of an element class.

    derived = derive_class(cls)        # cls: fccgen.plan.ElementClass
    derived.kernels["mass_matrix"]     # column Matrix of row-major outputs, or None

Only this package and fccgen.printing import SymPy.
"""
from . import cables, joint_loads, mechanism  # noqa: F401  (registers drivers, loads, ...)
from .derived import DerivedClass, derive_class

__all__ = ["DerivedClass", "derive_class"]
