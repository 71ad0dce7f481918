"""Tabulated functions of time: a CSV file of (t, value) rows as a piecewise cubic.

The rows are interpolated by a cubic spline with *clamped* ends (first derivative zero
at the first and last row, :class:`scipy.interpolate.CubicSpline` with
``bc_type="clamped"``) and held constant outside the table: the value and its first
derivative are continuous everywhere (a driver given by a table starts and ends at
rest, with no velocity jump); the second derivative jumps at the first and last rows.
On row interval k, with s = t - t_k::

    f(t) = y_k + s (c1_k + s (c2_k + s c3_k))          t_k <= t < t_(k+1)
    f(t) = y_0  for t < t_0,   f(t) = y_(n-1)  for t >= t_(n-1)

The result is a SymPy function application ``table_<hash>(t)`` (a
:class:`TableFunction`): SymPy treats it as one opaque function, so derivatives and
common-subexpression elimination cost nothing however long the table is (a SymPy
``Piecewise`` of 200 intervals took 10 s to differentiate); its derivative is the
function of the derivative polynomials, and it prints to C (``_ccode``) as nested
``?:`` expressions searching the intervals by bisection (depth log2 n).
:meth:`TableFunction.as_piecewise` gives the same function as a ``Piecewise``.

The file: UTF-8 text, one ``t, value`` row per line, comma separated; blank lines and
lines starting with ``#`` are skipped, and a first row that is not two numbers is
taken as a header. At least 2 and at most :data:`MAX_ROWS` rows, finite numbers, t
strictly increasing. A relative path is taken relative to the model file.

Which files: a table is read only from a regular file under the model file's folder,
or under a folder the user names in the environment variable ``FCCGEN_TABLE_DIRS``
(:data:`FOLDERS_VARIABLE`), symlinks resolved before the check; at most
:data:`MAX_BYTES` bytes are read. Errors say which row and field is wrong, never
what it holds: a model file shared with others cannot make fccgen show a file's text.
"""
from __future__ import annotations

import csv
import hashlib
import io
import math
import os
import stat
from pathlib import Path

import numpy as np
import sympy
from scipy.interpolate import CubicSpline

from ..errors import ModelError, os_reason

# Each interval prints as about 190 bytes of C; gcc -O2 compiled a 1,000-row table
# (value times second derivative, 385 kB) in 8 s and 0.2 GB, a 10,000-row one in 125 s
# and 1.1 GB (measured): longer tables would need data arrays and a lookup kernel.
MAX_ROWS = 1_000
MAX_BYTES = 1_000_000
# Folders besides the model file's own that tables may be read from (os.pathsep
# separated): the user names them; a model file cannot.
FOLDERS_VARIABLE = "FCCGEN_TABLE_DIRS"


def _fail(source, line, item, rule, value):
    return ModelError(source, line, item, rule, value)


def table_folders(source: str) -> list[Path]:
    """The folders a model's tables may be read from, symlinks resolved: the model
    file's own folder, then each folder of the environment variable
    :data:`FOLDERS_VARIABLE` (separated by ``os.pathsep``; relative ones from the
    current folder)."""
    folders = [Path(source).resolve().parent]
    for entry in os.environ.get(FOLDERS_VARIABLE, "").split(os.pathsep):
        if entry.strip():
            folders.append(Path(entry).resolve())
    return folders


def table_path(path: str, source: str) -> Path:
    """``path`` as written, relative to the model file's folder unless absolute."""
    p = Path(path)
    return p if p.is_absolute() else Path(source).resolve().parent / p


