"""Forward sensitivities carried by dopri5 (engine/fcc_sens_dopri5.c): its stages,
error estimate and continuous extension applied to the sensitivities, the
linearised projections, and the stop/log/lock/unlock jumps at located events.

An adaptive run's result is the motion to its tolerance, not one fixed discrete map,
so the references are the continuous motion's derivatives, reached three
independent ways:
- central differences of dopri5 runs at rtol = 1e-12 (d = 1e-3 |p| and 1e-4 |p|,
  combined by Richardson: the central difference's error is O(d^2), so
  R = (100 D(d/10) - D(d)) / 99 leaves O(d^4) ~ 1e-12, plus the runs' own error
  over 2 d, 1e-12 / 2e-4 ~ 1e-8 of the derivative): every parameter kind on the
  double pendulum and the sprung pendulum (spring, damper, free length, force),
  1e-7 relative to the key's largest derivative; measured 2e-9 to 1e-7 against
  the plain D(d/10), far less against R;
- the elliptic-integral closed form of the latch time (tests/test_sensitivity_events.py):
  1e-8 relative, the issue's figure; measured 4e-11 at rtol = 1e-10;
- the rk4 sensitivities (checked against central differences of rk4 in
  test_sensitivity_runs.py and test_sensitivity_events.py) at steps whose global
  error, (w0 h)^4, is below 1e-11: every event action on the latch pendulum and
  the solar array's two latches, 1e-8 relative; measured 2e-10 (pendulum) and
  3e-10 (solar array) at rtol = 1e-10, and the redundant Bricard linkage, 1e-7
  normwise (measured 1.7e-9). They follow the tolerance (measured 1e-6, 1e-8,
  1e-10 relative at rtol = 1e-6, 1e-8, 1e-10 on the pendulum): dopri5's global
  error is about rtol times the motion's growth.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import EXAMPLES, ROOT
from test_sensitivity_events import closed_latch_time

from fccgen.cli import main
from fccgen.results import Result
from fccgen.runtime.sensitivity.parameters import current_value

mp = pytest.importorskip("mpmath")

TIGHT = dict(method="dopri5", rtol=1e-12, atol=1e-14, reactions=False)
CASES = {
    "double_pendulum": ["bodies.rod1.mass", "bodies.rod2.inertia[1]",
                        "bodies.rod2.center[0]", "gravity[1]"],
    "sprung_pendulum": ["loads[0].stiffness", "loads[0].damping", "loads[0].length",
                        "loads[1].value[0]"],
}


@pytest.fixture(scope="module")
def load(compiled, build_dir):
    """load(name): examples/<name>.yaml (the session's) or tests/data/<name>.yaml."""
    import fccgen
    cache = {}

    def get(name):
        if (EXAMPLES / f"{name}.yaml").exists():
            return compiled(name)
        if name not in cache:
            cache[name] = fccgen.load(ROOT / "tests" / "data" / f"{name}.yaml", build_dir)
        return cache[name]
    return get


@pytest.mark.parametrize("name", sorted(CASES))
def test_every_parameter_kind_against_richardson_central_differences(load, name):
    solver, keys = load(name), CASES[name]
    run = dict(TIGHT, t_end=0.3, output_dt=0.1)
    r = solver.simulate(**run, sensitivities=keys)
    assert r.info["sensitivity_error_control"] is False
    columns = [c for c in r.names if f"d({c})/d({keys[0]})" in r.columns]
    for key in keys:
        x = current_value(solver.plan.model, key)
        diff = []
        for rel in (1e-3, 1e-4):
            plus, minus = (solver.with_parameters({key: x + s * rel * abs(x)}).simulate(
                **run) for s in (1, -1))
            diff.append(np.array([(plus[c] - minus[c]) / (2 * rel * abs(x))
                                  for c in columns]))
        richardson = (100 * diff[1] - diff[0]) / 99
        scale = np.max(np.abs(richardson))
        got = np.array([r.sensitivity(c, key) for c in columns])
        np.testing.assert_allclose(got, richardson, rtol=0, atol=1e-7 * scale,
                                   err_msg=f"{name}: {key}")


def event_sensitivities(r, key, column):
    return np.array([e[f"d(time)/d({key})"] for e in r.events]
                    + list(r.sensitivity(column, key)))


def test_latch_time_against_the_elliptic_closed_form(load):
    mp.mp.dps = 40
    r = load("latch_pendulum").simulate(t_end=0.5, output_dt=0.25, method="dopri5",
                                        rtol=1e-10, atol=1e-12, reactions=False,
                                        sensitivities=["bodies.arm.center[0]"])
    latch = r.events[1]
    assert latch["name"] == "latch"
    d, gx, gz = mp.mpf("0.8"), mp.mpf(3), mp.mpf(-9)
    dd = float(mp.diff(lambda x: closed_latch_time(x, gx, gz), d))
    assert latch["d(time)/d(bodies.arm.center[0])"] == pytest.approx(dd, rel=1e-8)


def test_every_event_action_against_rk4(load):
    """log, lock, unlock and stop (the last record: the total derivative at the moving
    end time), and every record between them (dense output, projected)."""
    solver = load("latch_pendulum")
    keys = ["bodies.arm.center[0]", "gravity[0]", "bodies.arm.mass"]
    ref = solver.simulate(t_end=1.5, dt=5e-4, output_dt=0.1, method="rk4",
                          sensitivities=keys, reactions=False)
    r = solver.simulate(t_end=1.5, output_dt=0.1, method="dopri5", rtol=1e-10,
                        atol=1e-12, sensitivities=keys, reactions=False)
    assert [e["action"] for e in r.events] == ["log", "lock", "unlock", "stop"]
    # the stop's time: the two motions agree to their global errors (2.3e-11 s measured)
    assert len(r.t) == len(ref.t) and r.t[-1] == pytest.approx(ref.t[-1], abs=1e-9)
    for key in keys:
        want = event_sensitivities(ref, key, "arm.cx")
        np.testing.assert_allclose(event_sensitivities(r, key, "arm.cx"), want, rtol=0,
                                   atol=1e-8 * np.max(np.abs(want)), err_msg=key)


def test_solar_array_latches_against_rk4(compiled):
    solver = compiled("solar_array")
    keys = ["loads[0].stiffness", "bodies.panel2.mass"]
    run = dict(t_end=2.1, output_dt=0.1, reactions=False, sensitivities=keys)
    ref = solver.simulate(**run, dt=1e-3, method="rk4")
    r = solver.simulate(**run, method="dopri5", rtol=1e-10, atol=1e-12)
    assert [e["name"] for e in r.events] == ["panel_latch", "root_latch"]
    for key in keys:
        want = event_sensitivities(ref, key, "P.x")
        np.testing.assert_allclose(event_sensitivities(r, key, "P.x"), want, rtol=0,
                                   atol=1e-8 * np.max(np.abs(want)), err_msg=key)


def test_redundant_bricard_against_rk4(compiled):
    """One redundant joint equation at every position (rank 23 of 24 rows): dopri5 at
    rtol 1e-10 against rk4 at 0.25 ms (checked against central differences in
    test_sensitivity_singular.py), 1e-7 of the parameter's largest derivative of any
    column, normwise as there; measured 8e-12 (mass) and 1.7e-9 (inertia)."""
    solver = compiled("bricard")
    keys = ["bodies.bar2.mass", "bodies.bar3.inertia[1]"]
    run = dict(t_end=0.15, output_dt=0.05, reactions=False, sensitivities=keys)
    ref = solver.simulate(**run, dt=2.5e-4, method="rk4")
    r = solver.simulate(**run, method="dopri5", rtol=1e-10, atol=1e-12)
    assert r.info["rank"] < solver.n_g
    columns = [c for c in r.names if f"d({c})/d({keys[0]})" in r.columns]
    for key in keys:
        want = np.array([ref.sensitivity(c, key) for c in columns])
        got = np.array([r.sensitivity(c, key) for c in columns])
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-7 * np.max(np.abs(want)),
                                   err_msg=key)


