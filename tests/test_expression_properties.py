"""Property tests (Hypothesis, derandomized) of the expression grammar's guard: text
with a comment, a quote, an escape, a line break or any other odd token is refused,
wherever the odd part stands, and what the grammar accepts prints to C that holds
nothing but the printer's own tokens.

At the parse and print level only (no compiles), so that many cases stay fast.
"""
from __future__ import annotations

import re

import pytest
import sympy
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fccgen.errors import ModelError
from fccgen.expressions.grammar import parse_condition, parse_expression
from fccgen.printing.c99 import KernelPrinter
from fccgen.render.escape import c_comment, c_expression

NAMES = ("t", "A.angle", "A.rate", "S.position")
SYMBOLS = {n: sympy.Symbol(n.replace(".", "_"), real=True) for n in NAMES}
WHERE = dict(source="model.yaml", line=3, item="loads[0].value[2]")
PRINTER = KernelPrinter({s: f"x[{k}]" for k, s in enumerate(SYMBOLS.values())})
SETTINGS = settings(max_examples=400, derandomize=True, database=None, deadline=None,
                    suppress_health_check=list(HealthCheck))

# Pieces no accepted text may hold: comments, quotes, escapes, line breaks, control
# and non-ASCII characters, C comment and trigraph sequences, template syntax, and
# Python tokens outside the grammar.
ODD = ["#", "# */ system(x) /*", "'", '"', '"""', "\\", "\\n", "\n", "\r", "\t", "\0",
       "\x7f", "\x0b", "\x0c", "/*", "*/", "//", "??/", "??=", "{{", "}}", "{%", "%}",
       "[", "]", "{", "}", ":", ";", "%", "@", "`", "$", "?", "!", "~", "^", "&", "|",
       "=", ":=", "->", "...", "\u00e9", "\u2028", "\u200b", "\uff0a", "\U0001f600"]
odd = st.one_of(st.sampled_from(ODD),
                st.characters(min_codepoint=0x80, max_codepoint=0x10FFFF,
                              blacklist_categories=("Cs",)),
                st.characters(max_codepoint=0x1F))


def expressions():
    """Texts of the grammar over NAMES."""
    leaves = st.one_of(st.sampled_from(NAMES + ("pi",)),
                       st.integers(0, 10 ** 30).map(str),
                       st.floats(0, 1e6, allow_nan=False).map(repr))

    def extend(inner):
        return st.one_of(
            st.tuples(inner, st.sampled_from(["+", "-", "*", "/", "**"]), inner)
            .map(lambda x: f"({x[0]} {x[1]} {x[2]})"),
            inner.map(lambda x: f"-{x}"),
            st.tuples(st.sampled_from(["sin", "cos", "exp", "abs", "sqrt"]), inner)
            .map(lambda x: f"{x[0]}({x[1]})"),
            st.tuples(st.sampled_from(["min", "max", "atan2"]), inner, inner)
            .map(lambda x: f"{x[0]}({x[1]}, {x[2]})"))
    return st.recursive(leaves, extend, max_leaves=8)


@st.composite
def with_odd_piece(draw):
    """A text of the grammar with one to three odd pieces put in anywhere (the ends
    included, but never only ASCII whitespace at an end, which is stripped)."""
    text = draw(expressions())
    for _ in range(draw(st.integers(1, 3))):
        k = draw(st.integers(0, len(text)))
        text = text[:k] + draw(odd) + text[k:]
    return text


def accepts(parse, text) -> bool:
    try:
        parse(text, SYMBOLS, **WHERE)
    except ModelError as err:
        assert (err.file, err.line, err.item) == ("model.yaml", 3, "loads[0].value[2]")
        return False
    return True


C_EXPRESSION = re.compile(r"[A-Za-z0-9_.+\-*/(), \[\]]+")


@SETTINGS
@given(expressions())
def test_what_the_grammar_accepts_prints_as_plain_c(text):
    """An accepted expression prints to C made of names, numbers, array slots,
    operators and parentheses only; its text is printable ASCII and a C comment
    shows it unchanged."""
    try:
        expr = parse_expression(text, SYMBOLS, **WHERE)
    except ModelError:
        return                                   # 1/0, overflow: refused, fine
    code = PRINTER.doprint(expr)
    assert C_EXPRESSION.fullmatch(code), code
    assert c_expression(code) == code
    assert c_comment(text) == text


@SETTINGS
@given(with_odd_piece())
def test_an_odd_piece_anywhere_is_refused(text):
    """Whatever the odd piece and wherever it stands, the expression is refused with
    the file, line and item; so is a condition holding it."""
    stripped = text.strip(" \t\n\r\f\v")
    pieces_left = any(not ("0" <= c <= "9" or "A" <= c <= "Z" or "a" <= c <= "z"
                           or c in " _.+-*/(),") for c in stripped)
    odd_sequences = any(s in stripped for s in ("/*", "*/", "//"))
    if not (pieces_left or odd_sequences):
        return                 # the odd pieces were ASCII whitespace at the ends only
    assert not accepts(parse_expression, text), repr(text)
    assert not accepts(parse_condition, f"{text} >= 0"), repr(text)


@pytest.mark.parametrize("text", ["0.1*t # */ system(x) /*", "t /* x */", "t // x",
                                  "t ??/", "t\n+1", "(t\n+1)", "t\\\n+1", "t +\u00a01",
                                  "'t'", "(t # c\n + 1)", "t\0", "sin(t)\u2028"])
def test_known_breakers_are_refused(text):
    assert not accepts(parse_expression, text), repr(text)
