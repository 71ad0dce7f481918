"""Analyses built on a solver (compiled or numeric): static equilibrium,
linearization and natural frequencies. Imports point down: the solvers never import
this package."""
from .linearize import Linearization, linearize, state_from_z
from .modes import Modes, modes
from .statics import Equilibrium, statics

__all__ = ["Equilibrium", "statics", "Linearization", "linearize", "state_from_z",
           "Modes", "modes"]
