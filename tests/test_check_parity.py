"""``fccgen check`` neither crashes, hangs, nor accepts what ``simulate`` refuses: each
case below once ended check in a traceback, ran without a time limit, or passed check
and then failed in simulate. Each is now refused when the model is read, with a
ModelError naming the file, the line, the item, the rule and the value, or (the weld)
works."""
from __future__ import annotations

import pytest

from fccgen.diagnostics.check import check_model
from fccgen.errors import ModelError

ARM = """\
name: arm
gravity: [0, 0, -9.81]
bodies:
  arm: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-4, 0.0833, 0.0833]}
joints:
  - {name: A, type: revolute, bodies: [ground, arm], at: [0, 0, 0], axis: [0, 1, 0]}
simulate: {t_end: 0.05, dt: 1.0e-3, method: rk4}
"""
LINE = ARM.count("\n") + 2          # the line of the one item added below its key


def refused(tmp_path, extra: str, item: str, rule: str, value=None):
    path = tmp_path / "case.yaml"
    path.write_text(ARM + extra)
    with pytest.raises(ModelError) as info:
        check_model(path)
    err = info.value
    assert (err.file, err.item) == (str(path), item), str(err)
    assert err.line is not None and rule in err.rule, str(err)
    if value is not None:
        assert err.value == value, str(err)
    return err


@pytest.mark.parametrize("angle, what", [
    ("sqrt(t)", "the driver's rate at t = 0 is not a finite number"),
    ("t**1.5", "the driver's acceleration at t = 0 is not a finite number"),
    ("log(t)", "the driver's value at t = 0 is not a finite number"),
    ("sin(t)/t", "the driver's value at t = 0 is not a finite number"),
    ("abs(t - 0.01)", "must be smooth in t"),
    ("min(1, t)", "must be smooth in t"),
    ("max(t, 2*t)", "must be smooth in t"),
])
def test_drivers_singular_or_kinked_at_the_start_are_refused(tmp_path, angle, what):
    """Once a ZeroDivisionError or 'math domain error' in check (singular), or a
    DiracDelta traceback in simulate (kinked)."""
    refused(tmp_path, f'drivers:\n  - {{name: m, joint: A, angle: "{angle}"}}\n',
            "drivers[0].angle", what, angle)


@pytest.mark.parametrize("torque, rule", [
    ("1/A.angle", "is not a finite number at the start"),
    ("sin(A.angle)/A.angle", "is not a finite number at the start"),
    ("log(t)", "is not a finite number at the start"),
    ("0.1*min(1, A.rate)", "must be linear in the joint rates"),
    ("0.1*abs(A.rate)", "must be linear in the joint rates"),
    ("log(2 + A.rate)", "must be linear in the joint rates"),
    ("A.rate**2", "must be linear in the joint rates"),
    ("1e308*t", "is larger than 1e+12 in magnitude"),
])
def test_loads_singular_at_the_start_or_not_linear_in_rates_are_refused(tmp_path, torque,
                                                                         rule):
    """Once a traceback in check (singular), an internal 'uses symbols that are not
    inputs of the kernel' in simulate (rates), a stop at the first step (1e308)."""
    refused(tmp_path, f'loads:\n  - {{type: torque, body: arm, value: [0, "{torque}", '
                      '0]}\n', "loads[0].value[1]", rule, torque)


def test_a_load_affine_in_the_rates_passes(tmp_path):
    path = tmp_path / "case.yaml"
    path.write_text(ARM + 'loads:\n  - {type: torque, body: arm, value: '
                          '[0, "-0.1*A.rate*cos(A.angle) + sin(t)", 0]}\n')
    assert check_model(path).dof == 1


def test_events_with_a_method_that_cannot_locate_them_are_refused(tmp_path):
    text = ARM.replace("method: rk4", "method: scipy-RK45")
    path = tmp_path / "case.yaml"
    path.write_text(text + 'events:\n  - {name: e, when: "A.angle >= 0.5", do: log}\n')
    with pytest.raises(ModelError) as info:
        check_model(path)
    err = info.value
    assert (err.item, err.line, err.value) == ("simulate.method", 7, "scipy-RK45")
    assert "must be one of rk4, dopri5 in a model with events" in err.rule


def test_a_rate_driver_s_integration_is_bounded_in_time(tmp_path, monkeypatch):
    """SymPy's integration runs in a child process killed when the time is up; here
    it never ends (a sleeping stand-in), and the driver is refused, not waited for."""
    import time

    import fccgen.model.drivers as drivers
    monkeypatch.setattr(drivers, "integral_text", lambda rate, t: time.sleep(3600))
    monkeypatch.setattr(drivers, "INTEGRAL_SECONDS", 0.5)
    monkeypatch.setattr(drivers, "_INTEGRALS", {})
    refused(tmp_path, 'drivers:\n  - {name: m, joint: A, rate: "exp(-t**2)*log(1 + t)"}\n',
            "drivers[0].rate", "SymPy found none within 0.5 s")


def test_a_rate_driver_is_integrated_in_a_child_process():
    import sympy

    from fccgen.model.drivers import bounded_integral_text
    t = sympy.Symbol("t", real=True)
    assert bounded_integral_text(sympy.cos(t), t) == "sin(t)"


