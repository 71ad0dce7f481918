"""Events in a compiled run (fccgen/runtime/_events.pyx, the rk4 hooks): location
against closed-form times, Newton's impact law, the geometric series of bounces of a
ball on a limit until it rests, and the event table in every result file format."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ellipkinc

import fccgen.api as api
from fccgen.results.result import Result

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
G = 9.81
BALL = """\
name: ball_limit
gravity: [0, 0, -9.81]
bodies:
  ball: {mass: 2.0, center: [0, 0, 0], inertia: [0.01, 0.01, 0.01]}
joints:
  - {name: S, type: prismatic, bodies: [ground, ball], at: [0, 0, 0], axis: [0, 0, 1],
     limits: [-1.0, 1.0], restitution: 0.5}
simulate: {t_end: 2.0, dt: 1.0e-3, method: rk4}
"""


@pytest.fixture(scope="session")
def pendulum(build_dir):
    return api.load(EXAMPLES / "pendulum_limit.yaml", build_dir)


@pytest.fixture(scope="session")
def ball(build_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("events") / "ball_limit.yaml"
    path.write_text(BALL)
    return api.load(path, build_dir)


def _elliptic_time(phi: float) -> float:
    """Time for the example's pendulum, released at rest horizontally, to turn by phi:
    I w^2 / 2 = m g c sin(theta), so t = int_0^phi dtheta / sqrt(k sin theta) with
    k = 2 m g c / I, and int_0^a dx / sqrt(cos x) = sqrt(2) F(asin(sqrt(2) sin(a/2)) | 1/2)
    (x = pi/2 - theta)."""
    k = 2 * 1.0 * G * 0.5 / (1.0 / 3.0)        # m = 1, c = 0.5, I about the pivot 1/3

    def f(a):
        return math.sqrt(2) * ellipkinc(math.asin(math.sqrt(2) * math.sin(a / 2)), 0.5)
    return (f(math.pi / 2) - f(math.pi / 2 - phi)) / math.sqrt(k)


def test_rk4_locates_a_pendulum_angle_at_the_elliptic_integral_time(pendulum):
    """The 'quarter' event (A.angle >= 0.5) against the elliptic-integral time. The
    located time's error is the root tolerance (1e-12 s) plus the trajectory's global
    error over the angular rate: RK4's ~C dt^4 with C ~ 0.5 measured at dt = 1e-3
    (4.8e-13 s; 3.1e-14 s at dt/2: the h^4 ratio 16), so 1e-10 s holds with margin."""
    result = pendulum.simulate(t_end=0.3, dt=1e-3, method="rk4")
    first = result.events[0]
    assert (first["name"], first["action"]) == ("quarter", "log")
    assert abs(first["t"] - _elliptic_time(0.5)) <= 1e-10


def test_rk4_location_converges_with_the_step(pendulum):
    """Halving dt shrinks the location error by about 2^4: it is the step error,
    not the root finder's, that bounds it."""
    errors = [abs(pendulum.simulate(t_end=0.3, dt=dt, method="rk4").events[0]["t"]
                  - _elliptic_time(0.5)) for dt in (2e-3, 1e-3)]
    assert errors[1] < errors[0] / 8


