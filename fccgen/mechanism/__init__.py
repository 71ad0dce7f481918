"""Stage 1b of the pipeline: the mechanism level (docs/design.md §2b). Joints and
pose-form bodies are lowered onto section 2's points, vectors and constraints, so
that plan, derive, the kernels and the solvers see one kind of model; drivers, loads
and events are written as expressions (expressions.py) and tables (tables.py)."""
from .lowering import Lowering, lower

__all__ = ["Lowering", "lower"]
