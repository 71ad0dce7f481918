"""The model file's inputs: section (docs/model-file.md, "Inputs") and
simulate(inputs=...).

* the section's rules: a clear error (file, line, item, rule, value) for a name that
  clashes with another of the model's names, with t, a function, a constant, a result
  column, a keyword or a section, for a value that is not a number, and for an input
  read where it cannot work (drivers, forces on cable nodes); an input name
  that carries C text is refused before anything is generated;
* simulate(inputs={name: number}) equals the model file with that start value, bit
  for bit (the same kernels, the same parameter);
* an input that is a function of t, sampled at every step and held, differs from the
  same function written in t in the model file by at most the hold's bound
  max|u'| h t^2 / (2 J) (the panel's angle is linear in its torque);
* the compiled run equals the NumPy version with the same inputs to 1e-12;
* inputs that change over the run are refused for methods that step across output
  times, and unknown names are refused.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import EXAMPLES

import fccgen
from fccgen.errors import ModelError
from fccgen.model import load_model_text

PANEL = (EXAMPLES / "panel_input.yaml").read_text()
J = 0.1666667 + 2.0 * 0.5 ** 2          # the panel's inertia about the hinge


def panel_text(old: str, new: str) -> str:
    assert old in PANEL
    return PANEL.replace(old, new, 1)


@pytest.fixture(scope="module")
def panel(compiled):
    return compiled("panel_input")


def model_error(text: str) -> ModelError:
    with pytest.raises(ModelError) as info:
        load_model_text(text, "m.yaml")
    return info.value


@pytest.mark.parametrize("name, rule", [
    ("panel", "already used"), ("hinge", "already used"), ("t", "the time"),
    ("sin", "function"), ("pi", "constant"), ("energy", "result column"),
    ("lambda", "keyword"), ("gravity", "section")])
def test_an_input_name_must_be_its_own(name, rule):
    err = model_error(panel_text("inputs: {hinge_torque: 0.02}",
                                 f"inputs: {{hinge_torque: 0.02, {name}: 1.0}}"))
    text = str(err)
    assert "m.yaml" in text and f"inputs.{name}" in text and rule in text
    assert err.line == 1 + PANEL.splitlines().index("inputs: {hinge_torque: 0.02}")


def test_an_input_start_value_is_a_finite_number():
    err = model_error(panel_text("hinge_torque: 0.02", "hinge_torque: fast"))
    assert "inputs.hinge_torque" in str(err) and "must be a number" in str(err)
    err = model_error(panel_text("hinge_torque: 0.02", "hinge_torque: .inf"))
    assert "finite" in str(err)


@pytest.mark.parametrize("name", ['"a*/ exit(1); /*"', '"x\\ny"', '"x;y"', '"x.y"'])
def test_an_input_name_carrying_code_is_refused(name):
    """Only identifiers: nothing of the name can reach generated text unchecked."""
    err = model_error(panel_text("inputs: {hinge_torque: 0.02}",
                                 f"inputs: {{hinge_torque: 0.02, {name}: 1.0}}"))
    assert "inputs." in str(err) and "must be a name matching" in str(err)


def test_an_input_is_refused_in_a_driver():
    text = panel_text("loads:", "drivers:\n  - {name: m, joint: hinge, "
                      "angle: \"hinge_torque*t\"}\nloads:")
    err = model_error(text)
    assert "drivers[0].angle" in str(err) and "reads the input hinge_torque" in str(err)
    assert "jump" in str(err)


def test_an_event_may_read_an_input():
    """Events read inputs (their runs: tests/test_event_inputs.py)."""
    text = PANEL.replace("simulate:", "events:\n  - {name: e, when: \"hinge.angle >= "
                         "hinge_torque\", do: stop}\nsimulate:")
    model = load_model_text(text, "m.yaml")
    assert "hinge_torque" in {s.name for s in model.events[0].function.free_symbols}


def test_an_unknown_name_in_a_load_lists_the_inputs():
    err = model_error(panel_text('"hinge_torque"', '"hinge_torq"'))
    assert "did you mean 'hinge_torque'" in str(err)


def test_a_constant_input_equals_the_start_value(panel, build_dir, tmp_path):
    path = tmp_path / "panel_input.yaml"
    path.write_text(panel_text("hinge_torque: 0.02", "hinge_torque: 0.05"))
    other = fccgen.load(path, build_dir)
    want = other.simulate(reactions=False)
    got = panel.simulate(inputs={"hinge_torque": 0.05}, reactions=False)
    for name in want.names:
        assert np.array_equal(got[name], want[name]), name
    # and the next run, without inputs, is back at the start value
    again = panel.simulate(reactions=False)
    assert again["hinge.angle"][-1] == pytest.approx(0.02 * 2.0 ** 2 / (2 * J), rel=1e-6)


def test_a_sampled_input_follows_the_same_function_of_t(panel, build_dir, tmp_path):
    """u(t) = 0.02 sin(3 t) held over each step h against the model with the torque
    written in t: |angle difference| <= max|u'| h t^2 / (2 J) (a torque error of at
    most max|u'| h, integrated twice through J), and it is not zero (the hold acts)."""
    path = tmp_path / "panel_in_t.yaml"
    path.write_text(panel_text('"hinge_torque"', '"0.02*sin(3*t)"'))
    in_t = fccgen.load(path, build_dir).simulate(reactions=False)
    held = panel.simulate(inputs={"hinge_torque": lambda t: 0.02 * np.sin(3 * t)},
                          reactions=False)
    h, t = 0.01, held.t
    bound = 0.06 * h * t ** 2 / (2 * J)
    diff = np.abs(held["hinge.angle"] - in_t["hinge.angle"])
    assert np.all(diff <= bound + 1e-14)
    assert diff.max() > 1e-8        # the hold acts: far above rounding (1e-16)


def test_compiled_equals_numeric_with_the_same_inputs(panel, numeric):
    times = np.array([0.0, 0.5, 1.0, 2.0])
    inputs = {"hinge_torque": (times, [0.0, 0.04, -0.02, 0.01])}
    a = panel.simulate(inputs=inputs, output_dt=0.05, reactions=False)
    b = numeric("panel_input").simulate(inputs=inputs, output_dt=0.05, reactions=False)
    for name in a.names:
        if name == "constraint_error":      # rounding of g = 0 in each version
            assert max(a[name].max(), b[name].max()) < 1e-14
            continue
        scale = max(float(np.max(np.abs(a[name]))), 1e-300)
        assert np.max(np.abs(a[name] - b[name])) <= 1e-12 * scale, name


def test_changing_inputs_need_a_method_that_stops_at_output_times(panel):
    with pytest.raises(ValueError, match="only the fixed-step methods"):
        panel.simulate(method="dopri5", inputs={"hinge_torque": lambda t: t})
    with pytest.raises(ValueError, match="has no input 'torque'"):
        panel.simulate(inputs={"torque": 1.0})
    with pytest.raises(ValueError, match="not a finite number"):
        panel.simulate(inputs={"hinge_torque": lambda t: np.nan})


def test_an_input_no_load_reads_changes_nothing(build_dir, tmp_path, panel):
    path = tmp_path / "panel_input.yaml"
    path.write_text(panel_text("inputs: {hinge_torque: 0.02}",
                               "inputs: {hinge_torque: 0.02, spare: 1.0}"))
    solver = fccgen.load(path, build_dir)              # the same kernels: no new build
    got = solver.simulate(inputs={"spare": lambda t: t}, reactions=False)
    assert np.array_equal(got["hinge.angle"], panel.simulate(reactions=False)["hinge.angle"])
