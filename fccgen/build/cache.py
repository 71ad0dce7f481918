"""Content hashes that decide whether a model's module must be rebuilt, and the
manifest that records a finished build.

Nothing here imports SymPy (or Cython, or Jinja2): a cache hit must stay cheap, so
tool versions are read from package metadata, not from the packages.
"""
from __future__ import annotations

import hashlib
import importlib.metadata
import importlib.resources
import json
import os
import sysconfig
import uuid
from pathlib import Path

from ..version import __version__
from ..render import template_texts

MANIFEST = "fccgen.json"
HEADER = "fccgen_model.h"


def _sha256(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def structure_hash(classes) -> str:
    """Hash of the element-class keys, in order: what a module was built for.

    The runtime compares it with the ``structure_hash`` of a module's table.
    """
    return _sha256("\n".join(c.key for c in classes))


def runtime_header() -> str:
    """Text of ``fccgen_model.h``, the C interface, from the installed package."""
    return (importlib.resources.files("fccgen.runtime") / HEADER).read_text(encoding="utf-8")


def tool_versions() -> dict[str, str]:
    """Versions of the tools that shape the generated code (read without importing)."""
    versions = {"fccgen": __version__}
    for dist in ("sympy", "Cython"):
        versions[dist] = importlib.metadata.version(dist)
    return versions


def compiler_identity() -> dict[str, str]:
    """What decides which compiler runs and what it produces for this interpreter."""
    return {"ext_suffix": sysconfig.get_config_var("EXT_SUFFIX") or "",
            "cc": os.environ.get("CC") or sysconfig.get_config_var("CC") or "",
            "cflags": os.environ.get("CFLAGS", "")}


def cache_key(model_name: str, classes, flag_policy: dict, extra: str = "") -> str:
    """sha256 over everything the built module depends on.

    That is the module name, the class keys and parameter layouts in order, the tool
    versions, the template
    and C-interface texts, the flag policy and the compiler. ``extra`` distinguishes
    modules built from kernels that did not come from ``fccgen.derive``.
    """
    payload = {
        "model_name": model_name,
        "class_keys": [c.key for c in classes],
        # the kernels' parameter layout: a layout change (a new runtime parameter) is a
        # new build even where the class keys are the same
        "class_params": [list(getattr(c, "param_names", ())) for c in classes],
        "versions": tool_versions(),
        "templates": {name: _sha256(text) for name, text in template_texts().items()},
        "header": _sha256(runtime_header()),
        "flags": flag_policy,
        "compiler": compiler_identity(),
        "extra": extra,
    }
    return _sha256(json.dumps(payload, sort_keys=True))


def read_manifest(directory: Path) -> dict | None:
    """The manifest of a finished build, or None if there is none or it is unreadable."""
    try:
        with open(Path(directory) / MANIFEST, encoding="utf-8") as f:
            data = json.load(f)
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


# Manifest entries a build must have, with their types; anything else is a damaged,
# incomplete or foreign entry and is rebuilt.
REQUIRED = {"model_name": str, "cache_key": str, "structure_hash": str, "extension": str,
            "files": dict, "n_ops": dict, "flags": list, "timings": dict}


def file_sha256(path: Path) -> str:
    """sha256 of a file's bytes, read in blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def file_hashes(directory: Path, names) -> dict[str, str]:
    """File name -> sha256 of the files ``names`` in ``directory``."""
    return {name: file_sha256(Path(directory) / name) for name in names}


def manifest_problem(manifest: dict | None, key: str, model_name: str) -> str | None:
    """What is wrong with the manifest of an entry built for (model_name, key), if
    anything: missing keys, a foreign model or structure, no module files listed."""
    if manifest is None:
        return f"its {MANIFEST} is missing or unreadable"
    missing = sorted(k for k, kind in REQUIRED.items()
                     if not isinstance(manifest.get(k), kind))
    if missing:
        return f"its {MANIFEST} lacks {', '.join(missing)}"
    if manifest["model_name"] != model_name or manifest["cache_key"] != key:
        return (f"it holds the module of another model or structure "
                f"({manifest['model_name']!r}, key {manifest['cache_key'][:16]})")
    if manifest["extension"] not in manifest["files"]:
        return f"its {MANIFEST} records no hash of {manifest['extension']}"
    return None


def files_problem(directory: Path, manifest: dict) -> str | None:
    """Which module file differs from the hash recorded at build time, if any (a
    truncated or overwritten module must never be imported: it can crash the process)."""
    for name, expected in sorted(manifest["files"].items()):
        try:
            if file_sha256(Path(directory) / name) != expected:
                return f"{name} differs from the file built (sha256 mismatch)"
        except OSError as exc:
            return f"{name} cannot be read ({exc.strerror or exc})"
    return None


def check_entry(directory: Path, key: str, model_name: str) -> tuple[dict | None, str | None]:
    """(manifest, None) for a sound build of (model_name, key) in ``directory``;
    (None, None) when there is no build there; (None, problem) for a damaged,
    incomplete or foreign one."""
    directory = Path(directory)
    if not directory.exists():
        return None, None
    manifest = read_manifest(directory)
    problem = manifest_problem(manifest, key, model_name)
    if problem is None:
        problem = files_problem(directory, manifest)
    return (manifest, None) if problem is None else (None, problem)


def write_manifest(directory: Path, manifest: dict) -> None:
    """Write the manifest atomically (a file of a unique name, then ``os.replace``)."""
    tmp = Path(directory) / f".{MANIFEST}.{os.getpid()}.{uuid.uuid4().hex}"
    try:
        with open(tmp, "x", encoding="utf-8") as f:
            json.dump(manifest, f, indent=2, sort_keys=True)
            f.write("\n")
        os.replace(tmp, Path(directory) / MANIFEST)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
