"""Stage 5 of the pipeline: the generated sources, rendered from Jinja2 templates.

Templates live in the top-level ``templates/`` folder, installed as the package
``fccgen.templates``; from a source tree that is not installed they are read from the
folder directly. Rendering uses ``StrictUndefined``, so a missing variable is an error,
never a hole in the generated code. Jinja2 is imported only when rendering: finding
the templates (for the cache key) stays cheap.
"""
from __future__ import annotations

import importlib.resources
from pathlib import Path
from typing import TYPE_CHECKING

from ..version import __version__
from ..plan.kernels import KERNEL_NAMES, KERNELS
from .escape import c_identifier

if TYPE_CHECKING:
    from importlib.abc import Traversable

# Generated file name -> template that produces it.
OUTPUTS = {
    "kernels.c": "kernels.c.jinja",
    "kernels.h": "kernels.h.jinja",
    "module.pyx": "module.pyx.jinja",
    "build_module.py": "build_module.py.jinja",
}


def templates_root() -> "Traversable":
    """The folder of the templates: the source tree's when this package is in one (so
    that an editable install of another tree cannot shadow it), else the installed."""
    tree = Path(__file__).resolve().parents[2] / "templates"
    if (tree / "kernels.c.jinja").is_file():
        return tree
    try:
        return importlib.resources.files("fccgen.templates")
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[2] / "templates"


def template_texts() -> dict[str, str]:
    """Name -> text of every template, sorted by name (the cache key hashes them)."""
    root = templates_root()
    texts = {t.name: t.read_text(encoding="utf-8") for t in root.iterdir()
             if t.name.endswith(".jinja")}
    missing = set(OUTPUTS.values()) - set(texts)
    if missing:
        raise FileNotFoundError(f"templates {sorted(missing)} not found in {root}")
    return dict(sorted(texts.items()))


def environment():
    """A Jinja2 environment over the templates: strict, with the escaping filters of
    :mod:`fccgen.render.escape` (``c_comment``, ``c_string``, ``c_identifier``, ``py``,
    ``py_doc``): every value a template writes passes through one of them."""
    import jinja2

    from .escape import FILTERS

    texts = template_texts()
    env = jinja2.Environment(loader=jinja2.DictLoader(texts),
                             undefined=jinja2.StrictUndefined, autoescape=False,
                             trim_blocks=True, lstrip_blocks=True,
                             keep_trailing_newline=True)
    env.filters.update(FILTERS)
    return env


def table_symbol(model_name: str) -> str:
    """C name of the model's kernel table."""
    return f"fccgen_table_{c_identifier(model_name)}"


def render_context(model_name: str, structure_hash: str, classes: list,
                   compile_args: list[str], link_args: list[str]) -> dict:
    """Template variables for a model made of printed classes (``PrintedClass``)."""
    c_identifier(model_name)
    return {
        "fccgen_version": __version__,
        "model_name": model_name,
        "structure_hash": structure_hash,
        "table": table_symbol(model_name),
        "classes": classes,
        "n_ops": sum(c.n_ops for c in classes),
        "kernel_specs": KERNELS,
        "kernel_names": KERNEL_NAMES,
        "class_names": tuple(c.name for c in classes),
        "class_keys": tuple(c.cls.key for c in classes),
        "output_sizes": tuple({name: (k.size if k is not None else None)
                               for name, k in c.kernels.items()} for c in classes),
        "compile_args": list(compile_args),
        "link_args": list(link_args),
    }


def render_sources(model_name: str, structure_hash: str, classes: list,
                   compile_args: list[str], link_args: list[str]) -> dict[str, str]:
    """Generated file name -> text, for the printed classes of one model."""
    env = environment()
    context = render_context(model_name, structure_hash, classes, compile_args, link_args)
    return {out: env.get_template(tpl).render(context) for out, tpl in OUTPUTS.items()}


__all__ = ["OUTPUTS", "environment", "render_context", "render_sources", "table_symbol",
           "template_texts", "templates_root"]
