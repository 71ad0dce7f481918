"""Compiling generated sources into an extension module, and preparing it for the cache.

The build runs in a fresh temporary folder of the model's build folder (same
filesystem), as a subprocess of this interpreter on the generated build script, with
``cwd=`` that folder. Only a successful build becomes a cache entry (see
:mod:`fccgen.build.store`): the module is named ``<name>-<id><EXT_SUFFIX>``, unique per
build so that a rebuilt module never has the path of one the process may already have
loaded, and linked to its plain name ``<name><EXT_SUFFIX>`` for a plain import; the
manifest records the sha256 of both. A failed build keeps its sources and log in
``<key16>.failed-build/`` next to the entry.

Problems of the machine rather than of the model end in a HostError that says what to
do: no C compiler, a build folder that cannot be written, a full disk (then the tail of
the compiler's output is in the message, since its log may not have been written).
"""
from __future__ import annotations

import errno
import os
import shlex
import shutil
import subprocess
import sys
import sysconfig
import uuid
from pathlib import Path

from ..errors import BuildError, HostError
from .cache import file_hashes, write_manifest
from .store import failed_dir, new_temp_dir, put_in_place

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
# Lines of compiler output quoted when its log could not be written.
TAIL_LINES = 40
NO_SPACE = "No space left on device"


def compile_args(n_ops: int) -> list[str]:
    """Compiler flags for a kernels.c file with ``n_ops`` operations."""
    opt = FLAG_POLICY["large"] if n_ops > LARGE_FILE_OPS else FLAG_POLICY["default"]
    return [opt, *BASE_COMPILE_ARGS]


def link_args() -> list[str]:
    return list(LINK_ARGS)


def ext_suffix() -> str:
    return sysconfig.get_config_var("EXT_SUFFIX") or ".so"


def extension_filename(module_name: str) -> str:
    """File name of a newly built module: unique per build, so that a rebuilt module
    never has the path of one the process may already have loaded."""
    return f"{module_name}-{uuid.uuid4().hex[:16]}{ext_suffix()}"


