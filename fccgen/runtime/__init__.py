"""Stage 6 of the pipeline: the compiled runtime (assembly, constrained solve, RK4 with
projection), driven by a generated kernel module. Never imports SymPy."""
from .solver import CompiledSolver

__all__ = ["CompiledSolver"]
