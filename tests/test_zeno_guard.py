"""The Zeno guard of events (fccgen.runtime.event_settings.max_per_step, engine
fcc_rk4.c): it scales with the model's event functions, so that a step may carry the
events of many functions that cross in it, and it still stops a real Zeno loop.

Both runs are on a ball on a prismatic joint with limits: RK4 is exact for its constant
acceleration, so its impact times are closed forms up to the location tolerance."""
from __future__ import annotations

import math

import pytest

import fccgen.api as api
import fccgen.runtime.event_settings as event_settings

G = 9.81
DT = 1e-3


def balls(n: int, restitution: float, step: float) -> str:
    """n balls falling side by side onto their lower limits, ball k's limit lower by
    k step (m): distinct impact times, all in one step for a small step."""
    lines = ["name: guard_balls", "gravity: [0, 0, -9.81]", "bodies:"]
    body = "mass: 1.0, inertia: [0.01, 0.01, 0.01]"
    lines += [f"  b{k}: {{{body}, center: [{k}, 0, 0]}}" for k in range(n)]
    lines.append("joints:")
    lines += [f"  - {{name: S{k}, type: prismatic, bodies: [ground, b{k}], "
              f"at: [{k}, 0, 0], axis: [0, 0, 1], limits: [{-1.0 - k * step!r}, 1.0], "
              f"restitution: {restitution}}}" for k in range(n)]
    lines.append("simulate: {t_end: 1.0, dt: 1.0e-3, method: rk4}")
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def four_balls(build_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("guard") / "four_balls.yaml"
    path.write_text(balls(4, 0.5, 1e-5))
    return path


@pytest.mark.parametrize("path_kind", ["dense", "sparse"])
def test_a_step_carries_more_events_than_the_margin(four_balls, build_dir, monkeypatch,
                                                    path_kind):
    """Four balls hit their limits within 7 us, in one step. With the margin set to 1
    event (a constant guard of 1 would rest the second, third and fourth ball), the
    guard of 8 event functions, 1 + 2 x 8, lets all four bounce: each at its closed-form
    time sqrt(2 (1 + k 1e-5) / g) (to 1e-10 s: the location tolerance is 1e-12 s), at
    its speed sqrt(2 g (1 + k 1e-5)) (to 1e-9 of it), and with Newton's law
    |s'+| = e |s'-|: the energy the impact takes is (1 - e^2) m s'^2 / 2 (to 1e-12 of
    the balls' kinetic energy, its rounding; the other balls' speeds do not change)."""
    monkeypatch.setattr(event_settings, "MAX_PER_STEP", 1)
    solver = api.load(four_balls, build_dir, linear_solver=path_kind)
    assert event_settings.max_per_step(8) == 17
    result = solver.simulate(t_end=0.6, dt=DT, method="rk4", reactions=False)
    rows = result.events
    assert [r["action"] for r in rows] == ["bounce"] * 4
    assert [r["name"] for r in rows] == [f"S{k}_lower" for k in range(4)]
    assert len({math.floor(r["t"] / DT) for r in rows}) == 1          # one step
    for k, r in enumerate(rows):
        assert abs(r["t"] - math.sqrt(2 * (1 + k * 1e-5) / G)) <= 1e-10
        speed = math.sqrt(2 * G * (1 + k * 1e-5))
        assert abs(r["speed_before"] + speed) <= 1e-9 * speed
        lost = r["kinetic_energy_before"] - r["kinetic_energy_after"]
        scale = r["kinetic_energy_before"]
        assert abs(lost - (1 - 0.25) * speed ** 2 / 2) <= 1e-12 * scale


def test_a_zeno_loop_still_meets_the_guard(build_dir, tmp_path):
    """One ball, restitution 0.9, no rest speed: its bounces never end by themselves
    (flights 2 v0 e^k / g, an infinite series summing to t1 + 2 v0 e / (g (1 - e))).
    The guard stops the loop: the step where it meets it carries max_per_step(2) = 54
    bounces, and the 55th event rests the ball on its limit, within the series' tail
    of its sum (the flights left after about 140 bounces: 1e-5 s); earlier impact
    times follow the series to 1e-9 s."""
    path = tmp_path / "zeno_ball.yaml"
    path.write_text(balls(1, 0.9, 0.0))
    solver = api.load(path, build_dir)
    result = solver.simulate(t_end=10.0, dt=DT, method="rk4", rest_speed=0.0,
                             reactions=False)
    rows = result.events
    assert rows[-1]["action"] == "rest"
    assert all(r["action"] == "bounce" for r in rows[:-1])
    last = math.floor(rows[-1]["t"] / DT)
    in_last = [r for r in rows if math.floor(r["t"] / DT) == last]
    assert len(in_last) == event_settings.max_per_step(2) + 1 == 55
    v0, e = math.sqrt(2 * G), 0.9
    t1 = math.sqrt(2 / G)
    assert abs(rows[-1]["t"] - (t1 + 2 * v0 * e / (G * (1 - e)))) <= 1e-5
    expected = t1
    for k, r in enumerate(rows[:20]):
        assert abs(r["t"] - expected) <= 1e-9, k
        expected += 2 * v0 * e ** (k + 1) / G
    assert abs(result["S0.position"][-1] + 1.0) <= 1e-12
    assert abs(result["S0.speed"][-1]) <= 1e-9
