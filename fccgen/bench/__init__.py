"""What ``fccgen bench`` measures: the speed of a model's compiled and NumPy versions
(``speed``) and the work-precision ladder of every method (``accuracy``, reported by
``accuracy_report``)."""
from .speed import BenchReport, bench_model

__all__ = ["BenchReport", "bench_model"]
