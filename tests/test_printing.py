"""Printing and rendering: SymPy expressions to C kernels, checked by compiling them.

The compiled check uses hand-made kernels (a known expression set), so it tests the
printer, the templates and the build without depending on the derivation.
"""
from __future__ import annotations

import os
import subprocess
import sysconfig
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import sympy

from fccgen.build import build_derived, load_module, structure_hash
from fccgen.build.cache import runtime_header
from fccgen.build.compile import BUILD_LOG, compile_args, link_args
from fccgen.plan.classes import (DRIVER_KINDS, JOINT_LOAD_KINDS, KIND_ENDS, KIND_TRIPLES,
                                  TIMED_LOAD_KINDS, ElementClass)
from fccgen.plan.kernels import KERNEL_NAMES, KERNELS
from fccgen.printing import KernelPrinter, print_class, print_kernel, slot_map
from fccgen.render import environment, render_sources

GOLDENS = Path(__file__).resolve().parent / "goldens"
SYMPY_MINOR = ".".join(sympy.__version__.split(".")[:2])
SPECS = {k.name: k for k in KERNELS}


@dataclass
class HandDerived:
    """Same fields as fccgen.derive.DerivedClass, filled by hand."""
    cls: ElementClass
    q: tuple
    v: tuple
    p: tuple
    kernels: dict


def symbols_of(cls: ElementClass):
    return (sympy.symbols(f"q0:{cls.n_q}"), sympy.symbols(f"v0:{cls.n_q}"),
            sympy.symbols(f"p0:{cls.n_p}") if cls.n_p else ())


def unit_vector_class() -> HandDerived:
    """The unit-vector constraint written out by hand (docs/elements.md)."""
    cls = ElementClass("unit_vector", (), (False,), frozenset())
    q, v, p = symbols_of(cls)
    u, ud = sympy.Matrix(q), sympy.Matrix(v)
    kernels = dict.fromkeys(KERNEL_NAMES)
    kernels["constraints"] = sympy.Matrix([u.dot(u) - 1])
    kernels["constraint_jacobian"] = sympy.Matrix([2 * x for x in q])
    kernels["constraint_bias"] = sympy.Matrix([2 * ud.dot(ud)])
    return HandDerived(cls, q, v, p, kernels)


def expression_set_class() -> HandDerived:
    """A body-shaped class (ri fixed: 6 coordinates, 19 parameters) whose kernels hold
    a known set of expressions: every power the printer special-cases and some it
    does not, rationals, floats, fabs, structural zeros and shared subexpressions."""
    cls = ElementClass("body", (), (True, False, False), frozenset())
    q, v, p = symbols_of(cls)
    s = sympy.sqrt(q[0] * q[1] + p[0] ** 2)                 # shared by many outputs
    r = 1 / (q[2] ** 2 + q[3] ** 2 + p[1])
    base = [
        q[0] ** 2 * s,
        q[1] ** 3 * r + sympy.Rational(1, 3) * p[2],
        p[3] ** 4 / q[4] ** 2,
        q[5] ** -3 * s + sympy.Float("0.1") * q[0],
        sympy.sqrt(q[1]) * q[2] ** sympy.Rational(3, 2),
        q[3] ** sympy.Rational(-3, 2) + 1 / sympy.sqrt(p[4]),
        q[4] ** 7 * r,
        q[5] ** sympy.Rational(5, 2) * p[5] / q[0] ** 4,
        sympy.Abs(q[0] - 2) * s,
        (q[0] + q[1]) ** -2 * p[6] + q[2] ** -1,
        p[18] * q[3] ** sympy.Rational(-1, 2) * r,
    ]
    mass = [0 if k % 7 == 3 else base[k % len(base)] * (1 + p[k % cls.n_p])
            for k in range(cls.n_q ** 2)]
    kernels = dict.fromkeys(KERNEL_NAMES)
    kernels["mass_matrix"] = sympy.Matrix(mass)
    kernels["h_vector"] = sympy.Matrix([v[i] ** 2 * s + v[(i + 1) % 6] * q[i] * r
                                        for i in range(6)])
    kernels["constraints"] = sympy.Matrix([s * r, q[0] ** 2 + q[1] ** 2 - p[0] ** 2])
    return HandDerived(cls, q, v, p, kernels)


def reference_values(derived: HandDerived, name: str, q, v, p) -> np.ndarray:
    """Direct evaluation of the SymPy expressions at 30 digits."""
    subs = {s: sympy.Float(float(x), 30)
            for syms, vals in ((derived.q, q), (derived.v, v), (derived.p, p))
            for s, x in zip(syms, vals)}
    return np.array([float(e.evalf(30, subs=subs)) for e in derived.kernels[name]])


@pytest.fixture(scope="module")
def expression_module(tmp_path_factory):
    derived = expression_set_class()
    built = build_derived("expression_set", [derived], tmp_path_factory.mktemp("gen"))
    return derived, built, load_module(built)


