"""Tabulated functions of time (fccgen/expressions/tables.py): the clamped cubic spline
with constant extension, its derivatives, its C code, and the checks of the file."""
from __future__ import annotations

import ctypes
import subprocess
import sysconfig

import numpy as np
import pytest
import sympy
from scipy.interpolate import CubicSpline

from fccgen.errors import ModelError
from fccgen.expressions.tables import MAX_ROWS, table_expression
from fccgen.printing.c99 import KernelPrinter

T = sympy.Symbol("t", real=True)
KNOTS = np.array([0.0, 0.3, 0.5, 1.1, 1.7, 2.0, 3.2])
VALUES = np.sin(2 * KNOTS) + KNOTS


def write_table(folder, name="motion.csv", header="t, angle\n", rows=None):
    rows = zip(KNOTS, VALUES) if rows is None else rows
    text = header + "# a comment line\n\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in rows)
    (folder / name).write_text(text)
    return folder / "model.yaml"


def load(model, path="motion.csv"):
    return table_expression(path, T, source=str(model), line=7,
                            item="drivers[0].angle")


@pytest.fixture
def table(tmp_path):
    return load(write_table(tmp_path))


def reference(x, order=0):
    """SciPy's clamped spline inside the table, the end values (order 0) or zero
    (derivatives) outside."""
    spline = CubicSpline(KNOTS, VALUES, bc_type="clamped")
    inside = (x >= KNOTS[0]) & (x < KNOTS[-1])
    ends = np.where(x < KNOTS[0], VALUES[0], VALUES[-1]) if order == 0 else 0.0
    return np.where(inside, spline(np.clip(x, KNOTS[0], KNOTS[-1]), order), ends)


SAMPLES = np.concatenate([np.linspace(-0.5, 3.7, 57), KNOTS])


@pytest.mark.parametrize("order", [0, 1, 2, 3])
def test_values_and_derivatives_follow_the_clamped_spline(table, order):
    """The same cubic in another order of operations: 1e-13 of the values' size."""
    expr = sympy.diff(table, T, order) if order else table
    got = np.array([float(expr.subs(T, x)) for x in SAMPLES])
    want = reference(SAMPLES, order)
    assert np.max(np.abs(got - want)) <= 1e-13 * np.max(np.abs(want))


def test_rows_are_interpolated_and_value_and_rate_are_continuous(table):
    assert [float(table.subs(T, x)) for x in KNOTS] == pytest.approx(VALUES, rel=1e-14)
    rate = sympy.diff(table, T)
    for end in (KNOTS[0], KNOTS[-1]):          # clamped: zero slope where it is held
        assert abs(float(rate.subs(T, end))) < 1e-12
        assert abs(float(rate.subs(T, end - 1e-9))) < 1e-8
    assert sympy.diff(table, T, 4) == 0


def test_piecewise_form_agrees(table):
    pw = table.as_piecewise()
    assert isinstance(pw, sympy.Piecewise)
    for x in SAMPLES:
        assert float(pw.subs(T, x)) == pytest.approx(float(table.subs(T, x)),
                                                     rel=1e-13, abs=1e-14)


def test_printed_c_compiles_and_agrees(table, tmp_path):
    """Value and first two derivatives printed by fccgen's C printer (a table in an
    expression), compiled under strict C99, against the NumPy evaluation to 1e-13."""
    printer = KernelPrinter({T: "x[0]"})
    exprs = [table * 2 + sympy.sin(T), sympy.diff(table, T), sympy.diff(table, T, 2)]
    code = ("void table(const double *x, double *out)\n{\n"
            + "".join(f"    out[{k}] = {printer.doprint(e)};\n" for k, e in enumerate(exprs))
            + "}\n")
    (tmp_path / "table.c").write_text("#include <math.h>\n" + code)
    cc = (sysconfig.get_config_var("CC") or "cc").split()
    run = subprocess.run([*cc, "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
                          "-shared", "-fPIC", "-o", "table.so", "table.c", "-lm"],
                         cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    lib = ctypes.CDLL(str(tmp_path / "table.so"))
    for x in SAMPLES:
        out = (ctypes.c_double * 3)()
        lib.table((ctypes.c_double * 1)(x), out)
        want = [float(2 * reference(x) + np.sin(x)), float(reference(x, 1)),
                float(reference(x, 2))]
        assert list(out) == pytest.approx(want, rel=1e-13, abs=1e-12)


def test_path_is_relative_to_the_model_file(tmp_path):
    sub = tmp_path / "data"
    sub.mkdir()
    write_table(sub)
    expr = load(tmp_path / "model.yaml", "data/motion.csv")
    assert float(expr.subs(T, 0.5)) == pytest.approx(VALUES[2], rel=1e-14)
    two = load(write_table(tmp_path, "two.csv", header="", rows=[(0, 1), (1, 3)]),
               "two.csv")
    assert float(two.subs(T, 0.5)) == pytest.approx(2.0, rel=1e-14)   # symmetric


@pytest.mark.parametrize("rows, text, rule", [
    ([(0, 1)], None, "at least 2 rows"),
    ([(0, 1), (1, 2), (1, 3)], None, "t must increase strictly"),
    ([(0, 1), (2, 2), (1, 3)], None, "t must increase strictly"),
    (None, "0,1\n1,nan\n", "row 2: must be two finite numbers"),
    (None, "0,1\n1,inf\n", "row 2: must be two finite numbers"),
    (None, "0,1\n1,2,3\n", "row 2: must be two finite numbers"),
    (None, "0,1\n1,x\n", "row 2: must be two finite numbers"),
    (None, "t,y\nu,v\n0,1\n", "row 2: must be two finite numbers"),
    ([(k, 0.0) for k in range(MAX_ROWS + 1)], None, f"more than {MAX_ROWS} rows"),
])
def test_bad_tables_are_refused(tmp_path, rows, text, rule):
    if text is None:
        write_table(tmp_path, header="", rows=rows)
    else:
        (tmp_path / "motion.csv").write_text(text)
    with pytest.raises(ModelError) as info:
        load(tmp_path / "model.yaml")
    assert str(info.value).startswith(f"{tmp_path / 'model.yaml'}:7: drivers[0].angle: ")
    assert rule in str(info.value)


def test_missing_and_unreadable_files_are_refused(tmp_path):
    with pytest.raises(ModelError, match="table file does not exist.*'nothere.csv'"):
        load(tmp_path / "model.yaml", "nothere.csv")
    (tmp_path / "bin.csv").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ModelError, match="cannot be read as UTF-8"):
        load(tmp_path / "model.yaml", "bin.csv")