def test_error_control_holds_the_sensitivities_to_the_tolerance(load):
    """sensitivity_error=True: the sensitivities' local error joins the step's error
    test (parameter j's absolute tolerance atol / |p_j|). At rtol = 1e-6 the run then
    takes more steps (46 against 27) and its sensitivities are as accurate, relative
    to their size, as the run without the option keeps the state (errors against a
    run at 1e-12: the state's 1.6e-6 m on arms of 1 m and 0.8 m without it; the sensitivities'
    at most 8.7e-6 to 2.8e-5 without it, 2.7e-7 to 1.4e-6 with it: measured). Bounds:
    within 2x of the state's error, and at least 5x below the run without it."""
    solver = load("double_pendulum")
    keys = CASES["double_pendulum"]
    run = dict(t_end=1.0, output_dt=0.1, reactions=False, sensitivities=keys)
    ref = solver.simulate(**dict(run, **TIGHT))
    loose = dict(run, method="dopri5", rtol=1e-6, atol=1e-8)
    free, held = solver.simulate(**loose), solver.simulate(**loose, sensitivity_error=True)
    assert free.info["sensitivity_error_control"] is False
    assert held.info["sensitivity_error_control"] is True
    assert held.info["steps"] > free.info["steps"]
    columns = ("P2.x", "P2.y")
    state = max(np.max(np.abs(free[c] - ref[c])) for c in columns)   # arms of 1 m

    def error(r):
        return max(np.max(np.abs(r.sensitivity(c, k) - ref.sensitivity(c, k)))
                   / np.max(np.abs(ref.sensitivity(c, k))) for k in keys for c in columns)
    assert error(held) < 2 * state
    assert error(free) > 5 * error(held)


