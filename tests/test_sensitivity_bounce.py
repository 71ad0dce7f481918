"""Sensitivities through bounces and rests (engine/fcc_sens_events.c: Newton's impact
linearised, d(time)/dp of every impact, a rest carried as its row's lock).

- A ball on a prismatic limit (the model of tests/test_events_runtime.py), dropped 1 m
  with restitution 0.5, bounces 23 times and rests. Gravity only rescales time:
  z(t; g) = Z(t sqrt(g)), so every event time t_k and the position obey
  dt_k/dg = -t_k / (2 g) and dz/dg = -z'(t) t / (2 g) (g = -gravity[2]), through every
  bounce and the rest. RK4 is exact for this motion and the bounce's gradient is
  constant, so only the location tolerance (1e-12 s) and rounding remain: measured
  1e-15 s/(m/s^2) on the times and 2e-13 m/(m/s^2) on the position (of 0.1); checked
  at 1e-12 and 1e-11.
- The example pendulum on its limit (examples/pendulum_limit.yaml): its first two
  impact times against the elliptic-integral closed form, differentiated with respect
  to the mass centre's distance c, gravity, the mass and the inertia at 40 digits
  (mpmath). Released horizontally, I th'^2 / 2 = m g c sin(th) with I = Iyy + m c^2:
  the first impact at th_s = 1 comes at t1 = int_0^th_s dth / sqrt(k sin th),
  k = 2 m g c / I; it leaves at e th'_1 and turns where sin(th_t) = (1 - e^2) sin(th_s),
  so t2 = t1 + 2 int_th_t^th_s dth / sqrt(k (sin th - sin th_t)); with x = pi/2 - th
  both are incomplete elliptic integrals of the first kind. 1e-8 relative, the
  figure the issue asks of event times: RK4 at 1 ms is the continuous motion to about
  1e-12 s here (tests/test_events_runtime.py).
- The same pendulum through all 23 of its bounces and its rest against central
  differences of the same fixed-step runs at d = 1e-4 |p|: the event times and the
  mass centre at the end (resting on the stop: its derivatives vanish, so everything
  is judged on the key's largest derivative), 1e-7 of it. The reference's own error:
  each located time carries the location tolerance, 1e-12 s, over 2 d, and a late
  impact inherits the earlier ones' (the flights shrink by e each time). It is checked
  by d = 1e-5 |p|, which agrees to 1e-7 relative for the first ten events (flights
  above 10 ms); after them its own noise is 10 times larger (measured 7e-8 s per unit
  mass of 0.18 s, against 1.5e-8 s between d = 1e-4 |p| and the derivative).
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT
from test_events_runtime import BALL
from test_sensitivity_events import central, sensitivities

mp = pytest.importorskip("mpmath")
G = 9.81


@pytest.fixture(scope="module")
def ball(build_dir, tmp_path_factory):
    import fccgen
    path = tmp_path_factory.mktemp("bounce") / "ball_limit.yaml"
    path.write_text(BALL)
    return fccgen.load(path, build_dir)


def test_ball_bounce_times_and_height_scale_with_gravity(ball):
    r = ball.simulate(t_end=1.5, dt=1e-3, output_dt=0.01, sensitivities=["gravity[2]"],
                      reactions=False)
    actions = [row["action"] for row in r.events]
    assert actions.count("bounce") >= 20 and actions[-1] == "rest"
    for row in r.events:          # gravity[2] = -g: dt_k/d(gravity[2]) = t_k / (2 g)
        assert abs(row["d(time)/d(gravity[2])"] - row["t"] / (2 * G)) <= 1e-12, row
    t = np.asarray(r.t)
    dz = r.sensitivity("S.position", "gravity[2]")
    np.testing.assert_allclose(dz, -r["S.speed"] * t / (2 * G), rtol=0, atol=1e-11)
    assert np.max(np.abs(dz)) > 0.05                     # not trivially zero


def impact_times(c, g, m, Iyy, e=mp.mpf("0.5"), th_s=mp.mpf(1)):
    """The first two impact times of the example pendulum on its stop (docstring)."""
    k = 2 * m * g * c / (Iyy + m * c ** 2)

    def up_to(a, x0):
        """int_x0^a dx / sqrt(cos x - cos a) = sqrt(2) (K(s) - F(phi0, s)),
        s = sin^2(a / 2), sin(phi0) = sin(x0 / 2) / sin(a / 2)."""
        s = mp.sin(a / 2) ** 2
        return mp.sqrt(2) * (mp.ellipk(s) - mp.ellipf(mp.asin(mp.sin(x0 / 2)
                                                              / mp.sin(a / 2)), s))
    x_s = mp.pi / 2 - th_s
    t1 = up_to(mp.pi / 2, x_s) / mp.sqrt(k)              # from rest at th = 0
    th_t = mp.asin((1 - e ** 2) * mp.sin(th_s))
    t2 = t1 + 2 * up_to(mp.pi / 2 - th_t, x_s) / mp.sqrt(k)
    return t1, t2


def test_pendulum_first_two_impacts_against_the_elliptic_closed_form(compiled):
    mp.mp.dps = 40
    solver = compiled("pendulum_limit")
    keys = ["bodies.arm.center[0]", "gravity[2]", "bodies.arm.mass",
            "bodies.arm.inertia[1]"]
    r = solver.simulate(t_end=0.9, dt=1e-3, output_dt=0.1, sensitivities=keys,
                        reactions=False)
    impacts = [row for row in r.events if row["action"] == "bounce"]
    assert len(impacts) == 2 and all(row["name"] == "A_upper" for row in impacts)
    x = [mp.mpf("0.5"), mp.mpf(G), mp.mpf(1), 1 / mp.mpf(12)]
    for i in range(2):
        assert impacts[i]["t"] == pytest.approx(float(impact_times(*x)[i]), rel=1e-10)
        for j, key in enumerate(keys):
            def ti(p, j=j, i=i):
                return impact_times(*[p if jj == j else x[jj] for jj in range(4)])[i]
            exact = float(mp.diff(ti, x[j])) * (-1 if key == "gravity[2]" else 1)
            assert impacts[i][f"d(time)/d({key})"] == pytest.approx(exact, rel=1e-8), \
                (i, key)


def test_pendulum_bounces_and_rest_against_central_differences(compiled):
    solver = compiled("pendulum_limit")
    run = dict(t_end=1.5, dt=1e-3, output_dt=0.1)
    keys = ["bodies.arm.mass", "gravity[2]"]
    r = solver.simulate(**run, sensitivities=keys, reactions=False)
    actions = [row["action"] for row in r.events]
    assert actions[0] == "log" and actions.count("bounce") >= 20 and actions[-1] == "rest"
    for key in keys:
        est = central(solver, key, run, ["arm.cx", "arm.cz"])
        scale = np.max(np.abs(est[0]))
        np.testing.assert_allclose(est[1][:10], est[0][:10], rtol=1e-7)
        np.testing.assert_allclose(sensitivities(r, key, ["arm.cx", "arm.cz"]), est[0],
                                   rtol=0, atol=1e-7 * scale)


@pytest.fixture(scope="module")
def pulled(build_dir, tmp_path_factory):
    """The example pendulum with restitution 0.2 (it rests on its upper limit within
    0.8 s) and a torque -t N m about +y lifting the arm (tests/test_events_switches.py),
    which releases it."""
    import fccgen
    text = (ROOT / "examples" / "pendulum_limit.yaml").read_text()
    text = text.replace("restitution: 0.5", "restitution: 0.2")
    text += 'loads:\n  - {type: torque, body: arm, value: [0, "-t", 0]}\n'
    path = tmp_path_factory.mktemp("bounce") / "pendulum_pulled.yaml"
    path.write_text(text)
    return fccgen.load(path, build_dir)


def test_release_time_against_the_static_balance(pulled):
    """At rest on the limit theta = 1 the row holds gravity's torque m g c cos(theta)
    against the load's t: the release comes at T = m g c cos(1), so dT/dm = g c cos(1),
    dT/dc = m g cos(1), dT/d(gravity[2]) = -m c cos(1). The engine's release time's
    derivative is the row multiplier's linearised change over its rate (the rate by
    central differences along the motion, 1e-5 s: truncation and rounding below
    1e-10 relative); the time itself is located to about 3e-11 s
    (tests/test_events_switches.py). 1e-8 relative (measured 8e-12). Then the motion
    after the release (the mass centre at the end) against central differences at
    d = 1e-4 |p| (d = 1e-5 |p| agrees to 1e-7 of the largest on the release and the
    end; on the last impacts before the rest it is noisier, as in the test above),
    1e-7 of the key's largest derivative (measured 1e-8)."""
    run = dict(t_end=2.9, dt=1e-3, output_dt=0.1)
    keys = ["bodies.arm.mass", "bodies.arm.center[0]", "gravity[2]"]
    r = pulled.simulate(**run, sensitivities=keys, reactions=False)
    actions = [row["action"] for row in r.events]
    assert actions[-2:] == ["rest", "release"]
    release = r.events[-1]
    m, c, g, th = 1.0, 0.5, G, 1.0
    exact = {"bodies.arm.mass": g * c * np.cos(th), "bodies.arm.center[0]": m * g * np.cos(th),
             "gravity[2]": -m * c * np.cos(th)}
    for key, value in exact.items():
        assert release[f"d(time)/d({key})"] == pytest.approx(value, rel=1e-8), key
    for key in keys[:2]:
        est = central(pulled, key, run, ["arm.cx", "arm.cz"])
        scale = np.max(np.abs(est[0]))
        # the release and the end: the late impacts' own noise is above (first test)
        np.testing.assert_allclose(est[1][-3:], est[0][-3:], rtol=0, atol=1e-7 * scale)
        np.testing.assert_allclose(sensitivities(r, key, ["arm.cx", "arm.cz"]), est[0],
                                   rtol=0, atol=1e-7 * scale)


def test_a_bounce_on_the_sparse_path_is_refused_before_the_run():
    """The impact's jump takes the dense path's mass matrix and multipliers: a solver
    loaded on the sparse path is told so, and what works, before anything runs."""
    import fccgen
    from fccgen.errors import ModelError
    solver = fccgen.load(ROOT / "examples" / "pendulum_limit.yaml", linear_solver="sparse")
    with pytest.raises(ModelError, match="dense path only"):
        solver.simulate(t_end=0.01, dt=1e-3, method="rk4",
                        sensitivities=["gravity[1]"])