def test_a_weld_between_two_bodies_of_points_and_a_vector(tmp_path):
    """Once a KeyError: such bodies have no frame matrix. Body a hangs at the fixed
    point O, b is welded to a: one rigid body on a ball joint, 3 freedoms."""
    path = tmp_path / "weld.yaml"
    path.write_text("""\
name: weld
gravity: [0, 0, -9.81]
points:
  O: {at: [0, 0, 0], fixed: true}
  P: [1, 0, 0]
  Q: [2, 0, 0.5]
vectors:
  z: {along: [0, 0, 1]}
  w: {along: [0, 1, 0]}
bodies:
  a: {points: [O, P], vector: z, mass: 1.0, inertia: [0.01, 0.1, 0.1]}
  b: {points: [P, Q], vector: w, mass: 1.0, inertia: [0.01, 0.1, 0.1]}
joints:
  - {name: W, type: weld, bodies: [a, b], at: [1, 0, 0]}
""")
    assert check_model(path).dof == 3


@pytest.mark.parametrize("table, rule", [
    ("a" * 5000 + ".csv",
     "cannot be opened (its path is longer than the file system allows"),
    ("huge.csv", "row 3: cannot be read as CSV"),
])
def test_table_paths_and_fields_are_refused_not_raised(tmp_path, table, rule):
    (tmp_path / "huge.csv").write_text("t, a\n0, 0\n1, " + "7" * 200_000 + "\n")
    refused(tmp_path, f"drivers:\n  - {{name: m, joint: A, angle: {{table: {table}}}}}\n",
            "drivers[0].angle.table", rule, table)


def test_check_generates_the_kernels_or_says_it_did_not(tmp_path, monkeypatch):
    """check derives, prints and renders every class (and the event kernels); a class
    that cannot be generated fails check as it would fail a build, naming the file
    and the class; with generate=False the report says the kernels were not made."""
    import fccgen.diagnostics.check as check
    import fccgen.derive as derive
    from fccgen.errors import BuildError
    path = tmp_path / "case.yaml"
    path.write_text(ARM + 'events:\n  - {name: e, when: "A.angle >= 0.5", do: log}\n')
    report = check_model(path)
    assert "kernels: 1 element class derived, printed to C and rendered (not compiled); "\
           "event kernels of 1 events too" in report.text()
    assert "kernels not generated" in check_model(path, generate=False).text()

    def fails(cls):
        raise NotImplementedError("a kernel SymPy cannot print")
    monkeypatch.setattr(derive, "derive_class", fails)
    monkeypatch.setattr(check, "_PRINTED", {})
    with pytest.raises(BuildError, match=rf"{path}:\d+: bodies\.\w+: the kernels of "
                                         r"element class "
                                         r"body_\w+ \(body; .*\) cannot be generated: "
                                         "NotImplementedError: a kernel SymPy cannot"):
        check_model(path)


def test_the_command_line_check_has_no_generate(tmp_path, capsys):
    from fccgen.cli import main
    path = tmp_path / "case.yaml"
    path.write_text(ARM)
    assert main(["check", str(path), "--no-generate", "-q"]) == 0
    assert "kernels not generated" in capsys.readouterr().out


def test_an_initial_joint_angle_out_of_reach_keeps_its_item(tmp_path):
    """A ModelError raised while the initial state is assembled (the four-bar's
    rocker cannot reach 2.5 rad) reaches the user as it is (file, line, item), not
    reworded as a failure of the initial state."""
    from test_reactions import FOUR_BAR
    path = tmp_path / "case.yaml"
    path.write_text(FOUR_BAR.replace("joints: {O: {rate: 2.0}}", "joints: {C: {angle: 2.5}}"))
    with pytest.raises(ModelError) as info:
        check_model(path, generate=False)
    assert info.value.item == "initial.joints" and info.value.line is not None


def test_a_load_of_an_angle_of_a_hinge_on_its_bodies_axis_passes_check(tmp_path):
    """Found by the sections fuzz: a torque reading the angle of a hinge whose bodies'
    frame points lie on its axis divided 0 by 0 while the initial state was assembled.
    The angle is now measured from the body's vector (tests/test_hinge_reference.py):
    check passes with finite numbers."""
    path = tmp_path / "angle.yaml"
    path.write_text("""\
name: angle
gravity: [0, 0, 0]
bodies:
  a: {mass: 1.0, center: [0.5, 0, 0], inertia: [1.0e-3, 0.08, 0.08]}
  b: {mass: 0.5, center: [1.5, 0, 0], inertia: [1.0e-2, 0.04, 0.04]}
joints:
  - {name: A, type: revolute, bodies: [ground, a], at: [0, 0, 0], axis: [0, 1, 0]}
  - {name: B, type: cylindrical, bodies: [a, b], at: [1, 0, 0], axis: [1, 0, 0]}
loads:
  - {type: torque, body: a, value: [0, "B.angle", 0]}
""")
    text = check_model(path, generate=False).text()
    assert "nan" not in text and "degrees of freedom" in text

