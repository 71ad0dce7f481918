"""Integers beyond what a double holds exactly (|n| > 2**53) are printed as the double
nearest to them, never as C integer constants (which a compiler truncates to 64 bits,
with only a warning): the compiled run of a model holding one agrees with the NumPy
version, which reads the same numbers as Python numbers.

A model writes numbers of at most 1e12 (expressions.MAX_LITERAL), but the constants
it computes from them may reach 1e24 (MAX_CONSTANT): 4294967296**2 + 1 = 2**64 + 1
is such an integer, and a 64-bit C constant would make it 1."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import sympy

import fccgen
from fccgen.printing.c99 import KernelPrinter

N = 2 ** 64 + 1          # truncated to 1 as a 64-bit C integer constant
WRITTEN = "(4294967296**2 + 1)"
MODEL = f"""\
name: large_literals
gravity: [0, 0, -9.81]
bodies:
  arm: {{mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-4, 0.0833, 0.0833]}}
joints:
  - {{name: A, type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 1, 0]}}
loads:
  - {{type: torque, body: arm,
     value: [0, "2*min(1, {WRITTEN}*t) - 1.5 + sin({WRITTEN}*t)/{WRITTEN}", 0]}}
simulate: {{t_end: 0.2, dt: 1.0e-3, method: rk4}}
"""


@pytest.mark.parametrize("value, text", [
    (2 ** 53, "9007199254740992"), (2 ** 53 + 1, "9007199254740992.0"),
    (-(2 ** 53 + 1), "-9007199254740992.0"), (N, "1.8446744073709552e+19"),
    (10 ** 300, "1e+300"), (sympy.Rational(N, 3), "6.148914691236517e+18"),
    (sympy.Rational(1, N), "5.421010862427522e-20"), (sympy.Rational(1, 3), "1.0/3.0")])
def test_numbers_print_as_exact_or_nearest_doubles(value, text):
    assert KernelPrinter({}).doprint(sympy.sympify(value)) == text


def test_a_number_too_large_for_a_double_is_an_error():
    with pytest.raises(ValueError, match="too large for a double"):
        KernelPrinter({}).doprint(sympy.Integer(10 ** 400))


def test_compiled_run_agrees_with_numeric(tmp_path, build_dir):
    """The torque is 2 min(1, N t) - 1.5 + sin(N t)/N, 0.5 N m for t > 0 (with N
    truncated to 1 it would ramp up from -1.5 N m over a second). Both versions
    integrate the same equations with RK4 at the same step: they differ by rounding
    only, 1e-9 rad over 200 steps (the angle reaches ~0.05 rad)."""
    path = tmp_path / "large_literals.yaml"
    path.write_text(MODEL)
    c = fccgen.load(path, build_dir)
    n = fccgen.load_numeric(path)
    rc, rn = (s.simulate(q0=s.initial_state().q, v0=s.initial_state().v)
              for s in (c, n))
    assert np.max(np.abs(rc["A.angle"] - rn["A.angle"])) <= 1e-9
    assert abs(rn["A.angle"][-1]) > 1e-3                   # the torque did act
    folder = Path(c.module.__file__).parent             # the compiler said nothing
    assert "integer constant" not in (folder / "build.log").read_text()
    code = re.sub(r"/\*.*?\*/", "", (folder / "kernels.c").read_text(), flags=re.DOTALL)
    assert str(N) not in code and "1.8446744073709552e+19" in code
