"""Events that cross at the same instant (engine/fcc_event_locate.c, "Ties"). After
the first of them acts, the integrators read every event function again at its
instant; the others are then already past their zero and used to be never seen to
cross: a ball fell through its limit, a latch of a symmetric structure never locked,
and the run said nothing. Each of them now acts at the same instant, in the compiled
engine (dense and sparse paths, rk4 and dopri5) and in the NumPy version.

The model: four identical balls on prismatic joints, dropped from one height onto
their lower limits (exact ties), or latched there by lock events. A constant
acceleration, so RK4 and the continuous extension are exact and the impact time is
the closed form sqrt(2 / g) to the location tolerance (1e-12 s; 1e-10 s leaves room
for the state's rounding)."""
from __future__ import annotations

import math

import pytest

import fccgen
import fccgen.api as api

G = 9.81
N = 4
T_HIT = math.sqrt(2.0 / G)


def model(latch: bool) -> str:
    lines = ["name: tied_balls", "gravity: [0, 0, -9.81]", "bodies:"]
    lines += [f"  b{k}: {{mass: 1.0, inertia: [0.01, 0.01, 0.01], center: [{k}, 0, 0]}}"
              for k in range(N)]
    lines.append("joints:")
    limit = "" if latch else ", limits: [-1.0, 1.0], restitution: 0.5"
    lines += [f"  - {{name: S{k}, type: prismatic, bodies: [ground, b{k}], "
              f"at: [{k}, 0, 0], axis: [0, 0, 1]{limit}}}" for k in range(N)]
    if latch:
        lines.append("events:")
        lines += [f"  - {{name: latch{k}, when: \"S{k}.position <= -1\", do: lock, "
                  f"joint: S{k}}}" for k in range(N)]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module", params=[False, True], ids=["bounce", "lock"])
def case(request, tmp_path_factory, build_dir):
    path = tmp_path_factory.mktemp("ties") / "tied_balls.yaml"
    path.write_text(model(request.param))
    return request.param, path


def check(result, latch: bool) -> None:
    rows = result.events
    assert sorted(r["name"] for r in rows) == sorted(
        (f"latch{k}" if latch else f"S{k}_lower") for k in range(N))
    for r in rows:
        assert abs(r["t"] - T_HIT) <= 1e-10, r
    speed = math.sqrt(2 * G)                      # at the limit
    for k in range(N):
        z = result[f"S{k}.position"]
        assert z.min() >= -1.0 - 1e-9, k            # none passes its limit
        if latch:                                   # held at the limit
            assert abs(z[-1] + 1.0) <= 1e-9, k
        else:                                       # rebounds at half the speed
            assert abs(result[f"S{k}.speed"][-1] - (0.5 * speed - G * (0.6 - T_HIT))) \
                <= 1e-8 * speed, k


@pytest.mark.parametrize("path_kind", ["dense", "sparse"])
@pytest.mark.parametrize("method", ["rk4", "dopri5"])
def test_tied_events_all_act_in_the_compiled_engine(case, build_dir, path_kind, method):
    latch, path = case
    solver = api.load(path, build_dir, linear_solver=path_kind)
    check(solver.simulate(t_end=0.6, dt=1e-3, method=method, reactions=False), latch)


@pytest.mark.parametrize("method", ["rk4", "dopri5"])
def test_tied_events_all_act_in_the_numpy_version(case, method):
    latch, path = case
    check(fccgen.load_numeric(path).simulate(t_end=0.6, dt=1e-3, method=method,
                                             reactions=False), latch)


def test_a_tie_is_located_once(tmp_path, build_dir):
    """The crossings that had not crossed by the left end of the earliest crossing's
    located bracket are ties or later ones: they are acted at its instant (or found
    later in the step) without a location each (engine/fcc_rk4.c, events). Four tied
    latches then cost the run what one latch costs, but for the three other locks' own
    solves, two each on the sparse path (the impact's velocity projection and the new
    row's response): bound 3 each. Locating each of them again cost 49 more solves
    (a mast of 200 bays locked its 200 latches in 200 locations)."""
    solves = {}
    for latched in (1, N):
        text = model(True)
        head, events = text.split("events:\n")
        text = head + "events:\n" + "\n".join(events.splitlines()[:latched]) + "\n"
        path = tmp_path / f"balls_{latched}.yaml"
        path.write_text(text)
        solver = api.load(path, build_dir, linear_solver="sparse")
        solver._fold_trial = False       # the fold kept: the steps after equal in both
        result = solver.simulate(t_end=0.46, dt=1e-3, method="rk4", reactions=False)
        assert len(result.events) == latched
        assert all(abs(r["t"] - T_HIT) <= 1e-10 for r in result.events)
        solves[latched] = result.info["sparse_solves"]
    assert 0 <= solves[N] - solves[1] <= 3 * (N - 1), solves
