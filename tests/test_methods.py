"""Integration methods (fccgen.settings.methods): every method against a tight reference on the
double pendulum and the four-bar, convergence with step and tolerance, Baumgarte
stabilisation, run statistics, compiled vs numeric, the SciPy path and error paths."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fccgen.settings import methods
from fccgen.errors import ModelError, RunWarning, SimulationError
from fccgen.model import METHODS, load_model_text
from fccgen.numeric.dopri5 import simulate_dopri5 as numeric_dopri5
from fccgen.runs import scipy_ivp
from fccgen.runtime._dopri5 import simulate_dopri5
from fccgen.runtime.solver import METHODS as COMPILED_METHODS

EXAMPLES = ("double_pendulum", "four_bar")
T_END, OUT = 1.0, 0.04
ADAPTIVE = ("dopri5", "scipy-RK45", "scipy-DOP853", "scipy-Radau", "scipy-BDF",
            "scipy-LSODA")


def _position_error(a, b) -> float:
    cols = [c for c in a.names if c.endswith((".x", ".y", ".z"))]
    return max(float(np.max(np.abs(a[c] - b[c]))) for c in cols)


_REFS = {}


def _reference(solver, name):
    """DOPRI5 at rtol 1e-12 (checked below against rk4 at dt = 2.5e-4)."""
    if name not in _REFS:
        _REFS[name] = solver.simulate(t_end=T_END, method="dopri5", output_dt=OUT,
                                      rtol=1e-12, atol=1e-14)
    return _REFS[name]


# -- the registry -------------------------------------------------------------------------
def test_registry_is_the_one_list():
    assert METHODS == methods.names()
    assert {"rk4", "dopri5", "baumgarte", "scipy-RK45", "scipy-DOP853", "scipy-Radau",
            "scipy-BDF", "scipy-LSODA"} <= set(METHODS)
    for m in methods.METHODS.values():
        assert m.kind in ("fixed", "adaptive") and m.description
        for o in m.options:
            assert o.default > 0 and o.source and o.help
    assert methods.METHODS["dopri5"].defaults() == {"rtol": 1e-6, "atol": 1e-9}
    assert methods.METHODS["baumgarte"].defaults() == {"alpha": 5.0, "beta": 5.0}


@pytest.mark.parametrize("name", methods.names())
def test_model_file_accepts_every_method(name):
    text = ("name: m\npoints: {O: {at: [0, 0, 0], fixed: true}, P: [1, 0, 0]}\n"
            "vectors: {z: {along: [0, 0, 1], fixed: true}}\n"
            "bodies: {b: {points: [O, P], vector: z, mass: 1, inertia: [1, 1, 1]}}\n"
            f"simulate: {{method: {name}}}\n")
    assert load_model_text(text).simulate.method == name


def test_model_file_rejects_unknown_method_listing_the_others():
    text = ("name: m\npoints: {O: {at: [0, 0, 0], fixed: true}, P: [1, 0, 0]}\n"
            "vectors: {z: {along: [0, 0, 1], fixed: true}}\n"
            "bodies: {b: {points: [O, P], vector: z, mass: 1, inertia: [1, 1, 1]}}\n"
            "simulate: {method: euler}\n")
    with pytest.raises(ModelError, match="dopri5"):
        load_model_text(text)


@pytest.mark.parametrize("which", ["compiled", "numeric"])
def test_unknown_method_and_option_errors(which, compiled, numeric):
    solver = (compiled if which == "compiled" else numeric)("double_pendulum")
    with pytest.raises(ValueError, match=r"unknown method 'rk5'; available: rk4, dopri5"):
        solver.simulate(t_end=0.01, method="rk5")
    with pytest.raises(ValueError, match=r"takes no option 'alpha' \(its options: none\)"):
        solver.simulate(t_end=0.01, method="rk4", alpha=3.0)
    with pytest.raises(ValueError, match="must be a positive number"):
        solver.simulate(t_end=0.01, method="dopri5", rtol=-1.0)


# -- accuracy against a tight reference ------------------------------------------------------
def test_reference_is_converged(compiled):
    for name in EXAMPLES:
        s = compiled(name)
        rk4 = s.simulate(t_end=T_END, method="rk4", dt=2.5e-4, output_dt=OUT)
        # two independent fine solutions: observed 1e-12 (pendulum), 1.4e-11 (four-bar)
        assert _position_error(rk4, _reference(s, name)) < 1e-10


# Fixed-step methods at dt = 1e-3: a fourth-order error C dt^4 with each example's
# error constant; bounds are 5x the observed error of rk4 without projection
# (2.1e-10 on the pendulum, 4.6e-6 on the four-bar, whose coupler moves fast).
FIXED_BOUND = {"double_pendulum": 1e-9, "four_bar": 2.5e-5}


@pytest.mark.parametrize("name", EXAMPLES)
@pytest.mark.parametrize("method,options", [
    ("rk4", {}), ("rk4", {"project": False}), ("baumgarte", {})])
def test_fixed_step_methods_match_reference(compiled, name, method, options):
    s = compiled(name)
    r = s.simulate(t_end=T_END, method=method, dt=1e-3, output_dt=OUT, **options)
    assert _position_error(r, _reference(s, name)) < FIXED_BOUND[name]


# ALI3-P is second order (trapezoidal rule). Bounds: about 4x its observed error at
# dt = 1e-3 (8.4e-6 on the pendulum, 4.4e-4 on the four-bar, whose error constant is
# larger; the penalty changes it by up to 10x, so the order is checked as well).
ALI3P_BOUND = {"double_pendulum": 4e-5, "four_bar": 2e-3}


@pytest.mark.skipif("ali3p" not in COMPILED_METHODS, reason="_ali3p is not built")
@pytest.mark.parametrize("name", EXAMPLES)
def test_ali3p_matches_reference(compiled, name):
    s = compiled(name)
    ref = _reference(s, name)
    e = [_position_error(s.simulate(t_end=T_END, method="ali3p", dt=dt, output_dt=OUT),
                         ref) for dt in (1e-3, 5e-4)]
    assert e[0] < ALI3P_BOUND[name]
    # halving dt divides the error by ~4 (observed 4.0 and 5.7): order at least 1.6
    assert e[0] / e[1] > 3.0, e


@pytest.mark.parametrize("name", EXAMPLES)
@pytest.mark.parametrize("method", ADAPTIVE)
def test_adaptive_methods_match_reference(compiled, name, method):
    s = compiled(name)
    rtol = 1e-8
    r = s.simulate(t_end=T_END, method=method, output_dt=OUT, rtol=rtol, atol=1e-10)
    np.testing.assert_allclose(r.t, _reference(s, name).t, rtol=0, atol=1e-14)
    # Global error of a tolerance-controlled method: rtol times the error growth of the
    # problem over 1 s; observed at most 470 rtol (LSODA on the four-bar).
    assert _position_error(r, _reference(s, name)) < 1000 * rtol


@pytest.mark.parametrize("name", EXAMPLES)
def test_dopri5_error_falls_with_rtol(compiled, name):
    s = compiled(name)
    ref = _reference(s, name)
    errors = [_position_error(s.simulate(t_end=T_END, method="dopri5", output_dt=OUT,
                                         rtol=rtol, atol=rtol * 1e-3), ref)
              for rtol in (1e-4, 1e-6, 1e-8)]
    # each factor 100 in rtol: error down by more than 10 (observed 100-200)
    assert errors[0] > 10 * errors[1] > 100 * errors[2]
    assert errors[2] < 1e-6


@pytest.mark.parametrize("name", EXAMPLES)
def test_rk4_observed_order_is_four(compiled, name):
    s = compiled(name)
    ref = _reference(s, name)
    e = [_position_error(s.simulate(t_end=T_END, method="rk4", dt=dt, output_dt=OUT,
                                    project=False), ref) for dt in (4e-3, 2e-3, 1e-3)]
    orders = [math.log2(e[0] / e[1]), math.log2(e[1] / e[2])]
    # asymptotic order 4; observed 3.9-4.0 (higher-order terms at the coarse step)
    assert all(3.7 < p < 4.3 for p in orders), orders


def test_baumgarte_bounds_drift_that_rk4_accumulates(compiled):
    s = compiled("four_bar")
    # the unprojected run leaves the constraints by 2 % of the model's size and its
    # energy by 2 % of the peak kinetic energy, and says both
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", RunWarning)
        free = s.simulate(t_end=10.0, dt=5e-3, method="rk4", project=False, output_dt=0.1)
    said = " ".join(str(w.message) for w in seen)
    assert "without projection the run left the constraints" in said
    assert "the energy changed by" in said
    stab = s.simulate(t_end=10.0, dt=5e-3, method="baumgarte", output_dt=0.1)
    c_free, c_stab = free["constraint_error"], stab["constraint_error"]
    # unstabilised drift grows (observed 3.5e-4 at 5 s, 1.4e-3 at 10 s) ...
    assert c_free[-1] > 2 * c_free[50] > 1e-4
    # ... Baumgarte keeps it two decades lower over the run (observed 840x lower)
    assert c_stab.max() < c_free.max() / 100
    assert stab.info["newton_iterations"] == 0 and stab.info["project"] is False


def test_baumgarte_options_are_used(compiled):
    s = compiled("four_bar")
    a = s.simulate(t_end=1.0, dt=1e-3, method="baumgarte", output_dt=0.1)
    b = s.simulate(t_end=1.0, dt=1e-3, method="baumgarte", output_dt=0.1,
                   alpha=20.0, beta=20.0)
    assert a.info["options"] == {"alpha": 5.0, "beta": 5.0}
    assert b.info["options"] == {"alpha": 20.0, "beta": 20.0}
    # the parameters reach the compiled loop, and both runs follow the same motion
    # (each within the fixed-step bound of the reference)
    assert 0 < _position_error(a, b) < 2 * FIXED_BOUND["four_bar"]


# -- run statistics ------------------------------------------------------------------------
@pytest.mark.parametrize("method", COMPILED_METHODS)
def test_info_keys_present_and_sensible(compiled, method):
    s = compiled("four_bar")
    r = s.simulate(t_end=0.2, method=method, dt=1e-3, output_dt=0.01)
    info = r.info
    assert set(methods.INFO_KEYS) <= set(info)
    assert info["method"] == method
    assert info["steps"] > 0 and info["rhs_evaluations"] >= info["steps"]
    assert info["rejected_steps"] is None or info["rejected_steps"] >= 0
    assert info["wall_time"] > 0
    e = r["energy"]
    assert info["energy_drift"] == pytest.approx(np.max(np.abs(e - e[0])), abs=0)
    assert info["max_constraint_error"] >= r["constraint_error"].max()
    if methods.METHODS[method].projects:
        assert info["newton_iterations"] > 0 and info["project"] is True
    elif method == "ali3p":                           # Newton on every step
        assert info["newton_iterations"] >= info["steps"]
    else:
        assert info["newton_iterations"] == 0
    if method == "rk4":
        assert info["steps"] == 200 and info["rhs_evaluations"] == 800


@pytest.mark.parametrize("method", ["dopri5", "scipy-RK45", "scipy-DOP853"])
def test_loose_tolerance_rejects_steps(compiled, method):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", RunWarning)
        r = compiled("four_bar").simulate(t_end=1.0, method=method, output_dt=0.05,
                                          rtol=1e-3, atol=1e-6)
    assert r.info["rejected_steps"] > 0
    # SciPy's runs are not projected: their constraint drift is measured (RK45 at rtol
    # 1e-3 leaves the four-bar's constraints by 4 % of its size in 1 s, and says so);
    # DOPRI5 projects
    assert ("constraint_drift" in r.info) == method.startswith("scipy")
    left = any("left the constraints" in str(w.message) for w in seen)
    assert left == (method == "scipy-RK45")


def test_dopri5_matches_scipy_rk45_step_for_step(compiled):
    """Same tableau, error norm and controller: without projection the compiled
    DOPRI5 takes SciPy RK45's steps (SciPy's controller is Hairer's)."""
    s = compiled("four_bar")
    a = s.simulate(t_end=0.3, method="dopri5", output_dt=0.01, project=False)
    b = s.simulate(t_end=0.3, method="scipy-RK45", output_dt=0.01)
    for key in ("steps", "rejected_steps", "rhs_evaluations"):
        assert a.info[key] == b.info[key]
    assert _position_error(a, b) < 1e-12          # rounding of the same arithmetic


