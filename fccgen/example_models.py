"""The example models shipped with fccgen (the repository's ``examples/``, installed
as the package data ``fccgen.examples``), so that the README's lines work from any
folder: :func:`example_path` names one, :func:`copy_examples` (``fccgen examples``)
copies them all into a folder."""
from __future__ import annotations

import argparse
import shutil
from importlib import resources
from pathlib import Path

KINDS = (".yaml", ".py", ".md")     # models, the scripts that write models, the README


def _folder() -> Path:
    """The installed package data; in a source checkout imported without installing
    (a Python started in the repository root), the repository's ``examples/``."""
    try:
        return Path(str(resources.files("fccgen.examples")))
    except ModuleNotFoundError:
        source = Path(__file__).resolve().parent.parent / "examples"
        if (source / "double_pendulum.yaml").is_file():
            return source
        raise


def example_names() -> list[str]:
    """The names of the example models (file stems), sorted."""
    return sorted(p.stem for p in _folder().glob("*.yaml"))


def example_path(name: str) -> Path:
    """The path of the shipped example model ``name`` (``"double_pendulum"`` or
    ``"double_pendulum.yaml"``); ValueError naming the examples there are."""
    stem = name[:-5] if name.endswith(".yaml") else name
    path = _folder() / f"{stem}.yaml"
    if stem not in example_names():
        raise ValueError(f"no example named {name!r}; the examples are "
                         + ", ".join(example_names()))
    return path


def copy_examples(dest="examples", overwrite: bool = False) -> list[Path]:
    """Copy the example models, their scripts and README into ``dest`` (created if
    missing); a file already there is kept unless ``overwrite``. Returns the files
    written."""
    dest = Path(dest)
    if dest.exists() and not dest.is_dir():
        raise ValueError(f"{dest} exists and is not a folder")
    dest.mkdir(parents=True, exist_ok=True)
    written = []
    for src in sorted(_folder().iterdir()):
        if src.suffix not in KINDS or src.name.startswith("_"):
            continue
        target = dest / src.name
        if target.exists() and not overwrite:
            continue
        shutil.copyfile(src, target)
        written.append(target)
    return written


def size_arguments(argv: list[str], doc: str, default: int, what: str) -> argparse.Namespace:
    """The command line of a model-writing script (examples/make_*.py): a size n
    (``what``, e.g. "N, the number of bays") and the file to write, both optional;
    ``--help`` prints the script's docstring ``doc``."""
    parser = argparse.ArgumentParser(description=doc,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("n", nargs="?", type=int, default=default,
                        help=f"{what} (default: %(default)s)")
    parser.add_argument("path", nargs="?", type=Path, help="the model file to write")
    args = parser.parse_args(argv)
    if args.n < 1:
        parser.error(f"{what.split(',')[0]} must be at least 1, not {args.n}")
    return args
