"""The restricted expression grammar of drivers, loads and events (docs/design.md §2b).

An expression is text such as ``"0.5*sin(3*t) + A.angle"``. Its characters and then
its tokens (:mod:`tokenize`) are checked first: only numbers, names, the operators
``+ - * / **``, parentheses, commas, dots and comparisons, separated by spaces, so that
the text holds nothing the grammar does not print itself -- no comment (``#``, which
Python's parser would drop silently), string, backslash, line break, control or
non-ASCII character (:func:`check_tokens`). The text is then read with
``ast.parse(text, mode="eval")`` -- parsing only, nothing is evaluated -- and the tree
is walked against a whitelist; everything else is refused with a :class:`ModelError`
that names the file, line, item, rule and the text seen. The grammar::

    expr     := expr (+ | - | * | / | **) expr | (- | +) expr | ( expr )
              | NUMBER | pi | NAME | NAME.QUANTITY | FUNC(expr, ...)
    NUMBER   := digits [. digits] [e|E [+|-] digits]   (at most 1e12 in magnitude)
    FUNC     := sin cos tan exp log sqrt abs  (1 argument) | atan2 (2) | min max (>= 2)
    condition:= expr (>= | > | <= | <) expr               (events; exactly one comparison)

``NAME`` and ``NAME.QUANTITY`` must be keys of the symbol table the caller passes
(``t``, ``A.angle``, ``S.speed``, ``P.x``, ...): a dotted name is one entry of the
table, never an attribute lookup. An entry that is a SymPy function class (a named
table, fccgen.expressions.named_tables) is called with one argument, ``name(expr)``.
Limits: :data:`MAX_CHARS` characters,
:data:`MAX_NODES` syntax-tree nodes, :data:`MAX_DEPTH` levels of nesting, numbers
written at most :data:`MAX_LITERAL` and constants computed at most
:data:`MAX_CONSTANT` in magnitude.

The result is a SymPy expression over the caller's symbols (pass real symbols, so that
derivatives of ``abs``, ``min``, ``max`` stay real), printable by fccgen's C printer:
``abs`` -> ``fabs``, ``min``/``max`` -> ``fmin``/``fmax``; ``pi`` is the double
nearest to pi (C99 has no standard name for it).
"""
from __future__ import annotations

import ast
import difflib
import io
import math
import re
import tokenize
from typing import Callable, Mapping

import sympy

from ..errors import ModelError

MAX_CHARS = 1000
MAX_NODES = 400
MAX_DEPTH = 32
# Every number written in an expression is at most MAX_LITERAL in magnitude, as every
# number of a model (fccgen.model.fields.MAX_MAGNITUDE); every constant the expression
# computes from them (a product or power of numbers, folded by SymPy) at most
# MAX_CONSTANT, the size of a product of two model numbers: beyond that, the kernels'
# products of loads, lengths and speeds overflow doubles (a 1e308 in a load stopped
# the run at its first step).
MAX_LITERAL = 1e12
MAX_CONSTANT = MAX_LITERAL ** 2
# Integer powers of exact numbers with exponents up to this stay exact (2**-3 = 1/8);
# other powers of numbers are computed in floating point, so that 10**10**10 is
# refused as an overflow instead of being computed digit by digit.
MAX_EXACT_EXPONENT = 64

# name -> (SymPy function, minimum and maximum number of arguments; None: no maximum)
FUNCTIONS: dict[str, tuple[Callable, int, int | None]] = {
    "sin": (sympy.sin, 1, 1), "cos": (sympy.cos, 1, 1), "tan": (sympy.tan, 1, 1),
    "exp": (sympy.exp, 1, 1), "log": (sympy.log, 1, 1), "sqrt": (sympy.sqrt, 1, 1),
    "abs": (sympy.Abs, 1, 1), "atan2": (sympy.atan2, 2, 2),
    "min": (sympy.Min, 2, None), "max": (sympy.Max, 2, None),
}
# pi as the double nearest to it: C99 has no standard name for it (M_PI is POSIX).
CONSTANTS = {"pi": sympy.Float(math.pi, 17)}
RESERVED = frozenset(FUNCTIONS) | frozenset(CONSTANTS)
FUNCTION_LIST = ", ".join(FUNCTIONS)
NUMBER = re.compile(r"(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")

BINARY = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
          ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b}
COMPARISONS = {ast.GtE: ">=", ast.Gt: ">", ast.LtE: "<=", ast.Lt: "<"}
DIRECTIONS = {ast.GtE: "rising", ast.Gt: "rising", ast.LtE: "falling", ast.Lt: "falling"}

