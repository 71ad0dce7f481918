"""Text made safe for the place it takes in a generated source.

Every value a template writes goes through one of these (they are the Jinja filters
of :func:`fccgen.render.environment`), so that no text of a model file, whatever its
characters, can end a comment, a string or a line of the generated C, Cython or Python,
or change what a file is named:

* :func:`c_comment`: inside a C block comment. Only printable ASCII is kept, written
  so that no ``*/`` (closing the comment), ``/*`` (a nested one), ``??`` (a trigraph:
  ``??/`` is a backslash under ``-std=c99``) or backslash (a line splice, or the
  ``*`` + backslash-newline + ``/`` that closes a comment after splicing) is left;
  every other character (line breaks, NUL, non-ASCII) is written as ``<U+XXXX>``.
* :func:`c_string`: a C string literal's contents: backslash, quote and ``?`` escaped,
  everything outside printable ASCII as a three-digit octal escape.
* :func:`c_expression`: a C expression of the printer, checked: no quote, backslash,
  ``#``, comment or trigraph, nothing outside printable ASCII.
* :func:`c_identifier`: a C identifier, checked (ASCII letters, digits, underscores),
  never changed: a name that is not one is an internal error, not something to mend.
* :func:`py_literal`: a Python (and Cython) literal of numbers, text, tuples, lists and
  dicts, in ASCII with every non-printable character escaped (:func:`ascii`).
* :func:`py_docstring`: a value shown inside a ``\"\"\"docstring\"\"\"``: its ASCII
  repr with every double quote escaped, so that the docstring cannot end early.
"""
from __future__ import annotations

import re

C_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
# Zero-width places inside "*/", "/*" and "??": a space goes there.
_BREAKS = re.compile(r"(?<=\*)(?=/)|(?<=/)(?=\*)|(?<=\?)(?=\?)")


def _printable(ch: str) -> bool:
    return " " <= ch <= "~"


def c_comment(text) -> str:
    """``text`` written so that it stays inside a C block comment on one line."""
    out = "".join(ch if _printable(ch) and ch != "\\" else f"<U+{ord(ch):04X}>"
                  for ch in str(text))
    return _BREAKS.sub(" ", out)


def c_string(text) -> str:
    """The contents of a C string literal (without the quotes) that holds ``text``'s
    characters; non-ASCII text is written as the octal escapes of its UTF-8 bytes."""
    out = []
    for byte in str(text).encode("utf-8"):
        ch = chr(byte)
        if ch in '\\"?':
            out.append("\\" + ch)
        elif _printable(ch):
            out.append(ch)
        else:
            out.append(f"\\{byte:03o}")
    return "".join(out)


def c_identifier(name) -> str:
    """``name`` itself if it is an ASCII C identifier; ValueError otherwise."""
    if not isinstance(name, str) or not C_IDENTIFIER.fullmatch(name):
        raise ValueError(f"{name!r} is not an ASCII C identifier; it cannot be written "
                         "into generated code")
    return name


# What a printed C expression may hold: printable ASCII without quotes, backslashes,
# '#', and without the two-character sequences that open or close a comment or start a
# trigraph.
_C_EXPRESSION_BAD = re.compile(r"[^ -~]|[\\'\"#]|/\*|\*/|//|\?\?")


def c_expression(text) -> str:
    """``text`` itself if it can be a C expression the printer wrote (see
    _C_EXPRESSION_BAD); ValueError otherwise: the printer's output is checked, never
    mended."""
    text = str(text)
    bad = _C_EXPRESSION_BAD.search(text)
    if bad:
        raise ValueError(f"a printed C expression holds {bad.group()!r}, which no "
                         f"expression of fccgen's printer holds: {text[:200]!r}")
    return text


_LITERAL_TYPES = (str, int, float, bool, type(None))


def py_literal(value) -> str:
    """A Python literal of ``value`` (str, int, float, bool, None, and tuples, lists and
    dicts of them) in printable ASCII; ValueError for anything else."""
    def check(v):
        if isinstance(v, (tuple, list)):
            for x in v:
                check(x)
        elif isinstance(v, dict):
            for k, x in v.items():
                check(k)
                check(x)
        elif not isinstance(v, _LITERAL_TYPES):
            raise ValueError(f"a {type(v).__name__} cannot be written as a Python literal")
    check(value)
    return ascii(value)


def py_docstring(value) -> str:
    """``value``'s ASCII repr with double quotes escaped (\\x22), for a docstring."""
    return ascii(str(value)).replace('"', "\\x22")


FILTERS = {"c_comment": c_comment, "c_string": c_string, "c_identifier": c_identifier,
           "c_expression": c_expression,
           "py": py_literal, "py_doc": py_docstring}

__all__ = ["C_IDENTIFIER", "FILTERS", "c_comment", "c_expression", "c_identifier", "c_string",
           "py_docstring", "py_literal"]
