"""Stage 6 of the pipeline: a model's compiled, importable module, cached by content.

``build_module(plan)`` derives, prints, renders and compiles the kernels of the plan's
element classes into ``<out_dir>/<name>/``, unless that folder already holds a build
with the same cache key: then nothing is derived or compiled, and SymPy is not even
imported (see :mod:`fccgen.build.cache` for what the key covers). Numbers such as
masses and lengths are runtime parameters, so changing them keeps the cache valid.
"""
from __future__ import annotations

import importlib.util
import itertools
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from .. import __version__
from ..errors import BuildError
from .cache import (HEADER, MANIFEST, cache_key, cached_manifest, read_manifest,
                    runtime_header, structure_hash, tool_versions)
from .compile import (FLAG_POLICY, compile_args, compile_sources, extension_filename,
                      install, link_args)

Progress = Callable[[str], None]
STAGES = ("derive", "print", "render", "compile")


@dataclass(frozen=True)
class BuiltModule:
    """Where a model's module is and how it was obtained."""
    path: Path                    # the extension module (.so)
    directory: Path               # <out_dir>/<name>/: sources, module, manifest
    module_name: str              # the model name
    structure_hash: str
    cache_key: str
    cache_hit: bool
    timings: dict[str, float]     # seconds: derive, print, render, compile, total
    n_ops: dict[str, int]         # per class name: operations after CSE
    flags: tuple[str, ...]        # compiler flags of the build


def _quiet(_message: str) -> None:
    """Default progress callback: says nothing."""


def _classes(n: int) -> str:
    return f"{n} element class{'es' if n != 1 else ''}"


def _built(directory: Path, manifest: dict, hit: bool, timings: dict) -> BuiltModule:
    return BuiltModule(path=directory / manifest["extension"], directory=directory,
                       module_name=manifest["model_name"],
                       structure_hash=manifest["structure_hash"],
                       cache_key=manifest["cache_key"], cache_hit=hit, timings=timings,
                       n_ops=dict(manifest["n_ops"]), flags=tuple(manifest["flags"]))


def build_module(plan, out_dir="generated", *, force: bool = False,
                 progress: Progress | None = None) -> BuiltModule:
    """Build (or reuse) the compiled kernel module of a ``fccgen.plan.Plan``."""
    classes = list(plan.classes)
    say = progress or _quiet

    def derive_all():
        from ..derive import derive_class
        say(f"deriving {_classes(len(classes))}")
        derived = []
        for k, cls in enumerate(classes, 1):
            say(f"deriving class {k}/{len(classes)}: {cls.name} ({cls.describe()})")
            derived.append(derive_class(cls))
        return derived

    return _build(plan.model.name, classes, Path(out_dir).absolute(), derive_all, "", force,
                  say)


def build_derived(model_name: str, derived: list, out_dir="generated", *,
                  force: bool = False, progress: Progress | None = None) -> BuiltModule:
    """Build a module from classes derived elsewhere (``DerivedClass``-like objects).

    For kernels written by hand (tests) or by another derivation: the cache key then
    also covers the expressions themselves.
    """
    import sympy

    extra = "\n".join(sympy.srepr((d.q, d.v, d.p, sorted(d.kernels.items())))
                      for d in derived)
    classes = [d.cls for d in derived]
    return _build(model_name, classes, Path(out_dir).absolute(), lambda: list(derived),
                  extra, force, progress or _quiet)


class _Stopwatch:
    """Seconds spent in each stage of a build."""

    def __init__(self):
        self.start = self.last = time.perf_counter()
        self.timings: dict[str, float] = {}

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        self.timings[stage] = now - self.last
        self.last = now

    def total(self) -> dict[str, float]:
        self.timings["total"] = time.perf_counter() - self.start
        return self.timings


def _generate(model_name: str, derived: list, say: Progress, watch: _Stopwatch):
    """Print and render: (sources by file name, operations per class, compiler flags)."""
    from ..printing import print_class
    from ..render import render_sources

    say(f"printing C for {_classes(len(derived))}")
    printed = [print_class(d) for d in derived]
    n_ops = {p.name: p.n_ops for p in printed}
    flags = compile_args(sum(n_ops.values()))
    watch.lap("print")
    say("rendering sources")
    s_hash = structure_hash([d.cls for d in derived])
    sources = render_sources(model_name, s_hash, printed, flags, link_args())
    sources[HEADER] = runtime_header()
    watch.lap("render")
    return sources, n_ops, flags


def _build(model_name: str, classes: list, out_dir: Path, derive_all, extra: str,
           force: bool, say: Progress) -> BuiltModule:
    """Serve the build from the cache, or derive, print, render, compile, install."""
    watch = _Stopwatch()
    key = cache_key(model_name, classes, FLAG_POLICY, extra)
    directory = out_dir / model_name
    manifest = None if force else cached_manifest(directory, key)
    if manifest is not None:
        say(f"{model_name}: unchanged structure, using the cached build in {directory}")
        watch.timings.update(dict.fromkeys(STAGES, 0.0))
        return _built(directory, manifest, True, watch.total())

    derived = derive_all()
    if [d.cls for d in derived] != list(classes):
        raise BuildError(f"{model_name}: derived classes do not match the plan's classes")
    watch.lap("derive")
    sources, n_ops, flags = _generate(model_name, derived, say, watch)
    say(f"compiling {model_name} ({sum(n_ops.values())} operations, {' '.join(flags)})")
    tmp = compile_sources(sources, out_dir, model_name)
    watch.lap("compile")
    manifest = {
        "fccgen_version": __version__, "versions": tool_versions(),
        "model_name": model_name, "cache_key": key,
        "structure_hash": structure_hash(classes),
        "class_keys": [c.key for c in classes], "class_names": [c.name for c in classes],
        "n_ops": n_ops, "flags": flags, "timings": watch.total(),
        "extension": extension_filename(model_name, key), "sources": sorted(sources),
    }
    install(tmp, out_dir, model_name, sorted(sources), manifest)
    say(f"built {directory / manifest['extension']}")
    return _built(directory, manifest, False, watch.timings)


_loads = itertools.count()


def load_module(built: BuiltModule | str | os.PathLike):
    """Import a built module (a BuiltModule, or the folder of one) from its file.

    Each call imports under a new, unique module name, and every build has its own
    file name, so a module rebuilt in the same process is never a stale import.
    """
    if not isinstance(built, BuiltModule):
        directory = Path(built)
        manifest = read_manifest(directory)
        if manifest is None:
            raise BuildError(f"{directory} holds no built module (no readable {MANIFEST})")
        built = _built(directory, manifest, True, {})
    # The last part of the name must be the module's own: it names its init function.
    unique = f"_fccgen_models.load{next(_loads)}_{built.cache_key[:16]}.{built.module_name}"
    spec = importlib.util.spec_from_file_location(unique, built.path)
    if spec is None or spec.loader is None:
        raise BuildError(f"cannot import {built.path}")
    had_plain_name = built.module_name in sys.modules
    module = importlib.util.module_from_spec(spec)
    sys.modules[unique] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[unique]
        raise
    finally:
        # A Cython module also registers itself under its plain name; drop that entry,
        # or a later plain import would find this build, however old it gets.
        if not had_plain_name and sys.modules.get(built.module_name) is module:
            del sys.modules[built.module_name]
    return module


__all__ = ["BuiltModule", "build_derived", "build_module", "load_module", "structure_hash"]
