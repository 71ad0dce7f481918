"""Printing stage: the kernels of one derived element class as C statements.

Common subexpressions are eliminated over all outputs of a kernel together (one
``sympy.cse`` call per kernel), so that, e.g., the entries of a mass matrix share the
products they have in common. The result is plain data for the templates.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from ..plan.classes import ElementClass
from ..plan.kernels import KERNEL_NAMES, KERNELS, KernelSpec
from .c99 import KernelPrinter, slot_map

# Output shapes of the matrix kernels (row-major); every other kernel is a vector.
MATRIX_SHAPES = {
    "mass_matrix": lambda c: (c.n_q, c.n_q),
    "constraint_jacobian": lambda c: (c.n_g, c.n_q),
    "force_jacobian_q": lambda c: (c.n_q, c.n_q),
    "force_jacobian_v": lambda c: (c.n_q, c.n_q),
}


@dataclass(frozen=True)
class PrintedKernel:
    """One kernel of one element class, ready for the C template."""
    name: str                                 # kernel name, e.g. "mass_matrix"
    function: str                             # C function name
    signature: str                            # "q": (q, p, out); "qv": (q, v, p, out)
    equation: str                             # KernelSpec.equation
    shape: tuple[int, ...]                    # output shape, row-major
    unused: tuple[str, ...]                   # input arguments the body never reads
    temporaries: tuple[tuple[str, str], ...]  # (name, C expression), in order
    outputs: tuple[str, ...]                  # C expression of out[k]
    n_ops: int                                # sympy.count_ops after CSE

    @property
    def arguments(self) -> tuple[str, ...]:
        return ("q", "v", "p", "out") if self.signature == "qv" else ("q", "p", "out")

    @property
    def size(self) -> int:
        return len(self.outputs)


@dataclass(frozen=True)
class PrintedClass:
    """All kernels of one element class; ``kernels[name]`` is None for no kernel."""
    cls: ElementClass
    kernels: dict[str, PrintedKernel | None]

    @property
    def name(self) -> str:
        return self.cls.name

    @property
    def n_ops(self) -> int:
        return sum(k.n_ops for k in self.kernels.values() if k is not None)

    @property
    def q_names(self) -> tuple[str, ...]:
        return tuple(f"{t}.{c}" for t in self.cls.moving_triples for c in "xyz")


def _check_derived(derived) -> None:
    """Refuse a derived class whose shapes do not match its element class."""
    cls = derived.cls
    sizes = {"q": (len(derived.q), cls.n_q), "v": (len(derived.v), cls.n_q),
             "p": (len(derived.p), cls.n_p)}
    for what, (got, want) in sizes.items():
        if got != want:
            raise ValueError(f"{cls.name}: {want} {what} symbols expected (got {got})")
    if set(derived.kernels) != set(KERNEL_NAMES):
        raise ValueError(f"{cls.name}: kernels must be exactly {KERNEL_NAMES} "
                         f"(got {tuple(derived.kernels)})")


def _output_shape(spec: KernelSpec, cls: ElementClass) -> tuple[int, ...]:
    shape = MATRIX_SHAPES.get(spec.name)
    return shape(cls) if shape else (spec.size(cls),)


def _check_kernel(spec: KernelSpec, derived, exprs: list) -> None:
    """Outputs must have the kernel's size and use only the kernel's inputs."""
    cls = derived.cls
    if len(exprs) != spec.size(cls):
        raise ValueError(f"{cls.name}.{spec.name}: {spec.size(cls)} outputs expected "
                         f"(got {len(exprs)})")
    allowed = set(derived.q) | set(derived.p) | (set(derived.v) if spec.uses_v else set())
    for k, e in enumerate(exprs):
        stray = e.free_symbols - allowed
        if stray:
            raise ValueError(f"{cls.name}.{spec.name}[{k}] uses symbols that are not "
                             f"inputs of the kernel: {sorted(map(str, stray))}")
        if e.has(sympy.zoo, sympy.oo, -sympy.oo, sympy.nan):
            raise ValueError(f"{cls.name}.{spec.name}[{k}] is not finite: {e}")


def _hoist_table_arguments(temps, reduced, used):
    """A table (fccgen.expressions.tables.TableFunction) prints its argument once per
    interval it searches: an argument that is not a symbol becomes a temporary of
    its own, defined just before the first expression that calls the table."""
    from ..expressions.tables import TableFunction
    names = sympy.numbered_symbols("xt", exclude=used | {s for s, _ in temps})
    out = []

    def hoist(e):
        calls = [f for f in e.atoms(TableFunction) if not f.args[0].is_Symbol]
        if not calls:
            return e
        swap = {}
        for f in sorted(calls, key=sympy.default_sort_key):
            name = next(names)
            out.append((name, hoist(f.args[0])))
            swap[f] = f.func(name)
        return e.xreplace(swap)
    for s, e in temps:
        e = hoist(e)
        out.append((s, e))
    reduced = [hoist(e) for e in reduced]
    return out, reduced


def print_kernel(spec: KernelSpec, derived, matrix: sympy.Matrix) -> PrintedKernel:
    """CSE over all outputs of the kernel together, then print temporaries and outputs."""
    exprs = [sympy.sympify(e) for e in matrix]
    _check_kernel(spec, derived, exprs)
    used = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
    inputs = {"q": derived.q, "p": derived.p}
    if spec.uses_v:
        inputs["v"] = derived.v
    unused = tuple(a for a in ("q", "v", "p") if a in inputs and not used & set(inputs[a]))
    temps, reduced = sympy.cse(exprs, symbols=sympy.numbered_symbols("x", exclude=used))
    temps, reduced = _hoist_table_arguments(temps, reduced, used)
    printer = KernelPrinter(slot_map(derived.q, derived.v, derived.p))
    n_ops = (sum(sympy.count_ops(e) for _, e in temps)
             + sum(sympy.count_ops(e) for e in reduced))
    return PrintedKernel(
        name=spec.name,
        function=f"{derived.cls.name}_{spec.name}",
        signature="qv" if spec.uses_v else "q",
        equation=spec.equation,
        shape=_output_shape(spec, derived.cls),
        unused=unused,
        temporaries=tuple((str(s), printer.doprint(e)) for s, e in temps),
        outputs=tuple(printer.doprint(e) for e in reduced),
        n_ops=int(n_ops),
    )


def print_class(derived) -> PrintedClass:
    """Print every kernel of a derived class (``fccgen.derive.DerivedClass``)."""
    _check_derived(derived)
    kernels: dict[str, PrintedKernel | None] = {}
    for spec in KERNELS:
        matrix = derived.kernels[spec.name]
        if matrix is None:
            kernels[spec.name] = None
        elif not spec.applies(derived.cls):
            raise ValueError(f"{derived.cls.name}.{spec.name}: the kernel does not apply "
                             f"to a {derived.cls.kind} class, so it must be None")
        else:
            kernels[spec.name] = print_kernel(spec, derived, matrix)
    return PrintedClass(derived.cls, kernels)