# -- printer -------------------------------------------------------------------------

def test_printer_maps_symbols_to_array_slots():
    q0, q1, v0, p2 = sympy.symbols("q0 q1 v0 p2")
    printer = KernelPrinter(slot_map((q0, q1), (v0,), (sympy.Symbol("p0"),
                                                       sympy.Symbol("p1"), p2)))
    text = printer.doprint(q1 + p2 * v0 / q0 ** 2)
    assert "q[1]" in text and "v[0]" in text and "p[2]" in text and "q[0]" in text
    for bare in ("q1", "v0", "p2", "q0"):
        assert bare not in text.replace("[", " ")
    assert "pow" not in text                                  # q0**2 prints as a product


def test_printer_keeps_powers_correctly_grouped():
    q0, q1, p0 = sympy.symbols("q0 q1 p0")
    printer = KernelPrinter(slot_map((q0, q1), (), (p0,)))
    assert printer.doprint(q0 / q1 ** 2) == "q[0]/(q[1]*q[1])"
    assert printer.doprint(p0 / q1 ** sympy.Rational(3, 2)) == "p[0]/(q[1]*sqrt(q[1]))"
    assert printer.doprint(q0 ** 7) == "pow(q[0], 7)"


def test_cse_shares_subexpressions():
    derived = expression_set_class()
    kernel = print_kernel(SPECS["mass_matrix"], derived, derived.kernels["mass_matrix"])
    raw_ops = sum(sympy.count_ops(e) for e in derived.kernels["mass_matrix"])
    assert kernel.temporaries, "CSE found nothing to share"
    assert kernel.n_ops < raw_ops / 2
    # The shared square root (the only place q0*q1 occurs) is computed once.
    texts = [expr for _, expr in kernel.temporaries] + list(kernel.outputs)
    assert sum(t.count("q[0]*q[1]") for t in texts) == 1


def test_unused_arguments_are_listed():
    printed = print_class(unit_vector_class())
    assert printed.kernels["constraints"].unused == ("p",)
    assert printed.kernels["constraint_bias"].unused == ("q", "p")
    assert printed.kernels["mass_matrix"] is None


# -- errors --------------------------------------------------------------------------

def test_wrong_output_count_is_refused():
    derived = unit_vector_class()
    derived.kernels["constraint_jacobian"] = sympy.Matrix(derived.q[:2])
    with pytest.raises(ValueError, match=r"constraint_jacobian: 3 outputs expected \(got 2\)"):
        print_class(derived)


def test_speeds_in_a_position_kernel_are_refused():
    derived = unit_vector_class()
    derived.kernels["constraints"] = sympy.Matrix([derived.v[0]])
    with pytest.raises(ValueError, match=r"constraints\[0\] uses symbols .*'v0'"):
        print_class(derived)


def test_non_finite_output_is_refused():
    derived = unit_vector_class()
    derived.kernels["constraints"] = sympy.Matrix([derived.q[0] + sympy.zoo])
    with pytest.raises(ValueError, match="is not finite"):
        print_class(derived)


def test_kernel_that_does_not_apply_must_be_none():
    derived = unit_vector_class()
    derived.kernels["mass_matrix"] = sympy.Matrix([derived.q[0]])
    with pytest.raises(ValueError, match="does not apply to a unit_vector class"):
        print_class(derived)


def test_missing_kernel_name_is_refused():
    derived = unit_vector_class()
    del derived.kernels["energy"]
    with pytest.raises(ValueError, match="kernels must be exactly"):
        print_class(derived)


# -- generated C -----------------------------------------------------------------------

def render_unit_vector() -> dict[str, str]:
    printed = print_class(unit_vector_class())
    return render_sources("golden", structure_hash([printed.cls]), [printed],
                          compile_args(printed.n_ops), link_args())


def test_generated_c_matches_golden():
    """Golden per SymPy minor version; FCCGEN_UPDATE_GOLDENS=1 refreshes it."""
    text = render_unit_vector()["kernels.c"]
    path = GOLDENS / f"unit_vector_kernels.c.sympy-{SYMPY_MINOR}.golden"
    if os.environ.get("FCCGEN_UPDATE_GOLDENS") == "1":
        path.write_text(text, encoding="utf-8")
    elif not path.exists():
        path.write_text(text, encoding="utf-8")
        pytest.skip(f"created {path.name} for SymPy {SYMPY_MINOR}: review and keep it")
    assert text == path.read_text(encoding="utf-8"), (
        f"generated C differs from {path.name}; if the change is intended, rerun with "
        f"FCCGEN_UPDATE_GOLDENS=1")


def test_templates_refuse_missing_variables():
    import jinja2

    with pytest.raises(jinja2.UndefinedError, match="model_name"):
        environment().get_template("kernels.h.jinja").render({})


