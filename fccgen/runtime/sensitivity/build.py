"""Print the parameter derivatives of a model's element kernels
(fccgen.derive.parameters) to C and compile them into one small extension module,
cached by the model's structure (the derivatives of the same classes are the same).

The module is built only when sensitivities are asked for, so that models without
them never pay the derivation. Its table (fcc_dp.h) lists the classes in the order
of the model's kernel table (``plan.classes``).
"""
from __future__ import annotations

import hashlib
from importlib.resources import files

from ...version import __version__
from ...build import BuiltModule, load_module
from ...build.companion import build_companion
from ...build.compile import link_args
from ...progress import Progress, Reporter
from ...render import environment

DP_HEADER = "fcc_dp.h"
DP_FORMAT = 4              # bump when the kernels' meaning or layout changes


def dp_hash(classes) -> str:
    """sha256 of the class keys (what the derivatives are derived from)."""
    text = f"dp {DP_FORMAT}\n" + "\n".join(c.key for c in classes)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _print_all(classes, progress: Progress | None):
    from ...derive import derive_class
    from ...printing.parameters import PrintedDp, print_parameter_kernels, print_tangent
    say = Reporter(progress, "derive", total=len(classes))
    printed = []
    for k, cls in enumerate(classes, 1):
        say(f"deriving d/dp of class {k}/{len(classes)}: {cls.name}", done=k - 1)
        derived = derive_class(cls)
        printed.append(PrintedDp(cls, print_parameter_kernels(derived),
                                 print_tangent(derived)))
    return printed


def render(model_name: str, module_name: str, printed: list, s_hash: str,
           flags: list[str]) -> dict[str, str]:
    from ...derive.parameters import PARAMETER_KERNELS
    env = environment()
    table = f"fccgen_dp_{model_name}"
    n_ops = sum(p.n_ops for p in printed)
    ctx = dict(fccgen_version=__version__, model_name=model_name, module_name=module_name,
               structure_hash=s_hash, classes=printed, n_ops=n_ops, table=table,
               kernel_names=list(PARAMETER_KERNELS), compile_args=flags,
               link_args=link_args())
    out = {name: env.get_template(tpl).render(**ctx) for name, tpl in (
        ("dp_kernels.c", "dp_kernels.c.jinja"), ("dp_kernels.h", "dp_kernels.h.jinja"),
        ("dp_module.pyx", "dp.pyx.jinja"), ("build_module.py", "dp_build.py.jinja"))}
    out[DP_HEADER] = (files("fccgen.runtime") / "engine" / DP_HEADER).read_text(encoding="utf-8")
    return out


def build_dp(plan, out_dir="generated", *, force: bool = False,
             progress: Progress | None = None) -> BuiltModule:
    """Build (or reuse) the parameter-derivative module of ``plan``."""
    classes = list(plan.classes)
    s_hash = dp_hash(classes)
    module_name = f"{plan.model.name}_dp"
    return build_companion(
        module_name, s_hash, "dp", out_dir, force, lambda: _print_all(classes, progress),
        lambda printed, flags: render(plan.model.name, module_name, printed, s_hash, flags))


def load_dp(plan, out_dir="generated", *, force: bool = False,
            progress: Progress | None = None):
    """The imported parameter-derivative module of ``plan``."""
    return load_module(build_dp(plan, out_dir, force=force, progress=progress))