def test_what_is_refused_says_why(load):
    solver = load("double_pendulum")
    run = dict(t_end=0.1, output_dt=0.05, reactions=False)
    with pytest.raises(ValueError, match="rk4 has none"):
        solver.simulate(**run, dt=1e-3, method="rk4", sensitivities=["gravity[1]"],
                        sensitivity_error=True)
    with pytest.raises(ValueError, match="needs sensitivities"):
        solver.simulate(**run, method="dopri5", sensitivity_error=True)
    with pytest.raises(ValueError, match="True or False"):
        solver.simulate(**run, method="dopri5", sensitivities=["gravity[1]"],
                        sensitivity_error=1)
    with pytest.raises(ValueError, match="projected dopri5"):
        solver.simulate(**run, method="dopri5", project=False,
                        sensitivities=["gravity[1]"])
    with pytest.raises(ValueError, match="rk4 or dopri5 method"):
        solver.simulate(**run, dt=1e-3, method="baumgarte", sensitivities=["gravity[1]"])


def test_cli_runs_dopri5_with_the_option(build_dir, tmp_path, capsys, load):
    out = tmp_path / "S.csv"
    args = ["sensitivity", str(EXAMPLES / "double_pendulum.yaml"), "--params",
            "gravity[1]", "--t-end", "0.2", "--output-dt", "0.1", "--method", "dopri5",
            "--rtol", "1e-8", "--atol", "1e-10", "--build-dir", str(build_dir),
            "--out", str(out), "-q"]
    assert main(args + ["--sensitivity-error"]) == 0
    assert "dopri5: " in capsys.readouterr().out
    api = load("double_pendulum").simulate(t_end=0.2, output_dt=0.1, method="dopri5",
                                           rtol=1e-8, atol=1e-10, reactions=False,
                                           sensitivities=["gravity[1]"],
                                           sensitivity_error=True)
    np.testing.assert_array_equal(Result.load(out).sensitivity("P2.x", "gravity[1]"),
                                  api.sensitivity("P2.x", "gravity[1]"))


def test_dopri5_on_the_sparse_path_is_refused_before_the_run():
    """dopri5's sensitivities use the dense path's multipliers: a solver loaded on the
    sparse path is told so, and what works, before anything runs."""
    import fccgen
    solver = fccgen.load(EXAMPLES / "double_pendulum.yaml", linear_solver="sparse")
    with pytest.raises(ValueError, match="dense path only"):
        solver.simulate(t_end=0.01, dt=1e-3, method="dopri5",
                        sensitivities=["bodies.rod1.mass"])