def _open_table(path: str, source: str, fail) -> bytes:
    """The bytes of the table file ``path`` (relative to the model file ``source``),
    at most MAX_BYTES of them, from a regular file under one of
    :func:`table_folders`; ``raise fail(rule)`` for anything else. No rule quotes the
    file's contents."""
    if not isinstance(path, str) or not path.strip() or "\0" in path:
        raise fail("table must name a file (a path relative to the model file)")
    folders = table_folders(source)
    try:
        file = table_path(path, source).resolve(strict=True)     # symlinks resolved
    except FileNotFoundError:
        raise fail(f"table file does not exist ({table_path(path, source)})") from None
    except (OSError, RuntimeError) as exc:                      # a symlink loop, ...
        why = os_reason(exc) if isinstance(exc, OSError) else str(exc)
        raise fail(f"table file cannot be opened ({why})") from None
    if not any(file.is_relative_to(folder) for folder in folders):
        raise fail(f"table file {file} is outside the model file's folder {folders[0]}: "
                   f"a table may read only files under that folder, or under a folder "
                   f"named in the environment variable {FOLDERS_VARIABLE}")
    try:
        fd = os.open(file, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)
                     | getattr(os, "O_NOFOLLOW", 0))
    except OSError as exc:
        raise fail(f"table file cannot be opened ({os_reason(exc)})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise fail("table file is not a regular file (a folder, a device or a pipe)")
        if info.st_size > MAX_BYTES:
            raise fail(f"table file is larger than {MAX_BYTES} bytes")
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(MAX_BYTES + 1)
    except OSError as exc:
        raise fail(f"table file cannot be read ({os_reason(exc)})") from None
    finally:
        os.close(fd)
    if len(data) > MAX_BYTES:
        raise fail(f"table file is larger than {MAX_BYTES} bytes")
    return data


def read_table(path: str, *, source: str, line: int | None, item: str,
               columns: tuple[str, str] = ("t", "value")
               ) -> tuple[np.ndarray, np.ndarray]:
    """(t, values) of a table file, checked as the module docstring says; ``columns``
    name the two columns in messages (an angle table: ("angle", "moment"))."""
    def fail(rule: str) -> ModelError:
        return _fail(source, line, item, rule, path)

    data = _open_table(path, source, fail)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise fail(f"table file cannot be read as UTF-8 text (byte {exc.start + 1} is "
                   "not UTF-8)") from None
    rows: list[tuple[float, float]] = []
    numbers: list[int] = []                 # the file's row number of each row
    first = True                            # the first row may be a header
    reader = csv.reader(io.StringIO(text))
    number = 0
    while True:
        try:
            fields = next(reader)
        except StopIteration:
            break
        except csv.Error as exc:            # a field over csv's limit, a NUL, ...
            raise fail(f"{path} row {reader.line_num}: cannot be read as CSV ({exc})"
                       ) from None
        number = reader.line_num
        if not fields or not "".join(fields).strip() or fields[0].lstrip().startswith("#"):
            continue
        values = _row(fields)
        if values is None and not (first and _is_header(fields)):
            raise fail(f"{path} row {number}: must be two finite numbers "
                       f"{columns[0]}, {columns[1]} ({_row_problem(fields)})")
        first = False
        if values is not None:
            rows.append(values)
            numbers.append(number)
        if len(rows) > MAX_ROWS:
            raise fail(f"table has more than {MAX_ROWS} rows")
    if len(rows) < 2:
        raise fail("table must have at least 2 rows")
    t, y = np.array(rows).T
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        k = int(bad[0])
        x = columns[0]
        raise fail(f"{path} row {numbers[k + 1]}: {x} must increase strictly from row "
                   f"to row ({x} = {float(t[k])!r} is followed by {x} = "
                   f"{float(t[k + 1])!r})")
    return t, y


def _row_problem(fields: list[str]) -> str:
    """What is wrong with a row, in words that quote none of its text (the file may
    be one the model should not show)."""
    if len(fields) != 2:
        return f"found {len(fields)} fields"
    for k, text in enumerate(fields, 1):
        try:
            x = float(text)
        except ValueError:
            return f"field {k} is not a number"
        if not math.isfinite(x):
            return f"field {k} is not finite"
    return "not two numbers"


def _is_header(fields: list[str]) -> bool:
    """A first row is a header when it is not two numbers (a row of two numbers that
    are not finite, such as ``nan``, is refused, not skipped)."""
    if len(fields) != 2:
        return True
    try:
        float(fields[0]), float(fields[1])
    except ValueError:
        return True
    return False


def _row(fields: list[str]) -> tuple[float, float] | None:
    if len(fields) != 2:
        return None
    try:
        t, y = float(fields[0]), float(fields[1])
    except ValueError:
        return None
    return (t, y) if math.isfinite(t) and math.isfinite(y) else None


def spline_coefficients(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per interval k, [y_k, c1_k, c2_k, c3_k] of y_k + s c1 + s^2 c2 + s^3 c3
    (shape (n - 1, 4)), from the clamped cubic spline through the rows."""
    c = CubicSpline(t, y, bc_type="clamped").c          # (4, n - 1), highest power first
    return c[::-1].T.copy()


class TableFunction(sympy.Function):
    """The k-th derivative of a tabulated function (k = ``order``); each table and
    order is its own subclass (see :func:`table_function`), carrying ``knots`` t_0..,
    ``coef`` (per interval, ascending powers of s = t - t_k) and the constant values
    ``outside`` = (before t_0, from t_(n-1) on)."""
    nargs = 1
    knots: np.ndarray
    coef: np.ndarray
    outside: tuple[float, float]
    order: int
    table_key: str

    @classmethod
    def eval(cls, x):
        if x.is_Number:
            return sympy.Float(cls.value(float(x)))
        return None

    @classmethod
    def value(cls, x: float) -> float:
        """The function at a number x (NumPy evaluation of the same polynomials)."""
        t = cls.knots
        if x < t[0]:
            return cls.outside[0]
        if x >= t[-1]:
            return cls.outside[1]
        k = min(int(np.searchsorted(t, x, side="right")) - 1, len(t) - 2)
        return float(np.polynomial.polynomial.polyval(x - t[k], cls.coef[k]))

    def _eval_is_real(self):
        """Real: a table is evaluated at real arguments only (the time, a joint
        quantity, atan2 of real numbers, which SymPy cannot prove real when both
        could be 0), so abs() of a table differentiates to sign(), never to re(),
        im() or conjugate(), which C does not print."""
        return True

    def fdiff(self, argindex=1):
        if self.order >= 3:           # the derivative of a piecewise constant
            return sympy.S.Zero
        return table_function(self.table_key, self.knots, _ORIGINAL[self.table_key],
                              self.order + 1)(self.args[0])

    def _ccode(self, printer) -> str:
        x = printer._print(self.args[0])
        t = [repr(float(v)) for v in self.knots]
        c = self.coef

        def poly(k: int) -> str:
            terms = [repr(float(v)) for v in c[k]]
            s = f"({x} - {t[k]})"
            body = terms[3]
            for term in reversed(terms[:3]):
                body = f"{term} + {s}*({body})"
            return f"({body})"

        def search(lo: int, hi: int) -> str:       # intervals lo .. hi - 1
            if hi - lo == 1:
                return poly(lo)
            mid = (lo + hi) // 2
            return f"(({x} < {t[mid]}) ? {search(lo, mid)} : {search(mid, hi)})"

        before, after = (repr(float(v)) for v in self.outside)
        return (f"(({x} < {t[0]}) ? {before} : (({x} >= {t[-1]}) ? {after} : "
                f"{search(0, len(t) - 1)}))")

    def as_piecewise(self) -> sympy.Piecewise:
        """The same function as a SymPy Piecewise (slow for long tables)."""
        x, t = self.args[0], self.knots
        pieces = [(sympy.Float(self.outside[0]), x < t[0])]
        for k in range(len(t) - 1):
            s = x - sympy.Float(t[k])
            poly = sum((sympy.Float(v) * s ** j for j, v in enumerate(self.coef[k])),
                       sympy.S.Zero)
            pieces.append((poly, x < t[k + 1]))
        pieces.append((sympy.Float(self.outside[1]), True))
        return sympy.Piecewise(*pieces)


_ORIGINAL: dict[str, np.ndarray] = {}
_CLASSES: dict[tuple[str, int], type[TableFunction]] = {}


def _derivative(coef: np.ndarray, order: int) -> np.ndarray:
    """Ascending coefficients of the order-th derivative, padded to 4 columns."""
    out = np.array(coef, float)
    for _ in range(order):
        out = np.hstack([out[:, 1:] * np.arange(1, out.shape[1]), np.zeros((len(out), 1))])
    return out


def table_function(key: str, knots: np.ndarray, coef: np.ndarray,
                   order: int = 0) -> type[TableFunction]:
    """The TableFunction subclass of one table (``coef`` of order 0) and derivative
    order, created once per (key, order) so that equal tables give equal expressions."""
    if (key, order) not in _CLASSES:
        _ORIGINAL.setdefault(key, np.array(coef, float))
        dc = _derivative(coef, order)
        h = float(knots[-1] - knots[-2])
        end = float(dc[-1] @ h ** np.arange(4))          # the polynomial at t_(n-1)
        outside = (float(coef[0, 0]), end) if order == 0 else (0.0, 0.0)
        name = f"table_{key}" + (f"_d{order}" if order else "")
        _CLASSES[(key, order)] = type(name, (TableFunction,), {
            "knots": np.array(knots, float), "coef": dc, "outside": outside,
            "order": order, "table_key": key})
    return _CLASSES[(key, order)]


def table_expression(path: str, symbol_t: sympy.Symbol, *, source: str,
                     line: int | None, item: str) -> sympy.Expr:
    """The tabulated function of time in file ``path`` (relative to the model file
    ``source``) as a SymPy expression in ``symbol_t``; errors name source, line and
    item."""
    t, y = read_table(path, source=source, line=line, item=item)
    coef = spline_coefficients(t, y)
    key = hashlib.sha256(np.concatenate([t, y]).tobytes()).hexdigest()[:12]
    return table_function(key, t, coef)(symbol_t)


# -- a table as the text of a driver's function ----------------------------------------
# A driver carries its f(t) as text (Driver.function, ElementClass.function, part of
# the class key). A table is carried by its numbers: "table:<hash>:t,y t,y ...", each
# number written by repr (read back exactly), so that the key changes with the table's
# content (not its file name) and no file is read after the model is loaded.

TEXT_PREFIX = "table:"


def table_text(t: np.ndarray, y: np.ndarray) -> str:
    """The function text of the table (t, y) (see above)."""
    key = hashlib.sha256(np.concatenate([t, y]).tobytes()).hexdigest()[:12]
    rows = " ".join(f"{float(a)!r},{float(b)!r}" for a, b in zip(t, y))
    return f"{TEXT_PREFIX}{key}:{rows}"


def is_table_text(text: str) -> bool:
    return text.startswith(TEXT_PREFIX)


def table_rows(text: str) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) of a text made by :func:`table_text`."""
    rows = text[len(TEXT_PREFIX):].split(":", 1)[1].split()
    t, y = np.array([[float(x) for x in r.split(",")] for r in rows]).T
    return t, y


def table_text_expression(text: str, symbol_t: sympy.Symbol) -> sympy.Expr:
    """The tabulated function of a :func:`table_text` as a SymPy expression."""
    t, y = table_rows(text)
    key = hashlib.sha256(np.concatenate([t, y]).tobytes()).hexdigest()[:12]
    return table_function(key, t, spline_coefficients(t, y))(symbol_t)
