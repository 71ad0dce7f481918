"""Moments tabulated against a joint angle (the model file's ``tables:`` section, a
load calling ``name(expr)``; docs/flexible.md "Tape-spring hinges"): a linear table
against the torsion spring and the same expression, a nonlinear table against a
SciPy-integrated single-degree-of-freedom hinge, compiled against numeric kernels,
the spline's slope in df/dq, and the rules for bad tables and names."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

import fccgen
from conftest import EXAMPLES
from fccgen.errors import ModelError
from fccgen.model.load import load_model

from states import random_state

PANEL = """\
name: {name}
bodies:
  panel: {{mass: 2.0, center: [-0.259808, 0.15, 0], inertia: [0.05, 0.06, 0.1],
          frame: {{x: [-0.866025, 0.5, 0], y: [-0.5, -0.866025, 0]}}}}
joints:
  - {{name: H, type: revolute, bodies: [ground, panel], at: [0, 0, 0], axis: [0, 0, 1]}}
{tables}loads:
  - {load}
simulate: {{t_end: 3.0, dt: 5.0e-4, method: rk4}}
"""
K, REST, C = 3.0, 4.0, 0.05          # the panel turns from 0 to 2 REST = 8 rad
TABLE_LOAD = '{type: torque, body: panel, value: [0, 0, "moment(H.angle) - 0.05*H.rate"]}'
LOADS = {
    "table": TABLE_LOAD,
    "expression": ('{type: torque, body: panel, value: [0, 0, '
                   '"-3*(H.angle - 4) - 0.05*H.rate"]}'),
    "spring": "{type: torsion_spring, joint: H, stiffness: 3.0, angle: 4.0, damping: 0.05}",
}
TABLES = "tables:\n  moment: {file: line.csv}\n"


def write_model(folder, name, load, tables=TABLES):
    path = folder / f"{name}.yaml"
    path.write_text(PANEL.format(name=name, tables=tables, load=load))
    return path


def write_line(folder):
    """M = -k (x - rest) at rows 0.5 apart over [-12, 20]: the clamped spline's end
    conditions decay by (2 - sqrt 3) per row, so over the run's angles [0, 8] (24 rows
    from either end) it is the line to 1e-13 N m (measured 7e-14)."""
    x = np.arange(-12.0, 20.001, 0.5)
    rows = "".join(f"{float(a)!r}, {float(-K * (a - REST))!r}\n" for a in x)
    (folder / "line.csv").write_text("angle, moment\n" + rows)


@pytest.fixture(scope="module")
def linear_runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("hinge_line")
    write_line(folder)
    out = {}
    for kind, load in LOADS.items():
        solver = fccgen.load(write_model(folder, f"hinge_{kind}", load), folder / "gen")
        out[kind] = solver.simulate()
    return out


def test_linear_table_is_the_torsion_spring_past_half_a_turn(linear_runs):
    """The table's load, the same moment written as an expression and the torsion
    spring (k = 3, rest 4 rad, c = 0.05) turn the panel past pi alike. The table and
    the expression share the load's angle and differ by the spline's rounding (1e-12
    rad). The spring measures the angle by its own triples, which differ from the
    load's off the constraint manifold inside an RK4 step: the runs differ by O(dt^4)
    (measured 1e-8, 6.6e-10, 3.9e-11 rad at dt = 2e-3, 1e-3, 5e-4), so at dt = 5e-4
    they agree to 1e-10 rad."""
    table, expression, spring = (linear_runs[k]["H.angle"] for k in LOADS)
    assert np.max(table) > math.pi + 3.0                  # well past half a turn
    assert np.max(np.abs(table - expression)) <= 1e-12
    assert np.max(np.abs(table - spring)) <= 1e-10


TAPE = EXAMPLES / "tape_spring_table.yaml"
FOLD0 = 3.4906585                      # the example's initial fold angle (200 degrees)
# I_zz + m r^2 about the hinge, r from the example's mass centre as written (its six
# digits make r = 0.3 to 1e-7 only)
I_HINGE = 0.1 + 2.0 * (0.281908 ** 2 + 0.102606 ** 2)


def spline_moment():
    """phi -> M of the example's CSV by SciPy's clamped spline, constant outside."""
    x, y = np.loadtxt(EXAMPLES / "tape_spring_moment.csv", delimiter=",", comments="#",
                      skiprows=6, unpack=True)
    s = CubicSpline(x, y, bc_type="clamped")
    return lambda phi: float(y[0]) if phi < x[0] else float(y[-1]) if phi >= x[-1] \
        else float(s(phi))


def test_tabulated_tape_spring_matches_the_minimal_coordinate_hinge(tmp_path):
    """The example (panel released 200 degrees folded, RK4 at dt = 5e-4) against
    I theta'' = -M(phi0 + theta) - c theta' integrated by SciPy's DOP853 at rtol 1e-12:
    the spline is C2 (its third derivative jumps at the rows), so RK4's error is
    O(dt^4) with a jump term per row crossed; measured 2.2e-9 rad (and rad/s),
    checked at 1e-8 rad and 1e-7 rad/s."""
    moment = spline_moment()
    result = fccgen.load(TAPE, tmp_path / "gen").simulate(t_end=4.0)

    def rhs(t, y):
        return [y[1], (-moment(FOLD0 + y[0]) - 0.02 * y[1]) / I_HINGE]
    ref = solve_ivp(rhs, (0.0, 4.0), [0.0, 0.0], method="DOP853", rtol=1e-12,
                    atol=1e-13, t_eval=result.t)
    phi = FOLD0 + result["H.angle"]
    assert np.min(phi) < 0.0 < FOLD0 - math.pi      # through deployed, from past pi
    assert np.max(np.abs(result["H.angle"] - ref.y[0])) <= 1e-8
    assert np.max(np.abs(result["H.rate"] - ref.y[1])) <= 1e-7


@pytest.fixture(scope="module")
def steep(tmp_path_factory):
    """The example's table at fold angles on its steep branch (0.03 + H.angle), where
    the slope dM/dphi is up to 20 N m/rad, with a damping whose coefficient is a
    function of the angle (linear in the rate): compiled and numeric versions."""
    folder = tmp_path_factory.mktemp("hinge_steep")
    (folder / "tape.csv").write_text((EXAMPLES / "tape_spring_moment.csv").read_text())
    path = write_model(folder, "steep", '{type: torque, body: panel, value: [0, 0, '
                       '"-tape(0.03 + H.angle) - (0.02 + 0.05*abs(tape(0.03 + H.angle)))'
                       '*H.rate"]}',
                       "tables:\n  tape: {file: tape.csv}\n")
    return fccgen.load(path, folder / "gen"), fccgen.load_numeric(path)


def test_compiled_and_numeric_table_kernels_agree(steep):
    """The printed spline polynomials against SciPy's spline in the numeric version, at
    states on the manifold across the table's steep rows: 1e-12 of each kernel's
    largest entry."""
    solver, numeric = steep
    rng = np.random.default_rng(5)
    for _ in range(6):
        q, v = random_state(numeric, rng, spread=0.1)
        for name in ("applied_forces", "force_jacobian_q", "force_jacobian_v"):
            want, got = getattr(numeric, name)(q, v), getattr(solver, name)(q, v)
            assert np.max(np.abs(got - want)) <= 1e-12 * max(1.0, np.max(np.abs(want)))


def test_force_jacobian_carries_the_spline_slope(steep):
    """df/dq of the compiled kernels (the implicit method's tangent) against central
    differences of f (h = 1e-6, truncation ~h^2 M''' ~ 1e-9 of the slope): 1e-6 of
    the largest entry, and the slope term is not vacuous (f changes with q)."""
    solver, numeric = steep
    rng = np.random.default_rng(2)
    q, v = random_state(numeric, rng, spread=0.05)
    jq = solver.force_jacobian_q(q, v)
    h = 1e-6
    fd = np.column_stack([(solver.applied_forces(q + h * e, v)
                           - solver.applied_forces(q - h * e, v)) / (2 * h)
                          for e in np.eye(len(q))])
    assert np.max(np.abs(jq - fd)) <= 1e-6 * np.max(np.abs(fd))
    assert np.max(np.abs(fd)) > 1.0
    # df/dq' is exact for a load linear in the rate: the f's difference in v is exact
    # up to rounding (1e-9 of the entry at h = 1e-6)
    jv = solver.force_jacobian_v(q, v)
    fd = np.column_stack([(solver.applied_forces(q, v + h * e)
                           - solver.applied_forces(q, v - h * e)) / (2 * h)
                          for e in np.eye(len(q))])
    assert np.max(np.abs(jv - fd)) <= 1e-8 * np.max(np.abs(fd))
    assert np.max(np.abs(fd)) > 1e-3


def test_a_table_change_rebuilds_and_a_renamed_copy_does_not(tmp_path):
    """The class key holds the rows, not the file's name."""
    from fccgen.api import plan_model

    def classes(rows, name):
        (tmp_path / name).write_text("x, y\n" + "".join(f"{a}, {b}\n" for a, b in rows))
        tables = f"tables:\n  moment: {{file: {name}}}\n"
        plan = plan_model(write_model(tmp_path, "m", TABLE_LOAD, tables))
        return {c.name for c in plan.classes if c.kind == "torque_q"}
    first = classes([(0, 0), (1, 1), (2, 0)], "a.csv")
    assert classes([(0, 0), (1, 1), (2, 0)], "b.csv") == first
    assert classes([(0, 0), (1, 2), (2, 0)], "a.csv") != first


# -- rules ----------------------------------------------------------------------------

def refused(tmp_path, csv_text, load=TABLE_LOAD, tables=TABLES):
    if csv_text is not None:
        (tmp_path / "line.csv").write_text(csv_text)
    path = write_model(tmp_path, "m", load, tables)
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert info.value.file == str(path)
    return info.value


TABLE_LINE = PANEL.format(name="m", tables=TABLES, load="").splitlines().index(
    "  moment: {file: line.csv}") + 1


@pytest.mark.parametrize("csv_text, rule", [
    (None, "table file does not exist"),
    ("angle, moment\n0, 0\n1, 1\n0.5, 2\n",
     "line.csv row 4: x must increase strictly from row to row (x = 1.0 is followed "
     "by x = 0.5)"),
    ("angle, moment\n0, 0\n", "table must have at least 2 rows"),
    ("angle, moment\n0, 0\n1, nan\n2, 1\n", "line.csv row 3: must be two finite numbers "
     "x, value (field 2 is not finite)"),
    ("angle, moment\n0, 0\n1, 1, 1\n", "line.csv row 3: must be two finite numbers"),
], ids=["missing", "not-increasing", "one-row", "nan", "three-fields"])
def test_bad_tables_name_file_line_item_rule_and_value(tmp_path, csv_text, rule):
    err = refused(tmp_path, csv_text)
    assert (err.line, err.item, err.value) == (TABLE_LINE, "tables.moment.file",
                                               "line.csv"), str(err)
    assert rule in err.rule, str(err)


def test_a_table_outside_the_model_folder_is_refused_unless_named(tmp_path, monkeypatch):
    """A model file cannot read files elsewhere (a symlink is resolved first); a
    folder named in FCCGEN_TABLE_DIRS can be read."""
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "line.csv").write_text("0, 0\n1, 1\n")
    model = tmp_path / "model"
    model.mkdir()
    (model / "link.csv").symlink_to(outside / "line.csv")
    monkeypatch.delenv("FCCGEN_TABLE_DIRS", raising=False)
    for name in ("../outside/line.csv", "link.csv", str(outside / "line.csv")):
        tables = f"tables:\n  moment: {{file: '{name}'}}\n"
        err = refused(model, None, tables=tables)
        assert "outside the model file's folder" in err.rule, str(err)
        assert err.item == "tables.moment.file" and err.value == name
    monkeypatch.setenv("FCCGEN_TABLE_DIRS", str(outside))
    load_model(write_model(model, "m", TABLE_LOAD,
                           "tables:\n  moment: {file: ../outside/line.csv}\n"))


@pytest.mark.parametrize("tables, load, item, rule", [
    ("tables:\n  sin: {file: line.csv}\n", TABLE_LOAD, "tables.sin",
     "is a name of the expression grammar"),
    ("tables:\n  panel: {file: line.csv}\n", TABLE_LOAD, "tables.panel",
     "name already used by the body on line 3 (the names of points, vectors, bodies, "
     "joints, drivers, cables, inputs and tables must all differ)"),
    ("tables:\n  moment: line.csv\n", TABLE_LOAD, "tables.moment", "must be a mapping"),
    (TABLES, '{type: torque, body: panel, value: [0, 0, "moment + H.angle"]}',
     "loads[0].value[2]", "'moment' is a table: call it"),
    (TABLES, '{type: torque, body: panel, value: [0, 0, "moment(H.angle, 1)"]}',
     "loads[0].value[2]", "the table moment() takes 1 argument, not 2"),
    (TABLES, '{type: torque, body: panel, value: [0, 0, "moment(H.rate)"]}',
     "loads[0].value[2]", "must be linear in the joint rates"),
    (TABLES, '{type: torque, body: panel, value: [0, 0, '
             '"-moment(H.angle) - 0.1*abs(H.rate)"]}',
     "loads[0].value[2]", "must be linear in the joint rates and speeds"),
    (TABLES, '{type: torque, body: panel, value: [0, 0, "moment(t)"]}',
     "loads[0].value", "calls a table but reads no joint quantity"),
    (TABLES, '{type: torque, body: panel, value: [0, 0, "other(H.angle)"]}',
     "loads[0].value[2]", "calls only sin"),
], ids=["grammar-name", "model-name", "not-a-mapping", "not-called", "two-arguments",
        "of-a-rate", "fold-unfold-branches", "of-time", "unknown"])
def test_table_names_and_calls_are_checked(tmp_path, tables, load, item, rule):
    (tmp_path / "line.csv").write_text("0, 0\n1, 1\n")
    err = refused(tmp_path, None, load, tables)
    assert err.item == item and rule in err.rule, str(err)
    assert err.line is not None


def test_no_text_of_a_table_reaches_generated_code(tmp_path):
    """A file name with C comment and preprocessor text, and a header row with the
    same, do not appear in any generated file: only the rows' numbers do."""
    attack = "x */ #define evil 1 .csv"         # the folder "x *" and a file in it
    (tmp_path / "x *").mkdir()
    (tmp_path / attack).write_text("angle */ #include <evil> //, moment\n0, 0\n1, 1\n"
                                   "2, 0\n")
    tables = f"tables:\n  moment: {{file: '{attack}'}}\n"
    path = write_model(tmp_path, "m", TABLE_LOAD, tables)
    fccgen.generate(path, tmp_path / "gen")
    written = [p for p in (tmp_path / "gen").rglob("*")
               if p.suffix in (".c", ".h", ".pyx", ".py", ".txt", ".json")]
    assert any(p.suffix == ".c" for p in written)
    for p in written:
        text = p.read_text(encoding="utf-8", errors="replace")
        assert "evil" not in text and "*/ #" not in text, p
