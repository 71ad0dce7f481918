"""Builds fccgen's own compiled runtime (the integrator and the constrained solve).

Generated kernel modules are built later, per model, by ``fccgen.build``.
"""
from Cython.Build import cythonize
from setuptools import Extension, setup

RUNTIME_MODULES = ("_solve", "_assemble", "_engine", "_rk4")   # in cimport order

extensions = [
    Extension(
        f"fccgen.runtime.{name}",
        [f"fccgen/runtime/{name}.pyx"],
        include_dirs=["fccgen/runtime"],
        extra_compile_args=["-O2"],
    )
    for name in RUNTIME_MODULES
]

setup(
    ext_modules=cythonize(extensions, language_level=3,
                          compiler_directives={"boundscheck": False, "wraparound": False,
                                               "cdivision": True, "initializedcheck": False}),
)
