"""Drivers whose f(t) is a table (``angle: {table: file.csv}``, docs/joints.md
"Drivers"): reading and checking the file, the compiled and numeric kernels, a
tabulated motion followed by the joint, the driven four-bar by a tabulated constant
rate, and rebuilding when the table changes."""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy
from scipy.interpolate import CubicSpline

import fccgen
from fccgen.api import plan_model
from conftest import EXAMPLES
from fccgen.derive import derive_class
from fccgen.errors import ModelError
from fccgen.expressions.tables import TableFunction, table_text
from fccgen.model.load import load_model
from fccgen.numeric import element_kernel
from fccgen.plan.classes import ElementClass

from kernel_checks import random_case

FOUR_BAR = (EXAMPLES / "four_bar_driven.yaml").read_text()
ANGLE_LINE = 'angle: "10*t"'
assert ANGLE_LINE in FOUR_BAR

# Rows over [0, 2] of a smooth non-polynomial function (the kernels' t is drawn from
# [0, 2] by random_case, so every interval and both ends are visited).
KNOTS = np.linspace(0.0, 2.0, 21)
TEXT = table_text(KNOTS, 0.3 * np.sin(2 * KNOTS) + 0.1 * KNOTS ** 2)
F, T = False, True
CLASSES = [ElementClass("driver_angle", (), (F, F, F), frozenset(), TEXT),
           ElementClass("driver_position", (), (T, T, F), frozenset(), TEXT),
           ElementClass("driver_distance", (), (T, F), frozenset(), TEXT),
           ElementClass("driver_coordinate", (), (F,), frozenset(), TEXT)]


def write_rows(folder, name, rows, header="t, angle\n"):
    (folder / name).write_text(header + "".join(f"{float(a)!r},{float(b)!r}\n"
                                                  for a, b in rows))


def driven_four_bar(folder, rows, name="profile.csv"):
    """The example's four-bar with its motor angle read from ``name`` in ``folder``."""
    write_rows(folder, name, rows)
    path = folder / "four_bar_table.yaml"
    path.write_text(FOUR_BAR.replace(ANGLE_LINE, f"angle: {{table: {name}}}"))
    return path


@pytest.mark.parametrize("cls", CLASSES, ids=[c.kind for c in CLASSES])
def test_compiled_and_numeric_table_driver_kernels_agree(cls):
    """The kernels SymPy derives from the table's piecewise polynomials (evaluated by
    TableFunction.value; their C printing is checked in test_mechanism_tables) against
    the numeric version's chain rule and SciPy spline evaluation, at random (q, v, t):
    1e-12 of each kernel's largest entry (the same spline evaluated in a different
    order, sums of a few terms of size ~1, f'' of size ~1); also before, after and at
    the table's ends, where f holds its end values."""
    d = derive_class(cls)
    cases = [random_case(cls, seed) for seed in range(4)]
    for q, v, p in cases + [(q, v, np.r_[t, p[1:]]) for t, (q, v, p) in
                            zip((-0.3, 2.7, 0.0, 2.0), cases)]:      # outside, ends
        for name, m in d.kernels.items():
            if m is None:
                continue
            tables = {type(f).__name__: type(f).value
                      for f in sympy.Matrix(m).atoms(TableFunction)}
            got = np.array(sympy.lambdify((d.q, d.v, d.p), list(m), [tables, "numpy"])(
                q, v, p), float)
            want = element_kernel(cls, name, q, v, p)
            assert np.max(np.abs(got - want)) <= 1e-12 * max(1.0, np.max(np.abs(want))), \
                name


def test_a_tabulated_motion_is_followed(tmp_path, build_dir):
    """The crank follows a table of f(t) = 0.5 (1 - cos 2 pi t) on [0, 1] (f' = 0 at
    both ends, as the clamped spline's, so the spline's error is its O(h^4) one:
    5/384 h^4 max|f''''| = 1.6e-6 at h = 0.02). The recorded angle equals the spline
    to 1e-10 (the Newton projection's tolerance, as for the expression driver) and the
    function to 2e-6 but not to 1e-9 (it is the spline that is followed); after the
    table's end the angle holds its last value at rest."""
    knots = np.linspace(0.0, 1.0, 51)
    rows = zip(knots, 0.5 * (1.0 - np.cos(2 * math.pi * knots)))
    solver = fccgen.load(driven_four_bar(tmp_path, rows), build_dir)
    r = solver.simulate(t_end=1.2, dt=1e-3, output_dt=0.01)
    spline = CubicSpline(knots, 0.5 * (1.0 - np.cos(2 * math.pi * knots)),
                         bc_type="clamped")
    inside = r.t <= 1.0
    assert np.max(np.abs(r["O.angle"][inside] - spline(r.t[inside]))) <= 1e-10
    error = np.abs(r["O.angle"] - 0.5 * (1.0 - np.cos(2 * math.pi * np.minimum(r.t, 1))))
    assert 1e-9 < np.max(error) <= 2e-6
    assert np.max(np.abs(r["O.angle"][~inside])) <= 1e-10
    assert np.max(np.abs(r["O.rate"][~inside])) <= 1e-9


