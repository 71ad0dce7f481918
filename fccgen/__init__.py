"""fccgen: compiled solvers of the fully-Cartesian-coordinate form of Kane's equations."""
__version__ = "0.1.0"