# Syntax that is refused, with the rule that says why (anything else unlisted is
# refused too, by its node name).
REFUSED = {
    ast.Subscript: "subscripts (x[...]) are not allowed",
    ast.Lambda: "lambdas are not allowed",
    ast.IfExp: "conditional expressions (a if c else b) are not allowed",
    ast.BoolOp: "'and' and 'or' are not allowed",
    ast.Compare: "comparisons are allowed only as the one comparison of an event "
                 "condition",
    ast.JoinedStr: "strings are not allowed",
    ast.ListComp: "comprehensions are not allowed",
    ast.SetComp: "comprehensions are not allowed",
    ast.DictComp: "comprehensions are not allowed",
    ast.GeneratorExp: "comprehensions are not allowed",
    ast.Tuple: "tuples are not allowed", ast.List: "lists are not allowed",
    ast.Dict: "dictionaries are not allowed", ast.Set: "sets are not allowed",
    ast.Starred: "starred arguments are not allowed",
    ast.NamedExpr: "assignments (:=) are not allowed",
    ast.Await: "'await' is not allowed", ast.Yield: "'yield' is not allowed",
    ast.YieldFrom: "'yield' is not allowed", ast.Slice: "slices are not allowed",
}
OPERATOR_RULE = "operators are only + - * / ** and unary minus"

# -- characters and tokens ---------------------------------------------------------------
# Whitespace taken off both ends of a text before it is checked (only ASCII: any
# other character, U+2028 included, is refused wherever it stands).
ASCII_SPACE = " \t\n\r\f\v"
# Operator tokens the grammar reads (== and != are refused later, with their reason).
TOKEN_OPERATORS = frozenset({"+", "-", "*", "/", "**", "(", ")", ",", ".",
                             ">=", ">", "<=", "<", "==", "!="})
# Characters refused outright, with the rule that says why.
REFUSED_CHARACTERS = {
    "#": "a '#' comment is not allowed (the text after '#' would be ignored, not read)",
    "'": "strings are not allowed (no quotes)",
    '"': "strings are not allowed (no quotes)",
    "\\": "backslashes are not allowed",
    "\n": "line breaks are not allowed (an expression is one line)",
    "\r": "line breaks are not allowed (an expression is one line)",
    "\t": "tabs are not allowed (separate tokens with spaces)",
}
# Operator tokens refused, with the rule that says why.
REFUSED_TOKENS = {
    "[": "brackets [ ] are not allowed (no subscripts, lists or comprehensions)",
    "]": "brackets [ ] are not allowed (no subscripts, lists or comprehensions)",
    "{": "braces { } are not allowed (no sets or dictionaries)",
    "}": "braces { } are not allowed (no sets or dictionaries)",
    ":": "':' is not allowed (no lambdas, slices or annotations)",
    ":=": "assignments (:=) are not allowed",
    ";": "';' is not allowed (one expression only)",
    "=": "'=' is not allowed (no assignments or keyword arguments)",
    "->": "'->' is not allowed",
    "...": "'...' is not allowed",
}


def check_tokens(text: str, fail) -> None:
    """Refuse (``raise fail(rule)``) text holding a character or token the grammar does
    not print itself: anything but printable ASCII, '#', quotes, backslashes; tokens
    other than numbers written as NUMBER, names and :data:`TOKEN_OPERATORS`. A text
    whose brackets do not close is left to the parser, which says so."""
    for k, ch in enumerate(text):
        if ch in REFUSED_CHARACTERS:
            raise fail(REFUSED_CHARACTERS[ch])
        if not " " <= ch <= "~":
            what = ("a control character" if ord(ch) < 32 or ord(ch) == 127 else
                    "a non-ASCII character")
            raise fail(f"only ASCII letters, digits, spaces and the operators of the "
                       f"grammar are allowed; character {k + 1} is {what} "
                       f"(U+{ord(ch):04X})")
    try:
        for tok in tokenize.generate_tokens(io.StringIO(text).readline):
            if tok.type in (tokenize.NEWLINE, tokenize.NL, tokenize.ENDMARKER,
                            tokenize.INDENT, tokenize.DEDENT, tokenize.NAME):
                continue
            if tok.type == tokenize.NUMBER:
                if not NUMBER.fullmatch(tok.string):
                    raise fail(f"numbers are written as 12, 1.5 or 2.5e-3, not "
                               f"{tok.string}")
                continue
            if tok.type == tokenize.OP and tok.string in TOKEN_OPERATORS:
                continue
            if tok.type == tokenize.OP:
                raise fail(REFUSED_TOKENS.get(tok.string, OPERATOR_RULE
                                              + f" ('{tok.string}' is not one)"))
            raise fail(f"'{tok.string}' is not part of the grammar (only numbers, names, "
                       "+ - * / **, parentheses, commas, dots and comparisons)")
    except (tokenize.TokenError, IndentationError, SyntaxError):
        return             # unclosed brackets and the like: the parser's message


