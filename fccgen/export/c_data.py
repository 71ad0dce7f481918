"""The constants of an exported model, as C text (docs/export.md).

After a run of the Python build on the sparse path, everything the engine needs that
Python decided is read from the solver and written as ``static const`` arrays: the
model's element indices and parameters, the sparse pattern (the set-up's view, guards,
order and structure), the tolerances, the rank decided at the run's start, the initial
state, the run's schedule, the parameter map and the output columns. Numbers are
hexadecimal floating literals (exact); names pass :func:`fccgen.render.escape.c_string`.
"""
from __future__ import annotations

import numpy as np

from .. import rank as rank_rule
from ..render.escape import c_identifier, c_string


def c_array(ctype: str, name: str, values) -> str:
    """A static const C array (one dummy entry when empty: C has no empty arrays);
    doubles as hexadecimal literals, exact."""
    c_identifier(name)
    values = list(values)
    if ctype == "double":
        text = [c_double(x) for x in values]
    else:
        text = [str(int(x)) for x in values]
    rows = [", ".join(text[k:k + 6]) for k in range(0, len(text), 6)] or ["0"]
    body = ",\n    ".join(rows)
    return f"static const {ctype} {name}[] = {{\n    {body}\n}};\n"


def c_double(x) -> str:
    """An exact C99 literal of a finite double (hexadecimal); ValueError otherwise."""
    x = float(x)
    if not np.isfinite(x):
        raise ValueError(f"{x!r} cannot be written as a C constant")
    return x.hex()


def c_strings(name: str, values) -> str:
    """A static const array of C strings, each through c_string."""
    c_identifier(name)
    items = [f'"{c_string(v)}"' for v in values] or ["0"]
    return f"static const char *const {name}[] = {{\n    " + ",\n    ".join(items) + "\n};\n"


def define(name: str, value) -> str:
    c_identifier(name)
    if isinstance(value, (bool, int, np.integer)):
        return f"#define {name} {int(value)}\n"
    return f"#define {name} {c_double(value)}\n"


def engine_constants(solver) -> str:
    """The model's and the sparse pattern's arrays, tolerances and decided rank."""
    inst = solver._asm.instance_arrays()
    engine = solver._engine
    pat = engine.pattern_arrays()
    out = [define("N_Q", inst["n_q"]), define("N_EL", len(inst["class_of"])),
           define("N_BODIES", len(inst["body_elements"])),
           define("N_TIME", len(inst["time_slots"])),
           define("N_PARAMS", len(inst["params"]))]
    for ctype, name, key in (("int", "CLASS_OF", "class_of"), ("int", "Q_PTR", "q_ptr"),
                             ("int", "Q_IDX", "q_idx"), ("int", "P_PTR", "param_ptr"),
                             ("int", "BODY_ELEMENTS", "body_elements"),
                             ("int", "TIME_SLOTS", "time_slots"),
                             ("double", "PARAMS", "params")):
        out.append(c_array(ctype, name, inst[key]))
    view = pat["view"]
    out.append(define("HAS_VIEW", view is not None))
    if view is not None:
        out += [define("N_PINNED", len(view["pinned"])),
                define("N_FIXED_ROWS", len(view["fixed_rows"])),
                define("N_FIXED", len(view["fixed_off"]))]
        for key in ("snq", "sloc", "sng", "srloc", "pinned", "fixed_rows", "fixed_off"):
            out.append(c_array("int", key.upper(), view[key]))
        for key in ("efix", "fixed_norm", "fixed_g_tol", "fixed_val", "fixed_tol"):
            out.append(c_array("double", key.upper(), view[key]))
    guards = pat["guards"]
    out += [define("N_ZERO_M", len(guards["zero_m"])), define("N_ZERO_B", len(guards["zero_b"]))]
    for key in ("zero_m", "zero_b"):
        out.append(c_array("int", key.upper(), guards[key]))
        out.append(c_array("double", key.upper() + "_TOL", guards[key + "_tol"]))
    for key, values in pat["structure"].items():
        out.append(c_array("int", c_identifier(key).upper(), values))
    switchable = pat.get("switchable")          # the locked rows folded into A
    out.append(define("N_SW", 0 if switchable is None else len(switchable["sw_ptr"]) - 1))
    for key, values in (switchable or {}).items():
        out.append(c_array("int", c_identifier(key).upper(), values))
    for name, value in (("RANK_TOL", engine.rank_tol),
                        ("POSITION_TOL", engine.position_tol),
                        ("GROW_TOL", rank_rule.GROW_TOL),
                        ("DECIDE_TOL", rank_rule.DECIDE_TOL),
                        ("AMBIGUOUS_LOW", rank_rule.AMBIGUOUS_LOW),
                        ("ROW_FLOOR", rank_rule.ROW_FLOOR),
                        ("BEYOND_QUOTIENT", engine.beyond_rank_quotient)):
        out.append(define(name, float(value)))
    out += [define("MAX_NEWTON", int(engine.max_newton)),
            define("RANK", int(engine.decided_rank))]
    return "".join(out)
