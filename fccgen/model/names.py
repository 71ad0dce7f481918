"""Names a model may not take, and why.

The model name becomes the name of a compiled extension module (``PyInit_<name>``),
of its build folder (``generated/<name>``) and, behind fixed prefixes, of C symbols
(``fccgen_table_<name>``, ``FCCGEN_KERNELS_<NAME>_H``); see templates/ and
fccgen/render. Behind those prefixes no identifier can clash with a C keyword or
another symbol, so the names refused are the ones Python, Cython or a file system
give a meaning of their own (each found by building a model so named):

* Python keywords: ``import class`` is a syntax error;
* dunder names ``__x__``: ``__init__`` makes Cython compile the module as a package's
  ``__init__`` and fail, ``__main__`` is the running script;
* ``cython``: Cython refuses it ("cython is a special module");
* the device names of Windows (CON, NUL, COM1, ...): no folder can have them there.

Point, vector and body names reach no generated code (element classes are named by a
hash of their structure, fccgen.plan.classes); they name result columns as
``NAME.x``, ``NAME.vx``, ``NAME.cx``, ..., whose dot keeps them apart from the
columns ``t``, ``energy`` and ``constraint_error``, so any identifier is safe there.
"""
from __future__ import annotations

import keyword

WINDOWS_DEVICES = frozenset({"con", "prn", "aux", "nul",
                             *(f"com{k}" for k in range(1, 10)),
                             *(f"lpt{k}" for k in range(1, 10))})


def reserved_model_name(name: str) -> str | None:
    """The rule a model name breaks, or None."""
    if keyword.iskeyword(name):
        return "must not be a Python keyword (it becomes a module name)"
    if len(name) > 4 and name.startswith("__") and name.endswith("__"):
        return ("must not be a dunder name __x__ (it becomes a module name, and Python "
                "and Cython give these a meaning: __init__ is a package's module)")
    if name == "cython":
        return "must not be 'cython' (Cython refuses it as a module name)"
    if name.lower() in WINDOWS_DEVICES:
        return ("must not be a Windows device name (CON, PRN, AUX, NUL, COM1-9, "
                "LPT1-9): the model's build folder is named after it")
    return None
