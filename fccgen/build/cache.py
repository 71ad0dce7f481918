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

from .. import __version__
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

    That is the module name, the class keys in order, the tool versions, the template
    and C-interface texts, the flag policy and the compiler. ``extra`` distinguishes
    modules built from kernels that did not come from ``fccgen.derive``.
    """
    payload = {
        "model_name": model_name,
        "class_keys": [c.key for c in classes],
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


def cached_manifest(directory: Path, key: str) -> dict | None:
    """The manifest in ``directory`` if it was built for ``key`` and its module exists."""
    manifest = read_manifest(directory)
    if manifest is None or manifest.get("cache_key") != key:
        return None
    extension = manifest.get("extension")
    if not isinstance(extension, str) or not (Path(directory) / extension).is_file():
        return None
    return manifest


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