def test_adaptive_outputs_and_first_step(compiled):
    s = compiled("double_pendulum")
    r = s.simulate(t_end=0.25, method="dopri5", output_dt=0.1, dt=1e-4)
    np.testing.assert_allclose(r.t, [0.0, 0.1, 0.2, 0.25], rtol=0, atol=1e-15)
    assert r.info["dt"] == 1e-4
    auto = s.simulate(t_end=0.25, method="dopri5", output_dt=0.1)
    assert auto.info["dt"] is None
    assert _position_error(r, auto) < 1e-5          # both within rtol-sized error


@pytest.mark.parametrize("project", [True, False])
def test_dopri5_pauses_do_not_change_the_run(compiled, project):
    s = compiled("four_bar")
    init = s.initial_state()
    args = (s._engine, init.q, init.v, 0.3, 0.05, 1e-6, 1e-9, 0.0, project)
    seen = []
    paused, stats_p = simulate_dopri5(*args, progress=seen.append, progress_interval=0.0)
    plain, stats = simulate_dopri5(*args)
    # a pause after every attempted step but the last
    assert len(seen) == stats["steps"] + stats["rejected_steps"] - 1 and seen == sorted(seen)
    assert stats_p == stats
    for key in plain:
        np.testing.assert_array_equal(paused[key], plain[key])   # bit for bit


