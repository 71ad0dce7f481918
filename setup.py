"""Builds fccgen's own compiled runtime (the integrator and the constrained solve).

Generated kernel modules are built later, per model, by ``fccgen.build``.
"""
from Cython.Build import cythonize
from setuptools import Extension, setup

extensions = [
    Extension(
        "fccgen.runtime._engine",
        ["fccgen/runtime/_engine.pyx"],
        include_dirs=["fccgen/runtime"],
        extra_compile_args=["-O2"],
    ),
]

setup(
    ext_modules=cythonize(extensions, language_level=3,
                          compiler_directives={"boundscheck": False, "wraparound": False,
                                               "cdivision": True, "initializedcheck": False}),
)