def compiler_command() -> list[str]:
    """The C compiler setuptools will run: ``$CC``, else the interpreter's."""
    return shlex.split(os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc")


def require_compiler() -> str:
    """Path of the C compiler, or a HostError saying how to get one."""
    command = compiler_command()
    found = shutil.which(command[0]) if command else None
    if found is None:
        via = "$CC" if os.environ.get("CC") else "the Python build configuration"
        raise HostError(
            f"no C compiler: {command[0] if command else '(empty)'!r}, named by {via}, "
            "is not found on PATH. fccgen compiles every new model structure. To fix "
            "it, install one (e.g. 'apt-get install gcc' or 'xcode-select --install') "
            "or set CC to a compiler's path.", errno=errno.ENOENT)
    return found


def _excerpt(output: str) -> str:
    """The compiler output for a message: all of it, or its error lines and its end."""
    lines = output.splitlines()
    if len(lines) <= MAX_MESSAGE_LINES:
        return output
    errors = [line for line in lines if "error" in line.lower()][:MAX_MESSAGE_LINES // 4]
    tail = lines[-(MAX_MESSAGE_LINES // 2):]
    return "\n".join([*errors, f"[... {len(lines)} lines in all ...]", *tail])


def _tail(output: str) -> str:
    return "\n".join(output.splitlines()[-TAIL_LINES:])


def _fail(tmp: Path, entry: Path, module_name: str, why: str, output: str,
          log_written: bool):
    """Keep the failed build in ``<key16>.failed-build/``; raise HostError for a full
    disk, BuildError otherwise."""
    kept = failed_dir(entry)
    shutil.rmtree(kept, ignore_errors=True)
    try:
        os.replace(tmp, kept)
    except OSError:
        kept = tmp                      # leave it where it is; a later build removes it
    if NO_SPACE in output:
        raise HostError(
            f"building the module of model {module_name!r} failed: no space left on "
            f"the device of {entry.parent}. To fix it, free some space or choose "
            "another place with --build-dir. "
            + (f"The compiler's log is {kept / BUILD_LOG}; its end:" if log_written else
               "The compiler's log could not be written; its end:")
            + f"\n{_tail(output)}", errno=errno.ENOSPC)
    previous = f"; the previous build in {entry} is unchanged" if entry.exists() else ""
    log = (f"the full log are kept in {kept}" if log_written else
           f"are kept in {kept} (the log could not be written)")
    raise BuildError(
        f"building the module of model {module_name!r} failed: {why}.\n"
        f"Sources and {log}{previous}.\n"
        f"--- compiler output ---\n{_excerpt(output)}")


def _write_sources(tmp: Path, sources: dict[str, str]) -> None:
    for name, text in sources.items():
        try:
            (tmp / name).write_text(text, encoding="utf-8")
        except OSError as exc:
            raise HostError.from_os_error(exc, "write the generated sources in",
                                          tmp.parent, "--build-dir",
                                          name_file=False) from None


def compile_sources(sources: dict[str, str], entry: Path, module_name: str) -> Path:
    """Write the sources into a fresh folder next to ``entry`` and compile them.

    Returns the folder, holding ``<module_name><EXT_SUFFIX>`` and the compiler's
    output in ``build.log``. Raises BuildError, with that output, when the build
    fails, HostError when the disk is full or the folder cannot be written.
    """
    tmp = new_temp_dir(entry.parent)
    try:
        _write_sources(tmp, sources)
        try:
            run = subprocess.run([sys.executable, BUILD_SCRIPT], cwd=tmp,
                                 capture_output=True, text=True, errors="replace")
        except OSError as exc:
            _fail(tmp, entry, module_name, f"cannot run {sys.executable}: {exc}", "",
                  False)
        output = run.stdout + run.stderr
        try:
            (tmp / BUILD_LOG).write_text(output, encoding="utf-8")
            log_written = True
        except OSError as exc:
            if exc.errno in (errno.ENOSPC, errno.EDQUOT) and NO_SPACE not in output:
                output += f"\n{NO_SPACE} (writing {BUILD_LOG})"
            log_written = False
        if run.returncode != 0 or not log_written:
            _fail(tmp, entry, module_name, f"exit status {run.returncode}", output,
                  log_written)
        if not (tmp / f"{module_name}{ext_suffix()}").is_file():
            _fail(tmp, entry, module_name, "the build produced no extension module",
                  output, True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)     # nothing left if _fail did not keep it
        raise
    return tmp


def _link_plain_name(extension: Path, plain: Path) -> None:
    """Make the module importable by a plain ``import <name>`` from its folder too
    (a hard link, or a copy where links are not possible)."""
    try:
        os.link(extension, plain)
    except OSError:
        shutil.copy2(extension, plain)


def install(tmp: Path, entry: Path, module_name: str, manifest: dict) -> Path:
    """Make the successful build in ``tmp`` the cache entry ``entry``.

    The module gets its unique name and its plain link, the manifest (with the sha256
    of both) is written last inside ``tmp``, and the whole folder is renamed into
    place. Call with the key's lock held. Returns the path of the installed module.
    """
    try:
        built = tmp / f"{module_name}{ext_suffix()}"
        extension = tmp / manifest["extension"]
        os.replace(built, extension)
        _link_plain_name(extension, built)
        manifest["files"] = file_hashes(tmp, [extension.name, built.name])
        keep = {*manifest["sources"], BUILD_LOG, extension.name, built.name}
        for path in tmp.iterdir():          # object files, Cython's C: not needed
            if path.name not in keep:
                shutil.rmtree(path) if path.is_dir() else path.unlink()
        write_manifest(tmp, manifest)
        put_in_place(tmp, entry)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise HostError.from_os_error(exc, "install the built module in", entry.parent,
                                      "--build-dir", name_file=False) from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    shutil.rmtree(failed_dir(entry), ignore_errors=True)
    return entry / manifest["extension"]