# -- compiled vs numeric -----------------------------------------------------------------------
@pytest.mark.parametrize("method,options", [
    ("rk4", {}), ("rk4", {"project": False}), ("baumgarte", {"alpha": 8.0, "beta": 3.0}),
    ("dopri5", {}), ("dopri5", {"project": False}), ("scipy-RK45", {}),
    ("scipy-LSODA", {})])
def test_compiled_and_numeric_agree(compiled, numeric, method, options):
    c, n = compiled("four_bar"), numeric("four_bar")
    t_end = 0.05 if methods.METHODS[method].kind == "fixed" else 0.2
    a = c.simulate(t_end=t_end, method=method, output_dt=0.01, **options)
    b = n.simulate(t_end=t_end, method=method, output_dt=0.01, **options)
    # same algorithm on kernels that agree to ~1e-13: observed 1e-13 on every column
    for col in a.names:
        np.testing.assert_allclose(a[col], b[col], rtol=0, atol=1e-10, err_msg=col)
    for key in ("steps", "rejected_steps"):
        assert a.info[key] == b.info[key]


# -- the SciPy path --------------------------------------------------------------------------------
def test_rhs_returns_fresh_arrays(compiled):
    s = compiled("double_pendulum")
    init = s.initial_state()
    fun = scipy_ivp.make_rhs(s.accelerations, s.n_q)
    y = np.concatenate([init.q, init.v + 0.1])
    f1 = fun(0.0, y)
    keep = f1.copy()
    f2 = fun(0.0, y + 0.01)
    assert f1 is not f2 and not np.shares_memory(f1, f2)
    np.testing.assert_array_equal(f1, keep)          # the first value was not overwritten
    a1, a2 = s.accelerations(init.q, init.v), s.accelerations(init.q, init.v)
    assert not np.shares_memory(a1, a2)


