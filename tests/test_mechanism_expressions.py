"""The restricted expression grammar (fccgen/expressions/grammar.py): every allowed
construct gives the value Python's math gives, in SymPy and compiled from fccgen's C
printer; every forbidden construct is refused with file, line, item, rule and value."""
from __future__ import annotations

import ctypes
import math
import random
import subprocess
import sysconfig

import pytest
import sympy

from fccgen.errors import ModelError
from fccgen.expressions.grammar import (MAX_CHARS, MAX_DEPTH, parse_condition,
                                          parse_expression)
from fccgen.printing.c99 import KernelPrinter

NAMES = ("t", "A.angle", "A.rate", "S.position", "P.x")
SYMBOLS = {n: sympy.Symbol(n.replace(".", "_"), real=True) for n in NAMES}
WHERE = dict(source="model.yaml", line=12, item="drivers[0].angle")
# the values the names take in the checks (all in the domains of log, sqrt, ...)
VALUES = {"t": 0.7, "A.angle": 1.3, "A.rate": -0.4, "S.position": 2.5, "P.x": 0.25}
t, a, w, s, x = (VALUES[n] for n in NAMES)

# (text, the same formula in Python's math)
ALLOWED = [
    ("t", t), ("10*t", 10 * t), ("A.angle + A.rate - S.position", a + w - s),
    ("2*t*A.angle/3", 2 * t * a / 3), ("t**2", t ** 2), ("t**-1.5", t ** -1.5),
    ("2**-3", 2 ** -3), ("-t", -t), ("+t", t), ("-(t - 1)**3", -(t - 1) ** 3),
    ("1.5e-3*S.position", 1.5e-3 * s), ("2E2 + .5 + 3.", 2e2 + .5 + 3.),
    ("pi*t", math.pi * t), ("sin(3*t)", math.sin(3 * t)), ("cos(A.angle)", math.cos(a)),
    ("tan(t)", math.tan(t)), ("exp(-t)", math.exp(-t)), ("log(S.position)", math.log(s)),
    ("sqrt(S.position)", math.sqrt(s)), ("abs(A.rate)", abs(w)),
    ("atan2(A.rate, -t)", math.atan2(w, -t)), ("atan2(t, 2)", math.atan2(t, 2)),
    ("min(t, A.angle)", min(t, a)), ("max(t, A.rate, P.x)", max(t, w, x)),
    ("0.5*sin(3*t) + max(0, min(1, 2*t))**2", 0.5 * math.sin(3 * t) + max(0, min(1, 2 * t)) ** 2),
    ("t / (1 + A.angle**2)", t / (1 + a ** 2)),
    ("((((t))))", t), ("1/3", 1 / 3), ("10**300 * 1e-300", 1.0),
]
IDS = [text for text, _ in ALLOWED]


def parse(text):
    return parse_expression(text, SYMBOLS, **WHERE)


def at_values(expr) -> float:
    subs = {SYMBOLS[n]: VALUES[n] for n in NAMES}
    return float(expr.subs(subs).evalf(30))


@pytest.mark.parametrize("text, want", ALLOWED, ids=IDS)
def test_allowed_constructs_evaluate_as_python_math(text, want):
    """Rounding of at most a few operations in doubles against SymPy's 30 digits:
    1e-14 relative."""
    assert at_values(parse(text)) == pytest.approx(want, rel=1e-14, abs=1e-300)