def check_strict_c(sources: dict[str, str], folder: Path) -> None:
    """kernels.c compiles with -Wall -Wextra -Wpedantic -Werror (C99)."""
    (folder / "kernels.c").write_text(sources["kernels.c"])
    (folder / "kernels.h").write_text(sources["kernels.h"])
    (folder / "fccgen_model.h").write_text(runtime_header())
    cc = (sysconfig.get_config_var("CC") or "cc").split()
    run = subprocess.run([*cc, "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
                          "-fsyntax-only", "kernels.c"], cwd=folder, capture_output=True,
                         text=True)
    assert run.returncode == 0, run.stdout + run.stderr


def test_generated_c_is_clean_under_strict_warnings(tmp_path):
    """Unused arguments are cast away, so even -Wextra has nothing to say."""
    check_strict_c(render_unit_vector(), tmp_path)


def test_every_element_kind_prints_clean_c(tmp_path):
    """The real derivation of one class per kind (ends alternate body point / point,
    first triple fixed), printed and rendered together, compiles cleanly."""
    from fccgen.derive import derive_class

    printed = []
    for kind in KIND_ENDS:
        ends = tuple("body_point" if k % 2 == 0 else "point"
                     for k in range(len(KIND_ENDS[kind])))
        n_triples = len(KIND_TRIPLES[kind]) + sum(3 if e == "body_point" else 1 for e in ends)
        function = ("0.5*sin(3*t) + t**2" if kind in DRIVER_KINDS else
                    "sin(t);t**2;1" if kind in TIMED_LOAD_KINDS else "")
        if kind in JOINT_LOAD_KINDS:                  # + the angle's 5, the slide's 3
            n_triples += 8
            function = "A:angle,S:position|A.rate;S.position*t;A.angle - S.speed"
        fixed = (n_triples > 1,) + (False,) * (n_triples - 1)
        printed.append(print_class(derive_class(ElementClass(kind, ends, fixed,
                                                             frozenset(), function))))
    assert all(p.n_ops > 0 for p in printed)
    check_strict_c(render_sources("kinds", structure_hash([p.cls for p in printed]),
                                  printed, ["-O2"], []), tmp_path)


# -- compiled kernels against direct evaluation ---------------------------------------

def test_compiled_kernels_match_direct_evaluation(expression_module):
    derived, _, module = expression_module
    rng = np.random.default_rng(7)
    for _ in range(3):
        q = rng.uniform(0.5, 1.5, 6)
        v = rng.uniform(0.2, 1.0, 6)
        p = rng.uniform(0.5, 1.5, 19)
        for name in ("mass_matrix", "h_vector", "constraints"):
            got = module.evaluate(name, 0, q, v, p)
            want = reference_values(derived, name, q, v, p)
            # Double rounding of a few dozen well-conditioned operations: ~1e-15.
            np.testing.assert_allclose(got, want, rtol=1e-14, atol=0, err_msg=name)
    assert np.count_nonzero(module.evaluate("mass_matrix", 0, q, v, p) == 0.0) == 5


def test_build_of_generated_c_prints_no_warnings(expression_module):
    _, built, _ = expression_module
    log = (built.directory / BUILD_LOG).read_text()
    assert "kernels.c" in log
    assert not [line for line in log.splitlines() if "warning:" in line]


def test_evaluate_returns_fresh_arrays(expression_module):
    _, _, module = expression_module
    q, v, p = np.full(6, 0.9), np.full(6, 0.5), np.full(19, 1.1)
    first = module.evaluate("h_vector", 0, q, v, p)
    second = module.evaluate("h_vector", 0, q, v, p)
    assert first is not second and not np.shares_memory(first, second)
    first[:] = -1.0
    np.testing.assert_array_equal(module.evaluate("h_vector", 0, q, v, p), second)


def test_evaluate_reports_bad_calls(expression_module):
    _, _, module = expression_module
    q, v, p = np.ones(6), np.ones(6), np.ones(19)
    with pytest.raises(ValueError, match="'energy' does not exist for class body_"):
        module.evaluate("energy", 0, q, v, p)
    with pytest.raises(ValueError, match="unknown kernel 'inertia'"):
        module.evaluate("inertia", 0, q, v, p)
    with pytest.raises(IndexError, match="class index 1 out of range"):
        module.evaluate("mass_matrix", 1, q, v, p)
    with pytest.raises(ValueError, match=r"q must hold 6 numbers .* \(got 5\)"):
        module.evaluate("mass_matrix", 0, q[:5], v, p)
    with pytest.raises(ValueError, match=r"v must hold 6 numbers"):
        module.evaluate("h_vector", 0, q, None, p)
    with pytest.raises(ValueError, match=r"p must hold 19 numbers"):
        module.evaluate("constraints", 0, q, v, p[:3])
