"""Builds fccgen's own compiled runtime (the constrained solve, the engine, the
integrators).

Every ``fccgen/runtime/_*.pyx`` is built: first those named in CIMPORT_ORDER (each one
cimports only modules before it), then any other, in name order (integrators that
cimport only the engine). Generated kernel modules are built later, per model, by
``fccgen.build``.
"""
from pathlib import Path

from Cython.Build import cythonize
from setuptools import Extension, setup

CIMPORT_ORDER = ("_solve", "_assemble", "_engine", "_ldl", "_sparse_blocks", "_al_refine",
                 "_events")


def runtime_modules() -> list[str]:
    """Module names of every runtime .pyx, in a dependency-correct order."""
    runtime = Path(__file__).resolve().parent / "fccgen" / "runtime"
    found = sorted(p.stem for p in runtime.glob("_*.pyx"))
    return [m for m in CIMPORT_ORDER if m in found] + [m for m in found
                                                       if m not in CIMPORT_ORDER]


extensions = [
    Extension(
        f"fccgen.runtime.{name}",
        [f"fccgen/runtime/{name}.pyx"],
        include_dirs=["fccgen/runtime"],
        extra_compile_args=["-O2"],
    )
    for name in runtime_modules()
]

setup(
    ext_modules=cythonize(extensions, language_level=3,
                          compiler_directives={"boundscheck": False, "wraparound": False,
                                               "cdivision": True, "initializedcheck": False}),
)
