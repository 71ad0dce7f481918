"""Compiling generated sources into an extension module, and putting it in place.

The build runs in a fresh temporary folder next to the target (same filesystem), as a
subprocess of this interpreter on the generated build script, with ``cwd=`` that
folder. Only a successful build is moved into ``<out_dir>/<name>/``: sources first,
then the module under a name tagged with its cache key (linked to its plain name
``<name><EXT_SUFFIX>`` for a plain import), then the manifest. A failed build leaves
the target untouched and keeps its sources and log in ``<out_dir>/<name>.failed-build/``.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import uuid
from pathlib import Path

from ..errors import BuildError
from .cache import write_manifest

# Above this many operations (after CSE) in kernels.c, compile at -O1: optimising huge
# generated files costs far more compile time and memory than it gains at run time.
LARGE_FILE_OPS = 20000
BASE_COMPILE_ARGS = ("-Wall", "-g0")    # -g0 cancels the interpreter's default -g
LINK_ARGS = ("-g0",)
FLAG_POLICY = {"base": list(BASE_COMPILE_ARGS), "default": "-O2", "large": "-O1",
               "large_ops": LARGE_FILE_OPS, "link": list(LINK_ARGS)}
BUILD_SCRIPT = "build_module.py"
BUILD_LOG = "build.log"
# Lines of compiler output quoted in a BuildError; the full output is in the log.
MAX_MESSAGE_LINES = 400


def compile_args(n_ops: int) -> list[str]:
    """Compiler flags for a kernels.c file with ``n_ops`` operations."""
    opt = FLAG_POLICY["large"] if n_ops > LARGE_FILE_OPS else FLAG_POLICY["default"]
    return [opt, *BASE_COMPILE_ARGS]


def link_args() -> list[str]:
    return list(LINK_ARGS)


def ext_suffix() -> str:
    return sysconfig.get_config_var("EXT_SUFFIX") or ".so"


def extension_filename(module_name: str, key: str) -> str:
    """File name of a built module: tagged with its cache key, so that a rebuilt module
    never has the path of one the process may already have loaded."""
    return f"{module_name}-{key[:16]}{ext_suffix()}"


def failed_dir(out_dir: Path, module_name: str) -> Path:
    return Path(out_dir) / f"{module_name}.failed-build"


def _excerpt(output: str) -> str:
    """The compiler output for a message: all of it, or its error lines and its end."""
    lines = output.splitlines()
    if len(lines) <= MAX_MESSAGE_LINES:
        return output
    errors = [line for line in lines if "error" in line.lower()][:MAX_MESSAGE_LINES // 4]
    tail = lines[-(MAX_MESSAGE_LINES // 2):]
    return "\n".join([*errors, f"[... {len(lines)} lines in all ...]", *tail])


def _fail(tmp: Path, out_dir: Path, module_name: str, why: str, output: str):
    """Keep the failed build under a clearly named folder and raise BuildError."""
    kept = failed_dir(out_dir, module_name)
    shutil.rmtree(kept, ignore_errors=True)
    os.replace(tmp, kept)
    target = Path(out_dir) / module_name
    previous = f"; the previous build in {target} is unchanged" if target.exists() else ""
    raise BuildError(
        f"building the module of model {module_name!r} failed: {why}.\n"
        f"Sources and the full log are kept in {kept}{previous}.\n"
        f"--- compiler output ---\n{_excerpt(output)}")


def compile_sources(sources: dict[str, str], out_dir: Path, module_name: str) -> Path:
    """Write the sources into a fresh folder inside ``out_dir`` and compile them.

    Returns the folder, holding ``<module_name><EXT_SUFFIX>`` and the compiler's
    output in ``build.log``. Raises BuildError, with that output, when the build fails.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{module_name}.build-", dir=out_dir))
    try:
        for name, text in sources.items():
            (tmp / name).write_text(text, encoding="utf-8")
        try:
            run = subprocess.run([sys.executable, BUILD_SCRIPT], cwd=tmp,
                                 capture_output=True, text=True, errors="replace")
        except OSError as exc:
            _fail(tmp, out_dir, module_name, f"cannot run {sys.executable}: {exc}", "")
        output = run.stdout + run.stderr
        (tmp / BUILD_LOG).write_text(output, encoding="utf-8")
        if run.returncode != 0:
            _fail(tmp, out_dir, module_name, f"exit status {run.returncode}", output)
        if not (tmp / f"{module_name}{ext_suffix()}").is_file():
            _fail(tmp, out_dir, module_name, "the build produced no extension module",
                  output)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)     # nothing left if _fail did not keep it
        raise
    return tmp


def _link_plain_name(extension: Path, plain: Path) -> None:
    """Make the module importable by a plain ``import <name>`` from its folder too
    (a hard link, or a copy where links are not possible)."""
    tmp = plain.with_name(f".{plain.name}.{uuid.uuid4().hex}")
    try:
        os.link(extension, tmp)
    except OSError:
        shutil.copy2(extension, tmp)
    os.replace(tmp, plain)


def install(tmp: Path, out_dir: Path, module_name: str, sources: list[str],
            manifest: dict) -> Path:
    """Move a successful build from ``tmp`` into ``<out_dir>/<module_name>/``.

    Every step is an atomic rename; the manifest, which makes the build visible to the
    cache, comes last, and superseded modules are removed after it. Returns the path
    of the installed module.
    """
    target = Path(out_dir) / module_name
    target.mkdir(parents=True, exist_ok=True)
    try:
        for name in [*sources, BUILD_LOG]:
            os.replace(tmp / name, target / name)
        extension = target / manifest["extension"]
        os.replace(tmp / f"{module_name}{ext_suffix()}", extension)
        _link_plain_name(extension, target / f"{module_name}{ext_suffix()}")
        write_manifest(target, manifest)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    for old in target.glob(f"{module_name}-*{ext_suffix()}"):
        if old != extension:
            old.unlink(missing_ok=True)
    shutil.rmtree(failed_dir(out_dir, module_name), ignore_errors=True)
    return extension