def test_scipy_path_equals_solve_ivp(compiled):
    """Our stepping loop gives what solve_ivp itself gives with the same t_eval."""
    s = compiled("double_pendulum")
    init = s.initial_state()
    r = s.simulate(t_end=0.5, method="scipy-DOP853", output_dt=0.05, rtol=1e-9,
                   atol=1e-12)
    sol = solve_ivp(scipy_ivp.make_rhs(s.accelerations, s.n_q), (0.0, 0.5),
                    np.concatenate([init.q, init.v]), method="DOP853", t_eval=r.t,
                    rtol=1e-9, atol=1e-12)
    assert sol.success
    for k, (name, _) in enumerate(s.plan.triples):
        for c in range(3):
            np.testing.assert_allclose(r[f"{name}.{'xyz'[c]}"], sol.y[3 * k + c],
                                       rtol=0, atol=1e-14)   # identical arithmetic
    assert r.info["max_constraint_error"] > 0          # no projection on this path


def test_implicit_scipy_methods_report_jacobians(compiled):
    r = compiled("double_pendulum").simulate(t_end=0.2, method="scipy-Radau",
                                             output_dt=0.05)
    assert r.info["njev"] >= 1 and r.info["nlu"] >= 1
    assert r.info["rejected_steps"] is None            # SciPy does not expose it


