"""ALI3-P on the scissor structures (fccgen/runtime/ali3p_setup.py, conditioned_penalty;
the penalty raise of _ali3p.pyx) and its refusal of models with events
(fccgen/settings/limits.py).

A scissor chain's row-scaled constraint Jacobian has a small last kept singular value
s_r (8-bay mast 1.2e-2, 50-bay mast 3.1e-4, 12-unit boom 3.0e-3): with the fixed
penalty 1e9 each multiplier update shrank g along that direction by only 1 /
(1 + (dt^2/4) 1e9 s_r^2) = 0.97 (8 bays), and the 8-bay mast stopped at t = 0.024 s
with Newton corrections stuck at 9e-10 against a tolerance of 1e-10."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import fccgen
from conftest import EXAMPLES, example_module
from fccgen.cli import main

T_END = 0.5


@pytest.fixture(scope="module")
def mast(build_dir, tmp_path_factory):
    """The 8-bay triangular scissor mast (162 coordinates, 255 rows, 1 DOF)."""
    path = tmp_path_factory.mktemp("mast") / "mast8.yaml"
    path.write_text(example_module("make_scissor_mast").model_text(8))
    return fccgen.load(path, build_dir)


@pytest.fixture(scope="module")
def reference(mast):
    """dopri5 at rtol 1e-10: its error is orders below ALI3-P's at dt = 1e-3."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return mast.simulate(method="dopri5", t_end=T_END, rtol=1e-10, atol=1e-12)


def position_error(result, reference) -> float:
    cols = [c for c in reference.names if c[-2:] in (".x", ".y", ".z")]
    return max(float(np.max(np.abs(result[c] - reference[c]))) for c in cols)


def test_the_mast_runs_and_converges_at_second_order(mast, reference):
    """Two steps against dopri5: the error falls 4-fold when dt halves (the trapezoidal
    rule's order 2), so the run follows the motion and is not merely stable."""
    runs = [mast.simulate(method="ali3p", t_end=T_END, dt=dt) for dt in (1e-3, 5e-4)]
    for r in runs:
        assert r.info["max_newton_iterations"] <= 5        # measured 4 and 3
        assert r.info["penalty_raises"] == 0
        assert r.info["penalty_start"] > 1e9                # raised at the start
        assert r.info["max_constraint_error"] <= 1e-9
    errors = [position_error(r, reference) for r in runs]
    # measured 1.04e-6 and 2.60e-7 m (ratio 4.0) while the points move by up to
    # 1.85 m; dopri5 at rtol 1e-12 moves the reference by 1.2e-10 m
    assert errors[0] <= 5e-6
    assert 3.5 <= errors[0] / errors[1] <= 4.5


def test_a_given_penalty_is_raised_only_where_newton_stalls(mast, reference):
    """penalty=1e9 given: the run starts with it, the first stalled step is taken
    again with ten times the penalty (until it converges) and the run ends as
    accurate as with the conditioned penalty."""
    r = mast.simulate(method="ali3p", t_end=T_END, penalty=1e9)
    assert r.info["penalty_start"] == 1e9 and 1 <= r.info["penalty_raises"] <= 4
    assert r.info["penalty"] == 1e9 * 10 ** r.info["penalty_raises"]
    assert position_error(r, reference) <= 5e-6


def test_simulate_refuses_ali3p_on_a_model_with_events_before_building(tmp_path, capsys):
    build = tmp_path / "build"
    code = main(["simulate", str(EXAMPLES / "pendulum_limit.yaml"), "--method", "ali3p",
                 "--build-dir", str(build), "-q"])
    out, err = capsys.readouterr()
    assert code == 1 and out == ""
    assert err == (f"fccgen: error: {EXAMPLES / 'pendulum_limit.yaml'}:13: joints.A.limits: "
                   "method ali3p does "
                   "not take models with events (this one has A_lower, A_upper, quarter): "
                   "its trapezoidal step has no event location yet, nor the lock and "
                   "bounce projections; use rk4 or dopri5 (docs/events.md) (got 'ali3p')\n")
    assert not build.exists()


def test_check_names_the_methods_that_cannot_run_a_model():
    from fccgen.diagnostics.check import check_model
    text = check_model(EXAMPLES / "pendulum_limit.yaml").text()
    assert ("note: methods: only rk4 and dopri5 run this model, since it has events "
            "(A_lower, A_upper, quarter); refused: baumgarte, ali3p, scipy-RK45") in text
    assert "methods:" not in check_model(EXAMPLES / "four_bar.yaml").text()


def test_a_sweep_refuses_ali3p_on_a_model_with_events(compiled):
    from fccgen.sweep import sweep as run_sweep
    with pytest.raises(ValueError, match="method ali3p does not take models with events"):
        run_sweep(compiled("pendulum_limit"), {"simulate.t_end": [0.1]}, method="ali3p")