# -- which files a table may read, and what its errors show ---------------------------
SECRET = "SECRET-TEXT-OF-ANOTHER-FILE"


def refused(model, path, rule):
    with pytest.raises(ModelError) as info:
        load(model, path)
    assert rule in info.value.rule, str(info.value)
    assert SECRET not in str(info.value)
    assert (info.value.line, info.value.item) == (7, "drivers[0].angle")
    return info.value


@pytest.fixture
def outside(tmp_path):
    """(model file in tmp_path/model/, a CSV file of two numeric rows and one secret
    row in tmp_path/other/)."""
    (tmp_path / "model").mkdir()
    (tmp_path / "other").mkdir()
    secret = tmp_path / "other" / "secret.csv"
    secret.write_text(f"0,1\n1,2\n{SECRET},{SECRET}\n")
    return tmp_path / "model" / "model.yaml", secret


def test_tables_outside_the_model_folder_are_refused(outside):
    model, secret = outside
    for path in (str(secret), "../other/secret.csv", "/etc/passwd"):
        err = refused(model, path, "is outside the model file's folder")
        assert "FCCGEN_TABLE_DIRS" in err.rule


def test_a_symlink_is_resolved_before_the_check(outside):
    model, secret = outside
    (model.parent / "link.csv").symlink_to(secret)
    refused(model, "link.csv", "is outside the model file's folder")
    inside = model.parent / "data.csv"
    inside.write_text("0,1\n1,2\n")
    (model.parent / "alias.csv").symlink_to(inside)
    assert float(load(model, "alias.csv").subs(T, 1.5)) == 2.0


def test_folders_named_by_the_user_may_be_read(outside, monkeypatch):
    """FCCGEN_TABLE_DIRS names further folders; the secret row of the file is then
    read and refused by row and field, without its text."""
    model, secret = outside
    monkeypatch.setenv("FCCGEN_TABLE_DIRS", str(secret.parent))
    err = refused(model, str(secret), "row 3: must be two finite numbers t, value "
                                      "(field 1 is not a number)")
    assert err.value == str(secret)
    secret.write_text("0,1\n1,2\n")
    assert float(load(model, str(secret)).subs(T, 1.5)) == 2.0


def test_rows_are_named_by_number_never_by_their_text(tmp_path):
    (tmp_path / "motion.csv").write_text(f"t,y\n0,1\n1,{SECRET}\n2,3,{SECRET}\n")
    refused(tmp_path / "model.yaml", "motion.csv", "row 3: must be two finite numbers "
                                                   "t, value (field 2 is not a number)")
    (tmp_path / "motion.csv").write_text(f"t,y\n0,1\n1,2,{SECRET}\n")
    refused(tmp_path / "model.yaml", "motion.csv", "(found 3 fields)")


def test_a_huge_field_is_refused_cleanly(tmp_path):
    """A field longer than the csv module's limit (131,072 characters) is a CSV error
    of that row, not a traceback."""
    (tmp_path / "motion.csv").write_text("t,y\n0,1\n1," + "9" * 300_000 + "\n")
    refused(tmp_path / "model.yaml", "motion.csv", "motion.csv row 3: cannot be read as CSV")
    (tmp_path / "motion.csv").write_text('t,y\n0,1\n1,"' + SECRET * 8000 + '\n')
    refused(tmp_path / "model.yaml", "motion.csv", "cannot be read as CSV")


def test_paths_that_name_no_regular_file_are_refused(tmp_path):
    import os
    model = tmp_path / "model.yaml"
    (tmp_path / "folder.csv").mkdir()
    refused(model, "folder.csv", "not a regular file")
    os.mkfifo(tmp_path / "pipe.csv")                  # opened without blocking
    refused(model, "pipe.csv", "not a regular file")
    refused(model, "a" * 5000 + ".csv",
            "cannot be opened (its path is longer than the file system allows")
    refused(model, "x\0y.csv", "must name a file")
    refused(model, "", "must name a file")
    (tmp_path / "loop.csv").symlink_to(tmp_path / "loop.csv")
    refused(model, "loop.csv", "cannot be opened")
    (tmp_path / "big.csv").write_bytes(b"0,1\n" * 300_000)
    refused(model, "big.csv", "larger than 1000000 bytes")
