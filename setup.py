"""Builds fccgen's own compiled runtime: the C engine (``fccgen/runtime/engine/*.c``,
plain C99: assembly, constrained solves, projections, events, integrators) and the
Cython modules that wrap it for Python.

The engine's C sources are compiled into every runtime extension with the same flags
as the Cython code; each extension holds its own copy, its symbols hidden
(``-fvisibility=hidden`` on GCC and Clang: only the module's init function is exported,
so no copy's symbol is seen from another module). Every ``fccgen/runtime/_*.pyx`` is built: first those named in CIMPORT_ORDER (each one
cimports only modules before it), then any other, in name order (integrators that
cimport only the engine). Generated kernel modules are built later, per model, by
``fccgen.build``.

The modules are compiled without debug information (``-g0`` after the interpreter's
own flags, which often carry ``-g``; GCC and Clang both take it) and with ``-O2``:
smaller libraries and a faster install. Each module prints one line as it is
compiled, which ``pip install -v .`` shows (plain pip hides a build's output).
"""
import sys
from pathlib import Path

from Cython.Build import cythonize
from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

CIMPORT_ORDER = ("_solve", "_assemble", "_engine",
                 "_events", "_power", "_sens")


def runtime_modules() -> list[str]:
    """Module names of every runtime .pyx, in a dependency-correct order."""
    runtime = Path(__file__).resolve().parent / "fccgen" / "runtime"
    found = sorted(p.stem for p in runtime.glob("_*.pyx"))
    return [m for m in CIMPORT_ORDER if m in found] + [m for m in found
                                                       if m not in CIMPORT_ORDER]


UNIX_COMPILE_ARGS = ["-g0", "-fvisibility=hidden"]   # last on the command line: -g0 wins
UNIX_LINK_ARGS = ["-g0"]


class QuietDebugBuild(build_ext):
    """build_ext that drops debug information on GCC/Clang (unix compilers) and says
    which module it compiles."""

    def build_extensions(self):
        self._done = 0
        if self.compiler.compiler_type == "unix":
            for ext in self.extensions:
                ext.extra_compile_args = [*ext.extra_compile_args, *UNIX_COMPILE_ARGS]
                ext.extra_link_args = [*ext.extra_link_args, *UNIX_LINK_ARGS]
        super().build_extensions()

    def build_extension(self, ext):
        self._done += 1
        print(f"fccgen: compiling {ext.name} ({self._done}/{len(self.extensions)})",
              file=sys.stderr, flush=True)
        super().build_extension(ext)


ENGINE = "fccgen/runtime/engine"
_HERE = Path(__file__).resolve().parent
ENGINE_SOURCES = sorted(f"{ENGINE}/{p.name}" for p in (_HERE / ENGINE).glob("*.c"))
ENGINE_HEADERS = sorted(f"{ENGINE}/{p.name}" for p in (_HERE / ENGINE).glob("*.h"))

extensions = [
    Extension(
        f"fccgen.runtime.{name}",
        [f"fccgen/runtime/{name}.pyx", *ENGINE_SOURCES],
        include_dirs=["fccgen/runtime", ENGINE],
        depends=ENGINE_HEADERS,
        extra_compile_args=["-O2"],
    )
    for name in runtime_modules()
]

setup(
    cmdclass={"build_ext": QuietDebugBuild},
    ext_modules=cythonize(extensions, language_level=3,
                          compiler_directives={"boundscheck": False, "wraparound": False,
                                               "cdivision": True, "initializedcheck": False}),
)