# -- divergence and failures ---------------------------------------------------------------------
def test_unstable_baumgarte_settings_are_refused_before_the_run(compiled):
    """alpha dt = 10 is far outside RK4's stability interval (alpha dt < 2.78): the run
    settings are refused up front with the largest stable dt (fccgen.settings.run);
    runs that blow up anyway stop as 'diverged' (tests/test_run_guards.py)."""
    s = compiled("double_pendulum")
    with pytest.raises(ValueError, match=r"RK4 is unstable on the Baumgarte modes.*"
                                         r"use dt <= 0\.00279"):
        s.simulate(t_end=1.0, dt=1e-2, method="baumgarte", alpha=1e3, beta=1e3)


class _Blowup:
    """q'' = 2 q^3 from q = q' = 1: q = 1 / (1 - t), infinite at t = 1."""

    class plan:
        bodies = ()

    def accelerations(self, q, v):
        return 2.0 * q ** 3

    def constraints(self, q):
        return np.zeros(0)

    def energy(self, q, v):
        return 0.0

    def body_outputs(self, q, v):
        return np.zeros((0, 6))


def test_dopri5_step_size_underflow_is_an_error():
    sched = methods.Schedule(t_end=2.0, dt=None, output_dt=0.5)
    # the blow-up time moves by the rounding of the run: 1 within 1e-6
    with pytest.raises(SimulationError, match=r"t = (0\.99999|1\.00000)\d*: DOPRI5 step "
                                              r"size underflow"):
        numeric_dopri5(_Blowup(), np.ones(1), np.ones(1), sched,
                       {"rtol": 1e-6, "atol": 1e-9}, False)


def test_scipy_failure_is_an_error():
    # the state passes the run's divergence bound (guards.py) just before SciPy fails
    with pytest.raises(SimulationError, match=r"stopped at t = (0\.999|1\.00000)\d*: "
                                              r"(SciPy RK45 failed|the run diverged)"):
        scipy_ivp.integrate(_Blowup().accelerations, np.ones(1), np.ones(1), 2.0, 0.5,
                            "RK45", 1e-6, 1e-9)


# -- command line -------------------------------------------------------------------------------
def test_cli_passes_tolerances_and_options(compiled, build_dir, tmp_path, capsys):
    from conftest import EXAMPLES as EXAMPLE_DIR
    from fccgen.cli import main
    from fccgen.results.result import Result
    compiled("double_pendulum")                      # built once, served from the cache
    model = str(EXAMPLE_DIR / "double_pendulum.yaml")
    common = [model, "--build-dir", str(build_dir), "-q", "--t-end", "0.2"]
    out = tmp_path / "r.npz"
    assert main(["simulate", *common, "--method", "dopri5", "--rtol", "1e-9",
                 "--atol", "1e-12", "--output-dt", "0.05", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "dopri5:" in text and "rejected steps" in text and "energy drift" in text
    direct = compiled("double_pendulum").simulate(t_end=0.2, method="dopri5",
                                                  output_dt=0.05, rtol=1e-9, atol=1e-12)
    assert _position_error(Result.load(out), direct) == 0     # the same run
    assert main(["simulate", *common, "--method", "baumgarte", "--baumgarte-alpha", "8",
                 "--baumgarte-beta", "2"]) == 0
    assert "baumgarte:" in capsys.readouterr().out
    assert main(["simulate", *common, "--method", "baumgarte", "--method-option",
                 "gamma=1"]) == 1
    assert "takes no option 'gamma' (its options: alpha, beta)" in capsys.readouterr().err
    assert main(["simulate", *common, "--baumgarte-alpha", "8"]) == 1
    assert "takes no option 'alpha'" in capsys.readouterr().err
