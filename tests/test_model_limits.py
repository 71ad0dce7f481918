"""The limits of model input and run settings (docs/reliability.md, "Input"): each case
of the input audit as a named test.

Model-file cases edit the valid model of test_model_errors (BASE) and mark the line the
error must name with ``#<``, as there; run-setting cases call the one function both
solvers and the loader use (fccgen.settings.run), and the command line end to end.
"""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from fccgen.settings import methods
from fccgen.diagnostics.check import _require_finite
from fccgen.cli import main
from fccgen.errors import FccgenError, ModelError, SimulationError, shown
from fccgen.model import load_model, load_model_text, yamlcompose, yamlnodes
from fccgen.model.fields import MAX_MAGNITUDE, MIN_POSITIVE
from fccgen.settings.run import RunSettingError, baumgarte_modes, rk4_growth
from test_model_errors import (BASE, HIDDEN, SIMULATE, SOURCE, check, edited, expect_error,
                               marked_line, sub)

# Every message, whatever the file holds, stays below this (the audit saw 351 MB).
MESSAGE_LIMIT = 2_000


def bomb(levels: int) -> str:
    """A "billion laughs" YAML text: 9**levels strings once expanded, in ~50 bytes a
    level."""
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for k in range(1, levels):
        lines.append(f"a{k}: &a{k} [" + ",".join([f"*a{k - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def flow_bomb(levels: int) -> str:
    """The same as one flow list: [&a0 [...], &a1 [*a0, ...], ...]."""
    items = ['&a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for k in range(1, levels):
        items.append(f"&a{k} [" + ",".join([f"*a{k - 1}"] * 9) + "]")
    return "[" + ", ".join(items) + "]"


def error_of(text: str) -> ModelError:
    err = expect_error(text)
    assert len(str(err)) < MESSAGE_LIMIT, str(err)[:300]
    return err


# -- YAML: nesting, aliases, size ---------------------------------------------------------
@pytest.mark.parametrize("depth", [51, 490, 100_000], ids=lambda d: f"flow {d} levels")
def test_deep_flow_nesting_is_refused(depth):
    """490 levels gave RecursionError in PyYAML's composer; the scanner's check stops
    100,000 levels at once."""
    text = BASE + "deep: " + "[" * depth + "]" * depth + " #<\n"
    check(error_of(text), marked_line(text), "YAML", "nests deeper than 50 levels",
          text.splitlines()[-1])


def test_deep_block_nesting_is_refused():
    text = "name: m\nx:\n" + "".join("  " * k + "-\n" for k in range(600))
    err = error_of(text)
    assert (err.item, err.rule) == ("YAML", "nests deeper than 50 levels (a model needs "
                                            "fewer than 10)")
    assert 50 <= err.line <= 52         # the first node past 50 levels (root: level 1)


def test_nesting_within_the_limit_reaches_the_model_rules():
    text = edited([sub("gravity: [0, 0, -9.81]", "gravity: " + "[" * 45 + "]" * 45 + " #<")])
    value = []
    for _ in range(43):
        value = [value]
    check(error_of(text), marked_line(text), "gravity", "must be a list of 3 numbers",
          [value])


@pytest.mark.parametrize("levels", [7, 9], ids=["bomb of 7 levels", "billion laughs"])
def test_alias_bomb_is_refused_without_expanding(levels):
    """The audit's 567-byte file printed 351 MB of error text (610 bytes: MemoryError):
    the walk adds up expanded sizes from the shared nodes and stops at the first node
    past MAX_NODES, a5 (1 + 9 (1 + 9 (...)) = 597,871 nodes), at once."""
    text = bomb(levels)
    check(error_of(text), 6, "a5", "expands to more than 100000 YAML nodes", 597_871)


def test_alias_bomb_under_a_model_key():
    text = edited([sub("gravity: [0, 0, -9.81]", f"gravity: {flow_bomb(7)} #<")])
    check(error_of(text), marked_line(text), "gravity[5]", "expands to more than", 597_871)


def test_large_value_is_shown_clipped():
    """A list of 8,303 nodes (aliases expanded) where 3 numbers belong: the message
    shows the start of its text and its size."""
    text = edited([sub("gravity: [0, 0, -9.81]", f"gravity: {flow_bomb(4)} #<")])
    err = error_of(text)
    assert (err.item, err.line) == ("gravity", marked_line(text))
    assert "must be a list of 3 numbers" in err.rule
    assert str(err).endswith("(8303 nodes))") and "(got [['lol', 'lol'" in str(err)


def test_too_many_nodes_is_refused(monkeypatch):
    monkeypatch.setattr(yamlcompose, "MAX_NODES", 300)
    text = BASE + "extra: [" + ", ".join(["0"] * 300) + "]\n"
    err = error_of(text)
    assert err.rule == "has more than 300 YAML nodes (a model needs far fewer)"


def test_input_size_limit(tmp_path):
    text = BASE + "# " + "x" * yamlnodes.MAX_INPUT_CHARS + "\n"
    check(error_of(text), None, "model file", "characters long; at most 1000000 are read",
          HIDDEN)
    path = tmp_path / "big.yaml"
    path.write_text(text)
    with pytest.raises(ModelError, match="is longer than 1000000 characters, the most a "
                                         "model file may hold"):
        load_model(path)


def test_limits_leave_room_for_the_largest_example():
    """A02 (40 four-bars): 15 kB, 1,729 nodes, 6 levels; the limits are 60x, 50x, 8x."""
    from conftest import EXAMPLES
    text = (EXAMPLES / "a02_n_four_bar.yaml").read_text()
    root = yamlnodes.parse_yaml(text, "a02")
    assert 60 * len(text) <= yamlnodes.MAX_INPUT_CHARS
    assert 50 * root.size <= yamlnodes.MAX_NODES
    assert yamlnodes.MAX_DEPTH >= 8 * 6


# -- messages stay short --------------------------------------------------------------------
def test_long_scalar_is_clipped_in_the_message():
    text = edited([sub("    mass: 1.0", "    mass: " + "x" * 100_000 + " #<")])
    err = error_of(text)
    assert err.value == "x" * 100_000                    # the attribute keeps it whole
    assert str(err).endswith(f"(got {shown('x' * 100_000)})")
    assert "... (100002 characters)" in str(err)


def test_long_key_is_clipped_in_the_message():
    """YAML keys are at most 1024 characters (a longer plain key is a syntax error)."""
    text = edited([sub("name: slider", "name: slider\n" + "k" * 1000 + ": 1 #<")])
    err = error_of(text)
    assert err.item == "k" * 1000 and "unknown key" in err.rule
    assert str(err).startswith("slider.yaml:2: " + "k" * 300 + "... (1000 characters): ")


def test_integer_too_long_to_print_is_shown_by_its_size():
    """A hex integer has no digit limit, but its decimal repr raises ValueError."""
    text = edited([sub("  A: [1, 0, 0]", "  A: [0x" + "f" * 5000 + ", 0] #<")])
    check(error_of(text), marked_line(text), "points.A", "must be a list of 3 numbers",
          [16 ** 5000 - 1, 0])
    assert "(got [<an integer of about 6021 digits>, 0])" in str(error_of(text))
    with pytest.raises(RunSettingError, match=r"t_end \(--t-end\): .* \(got <an integer "
                                              r"of about 5001 digits>\)"):
        methods.schedule(methods.get("rk4"), _Defaults, t_end=10 ** 5000)


def test_long_name_lists_are_cut():
    points = "".join(f"  P{k}: {{at: [{k}, 0, 0], fixed: true}}\n" for k in range(100))
    text = edited([sub("  B: [2, 0, 0]", "  B: [2, 0, 0]\n" + points.rstrip("\n")),
                   sub("    points: [O, A]", "    points: [O, Q] #<")])
    err = error_of(text)
    assert err.rule.endswith("P15, P16, ... (103 in all)")


# -- numbers: finite and within range ---------------------------------------------------------
NUMBER_CASES = [
    ("distance 1e154", sub("length: 2.0}", "length: 1e154} #<"), "constraints[1].length",
     "must be at most 1e+12 in magnitude", 1e154),
    ("coordinate 1e13", sub("  B: [2, 0, 0]", "  B: [1e13, 0, 0] #<"), "points.B[0]",
     "must be at most 1e+12 in magnitude", 1e13),
    ("gravity 1e300", sub("gravity: [0, 0, -9.81]", "gravity: [0, 0, -1e300] #<"),
     "gravity[2]", "must be at most 1e+12 in magnitude", -1e300),
    ("gravity 1e308", sub("gravity: [0, 0, -9.81]", "gravity: [0, 0, 1.0e+308] #<"),
     "gravity[2]", "must be at most 1e+12", 1e308),
    ("velocity 1e13", sub("  points: {A: [0, 1, 0]}", "  points: {A: [0, 1e13, 0]} #<"),
     "initial.points.A[1]", "must be at most 1e+12", 1e13),
    ("angular velocity nan", sub("angular_velocity: [0, 0, 1]", "angular_velocity: [0, 0, .nan]"),
     "initial.bodies.crank.angular_velocity[2]", "must be a finite number", "nan"),
    ("stiffness 1e20", sub("stiffness: 100", "stiffness: 1e20"), "loads[2].stiffness",
     "must be at most 1e+12", 1e20),
    ("force 1e13", sub("value: [0, 1, 0]}", "value: [0, 1e13, 0]}"), "loads[0].value[1]",
     "must be at most 1e+12", 1e13),
    ("inertia 1e13", sub("    inertia: [0.01, 0.1, 0.1]", "    inertia: [1e13, 0.1, 0.1] #<"),
     "bodies.crank.inertia[0]", "must be at most 1e+12", 1e13),
    ("mass 1e-31", sub("    mass: 1.0", "    mass: 1e-31 #<"), "bodies.crank.mass",
     "must be at least 1e-30", 1e-31),
    ("mass 1e-300", sub("    mass: 1.0", "    mass: 1e-300 #<"), "bodies.crank.mass",
     "must be at least 1e-30", 1e-300),
    ("inertia 1e-40", sub("    inertia: [0.01, 0.1, 0.1]", "    inertia: [1e-40, 1e-40, 1e-40] #<"),
     "bodies.crank.inertia", "must have a principal moment of at least 1e-30",
     [1e-40, 1e-40, 1e-40]),
    ("dt 1e-300", sub(SIMULATE, "simulate: {t_end: 2.0, dt: 1e-300} #<"), "simulate.dt",
     "must be at least 1e-30", 1e-300),
]


@pytest.mark.parametrize("edit, item, rule, value", [c[1:] for c in NUMBER_CASES],
                         ids=[c[0] for c in NUMBER_CASES])
def test_number_range(edit, item, rule, value):
    text = edited([edit])
    err = error_of(text)
    assert (err.item, err.file) == (item, SOURCE) and rule in err.rule, str(err)
    if value == "nan":
        assert math.isnan(err.value)
    else:
        assert err.value == value
    if "#<" in text:
        assert err.line == marked_line(text)


def test_number_limits_are_inclusive():
    text = edited([sub("  B: [2, 0, 0]", "  B: [2, 0, 1e12]"),
                   sub("    mass: 1.0", f"    mass: {MIN_POSITIVE!r}"),
                   sub("stiffness: 100", f"stiffness: {MAX_MAGNITUDE!r}")])
    model = load_model_text(text, SOURCE)
    assert model.bodies["crank"].mass == 1e-30 and model.points["B"].at[2] == 1e12


# -- the simulate section: refused at load, so by check too ------------------------------------
SIMULATE_CASES = [
    ("dt 1e-16: 2e16 steps", "simulate: {t_end: 2.0, dt: 1e-16} #<", "simulate.dt",
     "t_end / dt = 2e+16 steps, more than 1e+08 in one run: use a larger dt (at least 2e-08)",
     1e-16),
    ("t_end 1e12: 1e15 steps", "simulate: {t_end: 1e12} #<", "simulate.t_end",
     "more than 1e+08 in one run: use a shorter t_end (at most 1e+05)", 1e12),
    ("output_dt not a multiple", "simulate: {dt: 1e-3, output_dt: 1.5e-3} #<",
     "simulate.output_dt", "must be a positive whole multiple of dt = 0.001", 1.5e-3),
    ("1e8 output rows", "simulate: {t_end: 1e5, dt: 1e-3} #<", "simulate.t_end",
     "1e+08 output times, more than 1e+07: use a larger output_dt or a shorter t_end", 1e5),
    ("1 GiB of outputs", "simulate: {t_end: 5e3, dt: 1e-3, output_dt: 1e-3} #<",
     "simulate.output_dt", "5000002 output times of 33 numbers are 1.23 GiB, more than "
     "1 GiB: use a larger output_dt (at least 0.00123)", 1e-3),
    ("baumgarte dt beyond RK4", "simulate: {t_end: 6, dt: 0.6, method: baumgarte} #<",
     "simulate.dt", "RK4 is unstable on the Baumgarte modes of alpha = 5, beta = 5 at "
     "dt = 0.6", 0.6),
    ("ali3p dt loses the mass matrix", "simulate: {t_end: 1e4, dt: 1e4, method: ali3p} #<",
     "simulate.dt", "the mass matrix is lost in the rounding", 1e4),
]


@pytest.mark.parametrize("line, item, rule, value", [c[1:] for c in SIMULATE_CASES],
                         ids=[c[0] for c in SIMULATE_CASES])
def test_simulate_section(line, item, rule, value):
    text = edited([sub(SIMULATE, line)])
    check(error_of(text), marked_line(text), item, rule, value)


@pytest.mark.parametrize("line", [c[1] for c in SIMULATE_CASES[:4]] + [
    "simulate: {dt: 1e-300}"], ids=[c[0] for c in SIMULATE_CASES[:4]] + ["dt 1e-300"])
def test_check_fails_where_simulate_would(tmp_path, capsys, line):
    path = tmp_path / "m.yaml"
    path.write_text(edited([sub(SIMULATE, line.replace(" #<", ""))]))
    code = main(["check", str(path)])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err.startswith(f"fccgen: error: {path}:")
    assert "nan" not in err and len(err) < MESSAGE_LIMIT


def test_check_passes_the_base_model_with_finite_numbers(tmp_path, capsys):
    path = tmp_path / "m.yaml"
    path.write_text(BASE)
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "model slider" in out and not re.search(r"\b(nan|inf)\b", out)


def test_check_refuses_a_non_finite_initial_state():
    with pytest.raises(SimulationError, match=r"m.yaml: the residuals of the initial "
                                              r"state are not finite \(found nan\)"):
        _require_finite("m.yaml", {"the residuals": [0.0, math.nan]})
    _require_finite("m.yaml", {"the residuals": [0.0, 1e300]})


# -- run settings from the command line and the API --------------------------------------------
class _Defaults:
    t_end, dt, output_dt, values_per_output = 5.0, 1e-3, 1e-2, 33


def schedule_error(method="rk4", options=None, **args) -> RunSettingError:
    with pytest.raises(RunSettingError) as info:
        methods.schedule(methods.get(method), _Defaults, options=options, **args)
    return info.value


@pytest.mark.parametrize("args, flag, rule", [
    ({"dt": 1e-16}, "--dt", "5e+16 steps, more than 1e+08 in one run: use a larger dt"),
    ({"dt": 1e-300}, "--dt", "use a larger dt (at least 5e-08)"),
    ({"t_end": 1e12}, "--t-end", "use a shorter t_end (at most 1e+05)"),
    ({"t_end": math.nan}, "--t-end", "must be a positive number of at most 1e+12"),
    ({"t_end": math.inf}, "--t-end", "must be a positive number of at most 1e+12"),
    ({"dt": 2.0, "t_end": 1.0}, "--dt", "must be at most t_end = 1"),
    ({"output_dt": 1.5e-3}, "--output-dt", "must be a positive whole multiple of dt"),
    ({"dt": 3e-3}, "--dt", "must divide output_dt = 0.01 a whole number of times"),
    ({"output_dt": 1e-3, "t_end": 1e4}, "--output-dt",
     "1e+07 output times, more than 1e+07: use a larger output_dt (at least 0.001)"),
], ids=["dt 1e-16", "dt 1e-300", "t_end 1e12", "t_end nan", "t_end inf", "dt > t_end",
        "output_dt not a multiple", "dt not dividing output_dt", "too many outputs"])
def test_run_setting_flags(args, flag, rule):
    err = schedule_error(**args)
    assert f"({flag}): " in str(err) and rule in str(err), str(err)


def test_adaptive_outputs_are_bounded_too():
    err = schedule_error("dopri5", output_dt=1e-7, t_end=10.0)
    assert str(err).startswith("output_dt (--output-dt): 1e+08 output times")


@pytest.mark.parametrize("method, given, flag, rule", [
    ("dopri5", {"rtol": 100}, "--rtol", "must be a positive number in (2.22045e-15, 1)"),
    ("dopri5", {"rtol": 1e-16}, "--rtol", "below 10 eps is rounding"),
    ("dopri5", {"rtol": 1.0}, "--rtol", "must be a positive number in"),
    ("dopri5", {"atol": 0.0}, "--atol", "must be a positive number in (0, 1e+12]"),
    ("dopri5", {"atol": math.nan}, "--atol", "must be a positive number"),
    ("baumgarte", {"alpha": -1.0}, "--baumgarte-alpha", "must be a number in [0, 1e+12]"),
    ("baumgarte", {"beta": math.inf}, "--baumgarte-beta", "must be a number in [0, 1e+12]"),
    ("ali3p", {"penalty": 0.0}, "--method-option penalty=VALUE", "must be a positive number"),
    ("ali3p", {"newton_tol": 0.0}, "--method-option newton_tol=VALUE",
     "Newton cannot stop by tolerance"),
    ("ali3p", {"max_newton": 2.5}, "--method-option max_newton=VALUE",
     "must be a whole number in [1, 10000]"),
    ("ali3p", {"max_newton": 0}, "--method-option max_newton=VALUE", "a whole number"),
    ("ali3p", {"max_newton": "many"}, "--method-option max_newton=VALUE", "a whole number"),
], ids=["rtol 100", "rtol below 10 eps", "rtol 1", "atol 0", "atol nan", "alpha negative",
        "beta inf", "penalty 0", "newton_tol 0", "max_newton 2.5", "max_newton 0",
        "max_newton text"])
def test_method_option_ranges(method, given, flag, rule):
    with pytest.raises(RunSettingError) as info:
        methods.options_for(methods.get(method), given=given)
    assert f"({flag}): " in str(info.value) and rule in str(info.value)


def test_method_options_at_their_limits_are_accepted():
    assert methods.options_for(methods.get("ali3p"), given={"max_newton": 40.0}) == {
        "penalty": 1e9, "newton_tol": 1e-10, "max_newton": 40}
    assert isinstance(methods.options_for(methods.get("ali3p"),
                                          given={"max_newton": 40.0})["max_newton"], int)
    assert methods.options_for(methods.get("baumgarte"),
                               given={"alpha": 0.0, "beta": 0.0}) == {"alpha": 0, "beta": 0}


def test_baumgarte_step_limit_names_the_flag_given():
    base = methods.get("baumgarte")
    opts = methods.options_for(base, given={"alpha": 5000.0})
    err = schedule_error("baumgarte", options=opts)
    assert str(err).startswith("alpha (--baumgarte-alpha): RK4 is unstable on the Baumgarte "
                               "modes of alpha = 5000, beta = 5 at dt = 0.001")
    err = schedule_error("baumgarte", options=methods.options_for(base), dt=0.6,
                         output_dt=0.6, t_end=6.0)
    assert str(err).startswith("dt (--dt): RK4 is unstable") and "use dt <= 0.557" in str(err)


def test_baumgarte_step_limit_is_rk4_stability():
    """alpha = beta = 5: a double mode -5, stable while 5 dt <= 2.785 (RK4's real
    interval), so dt = 0.55 passes and 0.56 does not."""
    assert rk4_growth(-2.785) < 1 < rk4_growth(-2.786)
    assert baumgarte_modes(5.0, 5.0) == (-5, -5)
    opts = methods.options_for(methods.get("baumgarte"))
    methods.schedule(methods.get("baumgarte"), _Defaults, t_end=5.5, dt=0.55,
                     output_dt=0.55, options=opts)
    schedule_error("baumgarte", options=opts, t_end=5.6, dt=0.56, output_dt=0.56)


def test_run_setting_error_is_an_fccgen_error_and_a_value_error():
    err = schedule_error(dt=1e-16)
    assert isinstance(err, FccgenError) and isinstance(err, ValueError)
    assert (err.setting, err.value) == ("dt", 1e-16)


def test_simulate_flags_end_to_end(tmp_path, capsys):
    """``fccgen simulate --rtol 100`` (numeric: no compile) fails naming the flag."""
    path = tmp_path / "m.yaml"
    path.write_text(BASE)
    for args, flag in ((["--method", "dopri5", "--rtol", "100"], "--rtol"),
                       (["--dt", "1e-16"], "--dt"),
                       (["--t-end", "1e12"], "--t-end")):
        code = main(["simulate", str(path), "--numeric", "-q", *args])
        out, err = capsys.readouterr()
        assert code == 1 and err.startswith("fccgen: error: ") and f"({flag}): " in err, err


# -- names ------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, rule", [
    ("__init__", "must not be a dunder name"), ("__main__", "must not be a dunder name"),
    ("cython", "Cython refuses it"), ("class", "must not be a Python keyword"),
    ("CON", "Windows device name"), ("com1", "Windows device name"),
])
def test_reserved_model_names(name, rule):
    text = edited([sub("name: slider", f"name: {name} #<")])
    check(error_of(text), 1, "name", rule, name)


@pytest.mark.parametrize("name", ["numpy", "json", "main", "module", "kernels", "setup",
                                  "build_module", "array", "libc", "cpython"])
def test_names_that_build(name):
    """Names of modules and generated files that build and run all the same (each
    checked once by building and simulating a model so named)."""
    assert load_model_text(edited([sub("name: slider", f"name: {name}")])).name == name


def test_point_name_length():
    text = edited([sub("  B: [2, 0, 0]", "  B: [2, 0, 0]\n  " + "C" * 65 + ": {at: [3, 0, 0], "
                       "fixed: true} #<")])
    check(error_of(text), marked_line(text), "points." + "C" * 65,
          "must be at most 64 characters long", "C" * 65)


def test_names_like_result_columns_stay_apart():
    """A point named energy, a body named t, a vector named constraint_error: their
    columns are energy.x, t.cx, constraint_error.x, apart from t, energy and
    constraint_error."""
    from fccgen.numeric import NumericSolver
    from fccgen.plan import make_plan
    text = (BASE.replace("A", "energy").replace("rod", "t").replace("  u: [0, 1, 0]",
                                                                      "  constraint_error: [0, 1, 0]")
            .replace("vector: u", "vector: constraint_error"))
    result = NumericSolver(make_plan(load_model_text(text))).simulate(t_end=2e-3)
    names = result.names
    assert len(names) == len(set(names))
    assert {"t", "energy", "constraint_error", "energy.x", "t.cx",
            "constraint_error.vx"} <= set(names)
    assert np.all(np.isfinite(result.table()))


# -- the two parsers ----------------------------------------------------------------------------
def _lines(node):
    """(line, plain value) of every node, depth first."""
    out = [(node.line, node.plain())]
    children = (node.entries.values() if isinstance(node, yamlnodes.YMap) else
                node.items if isinstance(node, yamlnodes.YSeq) else ())
    for c in children:
        out += _lines(c)
    return out


def test_libyaml_events_and_python_parser_agree(monkeypatch):
    """libyaml's events (when PyYAML has it) and PyYAML's Python parser give the same
    nodes, lines and errors: on every example and every case of test_model_errors."""
    from conftest import EXAMPLES
    from test_model_errors import CASES
    if yamlcompose.FastModelLoader is None:
        pytest.skip("PyYAML without libyaml: only the Python parser runs")
    texts = [p.read_text() for p in sorted(EXAMPLES.glob("*.yaml"))]
    cases = [edited(c[1]) for c in CASES]

    def outcomes():
        trees = [_lines(yamlnodes.parse_yaml(t, "m")) for t in texts]
        errors = []
        for text in cases:
            with pytest.raises(ModelError) as info:
                load_model_text(text, SOURCE)
            errors.append(str(info.value))
        return trees, errors

    fast = outcomes()
    monkeypatch.setattr(yamlcompose, "FastModelLoader", None)
    assert outcomes() == fast
