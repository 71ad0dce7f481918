"""Modules that accompany a model's kernel module: its event functions and its parameter
derivatives. Each is built from its own printed kernels, cached by the hash of what it
is made of (fccgen.build.store), and compiled as the kernel module is."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from ..version import __version__
from . import BuiltModule, _built
from .cache import cache_key, check_entry
from .compile import FLAG_POLICY, compile_args, compile_sources, extension_filename, install
from .store import build_lock, clean_stale, entry_dir


def build_companion(module_name: str, content_hash: str, kind: str, out_dir, force: bool,
                    printed: Callable[[], list], render: Callable[[list, list], dict]
                    ) -> BuiltModule:
    """Build (or reuse) the module ``module_name`` whose content hashes to
    ``content_hash``: ``printed()`` gives its printed kernels (each with ``n_ops``),
    ``render(kernels, flags)`` their sources (file name -> text). The manifest counts
    the operations under ``kind``."""
    key = cache_key(module_name, [], FLAG_POLICY, content_hash)
    entry = entry_dir(Path(out_dir).absolute(), module_name, key)
    clean_stale(entry.parent)
    manifest, _ = (None, None) if force else check_entry(entry, key, module_name)
    if manifest is not None:
        return _built(entry, manifest, True, {})
    with build_lock(entry):
        manifest, _ = (None, None) if force else check_entry(entry, key, module_name)
        if manifest is not None:
            return _built(entry, manifest, True, {})
        kernels = printed()
        n_ops = sum(k.n_ops for k in kernels)
        flags = compile_args(n_ops)
        sources = render(kernels, flags)
        tmp = compile_sources(sources, entry, module_name)
        manifest = {"fccgen_version": __version__, "model_name": module_name,
                    "cache_key": key, "structure_hash": content_hash,
                    "n_ops": {kind: n_ops}, "flags": flags, "timings": {},
                    "extension": extension_filename(module_name),
                    "sources": sorted(sources)}
        install(tmp, entry, module_name, manifest)
    return _built(entry, manifest, False, {})