def test_tabulated_constant_rate_gives_the_expression_drivers_torque(
        tmp_path, build_dir, compiled):
    """The four-bar driven by a table of 10 t on [-5, 6] (h = 0.1) against the
    expression driver 10*t over 0.7 s. A cubic spline reproduces linear data except
    for the clamped ends' correction, which decays by 2 - sqrt(3) per interval: after
    the 50 intervals between the table's ends and the run it is below 1e-28, so the
    spline is 10 t to its coefficients' rounding (~1e-14). Torques agree to 1e-10 N m
    (the expression driver's own accuracy against minimal coordinates is 1e-8; both
    runs do the same arithmetic apart from f, f', f'')."""
    knots = np.round(np.arange(-50, 61) * 0.1, 12)
    path = driven_four_bar(tmp_path, zip(knots, 10.0 * knots))
    table = fccgen.load(path, build_dir).simulate(t_end=0.7, dt=1e-3, output_dt=0.01)
    expr = compiled("four_bar_driven").simulate(t_end=0.7, dt=1e-3, output_dt=0.01)
    assert np.max(np.abs(expr["motor.torque"])) > 0.5           # the motor works
    assert np.max(np.abs(table["motor.torque"] - expr["motor.torque"])) <= 1e-10
    numeric = fccgen.load_numeric(path).simulate(t_end=0.05, dt=1e-3, output_dt=0.05)
    assert np.max(np.abs(numeric["motor.torque"] - table["motor.torque"][[0, 5]])) <= 1e-10


def test_changing_the_table_changes_the_class(tmp_path):
    """The table's numbers (not its file name) are in the driver class's key: an
    edited table gives another class (and so another build), a copy under another
    name the same one."""
    def driver_class(rows, name="profile.csv"):
        plan = plan_model(driven_four_bar(tmp_path, rows, name))
        return {c.name for c in plan.classes if c.kind == "driver_angle"}

    knots = np.linspace(0.0, 1.0, 5)
    first = driver_class(zip(knots, knots))
    assert driver_class(zip(knots, knots), "copy.csv") == first
    assert driver_class(zip(knots, 2 * knots)) != first


def bad_model(tmp_path, csv_text, driver="angle: {table: profile.csv}"):
    if csv_text is not None:
        (tmp_path / "profile.csv").write_text(csv_text)
    path = tmp_path / "m.yaml"
    path.write_text(FOUR_BAR.replace(ANGLE_LINE, driver))
    return path


@pytest.mark.parametrize("csv_text, driver, rule, value", [
    (None, None, "table file does not exist", "profile.csv"),
    ("t, a\n0, 0\n1, 1\n1, 2\n", None, "t must increase strictly", "profile.csv"),
    ("t, a\n0, 0\n1, 1\n0.5, 2\n", None, "(t = 1.0 is followed by t = 0.5)",
     "profile.csv"),
    ("t, a\n0, 0\n1, nan\n2, 1\n", None, "profile.csv row 3: must be two finite", "profile.csv"),
    ("0, nan\n1, 1\n2, 1\n", None, "profile.csv row 1: must be two finite", "profile.csv"),
    ("t, a\n0, 0\n", None, "at least 2 rows", "profile.csv"),
    ("t, a\n0, 0\n1, 1\n", "rate: {table: profile.csv}", "not a rate or speed",
     "profile.csv"),
], ids=["missing", "repeated-t", "decreasing-t", "nan", "nan-first-row", "one-row",
        "rate"])
def test_bad_tables_are_refused(tmp_path, csv_text, driver, rule, value):
    path = bad_model(tmp_path, csv_text, driver or "angle: {table: profile.csv}")
    with pytest.raises(ModelError) as info:
        load_model(path)
    err = info.value
    assert err.file == str(path) and err.line == FOUR_BAR[:FOUR_BAR.index(ANGLE_LINE)] \
        .count("\n") + 1, str(err)
    key = "rate" if driver else "angle.table"
    assert err.item == f"drivers[0].{key}" and rule in err.rule, str(err)
    assert err.value == value, str(err)
