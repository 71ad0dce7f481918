"""Print the event kernels of a model (fccgen.events.symbolic) to C and compile them
into one small extension module, cached by a hash of the event expressions.

Kernels (fccgen_events.h): event_values s_k(q, v, t), event_gradients ds_k/dq,
quantity_values r_j(q) (joint angles and slides that events read or lock),
quantity_gradients dr_j/dq and quantity_bias (d/dt dr_j/dq) v. Each kernel is printed
in parts of PART_ROWS rows, common subexpressions eliminated over a part's outputs
together; structurally zero entries of the dense gradients are not printed (the kernel
clears out first).

The quantities' Jacobian is also printed packed (quantity_gradient_values): only its
structural nonzeros, row by row, with their columns (gradient_ptr, gradient_idx) in
the table. The runtime fills the rows it holds at every assembly from it, so that a
model with many switchable rows reads (rows x their nonzeros) numbers, not
(rows x n_q); the dense kernel is the packed one scattered (the same values).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import sympy

from ..version import __version__
from ..build import BuiltModule, load_module
from ..build.companion import build_companion
from ..build.compile import link_args
from ..printing.c99 import KernelPrinter, slot_map
from ..render import environment
from .symbolic import EventSystem, event_system

EVENT_HEADER = "fccgen_events.h"


# Rows (event functions or quantities) per part of a kernel. Common subexpressions are
# eliminated within a part, and each part is its own C function: one function of all
# rows made the compiler's time grow faster than the rows (the mast of 200 bays with a
# latch per bay, 800 quantities: 5.4 MB of C, over 20 minutes at -O1), and SymPy's
# elimination too. Rows of different parts rarely share a subexpression (each reads
# its own joint's bodies).
PART_ROWS = 32


@dataclass(frozen=True)
class KernelPart:
    temporaries: tuple[tuple[str, str], ...]
    outputs: tuple[tuple[int, int, str], ...]  # (slot, packed index, C expression)


@dataclass(frozen=True)
class EventKernel:
    name: str
    equation: str
    size: int
    sparse: bool                               # zero entries left out (out cleared)
    parts: tuple[KernelPart, ...]
    n_ops: int
    packed: bool = False                       # printed as <name>_values (out[k]: the
                                               # k-th output) and scattered to its slots

    @property
    def outputs(self) -> tuple[tuple[int, str], ...]:
        """(slot, C expression) of every output, in order."""
        return tuple((slot, expr) for part in self.parts for slot, _, expr in part.outputs)


def _print(name: str, equation: str, exprs: list, system: EventSystem,
           sparse: bool, packed: bool = False, width: int = 1) -> EventKernel:
    """The kernel of exprs (rows of width outputs each), in parts of PART_ROWS rows."""
    slots = slot_map(system.q, system.v, system.p)
    slots[system.t] = "t"
    printer = KernelPrinter(slots)
    parts, n_ops, index, step = [], 0, 0, PART_ROWS * max(width, 1)
    for start in range(0, len(exprs), step):
        keep = [(k, e) for k, e in enumerate(exprs[start:start + step], start)
                if not (sparse and e == 0)]
        if not keep:
            continue
        values = [e for _, e in keep]
        used = set().union(*(e.free_symbols for e in values))
        temps, reduced = sympy.cse(values,
                                   symbols=sympy.numbered_symbols("x", exclude=used))
        n_ops += (sum(sympy.count_ops(e) for _, e in temps)
                  + sum(sympy.count_ops(e) for e in reduced))
        parts.append(KernelPart(
            tuple((str(s), printer.doprint(e)) for s, e in temps),
            tuple((k, index + i, printer.doprint(e))
                  for i, ((k, _), e) in enumerate(zip(keep, reduced)))))
        index += len(keep)
    return EventKernel(name, equation, len(exprs), sparse, tuple(parts), int(n_ops),
                       packed and sparse)


def print_kernels(system: EventSystem) -> list[EventKernel]:
    qty = [x.expr for x in system.quantities]
    grad = lambda exprs: [g for e in exprs for g in system.gradient(e)]   # noqa: E731
    zero = [sympy.S.Zero] * len(system.q)
    width = len(system.q)
    return [
        _print("event_values", "s_k(q, v, t)", system.functions, system, False),
        _print("event_gradients", "ds_k/dq", grad(system.functions), system, True,
               width=width),
        _print("quantity_values", "r_j(q)", qty, system, False),
        _print("quantity_gradients", "dr_j/dq",
               [g for x in system.quantities
                for g in (system.gradient(x.expr) if x.lockable else zero)], system, True,
               packed=True, width=width),
        _print("quantity_bias", "(d/dt dr_j/dq) v",
               [system.quantity_bias(x) if x.lockable else sympy.S.Zero
                for x in system.quantities], system, False),
    ]


def gradient_pattern(kernel: EventKernel, n_q: int, n_rows: int) -> tuple[list, list]:
    """(ptr, idx) of a packed kernel's rows of n_q columns: row j's outputs are
    ptr[j] .. ptr[j + 1] - 1, their columns idx (increasing)."""
    ptr, idx = [0] * (n_rows + 1), []
    for slot, _ in kernel.outputs:
        ptr[slot // n_q + 1] += 1
        idx.append(slot % n_q)
    for j in range(n_rows):
        ptr[j + 1] += ptr[j]
    return ptr, idx


def event_hash(system: EventSystem) -> str:
    """sha256 of the event functions and quantities: what the module computes."""
    text = sympy.srepr((system.q, system.p, system.functions,
                        [x.expr for x in system.quantities]))
    if not all(x.lockable for x in system.quantities):
        text += repr([x.lockable for x in system.quantities])
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def render(model_name: str, module_name: str, system: EventSystem, names: list[str],
           kernels: list[EventKernel], e_hash: str, flags: list[str]) -> dict[str, str]:
    from importlib.resources import files
    env = environment()
    gradients = next((k for k in kernels if k.name == "quantity_gradients"), None)
    ptr, idx = (gradient_pattern(gradients, len(system.q), len(system.quantities))
                if gradients is not None else ([0] * (len(system.quantities) + 1), []))
    ctx = dict(gradient_ptr=ptr, gradient_idx=idx,
               fccgen_version=__version__, model_name=model_name, module_name=module_name,
               event_hash=e_hash, n_q=len(system.q), n_p=len(system.p),
               event_names=names, quantity_names=[x.name for x in system.quantities],
               kernels=kernels, compile_args=flags, link_args=link_args())
    out = {name: env.get_template(tpl).render(**ctx) for name, tpl in (
        ("events.c", "events.c.jinja"), ("events.h", "events.h.jinja"),
        ("events_module.pyx", "events.pyx.jinja"),
        ("build_module.py", "events_build.py.jinja"))}
    out[EVENT_HEADER] = (files("fccgen.runtime") / EVENT_HEADER).read_text(encoding="utf-8")
    return out


def build_events(plan, out_dir="generated", *, force: bool = False) -> BuiltModule | None:
    """Build (or reuse) the event module of ``plan.model`` (None: it has no events)."""
    model = plan.model
    if not needs_events_module(plan):
        return None
    system = event_system(plan)
    e_hash = event_hash(system)
    module_name = f"{model.name}_events"
    return build_companion(
        module_name, e_hash, "events", out_dir, force, lambda: print_kernels(system),
        lambda kernels, flags: render(model.name, module_name, system,
                                      [e.name for e in model.events], kernels, e_hash,
                                      flags))


def needs_events_module(plan) -> bool:
    """The model has events, or element kernels that read a joint angle through a
    turn-counting reference (fccgen.events.references)."""
    from .references import angle_sources
    return bool(plan.model.events) or bool(angle_sources(plan))


def load_events(plan, out_dir="generated", *, force: bool = False):
    """The imported event module of ``plan.model`` (None: no events, no referenced
    angles)."""
    built = build_events(plan, out_dir, force=force)
    return None if built is None else load_module(built)