def test_ball_bounces_in_a_geometric_series_until_it_rests(ball):
    """Falling 1 from rest onto the lower limit: impact at t1 = sqrt(2/g) with speed
    v0 = sqrt(2 g), then flights of 2 e^k v0 / g. RK4 is exact for this constant
    acceleration, so the times are off by the location tolerance (1e-12 s) and its
    effect on later speeds, which doubles at each bounce relative to the shrinking
    flight (measured 1e-12 after 12 bounces, 3e-10 after 23): checked at 1e-11 for the
    first 12, 1e-9 after. Newton's law |s'+| = e |s'-| holds at each impact: this
    1-DOF body's kinetic energy is m s'^2 / 2, so KE+/KE- = e^2 to 1e-12 (rounding
    of the impulse). Below the rest speed (1e-6) it rests: locked at the limit."""
    result = ball.simulate(t_end=2.0, dt=1e-3, method="rk4")
    rows = result.events
    e, v0 = 0.5, math.sqrt(2 * G)
    expected = [math.sqrt(2 / G)]
    for k in range(1, len(rows)):
        expected.append(expected[-1] + 2 * v0 * e ** k / G)
    bounces = [r for r in rows if r["action"] == "bounce"]
    assert len(bounces) >= 20 and rows[-1]["action"] == "rest"
    assert all(r["name"] == "S_lower" for r in rows)
    for k, r in enumerate(rows):
        assert abs(r["t"] - expected[k]) <= (1e-11 if k < 12 else 1e-9), k
        assert abs(r["speed_before"] + v0 * e ** k) <= 1e-9 * v0, k
    for r in bounces:
        ratio = r["kinetic_energy_after"] / r["kinetic_energy_before"]
        assert abs(ratio - e * e) <= 1e-12
    t_rest = math.sqrt(2 / G) + 2 * v0 * e / (G * (1 - e))   # sum of the series
    assert abs(rows[-1]["t"] - t_rest) <= 1e-6               # rest: |s'| < 1e-6
    assert rows[-1]["dof"] == 0
    assert np.all(result["S.position"] >= -1.0 - 1e-12)
    assert abs(result["S.position"][-1] + 1.0) <= 1e-12
    assert abs(result["S.speed"][-1]) <= 1e-12


def test_pendulum_bounces_on_its_limit_and_rests(pendulum):
    """The example: e = 0.5 on the upper limit; each bounce keeps e^2 of the kinetic
    energy (1 DOF) and the arm never passes the limit by more than the location
    tolerance's worth of angle (rate x 1e-12 s, plus the position projection)."""
    result = pendulum.simulate(t_end=2.0, dt=1e-3, method="rk4")
    bounces = [r for r in result.events if r["action"] == "bounce"]
    assert len(bounces) >= 10
    for r in bounces:
        assert r["name"] == "A_upper"
        ratio = r["kinetic_energy_after"] / r["kinetic_energy_before"]
        assert abs(ratio - 0.25) <= 1e-12
    assert result.events[-1]["action"] == "rest"
    assert np.max(result["A.angle"]) <= 1.0 + 1e-11
    assert abs(result["A.angle"][-1] - 1.0) <= 1e-11



REACTIONS = (".fx", ".fy", ".fz", ".tx", ".ty", ".tz")


def test_events_past_the_logs_rows_are_counted_and_said(pendulum, monkeypatch):
    """A log of 4 rows on the run above (10 and more bounces, then rest): the run goes
    through every event, result.events holds the first 4 of the full run's table, and
    the rest are counted in info and said in a warning, never dropped silently. What
    the later bounces held (their rest) is not known, so the reactions are NaN from
    the last logged event on, with a warning (fccgen.runs.held_rows)."""
    from fccgen.errors import RunWarning
    from fccgen.runtime import event_settings
    full = pendulum.simulate(t_end=2.0, dt=1e-3, method="rk4")
    monkeypatch.setattr(event_settings, "LOG_ROWS", 4)
    with pytest.warns(RunWarning) as said:
        cut = pendulum.simulate(t_end=2.0, dt=1e-3, method="rk4")
    texts = [str(w.message) for w in said]
    assert any(f"{len(full.events) - 4} events after the first 4 are not in "
               "result.events" in t for t in texts), texts
    assert any("joint reactions are NaN" in t for t in texts), texts
    assert cut.events == full.events[:4]
    assert cut.info["events_dropped"] == len(full.events) - 4
    assert cut.info["energy_check"]["until"] == full.events[3]["t"]
    def table(result, reactions):
        return np.column_stack([result[c] for c in full.columns
                                if c.endswith(REACTIONS) == reactions])
    assert np.array_equal(table(cut, False), table(full, False))  # the motion is the same
    known = cut.t < full.events[3]["t"]
    assert np.array_equal(table(cut, True)[known], table(full, True)[known])
    assert np.isnan(table(cut, True)[~known]).all() and (~known).any()