def test_parsed_expressions_compile_with_the_kernel_printer(tmp_path):
    """Each allowed expression, printed by fccgen's C printer into one C function
    (inputs x[0..4] = the names), compiles under -std=c99 -Wall -Wextra -Werror and
    gives Python's value to 1e-13 relative (libm against Python's math: an ulp or two,
    amplified by at most a few operations)."""
    printer = KernelPrinter({SYMBOLS[n]: f"x[{k}]" for k, n in enumerate(NAMES)})
    bodies = [f"    out[{k}] = {printer.doprint(parse(text))};"
              for k, (text, _) in enumerate(ALLOWED)]
    code = ("#include <math.h>\n"
            "void expressions(const double *x, double *out)\n{\n"
            + "\n".join(bodies) + "\n}\n")
    for fn in ("fabs(", "atan2(", "fmin(", "fmax(", "sqrt(", "pow(", "exp(", "log("):
        assert fn in code, fn
    (tmp_path / "expr.c").write_text(code)
    cc = (sysconfig.get_config_var("CC") or "cc").split()
    run = subprocess.run([*cc, "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
                          "-shared", "-fPIC", "-o", "expr.so", "expr.c", "-lm"],
                         cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    lib = ctypes.CDLL(str(tmp_path / "expr.so"))
    inputs = (ctypes.c_double * len(NAMES))(*(VALUES[n] for n in NAMES))
    out = (ctypes.c_double * len(ALLOWED))()
    lib.expressions(inputs, out)
    for k, (text, want) in enumerate(ALLOWED):
        assert out[k] == pytest.approx(want, rel=1e-13, abs=1e-300), text


# (text, a fragment of the rule the error must state)
FORBIDDEN = [
    ("__import__('os')", "strings are not allowed"),
    ("__import__(os)", "calls only sin, cos, tan, exp, log, sqrt, abs, atan2, min, max"),
    ("().__class__", "attribute access is only Joint.quantity"),
    ("t.real", "unknown name 't.real'"),
    ("A.angle.x", "attribute access is only Joint.quantity"),
    ("open(f)", "calls only sin"),
    ("eval(1)", "calls only sin"),
    ("sin(t, 2)", "sin() takes 1 argument, not 2"),
    ("atan2(t)", "atan2() takes 2 arguments, not 1"),
    ("min(t)", "min() takes at least 2 arguments, not 1"),
    ("sin(x=t)", "no assignments or keyword arguments"),
    ("x[0]", "subscripts"),
    ("lambda: 0", "no lambdas"),
    ("lambda t, /: 0", "no lambdas"),
    ("t if t>0 else -t", "conditional expressions"),
    ('"str"', "strings are not allowed"),
    ("f'{t}'", "strings are not allowed"),
    ("1 if t else 2", "conditional expressions"),
    ("t == 1", "comparisons are allowed only"),
    ("t < 1", "comparisons are allowed only"),
    ("a and b", "'and' and 'or' are not allowed"),
    ("not t", "operators are only"),
    ("t % 2", "operators are only"),
    ("t // 2", "operators are only"),
    ("t @ t", "operators are only"),
    ("[t]", "no subscripts, lists or comprehensions"),
    ("(t, 1)", "tuples are not allowed"),
    ("{t}", "no sets or dictionaries"),
    ("[i for i in t]", "comprehensions"),
    ("(y := 1)", "assignments"),
    ("sin(*t)", "starred"),
    ("10**10**10", "overflows"),
    ("1e999", "not finite"),
    ("9" * 400, "not finite"),
    ("exp(1000)", "not a finite real double"),
    ("1/0", "divides by zero"),
    ("(0-0.5)/((pi+-3)**(1+1e12))", "divides by zero"),      # a power underflowing to 0.0
    ("1e308*t", "the number 1e308 is larger than 1e+12 in magnitude"),
    ("10.0**300*t", "computes the constant 1e+300, larger than 1e+24"),
    ("t*(10**12)**3", "computes the constant 1e+36"),
    ("max(1, log(-4*10**t))", "max() cannot take these arguments"),
    ("0**-1", "divides by zero"),
    ("log(0)", "not a finite real number"),
    ("sqrt(-1)", "not real"),
    ("(-8)**0.5", "not a finite real number"),
    ("0x10", "numbers are written as"),
    ("1_000", "numbers are written as"),
    ("1j", "numbers are written as"),
    ("True", "only real numbers"),
    ("None", "only real numbers"),
    ("B.angel", "unknown name 'B.angel'; did you mean 'A.angle'?"),
    ("sin", "'sin' is a function"),
    ("sin(t", "is not an expression"),
    ("t;1", "one expression only"),
    ("t*/1", "is not an expression"),
    ("", "not empty text"),
    ("-" * (MAX_DEPTH + 1) + "t", f"nests deeper than {MAX_DEPTH} levels"),
    ("sin(" * 40 + "t" + ")" * 40, "nests deeper"),
    ("(" * 300 + "t" + ")" * 300, "is not an expression"),
    ("+".join(["t"] * 300), "syntax nodes"),
    ("t+" * MAX_CHARS + "t", f"longer than {MAX_CHARS} characters"),
]


@pytest.mark.parametrize("text, rule", FORBIDDEN, ids=[f[0][:30] for f in FORBIDDEN])
def test_forbidden_constructs_are_refused_with_where_and_rule(text, rule):
    with pytest.raises(ModelError) as info:
        parse(text)
    message = str(info.value)
    assert message.startswith("model.yaml:12: drivers[0].angle: "), message
    assert rule in message
    err = info.value
    assert (err.file, err.line, err.item) == ("model.yaml", 12, "drivers[0].angle")
    if len(text) <= MAX_CHARS:
        assert err.value == text.strip()


def test_only_names_of_the_table_are_known():
    """The caller says which dotted names exist: a point coordinate is refused where
    the table does not offer it."""
    assert parse("P.x") == SYMBOLS["P.x"]
    with pytest.raises(ModelError, match=r"unknown name 'P\.x'.*known: t, pi"):
        parse_expression("P.x", {"t": SYMBOLS["t"]}, **WHERE)
    with pytest.raises(ValueError, match="reserved"):
        parse_expression("t", {"t": SYMBOLS["t"], "sin": SYMBOLS["t"]}, **WHERE)
    assert parse_expression(3, SYMBOLS, **WHERE) == 3       # a YAML number
    assert parse_expression(-2.5e-3, SYMBOLS, **WHERE) == -2.5e-3
    with pytest.raises(ModelError, match="not finite as a double"):
        parse_expression(10 ** 400, SYMBOLS, **WHERE)
    for bad in (True, None, [1, 2], float("inf"), float("nan")):
        with pytest.raises(ModelError, match="must be an expression written as text or "
                                             "a number|must be a finite number"):
            parse_expression(bad, SYMBOLS, **WHERE)


@pytest.mark.parametrize("text, direction, value", [
    ("A.angle >= 3.14159", "rising", a - 3.14159),
    ("A.angle > pi/2", "rising", a - math.pi / 2),
    ("S.position <= 0.1", "falling", s - 0.1),
    ("2*t < sin(A.angle)", "falling", 2 * t - math.sin(a)),
])
def test_conditions_give_g_and_direction(text, direction, value):
    g, d = parse_condition(text, SYMBOLS, **WHERE)
    assert d == direction
    assert at_values(g) == pytest.approx(value, rel=1e-14)


@pytest.mark.parametrize("text, rule", [
    ("A.angle", "a condition is one comparison"),
    ("t == 1", "compares with >=, >, <= or <"),
    ("t != 1", "compares with >=, >, <= or <"),
    ("0 < t < 1", "exactly one comparison"),
    ("t >= 1 and t <= 2", "a condition is one comparison"),
    ("(t >= 1) >= 0", "comparisons are allowed only"),
    ("t >= open(x)", "calls only sin"),
    ("t >= 1 # */", "comment"),
    ("t >= 1/0", "divides by zero"),
])
def test_bad_conditions_are_refused(text, rule):
    with pytest.raises(ModelError) as info:
        parse_condition(text, SYMBOLS, **WHERE)
    assert str(info.value).startswith("model.yaml:12: drivers[0].angle: ")
    assert rule in str(info.value)


def _random_expression(rng, depth):
    """A random expression of the grammar, with numbers at the edges of its limits."""
    leaves = ["t", "A.angle", "0", "1", "2", "0.5", "1e12", "1e-308", "pi", "-1", "10"]
    if depth == 0 or rng.random() < 0.25:
        return rng.choice(leaves)
    r = rng.random()
    if r < 0.5:
        return (f"({_random_expression(rng, depth - 1)}{rng.choice('+-*/') if r < 0.4 else '**'}"
                f"{_random_expression(rng, depth - 1)})")
    if r < 0.6:
        return "-" + _random_expression(rng, depth - 1)
    name = rng.choice(["sin", "cos", "tan", "exp", "log", "sqrt", "abs", "atan2", "min", "max"])
    n = 2 if name == "atan2" else rng.randint(2, 3) if name in ("min", "max") else 1
    return f"{name}({', '.join(_random_expression(rng, depth - 1) for _ in range(n))})"


def test_random_text_gives_an_expression_or_a_model_error():
    """Fuzzing: random expressions of the grammar (overflows, zero divisions, logs of
    negative numbers included) and random token soup either parse or raise ModelError;
    no other exception escapes, and what parses is finite where it is constant."""
    rng = random.Random(5)
    tokens = ["t", "A.angle", "1", "0", "2.5", "1e12", "(", ")", "+", "-", "*", "/",
              "**", "sin(", "atan2(", "min(", ",", "pi", ".", ">=", "<", "A", "angle",
              "[", "]", "'", ":", "lambda", "if", "else", "and", "__class__"]
    texts = [_random_expression(rng, 4) for _ in range(400)]
    texts += [" ".join(rng.choice(tokens) for _ in range(rng.randint(1, 12)))
              for _ in range(1000)]
    parsed = 0
    for text in texts:
        try:
            expr = parse(text)
        except ModelError:
            continue
        parsed += 1
        if not expr.free_symbols:
            assert math.isfinite(float(expr)), text
    assert parsed > 300                    # the generator does reach the grammar
