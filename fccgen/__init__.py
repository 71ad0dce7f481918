"""fccgen: compiled solvers of the fully-Cartesian-coordinate form of Kane's equations.

    import fccgen
    solver = fccgen.load(fccgen.example_path("double_pendulum"))   # compiled, cached
    result = solver.simulate(t_end=2.0)

The runtime path (loading a cached module, simulating) never imports SymPy.
"""
from .version import __version__
from .api import generate, inverse_dynamics, load, load_numeric, simulate  # noqa: E402
from .example_models import example_names, example_path  # noqa: E402
from .progress import ProgressEvent  # noqa: E402
from .results.result import Result  # noqa: E402

__all__ = ["__version__", "generate", "load", "load_numeric", "simulate",
           "inverse_dynamics", "Result", "example_path", "example_names",
           "ProgressEvent"]