class _Walker:
    """Converts one checked syntax tree to SymPy, raising ModelError on any node that
    is not whitelisted."""

    def __init__(self, text: str, symbols: Mapping[str, sympy.Symbol], fail):
        self.text = text
        self.symbols = symbols
        self.fail = fail

    def convert(self, node: ast.AST, depth: int = 0) -> sympy.Expr:
        if depth > MAX_DEPTH:
            raise self.fail(f"nests deeper than {MAX_DEPTH} levels")
        if isinstance(node, ast.BinOp):
            return self.binary(node, depth)
        if isinstance(node, ast.UnaryOp):
            if not isinstance(node.op, (ast.USub, ast.UAdd)):
                raise self.fail(OPERATOR_RULE)
            x = self.convert(node.operand, depth + 1)
            return self.finite(-x if isinstance(node.op, ast.USub) else x)
        if isinstance(node, ast.Constant):
            return self.number(node)
        if isinstance(node, ast.Name):
            return self.name(node.id)
        if isinstance(node, ast.Attribute):
            return self.name(self.dotted(node))
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        raise self.fail(REFUSED.get(type(node), f"{type(node).__name__} syntax is not "
                                                "allowed in an expression"))

    def binary(self, node: ast.BinOp, depth: int) -> sympy.Expr:
        a = self.convert(node.left, depth + 1)
        b = self.convert(node.right, depth + 1)
        if isinstance(node.op, ast.Pow):
            return self.power(a, b)
        op = BINARY.get(type(node.op))
        if op is None:
            raise self.fail(OPERATOR_RULE)
        if isinstance(node.op, ast.Div) and b.is_zero:
            raise self.fail("divides by zero")
        try:
            return self.finite(op(a, b))
        except (ZeroDivisionError, OverflowError):       # mpmath, on Float operands
            raise self.fail("divides by zero or overflows") from None

    def power(self, base: sympy.Expr, exp: sympy.Expr) -> sympy.Expr:
        """base ** exp; powers of two numbers are computed in floating point unless the
        exponent is a small integer (exact), so that no power of numbers can take long."""
        if not (base.is_Number and exp.is_Number):
            return self.finite(base ** exp)
        if exp.is_Integer and abs(int(exp)) <= MAX_EXACT_EXPONENT and base.is_Rational:
            if base.is_zero and exp < 0:
                raise self.fail("divides by zero (0 to a negative power)")
            return self.finite(base ** exp)
        try:
            value = float(base) ** float(exp)
        except (OverflowError, ZeroDivisionError):
            raise self.fail("a power of numbers overflows a double or divides by zero")
        if isinstance(value, complex) or not math.isfinite(value):
            raise self.fail("a power of numbers is not a finite real number")
        return sympy.Float(value)

    def number(self, node: ast.Constant) -> sympy.Expr:
        value = node.value
        if isinstance(value, str):
            raise self.fail("strings are not allowed")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail("only real numbers, names and functions are allowed")
        literal = ast.get_source_segment(self.text, node) or ""
        if not NUMBER.fullmatch(literal):
            raise self.fail(f"numbers are written as 12, 1.5 or 2.5e-3, not {literal}")
        if isinstance(value, int):
            try:
                finite = math.isfinite(float(value))
            except OverflowError:
                finite = False
        else:
            finite = math.isfinite(value)
        if not finite:
            raise self.fail(f"the number {literal} is not finite as a double")
        if abs(value) > MAX_LITERAL:
            raise self.fail(f"the number {literal} is larger than {MAX_LITERAL:g} in "
                            "magnitude (fccgen's limit on every number of a model)")
        return sympy.Integer(value) if isinstance(value, int) else sympy.Float(value)

    def dotted(self, node: ast.Attribute) -> str:
        """``Known.quantity``: a name, a dot and an attribute name; or a cable node's
        point quantity ``member.node.x`` (two dots) when the table holds it."""
        value = node.value
        if (isinstance(value, ast.Attribute) and isinstance(value.value, ast.Name)
                and f"{value.value.id}.{value.attr}.{node.attr}" in self.symbols):
            return f"{value.value.id}.{value.attr}.{node.attr}"
        if not isinstance(node.value, ast.Name):
            raise self.fail("attribute access is only Joint.quantity (a name, a dot and "
                            "a quantity, such as A.angle)")
        return f"{node.value.id}.{node.attr}"

    def name(self, name: str) -> sympy.Expr:
        if name in self.symbols and _is_call(self.symbols[name]):
            raise self.fail(f"{name!r} is a table: call it on an expression, as in "
                            f"{name}(A.angle)")
        if name in self.symbols:
            return self.symbols[name]
        if name in CONSTANTS:
            return CONSTANTS[name]
        if name in FUNCTIONS:
            raise self.fail(f"{name!r} is a function: call it, as in {name}(t)")
        owner = name.split(".")[0] + "."
        has = sorted(n for n in self.symbols if n.startswith(owner))
        if "." in name and has:
            raise self.fail(f"{owner[:-1]} has no quantity {name.split('.', 1)[1]!r} "
                            f"(it has {', '.join(has)})")
        known = sorted(self.symbols) + sorted(CONSTANTS)
        close = difflib.get_close_matches(name, known, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise self.fail(f"unknown name {name!r}{hint} (known: {', '.join(known)})")

    def call(self, node: ast.Call, depth: int) -> sympy.Expr:
        if (isinstance(node.func, ast.Name) and node.func.id in self.symbols
                and _is_call(self.symbols[node.func.id])):
            return self.table_call(node, depth)
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            tables = [n for n, f in self.symbols.items() if _is_call(f)]
            more = f" and the tables {', '.join(sorted(tables))}" if tables else ""
            raise self.fail(f"calls only {FUNCTION_LIST}{more}")
        name = node.func.id
        fun, low, high = FUNCTIONS[name]
        if node.keywords:
            raise self.fail(f"{name}() takes no keyword arguments")
        n = len(node.args)
        if n < low or (high is not None and n > high):
            want = (f"{low}" if low == high else f"at least {low}")
            raise self.fail(f"{name}() takes {want} argument{'s' if want != '1' else ''}, "
                            f"not {n}")
        args = [self.convert(a, depth + 1) for a in node.args]
        if name in ("sqrt", "log") and args[0].is_Number and args[0] < 0:
            raise self.fail(f"{name}() of a negative number is not real")
        try:
            return self.finite(fun(*args))
        except (ValueError, TypeError, ZeroDivisionError, OverflowError) as exc:
            # e.g. max() of a value SymPy knows to be complex: "is not comparable"
            raise self.fail(f"{name}() cannot take these arguments ({exc})") from None

    def table_call(self, node: ast.Call, depth: int) -> sympy.Expr:
        """``name(expr)``: a named table (a function class the caller put in the
        symbol table) of one argument."""
        name = node.func.id
        if node.keywords or len(node.args) != 1:
            raise self.fail(f"the table {name}() takes 1 argument, not "
                            f"{len(node.args) + len(node.keywords)}")
        return self.finite(self.symbols[name](self.convert(node.args[0], depth + 1)))

    def finite(self, expr: sympy.Expr) -> sympy.Expr:
        """``expr`` if it holds no infinity, NaN or imaginary unit, and, when it is a
        constant, its value is a finite double."""
        if expr.has(sympy.zoo, sympy.oo, sympy.nan, sympy.I):
            raise self.fail("is not a finite real number (division by zero, log(0), "
                            "a root of a negative number?)")
        if not expr.free_symbols:
            try:
                value = complex(expr.evalf(20))
            except (TypeError, ValueError, OverflowError):
                value = complex(math.inf)
            if value.imag != 0 or not math.isfinite(value.real):
                raise self.fail("a constant part is not a finite real double "
                                "(overflow?)")
        return expr

    def bounded(self, expr: sympy.Expr) -> sympy.Expr:
        """``expr`` if each of its constants is at most MAX_CONSTANT in magnitude."""
        for number in expr.atoms(sympy.Number):
            if abs(float(number)) > MAX_CONSTANT:
                raise self.fail(f"computes the constant {float(number):.6g}, larger than "
                                f"{MAX_CONSTANT:g} in magnitude (the kernels multiply it "
                                "by lengths, masses and speeds: doubles would overflow)")
        return expr


def _is_call(entry) -> bool:
    """Whether a symbol-table entry is a function to call (a named table), not a
    symbol."""
    return isinstance(entry, sympy.FunctionClass)


def finite_value(expr: sympy.Expr) -> bool:
    """True when the constant ``expr`` (an expression with its symbols substituted) is
    a finite real number: no infinity, NaN or imaginary part, as SymPy and as a
    double."""
    if expr.has(sympy.zoo, sympy.oo, -sympy.oo, sympy.nan):
        return False
    try:
        number = complex(expr.evalf(20))
    except (TypeError, ValueError, OverflowError, ZeroDivisionError):
        return False
    return number.imag == 0 and math.isfinite(number.real)


def _parse(text, symbols, source, line, item, mode_rule: str):
    """(syntax tree body, walker) of ``text`` after the length, syntax and size checks."""
    def fail(rule: str) -> ModelError:
        return ModelError(source, line, item, rule, text)

    if isinstance(text, bool) or not isinstance(text, (str, int, float)):
        raise ModelError(source, line, item, f"must be {mode_rule} written as text or "
                         f"a number", text)
    if not isinstance(text, str):           # a YAML number: the same as its text
        if isinstance(text, float) and not math.isfinite(text):
            raise ModelError(source, line, item, "must be a finite number", text)
        text = repr(text)
    reserved = RESERVED & set(symbols)
    if reserved:
        raise ValueError(f"symbol table uses reserved names {sorted(reserved)}")
    if len(text) > MAX_CHARS:
        raise ModelError(source, line, item, f"is longer than {MAX_CHARS} characters",
                         f"{text[:40]}... ({len(text)} characters)")
    text = text.strip(ASCII_SPACE)        # a YAML block scalar ends in a line break
    if not text:
        raise fail(f"must be {mode_rule}, not empty text")
    check_tokens(text, fail)
    try:
        tree = ast.parse(text, mode="eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError) as exc:
        reason = getattr(exc, "msg", None) or type(exc).__name__
        raise fail(f"is not {mode_rule} ({reason})") from None
    n_nodes = sum(1 for _ in ast.walk(tree))
    if n_nodes > MAX_NODES:
        raise fail(f"has more than {MAX_NODES} syntax nodes ({n_nodes})")
    return tree.body, _Walker(text, symbols, fail)


def parse_expression(text: str, symbols: Mapping[str, sympy.Symbol], *, source: str,
                     line: int | None, item: str) -> sympy.Expr:
    """The SymPy expression of ``text`` over ``symbols`` (name -> Symbol; dotted names
    such as ``"A.angle"`` are single entries; ``t`` is one too when time is allowed).
    A number (YAML ``0`` rather than ``"0"``) is read as its text.

    Raises ModelError(source, line, item, rule, text) for anything outside the grammar
    of the module docstring."""
    body, walker = _parse(text, symbols, source, line, item, "an expression")
    return walker.bounded(walker.convert(body))


def parse_condition(text: str, symbols: Mapping[str, sympy.Symbol], *, source: str,
                    line: int | None, item: str) -> tuple[sympy.Expr, str]:
    """An event condition ``lhs OP rhs`` with one OP of ``>= > <= <``.

    Returns ``(g, direction)`` with g = lhs - rhs: the event happens when g crosses
    zero upwards (``"rising"``, for >= and >) or downwards (``"falling"``, <= and <)."""
    body, walker = _parse(text, symbols, source, line, item, "a condition")
    if not isinstance(body, ast.Compare):
        raise walker.fail("a condition is one comparison, lhs >= rhs, lhs > rhs, "
                          "lhs <= rhs or lhs < rhs")
    if len(body.ops) != 1:
        raise walker.fail("a condition has exactly one comparison (no a < b < c)")
    op = type(body.ops[0])
    if op not in COMPARISONS:
        raise walker.fail("a condition compares with >=, >, <= or < (== and != never "
                          "cross zero reliably)")
    lhs = walker.convert(body.left, 1)
    rhs = walker.convert(body.comparators[0], 1)
    return walker.bounded(walker.finite(lhs - rhs)), DIRECTIONS[op]


def parse_event_function(text: str, symbols: Mapping[str, sympy.Symbol], *, source: str,
                         line: int | None, item: str) -> tuple[sympy.Expr, str | None]:
    """An event's ``when``: a condition ``lhs OP rhs`` (returns ``(lhs - rhs, its
    direction)``, see :func:`parse_condition`) or a scalar expression s (returns
    ``(s, None)``: the direction is the event's own ``direction`` key)."""
    body, walker = _parse(text, symbols, source, line, item, "an event function")
    if isinstance(body, ast.Compare):
        return parse_condition(text, symbols, source=source, line=line, item=item)
    return walker.bounded(walker.finite(walker.convert(body))), None