@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_event_table_is_in_every_result_file(pendulum, tmp_path, suffix):
    result = pendulum.simulate(t_end=0.5, dt=1e-3, method="rk4")
    assert len(result.events) >= 2
    path = result.save(tmp_path / f"run{suffix}")
    back = Result.load(path)
    assert back.events == result.events
    np.testing.assert_array_equal(back.t, result.t)


FLOAT = """\
name: float_lock
bodies:
  A: {mass: 3.0, center: [0.1, 0.2, -0.3], inertia: [0.2, 0.3, 0.25]}
  B: {mass: 2.0, center: [-0.2, 0.1, 0.4], inertia: [0.1, 0.15, 0.12]}
joints:
  - {name: H, type: revolute, bodies: [A, B], at: [0, 0, 0], axis: [0, 0, 1]}
initial:
  bodies: {A: {angular_velocity: [0.3, -0.2, 1.0]}, B: {angular_velocity: [0.1, 0.4, -2.0]}}
events:
  - {name: latch, when: "H.angle <= -0.4", do: lock, joint: H}
simulate: {t_end: 0.5, dt: 1.0e-3, method: rk4}
"""
MASS = {"A": 3.0, "B": 2.0}
INERTIA = {"A": np.diag([0.2, 0.3, 0.25]), "B": np.diag([0.1, 0.15, 0.12])}


def _momenta(solver, result, row):
    """(m_total, centre-of-mass velocity, angular momentum about the centre of mass,
    total inertia about it) at record ``row``, from the result's columns: each body's
    inertia turned by R(t) R(0)^T (its frame from its i, j, u)."""
    from fccgen.mechanism.outputs import _Series
    series = _Series(solver.plan, result.columns, len(result.t))
    m = sum(MASS.values())
    c = {b: np.array([result[f"{b}_center.{k}"][row] for k in "xyz"]) for b in MASS}
    cd = {b: np.array([result[f"{b}_center.v{k}"][row] for k in "xyz"]) for b in MASS}
    cg = sum(MASS[b] * c[b] for b in MASS) / m
    vg = sum(MASS[b] * cd[b] for b in MASS) / m
    L, I = np.zeros(3), np.zeros((3, 3))
    for b in MASS:
        R = series.rotation(b)
        turn = R[row] @ R[0].T
        Ib = turn @ INERTIA[b] @ turn.T
        w = np.array([result[f"{b}.w{k}"][row] for k in "xyz"])
        d, dv = c[b] - cg, cd[b] - vg
        L += MASS[b] * np.cross(d, dv) + Ib @ w
        I += Ib + MASS[b] * (d @ d * np.eye(3) - np.outer(d, d))
    return m, vg, L, I


