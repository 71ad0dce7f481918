"""Stage 6 of the pipeline: a model's compiled, importable module, cached by content.

``build_module(plan)`` derives, prints, renders and compiles the kernels of the plan's
element classes into ``<out_dir>/<name>/<key16>/``, unless that folder already holds a
sound build with the same cache key: then nothing is derived or compiled, and SymPy is
not even imported (see :mod:`fccgen.build.cache` for what the key covers). Numbers such
as masses and lengths are runtime parameters, so changing them keeps the cache valid.

A cache entry is trusted only if its manifest has every entry, names this model and
key, and the sha256 of its module files matches the one recorded at build time; a
damaged, incomplete or foreign entry is rebuilt with a :class:`CacheRepairWarning`.
:mod:`fccgen.build.store` describes the layout and the locking between processes.
"""
from __future__ import annotations

import dataclasses
import importlib.util
import itertools
import os
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ..version import __version__
from ..errors import BuildError, CacheRepairWarning, HostError
from .cache import (HEADER, MANIFEST, cache_key, check_entry, files_problem,
                    manifest_problem, read_manifest, runtime_header, structure_hash,
                    tool_versions)
from .compile import (FLAG_POLICY, compile_args, compile_sources, extension_filename,
                      install, link_args, require_compiler)
from ..progress import Reporter
from .store import build_lock, clean_legacy, clean_stale, entry_dir

Progress = Callable[[str], None]     # called with fccgen.progress.ProgressEvent
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
    say = Reporter(progress, "build")

    def derive_all():
        from ..derive import derive_class
        n = len(classes)
        say(f"deriving {_classes(n)}", stage="derive", done=0, total=n)
        derived = []
        for k, cls in enumerate(classes, 1):
            say(f"deriving class {k}/{n}: {cls.name} ({cls.describe()})", stage="derive",
                done=k - 1, total=n)
            derived.append(derive_class(cls))
        say(f"derived {_classes(n)}", stage="derive", done=n, total=n)
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
                  extra, force, Reporter(progress, "build"))


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


def _generate(model_name: str, derived: list, say: Reporter, watch: _Stopwatch):
    """Print and render: (sources by file name, operations per class, compiler flags)."""
    from ..printing import print_class
    from ..render import render_sources

    n = len(derived)
    say(f"printing C for {_classes(n)}", stage="print", done=0, total=n)
    printed = []
    for k, d in enumerate(derived, 1):
        printed.append(print_class(d))
        say(f"printed C for class {k}/{n}", stage="print", done=k, total=n)
    n_ops = {p.name: p.n_ops for p in printed}
    flags = compile_args(sum(n_ops.values()))
    watch.lap("print")
    say("rendering sources", stage="render")
    s_hash = structure_hash([d.cls for d in derived])
    sources = render_sources(model_name, s_hash, printed, flags, link_args())
    sources[HEADER] = runtime_header()
    watch.lap("render")
    return sources, n_ops, flags


def _cached(model_name: str, key: str, entry: Path, force: bool, say: Reporter,
            watch: _Stopwatch) -> tuple[BuiltModule | None, str | None]:
    """(the cached build, None), or (None, what is wrong with the entry, if anything)."""
    if force:
        return None, None
    manifest, problem = check_entry(entry, key, model_name)
    if manifest is None:
        return None, problem
    say(f"{model_name}: unchanged structure, using the cached build in {entry}",
        stage="cache")
    watch.timings.update(dict.fromkeys(STAGES, 0.0))
    return _built(entry, manifest, True, watch.total()), None


def _build(model_name: str, classes: list, out_dir: Path, derive_all, extra: str,
           force: bool, say: Reporter) -> BuiltModule:
    """Serve the build from the cache, or derive, print, render, compile, install."""
    watch = _Stopwatch()
    key = cache_key(model_name, classes, FLAG_POLICY, extra)
    entry = entry_dir(out_dir, model_name, key)
    clean_stale(entry.parent)
    clean_legacy(out_dir, model_name)
    hit, problem = _cached(model_name, key, entry, force, say, watch)
    if hit is not None:
        return hit
    try:
        with build_lock(entry):     # one build of a key at a time; others wait, then hit
            hit, problem = _cached(model_name, key, entry, force, say, watch)
            if hit is not None:
                return hit
            if problem is not None:
                warnings.warn(CacheRepairWarning(
                    f"the cached module in {entry} is damaged or incomplete ({problem}); "
                    "rebuilding it"), stacklevel=3)
            return _compile_and_install(model_name, classes, key, entry, derive_all,
                                        say, watch)
    except HostError as exc:
        if problem is None:
            raise
        raise HostError(f"the cached module in {entry} is damaged ({problem}) and "
                        f"cannot be rebuilt: {exc}", errno=exc.errno) from None


def _compile_and_install(model_name: str, classes: list, key: str, entry: Path,
                         derive_all, say: Reporter, watch: _Stopwatch) -> BuiltModule:
    require_compiler()              # before the derivation: it can take long
    derived = derive_all()
    if [d.cls for d in derived] != list(classes):
        raise BuildError(f"{model_name}: derived classes do not match the plan's classes")
    watch.lap("derive")
    sources, n_ops, flags = _generate(model_name, derived, say, watch)
    say(f"compiling {model_name} ({sum(n_ops.values())} operations, {' '.join(flags)})",
        stage="compile")
    tmp = compile_sources(sources, entry, model_name)
    watch.lap("compile")
    manifest = {
        "fccgen_version": __version__, "versions": tool_versions(),
        "model_name": model_name, "cache_key": key,
        "structure_hash": structure_hash(classes),
        "class_keys": [c.key for c in classes], "class_names": [c.name for c in classes],
        "n_ops": n_ops, "flags": flags, "timings": watch.total(),
        "extension": extension_filename(model_name), "sources": sorted(sources),
    }
    install(tmp, entry, model_name, manifest)
    say(f"built {entry / manifest['extension']}", stage="compile")
    return _built(entry, manifest, False, watch.timings)


_loads = itertools.count()


def _refuse(directory: Path, problem: str):
    raise BuildError(f"the module in {directory} cannot be imported: {problem}. Build it "
                     "again (fccgen MODEL --force, or build_module(plan, force=True)).")


def load_module(built: BuiltModule | str | os.PathLike):
    """Import a built module (a BuiltModule, or the folder of one) from its file.

    The module files are checked against the sha256 in the manifest first: a damaged
    module is never loaded (it can crash the process). Each call imports under a new,
    unique module name, and every build has its own file name, so a module rebuilt in
    the same process is never a stale import.
    """
    if isinstance(built, BuiltModule):
        directory = built.directory
        manifest = read_manifest(directory)
        problem = manifest_problem(manifest, built.cache_key, built.module_name)
        if problem is None and manifest["extension"] != built.path.name:
            # rebuilt meanwhile (--force elsewhere): the same key, so the same code
            built = dataclasses.replace(built, path=directory / manifest["extension"])
    else:
        directory = Path(built)
        manifest = read_manifest(directory)
        if manifest is None:
            raise BuildError(f"{directory} holds no built module (no readable {MANIFEST})")
        problem = manifest_problem(manifest, manifest.get("cache_key"),
                                   manifest.get("model_name"))
        if problem is None:
            built = _built(directory, manifest, True, {})
    if problem is None:
        problem = files_problem(directory, manifest)
    if problem is not None:
        _refuse(directory, problem)
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
