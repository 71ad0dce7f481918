"""Named tables: functions of one argument that a load's expressions call by name
(docs/flexible.md "Tape-spring hinges", docs/model-file.md "tables").

The model file's ``tables:`` section names each table and its CSV file
(``hinge_moment: {file: hinge_moment.csv}``); a force or torque then calls it on an
expression, ``hinge_moment(H.angle)``. The rows are read and checked once, when the
model is loaded (:func:`fccgen.expressions.tables.read_table`: the same folder rules,
size limits and messages as a driver's table), and interpolated by the same clamped
cubic spline, held constant outside the rows.

A load carries its tables in its function text, after its three expressions::

    ex;ex;ex@name=table:<hash>:x,y x,y ...@name2=...

(:data:`SEPARATOR` is refused by the expression grammar, so it never occurs in an
expression; each table's text is :func:`fccgen.expressions.tables.table_text`, every
number written by ``repr``). The element class's key therefore changes with the
table's rows, never with its file's name, and no file is read after loading. Only the
numbers reach generated code: a table prints as the C of its polynomials
(:class:`fccgen.expressions.tables.TableFunction`).
"""
from __future__ import annotations

import hashlib
from functools import lru_cache

import numpy as np

SEPARATOR = "@"
# fccgen.expressions.tables (which imports SymPy) is imported inside the functions that
# need it: the runtime path reads a load's text (expressions_of) without SymPy.


def with_tables(expressions: str, tables: dict[str, tuple[np.ndarray, np.ndarray]]) -> str:
    """The function text of a load: ``expressions`` ("ex;ex;ex") and the rows of the
    tables it calls (name -> (x, y)), in name order."""
    from .tables import table_text
    return "".join([expressions, *(f"{SEPARATOR}{name}={table_text(*tables[name])}"
                                   for name in sorted(tables))])


def split_tables(text: str) -> tuple[str, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """(expressions, name -> (x, y)) of a function text made by :func:`with_tables`."""
    from .tables import table_rows
    expressions, *parts = text.split(SEPARATOR)
    tables = {}
    for part in parts:
        name, rows = part.split("=", 1)
        tables[name] = table_rows(rows)
    return expressions, tables


def expressions_of(text: str) -> str:
    """The expressions of a function text, without its tables."""
    return text.split(SEPARATOR, 1)[0]


def spline_class(x: np.ndarray, y: np.ndarray):
    """The TableFunction class of the rows (x, y) (one class per content)."""
    from .tables import spline_coefficients, table_function
    key = hashlib.sha256(np.concatenate([x, y]).tobytes()).hexdigest()[:12]
    return table_function(key, x, spline_coefficients(x, y))


def table_symbols(text: str) -> tuple[str, dict]:
    """(expressions, name -> TableFunction class) of a function text: the entries
    the expression grammar takes beside its symbols (a name it may call)."""
    expressions, tables = split_tables(text)
    return expressions, {name: spline_class(*rows) for name, rows in tables.items()}


def short_text(text: str) -> str:
    """The function text with each table written as its name and hash (for reports:
    the rows are long)."""
    expressions, *parts = text.split(SEPARATOR)
    return "".join([expressions, *(f"{SEPARATOR}{':'.join(p.split(':')[:2])}"
                                   for p in parts)])


@lru_cache(maxsize=64)
def numeric_splines(text: str) -> dict:
    """name -> function x -> (value, derivative) of each table of a function text,
    evaluated by SciPy's spline of the rows (the numeric version's own evaluation,
    independent of the polynomials TableFunction prints), constant outside."""
    from scipy.interpolate import CubicSpline

    out = {}
    for name, (x, y) in split_tables(text)[1].items():
        spline = CubicSpline(x, y, bc_type="clamped")
        slope = spline.derivative()

        def evaluate(a: float, x=x, y=y, spline=spline, slope=slope):
            if a < x[0]:
                return float(y[0]), 0.0
            if a >= x[-1]:
                return float(y[-1]), 0.0
            return float(spline(a)), float(slope(a))
        out[name] = evaluate
    return out