@pytest.fixture(scope="session")
def floating(build_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("events") / "float_lock.yaml"
    path.write_text(FLOAT)
    return api.load(path, build_dir)


def test_plastic_lock_of_a_free_floating_pair(floating):
    """A hinge between two free bodies locks at -0.4 rad. Internal impulses keep the
    angular momentum about the centre of mass (checked 1e-10 relative: RK4's error on
    these smooth rotations at dt = 1e-3 is ~1e-13) and the momentum. The plastic
    impact is the M-orthogonal projection onto the locked motions, which leaves the
    least kinetic energy with that momentum and angular momentum: the one rigid body's
    P^2 / 2m + L^T I^-1 L / 2 (checked 1e-10 relative). The hinge's rate is zero after
    (1e-12: the projection's rounding) and one DOF is gone (7 -> 6)."""
    result = floating.simulate(t_end=0.5, dt=1e-3, method="rk4")
    (row,) = result.events
    assert (row["name"], row["action"], row["dof"]) == ("latch", "lock", 6)
    after = result.t > row["t"]
    m, v0, L0, _ = _momenta(floating, result, 0)
    m, v1, L1, I1 = _momenta(floating, result, len(result.t) - 1)
    assert np.linalg.norm(L1 - L0) <= 1e-10 * np.linalg.norm(L0)
    assert np.linalg.norm(v1 - v0) <= 1e-12
    rigid = 0.5 * m * v1 @ v1 + 0.5 * L1 @ np.linalg.solve(I1, L1)
    assert abs(row["kinetic_energy_after"] - rigid) <= 1e-10 * rigid
    assert row["kinetic_energy_after"] < 0.5 * row["kinetic_energy_before"]
    assert abs(result["energy"][0] - row["kinetic_energy_before"]) <= 1e-10
    assert np.max(np.abs(result["energy"][after] - row["kinetic_energy_after"])) <= 1e-10
    assert np.max(np.abs(result["H.rate"][after])) <= 1e-12
    assert np.max(np.abs(result["H.angle"][after] + 0.4)) <= 1e-10
    assert row["constraint_error"] <= 1e-12


def test_dopri5_locates_on_its_dense_output(pendulum):
    """DOPRI5 locates on its continuous extension (order 4) within the accepted step,
    then ends the step at the event. At rtol = atol = 1e-10 the measured error is
    5e-12 s (1e-10 s at 1e-8, 4e-14 s at 1e-12: it follows the tolerance), so 1e-10
    holds with margin. The run then bounces to rest as with RK4."""
    result = pendulum.simulate(t_end=2.0, method="dopri5", rtol=1e-10, atol=1e-10,
                               output_dt=1e-2)
    assert abs(result.events[0]["t"] - _elliptic_time(0.5)) <= 1e-10
    assert result.events[-1]["action"] == "rest"
    assert np.max(result["A.angle"]) <= 1.0 + 1e-11
    for r in result.events:
        if r["action"] == "bounce":
            ratio = r["kinetic_energy_after"] / r["kinetic_energy_before"]
            assert abs(ratio - 0.25) <= 1e-12


def test_dopri5_ball_bounce_times(ball):
    """As with RK4 (exact here too: DOPRI5 and its extension integrate constant
    acceleration exactly): the first 12 bounce times to 1e-11 s."""
    result = ball.simulate(t_end=2.0, method="dopri5", rtol=1e-10, atol=1e-10,
                           output_dt=1e-2)
    e, v0 = 0.5, math.sqrt(2 * G)
    t = math.sqrt(2 / G)
    for k, r in enumerate(result.events[:12]):
        assert abs(r["t"] - t) <= 1e-11, k
        t += 2 * v0 * e ** (k + 1) / G
    assert result.events[-1]["action"] == "rest"


def test_stop_ends_the_run_at_the_event(build_dir, tmp_path):
    """do: stop ends the run at the located time, with a last record there (RK4 and
    DOPRI5): the example with its 'quarter' event made a stop."""
    text = (EXAMPLES / "pendulum_limit.yaml").read_text()
    path = tmp_path / "pendulum_stop.yaml"
    path.write_text(text.replace("do: log", "do: stop"))
    solver = api.load(path, build_dir)
    for method, opts in (("rk4", dict(dt=1e-3)), ("dopri5", dict(rtol=1e-10, atol=1e-10))):
        result = solver.simulate(t_end=1.0, method=method, **opts)
        assert [r["action"] for r in result.events] == ["stop"]
        assert result.t[-1] == result.events[0]["t"]
        assert abs(result.t[-1] - _elliptic_time(0.5)) <= 1e-10
        assert abs(result["A.angle"][-1] - 0.5) <= 1e-10


SPIN = """\
name: spin_events
bodies:
  wheel: {mass: 1.0, center: [0.5, 0, 0], inertia: [0.1, 0.1, 0.1]}
joints:
  - {name: A, type: revolute, bodies: [ground, wheel], at: [0, 0, 0], axis: [0, 0, 1]}
initial:
  joints: {A: {rate: 2.0}}
events:
  - {name: flat, when: "A.angle >= pi", do: log}
  - {name: turn, when: "A.angle - 2*pi", direction: rising, do: log}
  - {name: late, when: "A.angle >= 3.5*pi", do: log}
"""


def test_angles_locate_through_pi_and_over_turns(build_dir, tmp_path):
    """A wheel turning freely at 2 rad/s about a fixed hinge: angle = 2 t, so the
    events at pi (where atan2 wraps), 2 pi and 3.5 pi (past a full turn: turn counting)
    happen at pi/2, pi and 1.75 pi s. RK4 at dt = 1e-3 moves the wheel's point along
    its circle with an angle error ~1e-13 per unit time (the radius is held by the
    projection), so 1e-10 s holds."""
    path = tmp_path / "spin.yaml"
    path.write_text(SPIN)
    result = api.load(path, build_dir).simulate(t_end=6.0, dt=1e-3, method="rk4")
    got = {r["name"]: r["t"] for r in result.events}
    assert sorted(got) == ["flat", "late", "turn"] and len(result.events) == 3
    for name, t in (("flat", math.pi / 2), ("turn", math.pi), ("late", 1.75 * math.pi)):
        assert abs(got[name] - t) <= 1e-10, name
    assert abs(result["A.angle"][-1] - 12.0) <= 1e-9


def test_a_pickled_solver_keeps_its_events(pendulum):
    """Sweeps send solvers to workers by pickle: the event module goes along."""
    import pickle
    copy = pickle.loads(pickle.dumps(pendulum))
    a = pendulum.simulate(t_end=0.5, dt=1e-3, method="rk4").events
    b = copy.simulate(t_end=0.5, dt=1e-3, method="rk4").events
    assert a == b and len(a) >= 2


def test_latch_at_180_degrees_then_unlock(build_dir, tmp_path):
    """The panel example with a release at t = 4: the latch at 180 degrees (pi, where
    atan2 wraps) holds the hinge at pi to 1e-10 until the unlock; the unlock restores
    the DOF (6 -> 7) without an impulse, and the motor opens the hinge further."""
    text = (EXAMPLES / "panel_latch.yaml").read_text()
    path = tmp_path / "panel_release.yaml"
    latch_line = '  - {name: latch, when: "H.angle >= pi", do: lock, joint: H}\n'
    assert latch_line in text
    path.write_text(text.replace(latch_line, latch_line + '  - {name: release, when: '
                                 '"t >= 4", do: unlock, joint: H}\n'))
    result = api.load(path, build_dir).simulate(t_end=5.0, dt=1e-3, method="rk4")
    latch, release = result.events
    assert (latch["name"], latch["action"], latch["dof"]) == ("latch", "lock", 6)
    assert (release["name"], release["action"], release["dof"]) == ("release", "unlock", 7)
    assert abs(release["t"] - 4.0) <= 1e-12 and release["impulse"] == 0.0
    held = (result.t > latch["t"]) & (result.t <= 4.0)
    assert np.max(np.abs(result["H.angle"][held] - math.pi)) <= 1e-10
    assert result["H.angle"][-1] > math.pi + 0.05


def _event_set(solver):
    """The solver's compiled event state, reset (angle references 0, no rows held)."""
    events = solver._event_set(1e-12, 1e-6)
    events.reset(None)
    return events


def _random_states(solver, seed: int, count: int = 3):
    """count states (q, v) near the solver's initial q: q moved by 0.05 times a
    standard normal draw, v a standard normal draw."""
    q0 = solver.initial_state().q
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield q0 + 0.05 * rng.standard_normal(q0.shape), rng.standard_normal(q0.shape)


def test_lock_row_kernels_match_finite_differences(floating):
    """The compiled joint-quantity kernels of the hinge between two moving bodies: G
    against central differences of r, and the bias (dG/dt) v against central
    differences of G v along v, at random states near the initial one. Step 1e-5:
    truncation ~1e-10 |r'''|, rounding ~1e-16 / 1e-5; checked at 1e-7 relative."""
    events = _event_set(floating)
    for q, v in _random_states(floating, 5):
        r, g, b = events.quantity_kernels(q, v)
        h = 1e-5
        fd_g = np.array([(events.quantity_kernels(q + h * e, v)[0]
                          - events.quantity_kernels(q - h * e, v)[0]) / (2 * h)
                         for e in np.eye(len(q))]).T
        fd_b = ((events.quantity_kernels(q + h * v, v)[1]
                 - events.quantity_kernels(q - h * v, v)[1]) / (2 * h)) @ v
        assert np.max(np.abs(g - fd_g)) <= 1e-7 * max(1.0, np.max(np.abs(g)))
        assert np.max(np.abs(b - fd_b)) <= 1e-7 * max(1.0, np.max(np.abs(b)))
        assert np.max(np.abs(b)) > 1e-3                      # not vacuous


@pytest.mark.parametrize("model", ["floating", "solar_array"])
def test_gradient_rows_are_the_dense_kernels_nonzeros(model, floating, build_dir):
    """The engine reads the joint quantities' Jacobian from its structural nonzeros
    (quantity_gradient_values, gradient_ptr, gradient_idx: a fill reads each row's
    nonzeros, not n_q numbers per row). At random states: the dense kernel, written
    into a buffer of NaN, clears every other entry; its nonzeros all lie in the
    pattern (columns increasing in each row); and the packed values scattered are its
    rows exactly (the same printed expressions), so the finite-difference check above
    covers them too. The floating pair's one row reads all 12 coordinates; the solar
    array's latch rows a few of its 18."""
    solver = (floating if model == "floating"
              else api.load(EXAMPLES / "solar_array.yaml", build_dir))
    events = _event_set(solver)
    for q, v in _random_states(solver, 7):
        ptr, idx, values, dense = events.gradient_rows(q)
        nr, n = dense.shape
        assert not np.isnan(dense).any()
        assert ptr[0] == 0 and ptr[-1] == len(idx) == len(values)
        scattered = np.zeros((nr, n))
        for j in range(nr):
            cols = idx[ptr[j]:ptr[j + 1]]
            assert np.all(np.diff(cols) > 0)
            scattered[j, cols] = values[ptr[j]:ptr[j + 1]]
        assert np.array_equal(scattered, dense)
        assert np.array_equal(dense, events.quantity_kernels(q, v)[1])
        assert np.count_nonzero(values) > 0                          # not vacuous
    assert model == "floating" or len(idx) < nr * n


def test_kernels_printed_in_parts_give_the_same_values(build_dir, tmp_path, monkeypatch):
    """Each event kernel is printed in parts of PART_ROWS rows, each its own C function
    with its own common subexpressions (fccgen.events.build: one function of all rows
    took over 20 minutes to compile for a mast of 200 latched bays). The solar array's
    kernels printed one row per part (every kernel split) give the values of the
    default print (one part at its size) at random states: the same expressions, so
    equal to rounding (1e-15 of each kernel's largest value)."""
    import fccgen.events.build as events_build
    whole = api.load(EXAMPLES / "solar_array.yaml", build_dir)
    monkeypatch.setattr(events_build, "PART_ROWS", 1)
    split = api.load(EXAMPLES / "solar_array.yaml", tmp_path / "split")
    kernels = events_build.print_kernels(
        events_build.event_system(whole.plan))
    assert all(len(k.parts) > 1 for k in kernels if len(k.outputs) > 1)
    sets = [_event_set(s) for s in (whole, split)]
    for q, v in _random_states(whole, 11):
        a, b = (events.quantity_kernels(q, v) for events in sets)
        a += (sets[0].values(q, v, 0.3), sets[0].gradient_rows(q)[2])
        b += (sets[1].values(q, v, 0.3), sets[1].gradient_rows(q)[2])
        for x, y in zip(a, b):
            x, y = np.asarray(x), np.asarray(y)
            assert x.shape == y.shape
            assert np.max(np.abs(x - y)) <= 1e-15 * max(1.0, np.max(np.abs(x)))
