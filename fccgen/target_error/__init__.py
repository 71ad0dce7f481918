"""Accuracy on demand (docs/design.md §11, docs/accuracy.md): ``simulate(error=E)``
chooses the method and its step or tolerance from a short measured pilot, runs, and
reports the run's estimated largest position error."""
from .run import simulate_to_error

__all__ = ["simulate_to_error"]
