"""Stage 6 of the pipeline: the compiled runtime (assembly, constrained solve, RK4 with
projection), driven by a generated kernel module. Never imports SymPy.

The runtime's own compiled modules (``_assemble``, ``_engine``, ...) are built when
fccgen is installed. A Python started in the repository's root imports the source
folder ``fccgen/`` instead of the installed package, and that folder has no compiled
modules unless they were built in place: :func:`missing_runtime` turns the bare
``ModuleNotFoundError`` into an ImportError that says so and what to do.
"""
from __future__ import annotations

import importlib.machinery
import os
import sys
from pathlib import Path


def _installed_elsewhere(package_dir: Path) -> str | None:
    """The folder of another fccgen on sys.path than the one in ``package_dir``."""
    here = package_dir.resolve()
    for entry in sys.path:
        base = Path(entry or os.getcwd())
        if (base / "fccgen").resolve() == here:
            continue
        spec = importlib.machinery.PathFinder.find_spec("fccgen", [str(base)])
        if spec is not None and spec.origin:
            return str(Path(spec.origin).parent)
    return None


def missing_runtime(exc: ModuleNotFoundError) -> ImportError:
    """The ImportError for a compiled runtime module that is not there."""
    package_dir = Path(__file__).resolve().parent.parent
    elsewhere = _installed_elsewhere(package_dir)
    shadow = (f"fccgen was imported from {package_dir}, a source folder, which shadows "
              f"the installed fccgen in {elsewhere}" if elsewhere else
              f"fccgen was imported from {package_dir}")
    return ImportError(
        f"{shadow}; its compiled runtime ({exc.name}) is not built there. To fix it, "
        f"start Python in another folder than {package_dir.parent} (the installed "
        "package is then used), or build the runtime in this folder: pip install -e . "
        "(or python setup.py build_ext --inplace)", name=exc.name)


try:
    from .solver import CompiledSolver
except ModuleNotFoundError as _exc:
    if not (_exc.name or "").startswith(f"{__name__}._"):
        raise
    raise missing_runtime(_exc) from _exc

__all__ = ["CompiledSolver"]
