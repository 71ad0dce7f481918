"""Analyses built on a solver (compiled or numeric): static equilibrium,
linearization and natural frequencies. Imports point down: the solvers never import
this package."""
from .statics import Equilibrium, statics

__all__ = ["Equilibrium", "statics"]
